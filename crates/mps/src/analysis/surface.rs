//! Free-surface diagnostics that do not trust the free-surface flag: which particles are
//! deep inside the fluid by geometry, which flagged particles are such (false surface), which
//! particles have lost their neighbours (isolated), and which flagged particles have no
//! unflagged neighbour (a surface skin thicker than one row).

use crate::particles::{Kind, Vector, View};
use rayon::prelude::*;

/// Inner and outer radius of the shell a deep particle must see neighbours in, in every
/// direction (units of l0): a particle with a particle 2 to 3.1 l0 away in every direction
/// lies at least two rows (about 2 l0) inside the body.
const SHELL: (f64, f64) = (2.0, 3.1);

/// Cosine of the half-angle of the cone around each lattice direction (30 degrees: the cones
/// around the 3^d - 1 lattice directions cover every direction in 2D and 3D).
const CONE_COS: f64 = 0.866;

/// True when particle `i` lies at least about 2 l0 inside the body: in each of the
/// `3^D - 1` lattice directions a particle (fluid or solid) sits within 30 degrees of it at a
/// distance of 2 to 3.1 l0. Uses neither the free-surface flag nor the number density.
pub fn is_deep<const D: usize>(i: usize, v: &View<D>, l0: f64) -> bool {
    let (inner, outer) = (SHELL.0 * l0, (SHELL.1 * l0).min(v.neighbors.cutoff));
    let shell: Vec<Vector<D>> = v
        .pairs(i, outer)
        .filter(|q| q.r >= inner)
        .map(|q| q.xij / q.r)
        .collect();
    let mut covered = true;
    crate::numerics::kernel::for_each_lattice_offset::<D>(1, |dir| {
        let norm = dir.norm();
        if norm == 0.0 || !covered {
            return;
        }
        let u = dir / norm;
        covered = shell.iter().any(|e| e.dot(&u) >= CONE_COS);
    });
    covered
}

/// The surface diagnostics of a simulation's state, over every process's own particles.
pub fn surface_counts_of<const D: usize>(sim: &crate::simulation::Simulation<D>) -> SurfaceCounts {
    let c = surface_counts(&sim.view(), sim.owned(), sim.l0(), sim.kernels.grad.re);
    let mut v = [c.isolated, c.false_surface, c.surface_skin].map(|x| x as f64);
    sim.sum_over_processes(&mut v);
    SurfaceCounts {
        isolated: v[0] as usize,
        false_surface: v[1] as usize,
        surface_skin: v[2] as usize,
    }
}

/// Counts over the fluid particles of one state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceCounts {
    /// Particles with at most one fluid neighbour within re_grad.
    pub isolated: usize,
    /// Particles flagged free surface that lie deep inside the body ([`is_deep`]).
    pub false_surface: usize,
    /// Flagged particles with no unflagged fluid neighbour within re_grad (the surface is
    /// more than one row thick there; such particles feel no pressure from the bulk).
    pub surface_skin: usize,
}

/// The surface diagnostics of the particles `0 .. n` of view `v` (spacing `l0`, gradient
/// radius `re`, both m); their neighbours may lie beyond `n` (a distributed run's halo).
pub fn surface_counts<const D: usize>(v: &View<D>, n: usize, l0: f64, re: f64) -> SurfaceCounts {
    (0..n)
        .into_par_iter()
        .filter(|&i| v.kind[i] == Kind::Fluid)
        .map(|i| {
            let fluid = || v.pairs(i, re).filter(|q| v.kind[q.j] == Kind::Fluid);
            let flagged = v.free_surface[i];
            SurfaceCounts {
                isolated: (fluid().count() <= 1) as usize,
                false_surface: (flagged && is_deep(i, v, l0)) as usize,
                surface_skin: (flagged && fluid().all(|q| v.free_surface[q.j])) as usize,
            }
        })
        .reduce(SurfaceCounts::default, |a, b| SurfaceCounts {
            isolated: a.isolated + b.isolated,
            false_surface: a.false_surface + b.false_surface,
            surface_skin: a.surface_skin + b.surface_skin,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::view::Cloud;

    /// A block of `n x n` particles at spacing `a` (m).
    fn block(n: usize, a: f64) -> Vec<Vector<2>> {
        (0..n * n)
            .map(|k| Vector([(k % n) as f64 * a, (k / n) as f64 * a]))
            .collect()
    }

    /// On a block at rest, stretched by 3 % or not, exactly the particles two or more rows
    /// from every edge are deep.
    #[test]
    fn deep_means_two_rows_inside_whatever_the_density() {
        let l0 = 0.01;
        for stretch in [1.0, 1.03] {
            let pos = block(12, stretch * l0);
            let n = pos.len();
            let cloud = Cloud::new(
                pos.clone(),
                vec![Vector::zero(); n],
                vec![1.0; n],
                0.0,
                3.4 * l0,
            );
            let v = cloud.view();
            for i in 0..n {
                let (x, y) = (i % 12, i / 12);
                let depth = x.min(y).min(11 - x).min(11 - y);
                assert_eq!(
                    is_deep(i, &v, l0),
                    depth >= 2,
                    "({x}, {y}) at stretch {stretch}"
                );
            }
        }
    }

    #[test]
    fn a_lone_particle_is_isolated() {
        let l0 = 0.01;
        let mut pos = block(5, l0);
        pos.push(Vector([0.5, 0.5]));
        let n = pos.len();
        let cloud = Cloud::new(pos, vec![Vector::zero(); n], vec![1.0; n], 0.0, 3.4 * l0);
        let c = surface_counts(&cloud.view(), n, l0, 2.1 * l0);
        assert_eq!(c.isolated, 1);
        assert_eq!(c.false_surface, 0);
    }
}
