//! Sparse symmetric positive-definite linear algebra for the PPE: CSR matrices and
//! preconditioned conjugate gradient. Every reduction runs in a fixed order (fixed-size
//! chunks summed in sequence), so results do not depend on the number of threads.

use crate::amg::Amg;
use rayon::prelude::*;

/// Elements per chunk of a deterministic parallel reduction.
const CHUNK: usize = 4096;

/// A square sparse matrix in compressed-sparse-row form with `u32` column indices.
#[derive(Clone, Debug, Default)]
pub struct CsrMatrix {
    /// Row starts into `col`/`val` (length `n + 1`).
    pub row_ptr: Vec<u32>,
    /// Column index of each stored entry (sorted within a row).
    pub col: Vec<u32>,
    /// Value of each stored entry.
    pub val: Vec<f64>,
}

impl CsrMatrix {
    /// Number of rows.
    pub fn n(&self) -> usize {
        self.row_ptr.len().saturating_sub(1)
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.val.len()
    }
    /// The entries of row `i` as (columns, values).
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let (a, b) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
        (&self.col[a..b], &self.val[a..b])
    }
    /// `y = A x`, parallel over rows.
    pub fn spmv(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(1024).enumerate().for_each(|(c, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                let (cols, vals) = self.row(c * 1024 + k);
                let mut s = 0.0;
                for (cj, v) in cols.iter().zip(vals) {
                    s += v * x[*cj as usize];
                }
                *yi = s;
            }
        });
    }
    /// The diagonal entries (0 where none is stored).
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.n())
            .into_par_iter()
            .map(|i| {
                let (c, v) = self.row(i);
                c.iter()
                    .position(|&j| j as usize == i)
                    .map_or(0.0, |k| v[k])
            })
            .collect()
    }
    /// Value at `(i, j)`, 0 when not stored.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (c, v) = self.row(i);
        c.binary_search(&(j as u32)).map_or(0.0, |k| v[k])
    }
    /// Largest `|A_ij - A_ji|` over stored entries.
    pub fn asymmetry(&self) -> f64 {
        (0..self.n())
            .map(|i| {
                let (c, v) = self.row(i);
                c.iter()
                    .zip(v)
                    .map(|(&j, &a)| (a - self.get(j as usize, i)).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }
}

/// Transpose of an `n x ncols` CSR matrix (an `ncols x n` matrix, columns sorted).
pub fn transpose(a: &CsrMatrix, ncols: usize) -> CsrMatrix {
    let mut count = vec![0u32; ncols + 1];
    for &j in &a.col {
        count[j as usize + 1] += 1;
    }
    for k in 0..ncols {
        count[k + 1] += count[k];
    }
    let row_ptr = count.clone();
    let mut next = count;
    let mut col = vec![0u32; a.nnz()];
    let mut val = vec![0.0; a.nnz()];
    for i in 0..a.n() {
        let (c, v) = a.row(i);
        for (&j, &x) in c.iter().zip(v) {
            let slot = next[j as usize] as usize;
            col[slot] = i as u32;
            val[slot] = x;
            next[j as usize] += 1;
        }
    }
    CsrMatrix { row_ptr, col, val }
}

/// Sparse product `A B` of CSR matrices, `B` with `ncols` columns; parallel over rows of
/// `A`, each row accumulated in a dense scratch row (Gustavson's algorithm).
pub fn spgemm(a: &CsrMatrix, b: &CsrMatrix, ncols: usize) -> CsrMatrix {
    let rows: Vec<(Vec<u32>, Vec<f64>)> = (0..a.n())
        .into_par_iter()
        .map_init(
            || (vec![u32::MAX; ncols], vec![0.0f64; ncols]),
            |(mark, acc), i| {
                let mut cols: Vec<u32> = Vec::new();
                let (ca, va) = a.row(i);
                for (&k, &x) in ca.iter().zip(va) {
                    let (cb, vb) = b.row(k as usize);
                    for (&j, &y) in cb.iter().zip(vb) {
                        let j = j as usize;
                        if mark[j] != i as u32 {
                            mark[j] = i as u32;
                            acc[j] = 0.0;
                            cols.push(j as u32);
                        }
                        acc[j] += x * y;
                    }
                }
                cols.sort_unstable();
                let vals = cols.iter().map(|&j| acc[j as usize]).collect();
                (cols, vals)
            },
        )
        .collect();
    let mut out = CsrMatrix {
        row_ptr: Vec::with_capacity(a.n() + 1),
        col: Vec::with_capacity(rows.iter().map(|r| r.0.len()).sum()),
        val: Vec::new(),
    };
    out.val.reserve(out.col.capacity());
    out.row_ptr.push(0);
    for (c, v) in rows {
        out.col.extend_from_slice(&c);
        out.val.extend_from_slice(&v);
        out.row_ptr.push(out.col.len() as u32);
    }
    out
}

/// Dot product in a fixed summation order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let parts: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>())
        .collect();
    parts.iter().sum()
}

/// Incomplete Cholesky factor `L` (lower triangle incl. diagonal, row-wise) with the
/// sparsity of the lower triangle of `A`: IC(0).
#[derive(Clone, Debug)]
pub struct Ic0 {
    l: CsrMatrix,
}

impl Ic0 {
    /// Factors `a`; `None` if a pivot is not positive.
    pub fn new(a: &CsrMatrix) -> Option<Ic0> {
        let n = a.n();
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col = Vec::with_capacity(a.nnz() / 2 + n);
        let mut val = Vec::with_capacity(a.nnz() / 2 + n);
        row_ptr.push(0u32);
        for i in 0..n {
            let (c, v) = a.row(i);
            for (&j, &x) in c.iter().zip(v) {
                if (j as usize) <= i {
                    col.push(j);
                    val.push(x);
                }
            }
            row_ptr.push(col.len() as u32);
        }
        let mut l = CsrMatrix { row_ptr, col, val };
        for i in 0..n {
            let (start, end) = (l.row_ptr[i] as usize, l.row_ptr[i + 1] as usize);
            for p in start..end {
                let k = l.col[p] as usize;
                // s = sum_{m < k} L_im L_km over the common pattern.
                let (ks, ke) = (l.row_ptr[k] as usize, l.row_ptr[k + 1] as usize);
                let mut s = 0.0;
                let (mut a1, mut b1) = (start, ks);
                while a1 < p && b1 < ke {
                    let (ca, cb) = (l.col[a1], l.col[b1]);
                    if ca as usize >= k || cb as usize >= k {
                        break;
                    }
                    match ca.cmp(&cb) {
                        std::cmp::Ordering::Less => a1 += 1,
                        std::cmp::Ordering::Greater => b1 += 1,
                        std::cmp::Ordering::Equal => {
                            s += l.val[a1] * l.val[b1];
                            a1 += 1;
                            b1 += 1;
                        }
                    }
                }
                if k < i {
                    let lkk = l.val[ke - 1];
                    l.val[p] = (l.val[p] - s) / lkk;
                } else {
                    let d = l.val[p] - s;
                    if d <= 0.0 || !d.is_finite() {
                        return None;
                    }
                    l.val[p] = d.sqrt();
                }
            }
        }
        Some(Ic0 { l })
    }

    /// `z = (L L^T)^-1 r`.
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        let n = r.len();
        let l = &self.l;
        for i in 0..n {
            let (c, v) = l.row(i);
            let mut s = r[i];
            for k in 0..c.len() - 1 {
                s -= v[k] * z[c[k] as usize];
            }
            z[i] = s / v[c.len() - 1];
        }
        for i in (0..n).rev() {
            let (c, v) = l.row(i);
            let zi = z[i] / v[c.len() - 1];
            z[i] = zi;
            for k in 0..c.len() - 1 {
                z[c[k] as usize] -= v[k] * zi;
            }
        }
    }
}

