//! MPS differential operators (equations.md sections 1-3), one function per operator,
//! each evaluated for one particle `i` over the pair loop (a gather). These are the
//! operators the step uses; the unit tests below check them on lattices.

use super::kernel::KernelConstants;
use super::pairs::{pairs, Pair};
use crate::particles::{Matrix, NeighborList, Vector};

/// Particle number density `n_i = sum_{j != i} w(|r_ij|)` at radius `re` (m)
/// (equations.md s.1; dimensionless).
#[inline]
pub fn number_density<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    nl: &NeighborList,
    re: f64,
) -> f64 {
    number_density_and_closest(i, pos, nl, (re, 0.0), |_| false).0
}

/// [`number_density`] and, from the same pairs, the closest neighbour's distance (m; infinite
/// without neighbours) and how many neighbours closer than `close` (m) `counts` accepts.
#[inline]
pub fn number_density_and_closest<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    nl: &NeighborList,
    (re, close): (f64, f64),
    counts: impl Fn(usize) -> bool,
) -> (f64, f64, u64) {
    let (mut n, mut closest, mut count) = (0.0, f64::INFINITY, 0);
    for p in pairs(pos, nl, i, re) {
        n += p.w;
        closest = closest.min(p.r);
        count += (p.r < close && counts(p.j)) as u64;
    }
    (n, closest, count)
}

/// Laplacian of a vector field `u`, `(2d/(lambda n0)) sum_j (u_j - u_i) w_ij`
/// (equations.md s.2; units of `u` per m^2).
#[inline]
pub fn laplacian_vector<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    u: &[Vector<D>],
    nl: &NeighborList,
    k: &KernelConstants,
) -> Vector<D> {
    let mut s = Vector::zero();
    for p in pairs(pos, nl, i, k.re) {
        s += (u[p.j] - u[i]) * p.w;
    }
    s * (2.0 * D as f64 / (k.lambda * k.n0))
}

/// Laplacian of a scalar field `phi`, `(2d/(lambda n0)) sum_j (phi_j - phi_i) w_ij`
/// (equations.md s.2; units of `phi` per m^2).
#[inline]
pub fn laplacian<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    phi: &[f64],
    nl: &NeighborList,
    k: &KernelConstants,
) -> f64 {
    let mut s = 0.0;
    for p in pairs(pos, nl, i, k.re) {
        s += (phi[p.j] - phi[i]) * p.w;
    }
    s * 2.0 * D as f64 / (k.lambda * k.n0)
}

/// Taylor-consistent gradient `(d/n0) sum_j (phi_j - phi_i) r_ij w_ij / r^2`
/// (equations.md s.2; units of `phi` per m).
#[inline]
pub fn gradient<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    phi: &[f64],
    nl: &NeighborList,
    k: &KernelConstants,
) -> Vector<D> {
    let mut s = Vector::zero();
    for p in pairs(pos, nl, i, k.re) {
        s += p.xij * ((phi[p.j] - phi[i]) * p.w / p.r2);
    }
    s * (D as f64 / k.n0)
}

/// Divergence `(d/n0) sum_j (u_ij . r_ij) w_ij / r^2` (equations.md s.2; 1/s for velocities).
#[inline]
pub fn divergence<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    u: &[Vector<D>],
    nl: &NeighborList,
    k: &KernelConstants,
) -> f64 {
    let mut s = 0.0;
    for p in pairs(pos, nl, i, k.re) {
        s += (u[p.j] - u[i]).dot(&p.xij) * p.w / p.r2;
    }
    s * D as f64 / k.n0
}

/// Gradient-correction tensor `C_i = [(1/n0) sum_j w_ij (r_ij ⊗ r_ij)/r^2]^-1`
/// (Khayyer & Gotoh 2011; equations.md s.3) over the neighbours accepted by `include`.
/// Where the moment matrix is near-singular (its determinant, as a fraction of that of the
/// interior lattice matrix `I/d`, i.e. `d^-d`, raised to `2/d`, at most `fallback_fraction`)
/// it falls back to `d I`, or with `floored` to its inverse with each eigenvalue raised to at
/// least `fallback_fraction / d` (the lattice's eigenvalue is `1/d`): exact along the
/// directions its neighbours sample, bounded across the others. The power makes the test
/// the same in 2D and 3D (per pair of directions): a half neighbourhood at a free surface
/// has 0.43 of the lattice determinant in 2D and 0.35 in 3D (0.50 after the power); a
/// surface particle beside a wall, whose wall neighbours at its level carry no pressure,
/// 0.25 in 2D and 0.185 in 3D (0.32). The fallback `d I` gave a particle at the tip of a
/// filament a fraction of the force that holds it (docs/decisions.md, "GC fallback" and "The GC fallback floored").
#[inline]
pub fn gradient_correction<const D: usize>(
    i: usize,
    pos: &[Vector<D>],
    nl: &NeighborList,
    k: &KernelConstants,
    include: impl Fn(usize) -> bool,
    fallback_fraction: f64,
    floored: bool,
) -> Matrix<D> {
    let mut m = Matrix::zero();
    for p in pairs(pos, nl, i, k.re) {
        if include(p.j) {
            add_moment(&mut m, &p, k);
        }
    }
    moment_inverse(m, fallback_fraction, floored)
}

