//! Pressure-gradient models (paper Eq. 1-3 and the first term of Eq. 7; equations.md
//! section 3, multiphase form of section 7).
//!
//! Each model is a pair term `dp_ij (C_i r_ij) w_ij / (r^2 n0)` divided by a pair density,
//! summed over neighbours within re_grad that carry pressure. `C_i = d I` without gradient
//! correction, the GC tensor with it. The acceleration is `a_i = -sum(...)`.

use super::density::DensityAverage;
use super::kernel::Kernels;
use super::operators::{add_moment, moment_inverse};
use super::pairs::is_within;
use crate::particles::{Matrix, Vector, View};
use serde::{Deserialize, Serialize};

/// Which pressure-gradient model to use (equations.md section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GradientModel {
    /// Original MPS with `p_hat` (paper Eq. 1, 2): purely repulsive.
    Original,
    /// CMPS (paper Eq. 3): antisymmetric pair terms.
    Cmps,
    /// Taylor-consistent `(p_j - p_i)` (first term of paper Eq. 7).
    Taylor,
}

/// Which density divides the pressure gradient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GradientDensity {
    /// The pair density `rho_ij`, as in the PPE (default).
    Pair,
    /// The particle's own density `rho_i`.
    Own,
}

/// What the gradient correction does where the moment matrix is near-singular (a particle
/// whose neighbours sample some directions only: a filament, a tip, a corner).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GcFallback {
    /// `C = d I`, the uncorrected gradient: a fraction of the force along the sampled
    /// directions (0.70 along a line of neighbours in 2D).
    Identity,
    /// The inverse with each eigenvalue raised to at least `gc_min_determinant / d`: exact
    /// along the sampled directions, bounded across the others (the DS preset's; beyond the
    /// paper, docs/decisions.md, "The GC fallback floored").
    Floored,
}

/// The pressure-gradient model of a scheme and its options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressureGradient {
    /// The model.
    pub model: GradientModel,
    /// Gradient correction (Khayyer & Gotoh 2011).
    pub correction: bool,
    /// GC fallback threshold (fraction of the interior moment-matrix determinant).
    pub gc_min_determinant: f64,
    /// GC where the moment matrix is near-singular.
    pub gc_fallback: GcFallback,
    /// Which density divides the gradient.
    pub density: GradientDensity,
    /// How the pair density is formed.
    pub average: DensityAverage,
}

/// Minimum pressure `p_hat_i = min(p_i, min_j p_j)` (Pa) over neighbours within `re` (m) that
/// carry pressure (paper Eq. 2).
pub fn p_hat<const D: usize>(i: usize, v: &View<D>, p: &[f64], carries: &[bool], re: f64) -> f64 {
    // The pairs of `v.pairs(i, re)` without their geometry (a minimum: any order).
    let xi = v.pos[i];
    let mut m = p[i];
    for &j in v.neighbors.for_radius(re).of(i) {
        let j = j as usize;
        let take = carries[j] & is_within((v.pos[j] - xi).norm2(), re);
        m = if take { m.min(p[j]) } else { m };
    }
    m
}

/// Pressure difference (Pa) of one pair term by the model.
#[inline(always)]
fn pair_difference(model: GradientModel, p: &[f64], ph: &[f64], i: usize, j: usize) -> f64 {
    match model {
        // Paper Eq. 1: p_j - p_hat_i, every pair repels.
        GradientModel::Original => p[j] - ph[i],
        // Paper Eq. 3: (p_i + p_j) - (p_hat_i + p_hat_j), antisymmetric.
        GradientModel::Cmps => (p[i] + p[j]) - (ph[i] + ph[j]),
        // Taylor-consistent: p_j - p_i.
        GradientModel::Taylor => p[j] - p[i],
    }
}

/// Whether the GC tensor's fallback is floored (rather than `d I`).
fn floored(g: &PressureGradient) -> bool {
    g.gc_fallback == GcFallback::Floored
}

