//! The MPS weight function and its lattice constants `n0`, `lambda` (equations.md section 1).

use crate::particles::Vector;

/// `f(r/re)` for `0 < r < re`, else 0.
#[inline]
fn on_support(r: f64, re: f64, f: impl Fn(f64) -> f64) -> f64 {
    if r > 0.0 && r < re {
        f(r / re)
    } else {
        0.0
    }
}

/// MPS weight `w(r) = re/r - 1` for `0 < r < re`, else 0 (Koshizuka & Oka 1996).
#[inline]
pub fn weight(r: f64, re: f64) -> f64 {
    if r > 0.0 && r < re {
        re / r - 1.0
    } else {
        0.0
    }
}

/// Smooth weight `(1 - q)^4 (1 + 4 q)`, `q = r/re`, for `0 < r < re`, else 0 (Wendland's
/// C2 function): a number density by it hardly changes under an area-preserving strain of
/// the arrangement, where the MPS weight's grows (docs/decisions.md, "A DS preset for
/// strained bodies").
#[inline]
pub fn smooth_weight(r: f64, re: f64) -> f64 {
    on_support(r, re, |q| (1.0 - q).powi(4) * (1.0 + 4.0 * q))
}

/// Minus the derivative of [`smooth_weight`], `-dW/dr = 20 q (1 - q)^3 / re` (1/m).
#[inline]
pub fn smooth_slope(r: f64, re: f64) -> f64 {
    on_support(r, re, |q| 20.0 * q * (1.0 - q).powi(3) / re)
}

/// Constants of one kernel radius, measured on a perfect lattice around an interior particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelConstants {
    /// Effective radius `re` (m).
    pub re: f64,
    /// Reference particle number density `n0 = sum w(r_ij)` (dimensionless).
    pub n0: f64,
    /// Laplacian coefficient `lambda = sum r^2 w / sum w` (m^2).
    pub lambda: f64,
    /// `h0 = sum re/r` over the lattice neighbours, the HS-source normalisation (dimensionless).
    pub h0: f64,
    /// Number of lattice neighbours with `r < re`.
    pub neighbours: usize,
    /// Reference number density by [`smooth_weight`], `sum W(r_ij)` (dimensionless).
    pub n0_smooth: f64,
    /// `sum -W'(r_ij) r_ij` over the lattice neighbours (dimensionless): the rate of the
    /// smooth number density under a uniform expansion is minus this times the strain rate.
    pub s0_smooth: f64,
}

impl KernelConstants {
    /// Computes the constants for radius `re` (m) on a square/cubic lattice of spacing `l0` (m)
    /// in `D` dimensions.
    pub fn on_lattice<const D: usize>(re: f64, l0: f64) -> Self {
        let k = (re / l0).ceil() as i64 + 1;
        let (mut n0, mut r2w, mut h0, mut count) = (0.0, 0.0, 0.0, 0usize);
        let (mut n0_smooth, mut s0_smooth) = (0.0, 0.0);
        for_each_lattice_offset::<D>(k, |off| {
            let r = (off * l0).norm();
            let w = weight(r, re);
            n0_smooth += smooth_weight(r, re);
            s0_smooth += smooth_slope(r, re) * r;
            if w > 0.0 {
                n0 += w;
                r2w += r * r * w;
                h0 += re / r;
                count += 1;
            }
        });
        KernelConstants {
            re,
            n0,
            lambda: r2w / n0,
            h0,
            neighbours: count,
            n0_smooth,
            s0_smooth,
        }
    }
}

/// The two kernel radii of a simulation and the particle spacing.
#[derive(Clone, Copy, Debug)]
pub struct Kernels {
    /// Radius for number density, gradient, free surface and DS (equations.md s.1).
    pub grad: KernelConstants,
    /// Radius for the Laplacian and the PPE.
    pub lap: KernelConstants,
    /// Initial particle spacing `l0` (m).
    pub l0: f64,
}

impl Kernels {
    /// Kernel constants for spacing `l0` (m) and radii given in units of `l0`.
    pub fn new<const D: usize>(l0: f64, re_grad: f64, re_lap: f64) -> Self {
        Kernels {
            grad: KernelConstants::on_lattice::<D>(re_grad * l0, l0),
            lap: KernelConstants::on_lattice::<D>(re_lap * l0, l0),
            l0,
        }
    }
}

/// Calls `f` for every integer offset in `[-k, k]^D` (as a vector in lattice units).
pub fn for_each_lattice_offset<const D: usize>(k: i64, mut f: impl FnMut(Vector<D>)) {
    let side = (2 * k + 1) as usize;
    let total = side.pow(D as u32);
    for idx in 0..total {
        let mut rem = idx;
        let mut v = Vector::<D>::zero();
        for c in 0..D {
            v.0[c] = (rem % side) as f64 - k as f64;
            rem /= side;
        }
        f(v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<const D: usize>(re: f64, n0: f64, lambda: f64, nb: usize) {
        let c = KernelConstants::on_lattice::<D>(re, 1.0);
        assert!((c.n0 - n0).abs() < 1e-4, "n0 {} vs {}", c.n0, n0);
        assert!(
            (c.lambda - lambda).abs() < 1e-4,
            "lambda {} vs {}",
            c.lambda,
            lambda
        );
        assert_eq!(c.neighbours, nb);
    }

    /// Lattice table of equations.md section 1.
    #[test]
    fn lattice_constants_match_the_design_table() {
        check::<2>(2.1, 6.5397, 1.3884, 12);
        check::<2>(2.4, 9.7747, 1.7708, 20);
        check::<2>(3.1, 18.9764, 2.4485, 28);
        check::<2>(4.0, 35.6092, 3.7071, 44);
        check::<3>(2.1, 14.4186, 1.7017, 32);
        check::<3>(3.1, 54.3212, 3.2434, 122);
    }

    #[test]
    fn h0_is_n0_plus_neighbour_count() {
        let c = KernelConstants::on_lattice::<2>(2.1, 1.0);
        assert!((c.h0 - 18.5397).abs() < 1e-4);
        let c = KernelConstants::on_lattice::<2>(3.1, 1.0);
        assert!((c.h0 - 46.9764).abs() < 1e-4);
    }

    #[test]
    fn lambda_scales_with_spacing_squared() {
        let a = KernelConstants::on_lattice::<2>(0.021, 0.01);
        assert!((a.n0 - 6.5397).abs() < 1e-4);
        assert!((a.lambda / 1e-4 - 1.3884).abs() < 1e-4);
    }

    /// The smooth kernel: zero with zero slope at `re`, one at the centre, its slope the
    /// derivative of its weight (central differences), and its lattice sums at 3.1 l0 in 2D
    /// (`n0_smooth` 3.3330, `s0_smooth` 8.6021, computed independently).
    #[test]
    fn smooth_kernel_and_its_lattice_sums() {
        let re = 0.031;
        assert_eq!(smooth_weight(re, re), 0.0);
        assert!((smooth_weight(1e-12, re) - 1.0).abs() < 1e-9);
        for r in [0.002, 0.01, 0.02, 0.03] {
            let h = 1e-7;
            let fd = -(smooth_weight(r + h, re) - smooth_weight(r - h, re)) / (2.0 * h);
            assert!((fd - smooth_slope(r, re)).abs() < 1e-6 * smooth_slope(0.01, re));
        }
        let c = KernelConstants::on_lattice::<2>(0.031, 0.01);
        assert!((c.n0_smooth - 3.3330).abs() < 1e-4, "{}", c.n0_smooth);
        assert!((c.s0_smooth - 8.6021).abs() < 1e-4, "{}", c.s0_smooth);
    }
}