/// Pair `p`'s term of the GC moment matrix, `w r_ij (x) r_ij / (r^2 n0)`.
#[inline]
pub fn add_moment<const D: usize>(m: &mut Matrix<D>, p: &Pair<D>, k: &KernelConstants) {
    m.add_scaled(&p.xij.outer(&p.xij), p.w / (p.r2 * k.n0));
}

/// The GC tensor from the summed moment matrix `m` ([`gradient_correction`]'s fallbacks).
#[inline]
pub fn moment_inverse<const D: usize>(
    m: Matrix<D>,
    fallback_fraction: f64,
    floored: bool,
) -> Matrix<D> {
    let reference = (D as f64).powi(-(D as i32));
    let per_pair = |det: f64| {
        let ratio = det / reference;
        if D == 2 {
            ratio
        } else {
            ratio.max(0.0).powf(2.0 / D as f64)
        }
    };
    match m.determinant_and_inverse() {
        Some((det, inv)) if per_pair(det) > fallback_fraction => inv,
        _ if floored => m.floored_inverse(fallback_fraction / D as f64),
        _ => Matrix::scaled_identity(D as f64),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::numerics::kernel::weight;
    use crate::particles::neighbors::build_neighbor_list;

    /// The number density with the closest pair against a direct sum over every point: on
    /// a shaken lattice the same density bit for bit, the smallest distance within `re`
    /// and the count of those closer than 0.9 l0 that the filter accepts (even indices).
    #[test]
    fn number_density_and_closest_match_a_direct_sum() {
        let l0 = 0.01;
        let re = 2.1 * l0;
        let (p, _) = lattice_d::<2>(12, l0, 0.4);
        let nl = build_neighbor_list(&p, 3.1 * l0);
        let mut closer = 0;
        for i in 0..p.len() {
            let even = |j: usize| j.is_multiple_of(2);
            let (n, m, c) = number_density_and_closest(i, &p, &nl, (re, 0.9 * l0), even);
            assert_eq!(n.to_bits(), number_density(i, &p, &nl, re).to_bits());
            let near: Vec<(usize, f64)> = (0..p.len())
                .map(|j| (j, (p[j] - p[i]).norm()))
                .filter(|&(_, r)| r > 0.0 && r < re)
                .collect();
            let direct: f64 = near.iter().map(|&(_, r)| weight(r, re)).sum();
            assert!((n - direct).abs() < 1e-12 * direct, "{n} vs {direct}");
            let m_direct = near.iter().map(|&(_, r)| r).fold(f64::INFINITY, f64::min);
            assert_eq!(m, m_direct);
            let c_direct = near
                .iter()
                .filter(|&&(j, r)| r < 0.9 * l0 && even(j))
                .count();
            assert_eq!(c as usize, c_direct);
            closer += c;
        }
        // The shaken lattice has close pairs, so the count is tested, not only zero.
        assert!(closer > 0);
    }

    /// A square lattice of `n x n` points, spacing `l0`, and the index of a central point.
    pub(crate) fn lattice(n: usize, l0: f64) -> (Vec<Vector<2>>, usize) {
        let mut p = Vec::new();
        for a in 0..n {
            for b in 0..n {
                p.push(Vector([a as f64 * l0, b as f64 * l0]));
            }
        }
        (p, (n / 2) * n + n / 2)
    }

    /// The gradient-corrected gradient of `phi` at `c` (Khayyer & Gotoh's GC with the
    /// pair-difference form), every neighbour counted.
    fn corrected_gradient<const D: usize>(
        c: usize,
        p: &[Vector<D>],
        phi: &[f64],
        nl: &crate::particles::NeighborList,
        k: &KernelConstants,
    ) -> Vector<D> {
        let cm = gradient_correction(c, p, nl, k, |_| true, 0.2, false);
        let mut g = Vector::zero();
        for &j in nl.of(c) {
            let j = j as usize;
            let r = p[j] - p[c];
            let w = weight(r.norm(), k.re);
            g += cm.mul_vec(&r) * ((phi[j] - phi[c]) * w / (r.norm2() * k.n0));
        }
        g
    }

    /// A cubic lattice of `n^D` points, spacing `l0`, each coordinate shifted at random by
    /// up to `jitter` l0 / 2, and the index of the central point.
    pub(crate) fn lattice_d<const D: usize>(
        n: usize,
        l0: f64,
        jitter: f64,
    ) -> (Vec<Vector<D>>, usize) {
        let mut s = 7u64;
        let mut p = Vec::new();
        for k in 0..n.pow(D as u32) {
            let mut x = Vector::<D>::zero();
            let mut rest = k;
            for d in 0..D {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let r = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                x[d] = ((rest % n) as f64 + jitter * r) * l0;
                rest /= n;
            }
            p.push(x);
        }
        let c = (0..D).map(|d| (n / 2) * n.pow(d as u32)).sum();
        (p, c)
    }

    #[test]
    fn in_3d_c_is_3i_inside_and_the_corrected_gradient_is_exact_on_a_perturbed_lattice() {
        let l0 = 0.01;
        let (p, c) = lattice_d::<3>(9, l0, 0.0);
        let k = KernelConstants::on_lattice::<3>(2.1 * l0, l0);
        let nl = build_neighbor_list(&p, 3.1 * l0);
        let m = gradient_correction(c, &p, &nl, &k, |_| true, 0.2, false);
        for a in 0..3 {
            for b in 0..3 {
                let want = if a == b { 3.0 } else { 0.0 };
                assert!((m.0[a][b] - want).abs() < 1e-9, "{m:?}");
            }
        }
        // Laplacian of r^2 is 2 d = 6 with the 3D lambda at re_lap.
        let kl = KernelConstants::on_lattice::<3>(3.1 * l0, l0);
        let phi: Vec<f64> = p.iter().map(|x| x.norm2()).collect();
        let lap = laplacian(c, &p, &phi, &nl, &kl);
        assert!((lap - 6.0).abs() < 1e-9, "lap = {lap}");
        // A linear field on a lattice shaken by up to 0.15 l0: exact with GC, not without.
        let (p, c) = lattice_d::<3>(9, l0, 0.3);
        let nl = build_neighbor_list(&p, 3.1 * l0);
        let want = Vector([3.0, -2.0, 0.5]);
        let phi: Vec<f64> = p.iter().map(|x| want.dot(x)).collect();
        let g = corrected_gradient(c, &p, &phi, &nl, &k);
        assert!((g - want).norm() < 1e-9, "{g:?}");
        let raw = gradient(c, &p, &phi, &nl, &k);
        assert!((raw - want).norm() > 1e-3, "{raw:?}");
    }

    /// The GC fallback test is the same in 2D and 3D: a surface particle beside a wall (its
    /// pressure-carrying neighbours only below it and on one side) keeps the correction in
    /// both, and the corrected gradient of a linear field there is exact; a line of
    /// neighbours (a singular moment matrix) falls back to `d I`, or, floored, keeps it exact
    /// along the line.
    #[test]
    fn a_surface_particle_beside_a_wall_keeps_gc_in_2d_and_3d() {
        fn edge<const D: usize>() {
            let l0 = 0.01;
            let (p, c) = lattice_d::<D>(9, l0, 0.0);
            let k = KernelConstants::on_lattice::<D>(2.1 * l0, l0);
            let nl = build_neighbor_list(&p, 3.1 * l0);
            // Below it, and at its level only on the fluid side (the wall particles there
            // are at p <= 0 and carry nothing).
            let (z, x) = (p[c][D - 1], p[c][0]);
            let keep = |j: usize| {
                p[j][D - 1] < z - 1e-12 || (p[j][D - 1] < z + 1e-12 && p[j][0] > x - 1e-12)
            };
            let m = gradient_correction(c, &p, &nl, &k, keep, 0.2, false);
            let want = Vector::<D>::from_slice(&[3.0, -2.0, 0.5][..D]).unwrap();
            let mut g = Vector::<D>::zero();
            for q in pairs(&p, &nl, c, k.re) {
                if keep(q.j) {
                    g += m.mul_vec(&q.xij) * (want.dot(&q.xij) * q.w / (q.r2 * k.n0));
                }
            }
            assert!((g - want).norm() < 1e-9, "{D}D: {g:?}");
            // A line of neighbours along x (a filament one particle thick): singular. Floored,
            // the eigenvalues are raised to 0.2 / d. Along the line the gradient stays exact
            // (`d I` gave `d sum w x^2 / (r^2 n0)` of it, 0.70 in 2D and 0.48 in 3D here);
            // across it the correction is bounded by `d / 0.2`.
            let line = |j: usize| (1..D).all(|d| (p[j][d] - p[c][d]).abs() < 1e-12);
            let m = gradient_correction(c, &p, &nl, &k, line, 0.2, false);
            assert_eq!(m.0, Matrix::<D>::scaled_identity(D as f64).0);
            let m = gradient_correction(c, &p, &nl, &k, line, 0.2, true);
            let mut g = Vector::<D>::zero();
            for q in pairs(&p, &nl, c, k.re) {
                if line(q.j) {
                    g += m.mul_vec(&q.xij) * (want.dot(&q.xij) * q.w / (q.r2 * k.n0));
                }
            }
            assert!((g[0] - want[0]).abs() < 1e-9, "{D}D along the line: {g:?}");
            for d in 1..D {
                assert!(g[d].abs() < 1e-9, "{D}D across the line: {g:?}");
                assert!((m.0[d][d] - D as f64 / 0.2).abs() < 1e-9, "{:?}", m.0);
            }
        }
        edge::<2>();
        edge::<3>();
    }

    #[test]
    fn laplacian_of_r_squared_is_2d_on_the_lattice() {
        let l0 = 0.01;
        let (p, c) = lattice(11, l0);
        let k = KernelConstants::on_lattice::<2>(3.1 * l0, l0);
        let nl = build_neighbor_list(&p, k.re);
        let phi: Vec<f64> = p.iter().map(|x| x.norm2()).collect();
        let lap = laplacian(c, &p, &phi, &nl, &k);
        assert!((lap - 4.0).abs() < 1e-9, "lap = {lap}");
    }

    #[test]
    fn gradient_of_a_linear_field_is_exact_on_the_lattice() {
        let l0 = 0.01;
        let (p, c) = lattice(11, l0);
        let k = KernelConstants::on_lattice::<2>(2.1 * l0, l0);
        let nl = build_neighbor_list(&p, k.re);
        let phi: Vec<f64> = p.iter().map(|x| 3.0 * x[0] - 2.0 * x[1] + 1.0).collect();
        let g = gradient(c, &p, &phi, &nl, &k);
        assert!((g - Vector([3.0, -2.0])).norm() < 1e-9, "{g:?}");
    }

    #[test]
    fn divergence_of_linear_expansion() {
        let l0 = 0.01;
        let (p, c) = lattice(11, l0);
        let k = KernelConstants::on_lattice::<2>(2.1 * l0, l0);
        let nl = build_neighbor_list(&p, k.re);
        let u: Vec<Vector<2>> = p.iter().map(|x| *x * 0.5).collect();
        let div = divergence(c, &p, &u, &nl, &k);
        assert!((div - 1.0).abs() < 1e-9, "div = {div}");
    }

    #[test]
    fn correction_matrix_is_2i_in_the_interior() {
        let l0 = 0.01;
        let (p, c) = lattice(11, l0);
        let k = KernelConstants::on_lattice::<2>(2.1 * l0, l0);
        let nl = build_neighbor_list(&p, k.re);
        let m = gradient_correction(c, &p, &nl, &k, |_| true, 0.2, false);
        for a in 0..2 {
            for b in 0..2 {
                let want = if a == b { 2.0 } else { 0.0 };
                assert!((m.0[a][b] - want).abs() < 1e-9, "{m:?}");
            }
        }
    }

    #[test]
    fn corrected_gradient_is_exact_on_a_perturbed_lattice() {
        let l0 = 0.01;
        let (mut p, c) = lattice(11, l0);
        let mut s = 7u64;
        for x in p.iter_mut() {
            for k in 0..2 {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                x[k] += ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.3 * l0;
            }
        }
        let k = KernelConstants::on_lattice::<2>(2.1 * l0, l0);
        let nl = build_neighbor_list(&p, k.re);
        let phi: Vec<f64> = p.iter().map(|x| 3.0 * x[0] - 2.0 * x[1]).collect();
        let g = corrected_gradient(c, &p, &phi, &nl, &k);
        assert!((g - Vector([3.0, -2.0])).norm() < 1e-9, "{g:?}");
        // Without correction the perturbed-lattice gradient is off.
        let raw = gradient(c, &p, &phi, &nl, &k);
        assert!((raw - Vector([3.0, -2.0])).norm() > 1e-3);
    }
}
