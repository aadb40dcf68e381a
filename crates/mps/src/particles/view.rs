//! A read-only view of the particle state that the step's stages share: the intermediate
//! positions and velocities of the current step beside the arrays that do not change in it.

use super::fields::Kind;
use super::neighbors::NeighborList;
use super::vector::Vector;

/// The state one stage of the step reads.
#[derive(Clone, Copy)]
pub struct View<'a, const D: usize> {
    /// Positions (m), the intermediate `r*` after the explicit stage.
    pub pos: &'a [Vector<D>],
    /// Velocities (m/s), the intermediate `u*`.
    pub vel: &'a [Vector<D>],
    /// Particle kinds.
    pub kind: &'a [Kind],
    /// Densities (kg/m^3).
    pub density: &'a [f64],
    /// Free-surface flags.
    pub free_surface: &'a [bool],
    /// Number density `n*` at re_grad (dimensionless).
    pub number_density: &'a [f64],
    /// Neighbour lists (cut-off at least the largest radius).
    pub neighbors: &'a NeighborList,
}

/// Owned arrays of an all-fluid particle cloud, for unit tests of the stages.
#[cfg(test)]
pub(crate) struct Cloud<const D: usize> {
    pos: Vec<Vector<D>>,
    vel: Vec<Vector<D>>,
    kind: Vec<Kind>,
    density: Vec<f64>,
    free_surface: Vec<bool>,
    number_density: Vec<f64>,
    neighbors: NeighborList,
}

#[cfg(test)]
impl<const D: usize> Cloud<D> {
    /// A cloud of fluid particles (no free surface, number density `nd`), neighbours within
    /// `cutoff` (m).
    pub(crate) fn new(
        pos: Vec<Vector<D>>,
        vel: Vec<Vector<D>>,
        density: Vec<f64>,
        nd: f64,
        cutoff: f64,
    ) -> Self {
        let n = pos.len();
        let neighbors = super::neighbors::build_neighbor_list(&pos, cutoff);
        Cloud {
            pos,
            vel,
            kind: vec![Kind::Fluid; n],
            density,
            free_surface: vec![false; n],
            number_density: vec![nd; n],
            neighbors,
        }
    }
    /// Makes the particles at positions where `wall` holds wall particles.
    pub(crate) fn set_walls(&mut self, wall: impl Fn(&Vector<D>) -> bool) {
        for (k, x) in self.kind.iter_mut().zip(&self.pos) {
            if wall(x) {
                *k = Kind::Wall;
            }
        }
    }
    /// Flags the particles at positions where `surface` holds as free surface.
    pub(crate) fn set_surface(&mut self, surface: impl Fn(&Vector<D>) -> bool) {
        for (f, x) in self.free_surface.iter_mut().zip(&self.pos) {
            *f = surface(x);
        }
    }
    /// The view the stages read.
    pub(crate) fn view(&self) -> View<'_, D> {
        View {
            pos: &self.pos,
            vel: &self.vel,
            kind: &self.kind,
            density: &self.density,
            free_surface: &self.free_surface,
            number_density: &self.number_density,
            neighbors: &self.neighbors,
        }
    }
}