/// Pressure acceleration `a_i = -<grad p>_i / rho` of fluid particle `i` (m/s^2) by the
/// scheme's model, with the pair density `rho_ij` (default) or the particle's own density.
pub fn pressure_acceleration<const D: usize>(
    i: usize,
    v: &View<D>,
    p: &[f64],
    ph: &[f64],
    carries: &[bool],
    k: &Kernels,
    g: &PressureGradient,
) -> Vector<D> {
    let rho_i = v.density[i];
    // sum_j C_i r_ij s_ij = C_i sum_j r_ij s_ij: the tensor applied once, after the sum, its
    // moment matrix summed over the same pairs in the same loop.
    let (mut sum, mut moment) = (Vector::zero(), Matrix::zero());
    let re = k.grad.re;
    for q in v.pairs(i, re) {
        if !carries[q.j] {
            continue;
        }
        if g.correction {
            add_moment(&mut moment, &q, &k.grad);
        }
        let rho = match g.density {
            GradientDensity::Pair => g.average.of(rho_i, v.density[q.j]),
            GradientDensity::Own => rho_i,
        };
        let dp = pair_difference(g.model, p, ph, i, q.j);
        // w / r^2 = (re - r) / (r r^2): one division a pair instead of two.
        sum += q.xij * (dp * (re - q.r) / (q.r * q.r2 * rho));
    }
    let c = match g.correction {
        true => moment_inverse(moment, g.gc_min_determinant, floored(g)),
        false => Matrix::scaled_identity(D as f64),
    };
    c.mul_vec(&sum) * (-1.0 / k.grad.n0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::scheme::Scheme;
    use crate::particles::view::Cloud;

    fn scheme(name: &str) -> PressureGradient {
        Scheme::preset(name).unwrap().gradient
    }

    /// Total force, total torque (vector) and the sum of force magnitudes of `scheme`'s
    /// pressure gradient over a shaken lattice (`n` per side, D dimensions) with random
    /// pressures.
    fn totals<const D: usize>(name: &str, n: usize) -> (Vector<D>, Vector<3>, f64) {
        let l0 = 0.01;
        let (pos, _) = crate::numerics::operators::tests::lattice_d::<D>(n, l0, 0.4);
        let count = pos.len();
        let p: Vec<f64> = (0..count)
            .map(|i| 1000.0 * ((i as f64 * 0.37).sin() + 1.0))
            .collect();
        let k = Kernels::new::<D>(l0, 2.1, 3.1);
        let rho = vec![1000.0; count];
        let cloud = Cloud::new(pos.clone(), vec![Vector::zero(); count], rho, 0.0, k.lap.re);
        let f = cloud.view();
        let carries = vec![true; count];
        let ph: Vec<f64> = (0..count)
            .map(|i| p_hat(i, &f, &p, &carries, k.grad.re))
            .collect();
        let s = scheme(name);
        let (mut force, mut torque, mut scale) = (Vector::<D>::zero(), Vector::<3>::zero(), 0.0);
        for i in 0..count {
            let a = pressure_acceleration(i, &f, &p, &ph, &carries, &k, &s) * 1000.0;
            force += a;
            torque += Vector(pos[i].cross3(&a));
            scale += a.norm();
        }
        (force, torque, scale)
    }

    /// CMPS pair terms are antisymmetric: the total force and torque vanish to round-off on a
    /// shaken lattice with random pressures, in 2D and 3D; the Taylor gradient (not
    /// antisymmetric) leaves a net force on the same cloud.
    #[test]
    fn cmps_conserves_linear_and_angular_momentum() {
        let (force, torque, scale) = totals::<2>("CMPS-HS", 15);
        assert!(scale > 0.0);
        assert!(force.norm() < 1e-12 * scale, "force {force:?} vs {scale}");
        assert!(torque.norm() < 1e-12 * scale, "torque {torque:?}");
        let (force, torque, scale) = totals::<3>("CMPS-HS", 7);
        assert!(scale > 0.0);
        assert!(
            force.norm() < 1e-12 * scale,
            "3D force {force:?} vs {scale}"
        );
        assert!(torque.norm() < 1e-12 * scale, "3D torque {torque:?}");
        let (force, _, scale) = totals::<2>("MPS-HS-GC", 15);
        assert!(force.norm() > 1e-6 * scale);
    }
}