/// A preconditioner for CG.
#[derive(Clone, Debug)]
pub enum Preconditioner {
    /// None (plain CG).
    Identity,
    /// Inverse diagonal.
    Jacobi(Vec<f64>),
    /// Incomplete Cholesky.
    Ic0(Ic0),
    /// Smoothed-aggregation algebraic multigrid, one V-cycle.
    Amg(Amg),
}

/// Anything that applies an approximate inverse `z = M^-1 r` of the matrix `a` inside CG.
pub trait Precondition {
    /// `z = M^-1 r` (`M` symmetric positive definite, built for `a`).
    fn apply(&self, a: &CsrMatrix, r: &[f64], z: &mut [f64]);
}

impl Precondition for Amg {
    fn apply(&self, a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        Amg::apply(self, a, r, z)
    }
}

impl Precondition for Preconditioner {
    fn apply(&self, a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        match self {
            Preconditioner::Identity => z.copy_from_slice(r),
            Preconditioner::Jacobi(d) => z
                .par_chunks_mut(CHUNK)
                .zip(r.par_chunks(CHUNK).zip(d.par_chunks(CHUNK)))
                .for_each(|(z, (r, d))| {
                    for k in 0..z.len() {
                        z[k] = r[k] * d[k];
                    }
                }),
            Preconditioner::Ic0(f) => f.apply(r, z),
            Preconditioner::Amg(h) => h.apply(a, r, z),
        }
    }
}

