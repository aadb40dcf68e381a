//! Interface repulsion between unlike fluid particles (beyond the paper; docs/decisions.md,
//! "Interface repulsion against two-phase mixing").
//!
//! A background pressure `P` (Pa) that acts only across the interface between two phases,
//! in the symmetric MPS gradient form (equations.md s.3 with `p_i + p_j = 2 P`): for fluid
//! particle `i` of phase `a`,
//! `a_i = -(2 P d / (rho_i n0)) sum_j r_ij w_ij / |r_ij|^2` over the fluid neighbours `j` of
//! any other phase within re_grad. The pair force `rho_i V a_i` is equal and opposite on
//! `j`, so momentum is conserved whatever the densities; a particle with unlike neighbours
//! on every side of a regular lattice feels none, one at a flat interface is pushed back
//! into its own phase. It raises the energy of unlike contact, so neighbouring unlike
//! particles do not trade places (the interface-sharpness idea of Grenier, Antuono,
//! Colagrossi, Le Touze & Alessandrini 2009, J. Comput. Phys. 228, with a constant
//! pressure scale). An explicit force of the prediction (stage 2), so the projection
//! balances it at rest by a pressure step of about `2 P` across the interface. A case gives
//! `P` or the interface energy `P l0` (N/m), which keeps the interface as l0 changes
//! (docs/decisions.md, "The repulsion at l0 halved").

use super::kernel::Kernels;
use crate::particles::{Kind, Vector, View};

/// Interface repulsion parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterfaceRepulsion {
    /// Background pressure `P` across unlike pairs (Pa).
    pub pressure: f64,
}

/// The repulsion acceleration (m/s^2) of fluid particle `i` of view `v` (zero for other
/// kinds and for particles without an unlike fluid neighbour), `phase` each particle's phase.
pub fn interface_repulsion<const D: usize>(
    i: usize,
    v: &View<D>,
    phase: &[u16],
    k: &Kernels,
    r: &InterfaceRepulsion,
) -> Vector<D> {
    if v.kind[i] != Kind::Fluid {
        return Vector::zero();
    }
    let mut sum = Vector::zero();
    for q in v.pairs(i, k.grad.re) {
        if v.kind[q.j] == Kind::Fluid && phase[q.j] != phase[i] {
            sum += q.xij * (q.w / q.r2);
        }
    }
    sum * (-2.0 * r.pressure * D as f64 / (v.density[i] * k.grad.n0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::view::Cloud;

    /// A square lattice of two phases split at `split` (phase 1 for `x >= split`), with the
    /// phases' densities, and every particle's repulsion at `P = 10 Pa`.
    fn lattice(split: f64, rho: [f64; 2]) -> (Vec<Vector<2>>, Vec<f64>, Vec<Vector<2>>) {
        let l0 = 0.01;
        let mut pos = Vec::new();
        for ix in -6..6 {
            for iy in -6..6 {
                pos.push(Vector([ix as f64 * l0, iy as f64 * l0]));
            }
        }
        let phase: Vec<u16> = pos.iter().map(|x| u16::from(x[0] >= split)).collect();
        let density: Vec<f64> = phase.iter().map(|&p| rho[p as usize]).collect();
        let cloud = Cloud::new(
            pos.clone(),
            vec![Vector::zero(); pos.len()],
            density.clone(),
            0.0,
            3.1 * l0,
        );
        let v = cloud.view();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let r = InterfaceRepulsion { pressure: 10.0 };
        let a = (0..pos.len())
            .map(|i| interface_repulsion(i, &v, &phase, &k, &r))
            .collect();
        (pos, density, a)
    }

    #[test]
    fn one_phase_feels_nothing() {
        let (_, _, a) = lattice(1.0, [1000.0, 2650.0]);
        assert!(a.iter().all(|a| *a == Vector::zero()));
    }

    #[test]
    fn a_flat_interface_pushes_each_phase_back_and_conserves_momentum() {
        let (pos, rho, a) = lattice(0.0, [1000.0, 2650.0]);
        let mut momentum = Vector::<2>::zero();
        for i in 0..pos.len() {
            momentum += a[i] * rho[i];
            let x = pos[i][0];
            // The interface lies midway between the rows at -l0 and 0.
            if (x + 0.005).abs() > 0.021 {
                // No unlike particle within re_grad.
                assert_eq!(a[i], Vector::zero());
            } else if x < 0.0 {
                assert!(a[i][0] < 0.0, "{x}: {:?}", a[i]);
            } else {
                assert!(a[i][0] > 0.0, "{x}: {:?}", a[i]);
            }
        }
        assert!(momentum.norm() < 1e-9, "{momentum:?}");
        // Away from the lattice's own edges the push is along x only, and it is the MPS
        // gradient of a pressure step of 2 P across the interface: on the first row
        // (2 P d / (rho n0)) sum over the unlike neighbours of x / r^2 w.
        let i = pos
            .iter()
            .position(|x| (x[0] + 0.01).abs() < 1e-12 && x[1].abs() < 1e-12)
            .unwrap();
        let k = Kernels::new::<2>(0.01, 2.1, 3.1);
        let mut want = 0.0;
        for (dx, dy) in (1..=2).flat_map(|dx| (-2..=2).map(move |dy| (dx as f64, dy as f64))) {
            let r = (dx * dx + dy * dy).sqrt() * 0.01;
            if r < 0.021 {
                want += dx * 0.01 / (r * r) * crate::numerics::weight(r, 0.021);
            }
        }
        want *= -2.0 * 10.0 * 2.0 / (1000.0 * k.grad.n0);
        assert!(a[i][1].abs() < 1e-12);
        assert!(
            (a[i][0] - want).abs() < 1e-12 * want.abs(),
            "{} {want}",
            a[i][0]
        );
    }
}
