//! Modified D-ILU preconditioned conjugate gradient with Eisenstat's trick (Eisenstat 1981,
//! SIAM J. Sci. Stat. Comput. 2(1):1-4).
//!
//! The preconditioner is `M = T D^-1 T^T` with `T = D + L`, `L` the strict lower triangle of
//! the matrix itself and `D` a diagonal chosen so that `M` keeps the row sums of `A`
//! (relaxed by `omega`, as modified incomplete Cholesky does; `omega = 0` keeps the
//! diagonal instead: D-ILU). Because `T + T^T = A + K` with the diagonal `K = 2D - diag(A)`,
//! the preconditioned operator `T^-1 A T^-T` applied to a vector costs one backward and one
//! forward substitution with the rows of `A` (`w = T^-T p`, `q = w + T^-1 (p - K w)`),
//! instead of a product with `A` and two substitutions with a stored factor: half the
//! memory traffic per CG iteration, no factor to build or store, a set-up of one pass over
//! the lower triangle. CG runs on `T^-1 A T^-T y = T^-1 b` with the diagonal preconditioner
//! `D`, `x = T^-T y`; this is exactly PCG on `A x = b` with `M` (the same iterates in exact
//! arithmetic). It stops on the true residual `|b - A x| <= tol |b|`, checked whenever the
//! cheap `M^-1`-norm of the residual has fallen by the same factor.

use super::pcg::{NotConverged, SolveStats};
use super::sparse::{row_dot, CsrMatrix};

/// The modified D-ILU preconditioner of a symmetric matrix whose rows are sorted by column
/// and hold their diagonal.
#[derive(Clone, Debug, Default)]
pub struct Dilu {
    /// Position of each row's diagonal entry in the matrix's `col`/`val`.
    diag_pos: Vec<u32>,
    /// `D` (the pivots).
    d: Vec<f64>,
    /// `1 / D`.
    inv_d: Vec<f64>,
    /// `K = 2 D - diag(A)`.
    k: Vec<f64>,
    /// Each row's sum right of its diagonal (the set-up's scratch, kept).
    upper_sum: Vec<f64>,
}

impl Dilu {
    /// The pivots of `a` relaxed by `omega` in [0, 1]:
    /// `d_i = a_ii - sum_{j<i} (a_ij / d_j) (a_ij + omega (s_j - a_ij))`, `s_j` the sum of
    /// row `j`'s entries right of its diagonal. `None` if a row lacks its diagonal or a
    /// pivot is not positive.
    pub fn new(a: &CsrMatrix, omega: f64) -> Option<Dilu> {
        let mut m = Dilu::default();
        m.rebuild(a, omega).then_some(m)
    }

    /// [`Dilu::new`] in this preconditioner's memory; false (unusable) where `new` gives
    /// `None`.
    pub fn rebuild(&mut self, a: &CsrMatrix, omega: f64) -> bool {
        let n = a.n();
        let Dilu {
            diag_pos,
            d,
            inv_d,
            k,
            upper_sum,
        } = self;
        diag_pos.clear();
        upper_sum.clear();
        for v in [&mut *d, &mut *inv_d] {
            v.clear();
            v.resize(n, 0.0);
        }
        for i in 0..n {
            let (start, end) = (a.row_ptr[i] as usize, a.row_ptr[i + 1] as usize);
            let p = start + a.col[start..end].partition_point(|&c| (c as usize) < i);
            if p == end || a.col[p] as usize != i {
                return false;
            }
            diag_pos.push(p as u32);
            upper_sum.push(a.val[p + 1..end].iter().sum::<f64>());
            let mut di = a.val[p];
            for q in start..p {
                let j = a.col[q] as usize;
                let aij = a.val[q];
                di -= aij * inv_d[j] * (aij + omega * (upper_sum[j] - aij));
            }
            if !(di > 0.0) || !di.is_finite() {
                return false;
            }
            d[i] = di;
            inv_d[i] = 1.0 / di;
        }
        k.clear();
        k.extend((0..n).map(|i| 2.0 * d[i] - a.val[diag_pos[i] as usize]));
        true
    }

