//! Preconditioned conjugate gradient for symmetric positive-definite systems, and the
//! preconditioner interface (identity and Jacobi here; IC(0) and AMG in their own files).

use super::sparse::{chunk_dot, dot_split, spmv_dot, summed_parts, CsrMatrix, CHUNK};
use rayon::prelude::*;

/// Below this many unknowns, CG with a sequential preconditioner does its products and
/// vector updates on the calling thread: waking the pool's other workers for them cost more
/// than they saved (docs/decisions.md, "CG on one thread").
pub const SEQUENTIAL_BELOW: usize = 32768;

/// Anything that applies an approximate inverse `z = M^-1 r` of the matrix `a` inside CG.
pub trait Precondition {
    /// `z = M^-1 r` (`M` symmetric positive definite, built for `a`).
    fn apply(&self, a: &CsrMatrix, r: &[f64], z: &mut [f64]);
    /// True when `apply` runs on the calling thread only (substitutions).
    fn sequential(&self) -> bool {
        false
    }
}

/// No preconditioning (plain CG).
#[derive(Clone, Copy, Debug)]
pub struct Identity;

impl Precondition for Identity {
    fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r)
    }
}

/// Jacobi preconditioning: the inverse of the matrix diagonal.
#[derive(Clone, Debug)]
pub struct Jacobi(pub Vec<f64>);

impl Jacobi {
    /// The inverse diagonal of `a`.
    pub fn new(a: &CsrMatrix) -> Jacobi {
        Jacobi(a.diagonal().iter().map(|d| 1.0 / d).collect())
    }
}

impl Precondition for Jacobi {
    fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        z.par_chunks_mut(CHUNK)
            .zip(r.par_chunks(CHUNK).zip(self.0.par_chunks(CHUNK)))
            .for_each(|(z, (r, d))| {
                for k in 0..z.len() {
                    z[k] = r[k] * d[k];
                }
            })
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

impl NotConverged {
    /// Stopped after `iterations` at the relative residual `residual`.
    pub fn at(iterations: usize, residual: f64) -> NotConverged {
        NotConverged {
            stats: SolveStats {
                iterations,
                residual,
            },
        }
    }
}

/// Chunks of the iterate and the residual, updated together.
type XrChunks<'a> = (&'a mut [f64], &'a mut [f64]);
/// Chunks of the direction and its product.
type PqChunks<'a> = (&'a [f64], &'a [f64]);

/// `x += alpha p`, `r -= alpha q` and `r . r` in one pass, in [`dot_split`]'s order and
/// pieces (`min_chunks` chunks at least).
fn update_x_r(
    x: &mut [f64],
    r: &mut [f64],
    (p, q): (&[f64], &[f64]),
    alpha: f64,
    min_chunks: usize,
) -> f64 {
    let update = |((x, r), (p, q)): (XrChunks, PqChunks)| {
        for k in 0..x.len() {
            x[k] += alpha * p[k];
            r[k] -= alpha * q[k];
        }
        chunk_dot((r, r))
    };
    let chunks = x.len().div_ceil(CHUNK);
    if min_chunks >= chunks {
        return x
            .chunks_mut(CHUNK)
            .zip(r.chunks_mut(CHUNK))
            .zip(p.chunks(CHUNK).zip(q.chunks(CHUNK)))
            .map(update)
            .sum();
    }
    summed_parts(chunks, |parts| {
        parts
            .par_iter_mut()
            .zip(
                x.par_chunks_mut(CHUNK)
                    .zip(r.par_chunks_mut(CHUNK))
                    .zip(p.par_chunks(CHUNK).zip(q.par_chunks(CHUNK))),
            )
            .with_min_len(min_chunks)
            .for_each(|(part, c)| *part = update(c))
    })
}

/// The outcome after `it` iterations if the residual norm `rnorm` has reached `tol` times
/// the right-hand side's norm `bnorm`.
pub(crate) fn converged(it: usize, rnorm: f64, bnorm: f64, tol: f64) -> Option<SolveStats> {
    (rnorm <= tol * bnorm).then(|| SolveStats {
        iterations: it,
        residual: rnorm / bnorm,
    })
}

/// Preconditioned conjugate gradient for SPD `a`, starting from `x` (warm start), to the
/// relative residual `tol`.
pub fn pcg(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &(impl Precondition + ?Sized),
    tol: f64,
    max_iter: usize,
) -> Result<SolveStats, NotConverged> {
    pcg_in(a, b, x, m, (tol, max_iter), &mut CgVectors::default())
}

/// The work vectors of CG (residual, preconditioned residual, direction, product), kept
/// between solves so a solve allocates nothing once warm.
#[derive(Clone, Debug, Default)]
pub struct CgVectors {
    r: Vec<f64>,
    z: Vec<f64>,
    q: Vec<f64>,
    p: Vec<f64>,
}

/// [`pcg`] to `(tol, max_iter)` in the memory of `work`.
pub fn pcg_in(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &(impl Precondition + ?Sized),
    (tol, max_iter): (f64, usize),
    work: &mut CgVectors,
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let CgVectors { r, z, q, p } = work;
    for v in [&mut *r, &mut *z, &mut *q] {
        v.clear();
        v.resize(n, 0.0);
    }
    // Pieces handed to the pool: all on this thread for a small sequential solve.
    let ml = if m.sequential() && n < SEQUENTIAL_BELOW {
        usize::MAX
    } else {
        1
    };
    let dot = |u: &[f64], v: &[f64]| dot_split(u, v, ml);
    let bnorm = dot(b, b).sqrt();
    if bnorm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return Ok(SolveStats::default());
    }
    a.spmv_split(x, r, ml);
    r.par_iter_mut()
        .zip(b)
        .with_min_len(ml)
        .for_each(|(ri, bi)| *ri = bi - *ri);
    let mut rnorm = dot(r, r).sqrt();
    if let Some(done) = converged(0, rnorm, bnorm, tol) {
        return Ok(done);
    }
    m.apply(a, r, z);
    p.clear();
    p.extend_from_slice(z);
    let mut rz = dot(r, z);
    for it in 1..=max_iter {
        // q = A p with p . q, then x, r updated with r . r: two passes over the vectors.
        let pq = spmv_dot(a, p, q, ml);
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        let rr = update_x_r(x, r, (p, q), alpha, ml);
        rnorm = rr.sqrt();
        if !rnorm.is_finite() {
            break;
        }
        if let Some(done) = converged(it, rnorm, bnorm, tol) {
            return Ok(done);
        }
        m.apply(a, r, z);
        let rz_new = dot(r, z);
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_chunks_mut(CHUNK)
            .zip(z.par_chunks(CHUNK))
            .with_min_len(ml)
            .for_each(|(p, z)| {
                for k in 0..p.len() {
                    p[k] = z[k] + beta * p[k];
                }
            });
    }
    Err(NotConverged::at(max_iter, rnorm / bnorm))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::ic0::Ic0;