/// Outcome of a linear solve.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Iterations taken.
    pub iterations: usize,
    /// Final relative residual `|b - A x| / |b|`.
    pub residual: f64,
}

/// A solve that did not reach its tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NotConverged {
    /// Where it stopped.
    pub stats: SolveStats,
}

/// Preconditioned conjugate gradient for SPD `a`, starting from `x` (warm start), to the
/// relative residual `tol`.
pub fn pcg(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &impl Precondition,
    tol: f64,
    max_iter: usize,
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let bnorm = dot(b, b).sqrt();
    if bnorm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return Ok(SolveStats::default());
    }
    let mut r = vec![0.0; n];
    a.spmv(x, &mut r);
    r.par_iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    let mut z = vec![0.0; n];
    let mut q = vec![0.0; n];
    let mut rnorm = dot(&r, &r).sqrt();
    if rnorm <= tol * bnorm {
        return Ok(SolveStats {
            iterations: 0,
            residual: rnorm / bnorm,
        });
    }
    m.apply(a, &r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    for it in 1..=max_iter {
        a.spmv(&p, &mut q);
        let pq = dot(&p, &q);
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        x.par_chunks_mut(CHUNK)
            .zip(r.par_chunks_mut(CHUNK))
            .zip(p.par_chunks(CHUNK).zip(q.par_chunks(CHUNK)))
            .for_each(|((x, r), (p, q))| {
                for k in 0..x.len() {
                    x[k] += alpha * p[k];
                    r[k] -= alpha * q[k];
                }
            });
        rnorm = dot(&r, &r).sqrt();
        if !rnorm.is_finite() {
            break;
        }
        if rnorm <= tol * bnorm {
            return Ok(SolveStats {
                iterations: it,
                residual: rnorm / bnorm,
            });
        }
        m.apply(a, &r, &mut z);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_chunks_mut(CHUNK)
            .zip(z.par_chunks(CHUNK))
            .for_each(|(p, z)| {
                for k in 0..p.len() {
                    p[k] = z[k] + beta * p[k];
                }
            });
    }
    Err(NotConverged {
        stats: SolveStats {
            iterations: max_iter,
            residual: rnorm / bnorm,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1D Laplacian with Dirichlet ends: tridiagonal [-1 2 -1].
    fn laplace_1d(n: usize) -> CsrMatrix {
        let mut m = CsrMatrix::default();
        m.row_ptr.push(0);
        for i in 0..n {
            if i > 0 {
                m.col.push(i as u32 - 1);
                m.val.push(-1.0);
            }
            m.col.push(i as u32);
            m.val.push(2.0);
            if i + 1 < n {
                m.col.push(i as u32 + 1);
                m.val.push(-1.0);
            }
            m.row_ptr.push(m.col.len() as u32);
        }
        m
    }

    #[test]
    fn every_preconditioner_solves_a_laplacian() {
        let a = laplace_1d(200);
        let xs: Vec<f64> = (0..200).map(|i| (i as f64 * 0.1).sin()).collect();
        let mut b = vec![0.0; 200];
        a.spmv(&xs, &mut b);
        let d: Vec<f64> = a.diagonal().iter().map(|v| 1.0 / v).collect();
        for m in [
            Preconditioner::Identity,
            Preconditioner::Jacobi(d),
            Preconditioner::Ic0(Ic0::new(&a).unwrap()),
        ] {
            let mut x = vec![0.0; 200];
            let s = pcg(&a, &b, &mut x, &m, 1e-10, 1000).unwrap();
            let err = x
                .iter()
                .zip(&xs)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-6, "{m:?}: err {err} after {}", s.iterations);
        }
    }

    #[test]
    fn ic0_of_a_tridiagonal_matrix_is_exact() {
        // IC(0) of a tridiagonal matrix has no fill-in to drop: one iteration suffices.
        let a = laplace_1d(50);
        let b = vec![1.0; 50];
        let mut x = vec![0.0; 50];
        let s = pcg(
            &a,
            &b,
            &mut x,
            &Preconditioner::Ic0(Ic0::new(&a).unwrap()),
            1e-10,
            10,
        )
        .unwrap();
        assert!(s.iterations <= 2, "{s:?}");
    }

    #[test]
    fn non_convergence_is_reported() {
        let a = laplace_1d(400);
        let b = vec![1.0; 400];
        let mut x = vec![0.0; 400];
        assert!(pcg(&a, &b, &mut x, &Preconditioner::Identity, 1e-12, 5).is_err());
    }
}