    /// The strict lower part of row `i` of `a`.
    #[inline]
    fn lower<'a>(&self, a: &'a CsrMatrix, i: usize) -> (&'a [u32], &'a [f64]) {
        let (s, p) = (a.row_ptr[i] as usize, self.diag_pos[i] as usize);
        (&a.col[s..p], &a.val[s..p])
    }

    /// The strict upper part of row `i` of `a`.
    #[inline]
    fn upper<'a>(&self, a: &'a CsrMatrix, i: usize) -> (&'a [u32], &'a [f64]) {
        let (p, e) = (self.diag_pos[i] as usize, a.row_ptr[i + 1] as usize);
        (&a.col[p + 1..e], &a.val[p + 1..e])
    }

    /// `u = T^-1 v` (forward substitution).
    pub fn forward(&self, a: &CsrMatrix, v: &[f64], u: &mut [f64]) {
        for i in 0..v.len() {
            let (c, x) = self.lower(a, i);
            u[i] = (v[i] - lower_dot(c, x, u)) * self.inv_d[i];
        }
    }

    /// `w = T^-T v` (backward substitution over the rows' upper parts, `A` symmetric).
    pub fn backward(&self, a: &CsrMatrix, v: &[f64], w: &mut [f64]) {
        for i in (0..v.len()).rev() {
            let (c, x) = self.upper(a, i);
            w[i] = (v[i] - upper_dot(c, x, w)) * self.inv_d[i];
        }
    }

    /// `y = T^T x`.
    pub fn upper_times(&self, a: &CsrMatrix, x: &[f64], y: &mut [f64]) {
        for i in 0..x.len() {
            let (c, v) = self.upper(a, i);
            y[i] = self.d[i] * x[i] + row_dot(c, v, x);
        }
    }

    /// `q = T^-1 A T^-T p` by Eisenstat's trick; `w` receives `T^-T p`.
    fn operator(&self, a: &CsrMatrix, p: &[f64], w: &mut [f64], q: &mut [f64]) {
        self.backward(a, p, w);
        // u = T^-1 (p - K w), held in q while it is built; then q = w + u.
        for i in 0..p.len() {
            let (c, x) = self.lower(a, i);
            q[i] = (p[i] - self.k[i] * w[i] - lower_dot(c, x, q)) * self.inv_d[i];
        }
        for (qi, wi) in q.iter_mut().zip(w.iter()) {
            *qi += wi;
        }
    }
}

/// A substitution's row sum over the strict lower part of a row (columns ascending): the
/// last entry, the row just solved, is added after the others, so that only one product
/// waits on it (the rows' dependency chain sets the substitution's speed).
#[inline]
fn lower_dot(c: &[u32], x: &[f64], u: &[f64]) -> f64 {
    match c.len() {
        0 => 0.0,
        m => row_dot(&c[..m - 1], &x[..m - 1], u) + x[m - 1] * u[c[m - 1] as usize],
    }
}

/// The same over the strict upper part (columns ascending; the first is the row just solved
/// by the backward substitution).
#[inline]
fn upper_dot(c: &[u32], x: &[f64], w: &[f64]) -> f64 {
    match c.len() {
        0 => 0.0,
        _ => row_dot(&c[1..], &x[1..], w) + x[0] * w[c[0] as usize],
    }
}

