//! Particle state as structure-of-arrays.

use crate::vector::Vector;

/// What a particle is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Kind {
    /// A fluid particle: moves, carries pressure.
    Fluid = 0,
    /// The wall layer next to the fluid: fixed, carries pressure (a PPE unknown).
    Wall = 1,
    /// Dummy layers behind the wall: fixed, only complete the number density.
    Dummy = 2,
}

/// Marker for "no index" in `u32` index arrays.
pub const NONE: u32 = u32::MAX;

/// All particles of a simulation, one array per quantity.
#[derive(Clone, Debug, Default)]
pub struct Particles<const D: usize> {
    /// Stable particle id, kept through reordering.
    pub id: Vec<u32>,
    /// Position (m).
    pub position: Vec<Vector<D>>,
    /// Velocity (m/s).
    pub velocity: Vec<Vector<D>>,
    /// Pressure (Pa).
    pub pressure: Vec<f64>,
    /// Density (kg/m^3); wall and dummy particles take the density of the fluid beside them.
    pub density: Vec<f64>,
    /// Phase index into the case's phase table.
    pub phase: Vec<u16>,
    /// Fluid, wall or dummy.
    pub kind: Vec<Kind>,
    /// Free-surface flag (Dirichlet `p = 0` in the PPE).
    pub free_surface: Vec<bool>,
    /// Particle number density at `re_grad` (dimensionless).
    pub number_density: Vec<f64>,
    /// For dummy particles: index of the wall particle that backs it (pressure extrapolation).
    pub backing_wall: Vec<u32>,
    /// Fluid group for diagnostics (`NO_GROUP` when the region has none).
    pub group: Vec<u16>,
}

/// Marker for particles outside any named group.
pub const NO_GROUP: u16 = u16::MAX;

impl<const D: usize> Particles<D> {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position.len()
    }
    /// True when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
    /// Appends one particle at rest with zero pressure.
    pub fn push(&mut self, x: Vector<D>, u: Vector<D>, kind: Kind, phase: u16, density: f64) {
        self.id.push(self.position.len() as u32);
        self.position.push(x);
        self.velocity.push(u);
        self.pressure.push(0.0);
        self.density.push(density);
        self.phase.push(phase);
        self.kind.push(kind);
        self.free_surface.push(false);
        self.number_density.push(0.0);
        self.backing_wall.push(NONE);
        self.group.push(NO_GROUP);
    }
    /// Number of particles of a kind.
    pub fn count(&self, kind: Kind) -> usize {
        self.kind.iter().filter(|&&k| k == kind).count()
    }
    /// Reorders every array by `order` (new index -> old index), remapping index fields.
    pub fn permute(&mut self, order: &[u32]) {
        let n = self.len();
        debug_assert_eq!(order.len(), n);
        let mut inverse = vec![0u32; n];
        for (new, &old) in order.iter().enumerate() {
            inverse[old as usize] = new as u32;
        }
        fn apply<T: Copy>(v: &mut Vec<T>, order: &[u32]) {
            *v = order.iter().map(|&o| v[o as usize]).collect();
        }
        apply(&mut self.id, order);
        apply(&mut self.position, order);
        apply(&mut self.velocity, order);
        apply(&mut self.pressure, order);
        apply(&mut self.density, order);
        apply(&mut self.phase, order);
        apply(&mut self.kind, order);
        apply(&mut self.free_surface, order);
        apply(&mut self.number_density, order);
        apply(&mut self.backing_wall, order);
        apply(&mut self.group, order);
        for b in &mut self.backing_wall {
            if *b != NONE {
                *b = inverse[*b as usize];
            }
        }
    }
}
