//! Pressure-gradient models (equations.md section 3, multiphase form of section 7).
//!
//! Each model is a pair term `dp_ij (C_i r_ij) w_ij / (r^2 n0)` divided by a pair density,
//! summed over neighbours within re_grad that carry pressure. `C_i = d I` without gradient
//! correction, the GC tensor with it. The acceleration is `a_i = -sum(...)`.

use crate::case::{GradientDensity, GradientModel};
use crate::fields::{Fields, Kernels};
use crate::kernel::weight;
use crate::operators::gradient_correction;
use crate::scheme::Scheme;
use crate::vector::{Matrix, Vector};

/// Minimum pressure `p_hat_i = min(p_i, min_j p_j)` over neighbours within re_grad that carry
/// pressure (paper Eq. 2).
pub fn p_hat<const D: usize>(i: usize, f: &Fields<D>, p: &[f64], carries: &[bool], re: f64) -> f64 {
    let xi = f.pos[i];
    let mut m = p[i];
    for &j in f.neighbors.of(i) {
        let j = j as usize;
        if carries[j] && (f.pos[j] - xi).norm2() < re * re {
            m = m.min(p[j]);
        }
    }
    m
}

/// Pressure difference of one pair term by the model.
#[inline]
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

/// The tensor `C_i` of particle `i`: the GC inverse moment matrix, or `d I`.
pub fn correction_tensor<const D: usize>(
    i: usize,
    f: &Fields<D>,
    carries: &[bool],
    k: &Kernels,
    s: &Scheme,
) -> Matrix<D> {
    if s.gradient_correction {
        gradient_correction(
            i,
            f.pos,
            f.neighbors.of(i),
            &k.grad,
            |j| carries[j],
            s.gc_min_determinant,
        )
    } else {
        Matrix::scaled_identity(D as f64)
    }
}

/// Pressure acceleration `a_i = -<grad p>_i / rho` of fluid particle `i` (m/s^2) by the scheme's
/// model, with the pair density `rho_ij` (default) or the particle's own density.
pub fn pressure_acceleration<const D: usize>(
    i: usize,
    f: &Fields<D>,
    p: &[f64],
    ph: &[f64],
    carries: &[bool],
    k: &Kernels,
    s: &Scheme,
) -> Vector<D> {
    let c = correction_tensor(i, f, carries, k, s);
    let xi = f.pos[i];
    let re = k.grad.re;
    let rho_i = f.density[i];
    let mut acc = Vector::zero();
    for &j in f.neighbors.of(i) {
        let j = j as usize;
        if !carries[j] {
            continue;
        }
        let rij = f.pos[j] - xi;
        let r2 = rij.norm2();
        let w = weight(r2.sqrt(), re);
        if w == 0.0 {
            continue;
        }
        let rho = match s.gradient_density {
            GradientDensity::Pair => s.pair_density(rho_i, f.density[j]),
            GradientDensity::Own => rho_i,
        };
        let dp = pair_difference(s.gradient, p, ph, i, j);
        acc += c.mul_vec(&rij) * (dp * w / (r2 * rho));
    }
    acc * (-1.0 / k.grad.n0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::SchemeSpec;
    use crate::fields::Cloud;

    fn scheme(name: &str) -> Scheme {
        let sp = SchemeSpec {
            name: name.into(),
            ..Default::default()
        };
        Scheme::from_spec(&sp).unwrap()
    }

    /// CMPS pair terms are antisymmetric: the total force and torque vanish to round-off on a
    /// random cloud with random pressures.
    #[test]
    fn cmps_conserves_linear_and_angular_momentum() {
        let l0 = 0.01;
        let mut pos = Vec::new();
        let mut p = Vec::new();
        let mut seed = 99u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for a in 0..15 {
            for b in 0..15 {
                pos.push(Vector([
                    (a as f64 + 0.4 * (rnd() - 0.5)) * l0,
                    (b as f64 + 0.4 * (rnd() - 0.5)) * l0,
                ]));
                p.push(1000.0 * rnd());
            }
        }
        let n = pos.len();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let rho = vec![1000.0; n];
        let cloud = Cloud::new(
            pos.clone(),
            vec![Vector::zero(); n],
            rho.clone(),
            0.0,
            k.lap.re,
        );
        let f = cloud.fields();
        let s = scheme("CMPS-HS");
        let carries = vec![true; n];
        let ph: Vec<f64> = (0..n)
            .map(|i| p_hat(i, &f, &p, &carries, k.grad.re))
            .collect();
        let mut force = Vector::<2>::zero();
        let mut torque = 0.0;
        let mut scale = 0.0;
        for i in 0..n {
            let a = pressure_acceleration(i, &f, &p, &ph, &carries, &k, &s) * rho[i];
            force += a;
            torque += pos[i].cross_z(&a);
            scale += a.norm();
        }
        assert!(force.norm() < 1e-12 * scale, "force {force:?} vs {scale}");
        assert!(torque.abs() < 1e-12 * scale, "torque {torque}");
        // The Taylor gradient is not antisymmetric: the same cloud gives a net force.
        let t = scheme("MPS-HS-GC");
        let mut f2 = Vector::<2>::zero();
        for i in 0..n {
            f2 += pressure_acceleration(i, &f, &p, &ph, &carries, &k, &t) * rho[i];
        }
        assert!(f2.norm() > 1e-6 * scale);
    }
}