/// `a . b` on the calling thread in four partial sums (the solve is sequential: waking a
/// second worker for each dot product cost more than the product).
fn seq_dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    for (x, y) in ra.iter().zip(rb) {
        acc[0] += x * y;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// `r = b - A x`; returns `|r|`.
fn true_residual(a: &CsrMatrix, b: &[f64], x: &[f64], r: &mut [f64]) -> f64 {
    a.spmv(x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    seq_dot(r, r).sqrt()
}

/// PCG on the SPD matrix `a` (rows sorted, symmetric) with the modified D-ILU
/// preconditioner `m`, from the warm start `x`, to the relative residual `tol`
/// (module docs).
pub fn dilu_cg(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &Dilu,
    tol: f64,
    max_iter: usize,
) -> Result<SolveStats, NotConverged> {
    dilu_cg_in(a, b, x, m, (tol, max_iter), &mut DiluCgVectors::default())
}

/// The work vectors of [`dilu_cg`], kept between solves.
#[derive(Clone, Debug, Default)]
pub struct DiluCgVectors {
    r: Vec<f64>,
    y: Vec<f64>,
    rh: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    w: Vec<f64>,
    q: Vec<f64>,
}

/// [`dilu_cg`] to `(tol, max_iter)` in the memory of `work`.
pub fn dilu_cg_in(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &Dilu,
    (tol, max_iter): (f64, usize),
    work: &mut DiluCgVectors,
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let DiluCgVectors {
        r,
        y,
        rh,
        z,
        p,
        w,
        q,
    } = work;
    for v in [&mut *r, &mut *y, &mut *rh, &mut *w, &mut *q] {
        v.clear();
        v.resize(n, 0.0);
    }
    let bnorm = seq_dot(b, b).sqrt();
    if bnorm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return Ok(SolveStats::default());
    }
    let goal = tol * bnorm;
    let mut rnorm = true_residual(a, b, x, r);
    if rnorm <= goal {
        return Ok(SolveStats {
            iterations: 0,
            residual: rnorm / bnorm,
        });
    }
    // Transformed unknowns y = T^T x and residual r^ = T^-1 r; z = D r^.
    m.upper_times(a, x, y);
    m.forward(a, r, rh);
    z.clear();
    z.extend(rh.iter().zip(&m.d).map(|(r, d)| r * d));
    let mut rz = seq_dot(rh, z);
    // The M^-1 norm must fall by the factor the true residual has to.
    let mut target = rz.sqrt() * goal / rnorm;
    p.clear();
    p.extend_from_slice(z);
    for it in 1..=max_iter {
        m.operator(a, p, w, q);
        let pq = seq_dot(p, q);
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        let mut rz_new = 0.0;
        for i in 0..n {
            y[i] += alpha * p[i];
            rh[i] -= alpha * q[i];
            z[i] = m.d[i] * rh[i];
            rz_new += rh[i] * z[i];
        }
        if !rz_new.is_finite() {
            break;
        }
        if rz_new.sqrt() <= target {
            m.backward(a, y, x);
            rnorm = true_residual(a, b, x, r);
            if rnorm <= goal {
                return Ok(SolveStats {
                    iterations: it,
                    residual: rnorm / bnorm,
                });
            }
            target = rz_new.sqrt() * goal / rnorm;
        }
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    m.backward(a, y, x);
    rnorm = true_residual(a, b, x, r);
    Err(NotConverged::at(max_iter, rnorm / bnorm))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::ic0::Ic0;
    use crate::linalg::pcg::pcg;
    use crate::linalg::sparse::dot;
    use crate::linalg::tests::laplace_2d as laplacian;

    /// `M v = T D^-1 T^T v`, formed with the substitution helpers' inverses.
    fn m_times(m: &Dilu, a: &CsrMatrix, v: &[f64]) -> Vec<f64> {
        let n = v.len();
        let mut t = vec![0.0; n];
        m.upper_times(a, v, &mut t);
        for i in 0..n {
            t[i] *= m.inv_d[i];
        }
        // T t = D t + L t.
        (0..n)
            .map(|i| {
                let (c, x) = m.lower(a, i);
                m.d[i] * t[i] + row_dot(c, x, &t)
            })
            .collect()
    }

    /// Entry by entry within 1e-12.
    fn assert_close(got: &[f64], want: &[f64]) {
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 1e-12, "entry {i}: {g} vs {w}");
        }
    }

    /// At omega = 1 `M` keeps the row sums of `A`; at omega = 0 its diagonal (D-ILU).
    #[test]
    fn the_modified_pivots_keep_row_sums_and_the_plain_ones_the_diagonal() {
        let a = laplacian(9);
        let n = a.n();
        let one = vec![1.0; n];
        let m = Dilu::new(&a, 1.0).unwrap();
        let (mut ae, me) = (vec![0.0; n], m_times(&m, &a, &one));
        a.spmv(&one, &mut ae);
        assert_close(&ae, &me);
        let m0 = Dilu::new(&a, 0.0).unwrap();
        for i in 0..n {
            let mut e = vec![0.0; n];
            e[i] = 1.0;
            let mi = m_times(&m0, &a, &e)[i];
            assert!((mi - a.get(i, i)).abs() < 1e-12, "diag {i}: {mi}");
        }
    }

    /// Eisenstat's operator equals `T^-1 A T^-T` formed the long way.
    #[test]
    fn the_operator_is_the_preconditioned_matrix() {
        let a = laplacian(7);
        let n = a.n();
        let m = Dilu::new(&a, 0.97).unwrap();
        let p: Vec<f64> = (0..n).map(|i| ((i * 13 % 7) as f64 - 3.0) * 0.1).collect();
        let (mut w, mut q) = (vec![0.0; n], vec![0.0; n]);
        m.operator(&a, &p, &mut w, &mut q);
        let mut tp = vec![0.0; n];
        m.backward(&a, &p, &mut tp);
        let mut atp = vec![0.0; n];
        a.spmv(&tp, &mut atp);
        let mut want = vec![0.0; n];
        m.forward(&a, &atp, &mut want);
        assert_close(&q, &want);
    }

    /// The solve reaches the true relative residual asked for, in as many iterations as
    /// plain PCG with the same preconditioner takes (the same iterates), and fewer than
    /// IC(0)-CG at omega 0.97.
    #[test]
    fn it_solves_a_laplacian_like_pcg_with_the_same_preconditioner() {
        let a = laplacian(30);
        let n = a.n();
        let b: Vec<f64> = (0..n).map(|i| ((i * 37 % 11) as f64 - 5.0) / 5.0).collect();
        let m = Dilu::new(&a, 0.97).unwrap();
        let mut x = vec![0.0; n];
        let st = dilu_cg(&a, &b, &mut x, &m, 1e-10, 500).unwrap();
        let mut r = vec![0.0; n];
        let rn = true_residual(&a, &b, &x, &mut r);
        let bn = dot(&b, &b).sqrt();
        assert!(rn <= 1e-10 * bn && (st.residual - rn / bn).abs() < 1e-15);
        // The same preconditioner applied the long way inside the generic PCG.
        struct Long<'a>(&'a Dilu, &'a CsrMatrix);
        impl crate::linalg::pcg::Precondition for Long<'_> {
            fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
                let n = r.len();
                let mut t = vec![0.0; n];
                self.0.forward(self.1, r, &mut t);
                for i in 0..n {
                    t[i] *= self.0.d[i];
                }
                self.0.backward(self.1, &t, z);
            }
        }
        let mut x2 = vec![0.0; n];
        let st2 = pcg(&a, &b, &mut x2, &Long(&m, &a), 1e-10, 500).unwrap();
        assert!(
            st.iterations.abs_diff(st2.iterations) <= 1,
            "{} vs {}",
            st.iterations,
            st2.iterations
        );
        let ic = Ic0::new(&a).unwrap();
        let mut x3 = vec![0.0; n];
        let st3 = pcg(&a, &b, &mut x3, &ic, 1e-10, 500).unwrap();
        assert!(
            st.iterations < st3.iterations,
            "{} vs IC(0) {}",
            st.iterations,
            st3.iterations
        );
        // A warm start from the solution needs no iteration.
        let st4 = dilu_cg(&a, &b, &mut x, &m, 1e-10, 500).unwrap();
        assert_eq!(st4.iterations, 0);
    }

    /// A row without its diagonal is refused.
    #[test]
    fn a_missing_diagonal_is_refused() {
        let a = CsrMatrix::from_rows(vec![vec![(1, -1.0)], vec![(0, -1.0), (1, 2.0)]]);
        assert!(Dilu::new(&a, 0.0).is_none());
    }
}