    /// 1D Laplacian with Dirichlet ends: tridiagonal [-1 2 -1].
    fn laplace_1d(n: usize) -> CsrMatrix {
        CsrMatrix::from_rows((0..n).map(|i| {
            let mut row = Vec::new();
            if i > 0 {
                row.push((i as u32 - 1, -1.0));
            }
            row.push((i as u32, 2.0));
            if i + 1 < n {
                row.push((i as u32 + 1, -1.0));
            }
            row
        }))
    }

    #[test]
    fn every_preconditioner_solves_a_laplacian() {
        let a = laplace_1d(200);
        let xs: Vec<f64> = (0..200).map(|i| (i as f64 * 0.1).sin()).collect();
        let mut b = vec![0.0; 200];
        a.spmv(&xs, &mut b);
        let ic0 = Ic0::new(&a).unwrap();
        let jacobi = Jacobi::new(&a);
        let preconditioners: [(&str, &dyn Precondition); 3] =
            [("identity", &Identity), ("jacobi", &jacobi), ("ic0", &ic0)];
        for (m, pre) in preconditioners {
            let mut x = vec![0.0; 200];
            let s = pcg(&a, &b, &mut x, pre, 1e-10, 1000).unwrap();
            let err = x
                .iter()
                .zip(&xs)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-6, "{m}: err {err} after {}", s.iterations);
        }
    }

    #[test]
    fn ic0_of_a_tridiagonal_matrix_is_exact() {
        // IC(0) of a tridiagonal matrix has no fill-in to drop: one iteration suffices.
        let a = laplace_1d(50);
        let b = vec![1.0; 50];
        let mut x = vec![0.0; 50];
        let s = pcg(&a, &b, &mut x, &Ic0::new(&a).unwrap(), 1e-10, 10).unwrap();
        assert!(s.iterations <= 2, "{s:?}");
    }

    #[test]
    fn non_convergence_is_reported() {
        let a = laplace_1d(400);
        let b = vec![1.0; 400];
        let mut x = vec![0.0; 400];
        assert!(pcg(&a, &b, &mut x, &Identity, 1e-12, 5).is_err());
    }
}
