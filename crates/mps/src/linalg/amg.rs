//! Smoothed-aggregation algebraic multigrid (Vaněk, Mandel & Brezina 1996) as a CG
//! preconditioner for the PPE.
//!
//! Set-up, from the assembled matrix alone:
//! 0. the hierarchy is built for, and the V-cycle applied to, the fine matrix without its
//!    weak couplings (`|a_ij| < drop sqrt(a_ii a_jj)`, each dropped one added to both
//!    diagonals so the row sums stay): an operator spectrally close to the matrix at a third
//!    of its entries (the far kernel pairs of an MPS Laplacian carry little weight), while CG
//!    itself multiplies by the whole matrix;
//! 1. strength of connection: `j` is a strong neighbour of `i` when
//!    `|a_ij| >= theta sqrt(a_ii a_jj)`;
//! 2. aggregation: greedy, roots whose strong neighbourhood is still free take it whole,
//!    the rest join a neighbouring aggregate, leftovers form aggregates of their own;
//! 3. tentative prolongator `T`: one column per aggregate, the constant vector (the near null
//!    space of a Laplacian) on it;
//! 4. smoothed prolongator `P = (I - omega D^-1 A) T`, `omega = 4 / (3 lambda_max(D^-1 A))`;
//! 5. Galerkin coarse operator `A_c = P^T A P`, repeated until the coarse level is small,
//!    which is then factored by a dense Cholesky.
//!
//! One application is a symmetric V(1,1)-cycle with a Chebyshev polynomial smoother in
//! `D^-1 A` (parallel, and the same polynomial before and after the coarse correction, so
//! the cycle is a symmetric positive-definite operator as CG needs). Why smoothed
//! aggregation, and the parameters: docs/decisions.md, "AMG parameters". The hierarchy is
//! built in `f64` and then stored, with the cycle's vectors, in `f32` (every sum still in
//! `f64`): the cycle streams about two thirds of the bytes, and CG, in `f64` on the whole
//! matrix, stops at the same residual (docs/decisions.md, "The V-cycle in single precision").

use super::pcg::Precondition;
use super::sparse::{build_rows_into, row_dot, spgemm, transpose, CsrMatrix, Stored};
use rayon::prelude::*;
use std::sync::Mutex;

/// Parameters of the AMG hierarchy (defaults measured: docs/decisions.md, "AMG parameters").
#[derive(Clone, Copy, Debug)]
pub struct AmgParams {
    /// Couplings of the fine matrix left out of the hierarchy and its V-cycle:
    /// `|a_ij| < drop sqrt(a_ii a_jj)` (dimensionless; 0 keeps every one).
    pub drop: f64,
    /// Strength-of-connection threshold `theta` (dimensionless).
    pub theta: f64,
    /// Degree of the Chebyshev smoother (matrix-vector products per smoothing).
    pub smoother_degree: usize,
    /// Lower end of the smoothed spectrum as a fraction of `lambda_max`.
    pub smoother_ratio: f64,
    /// Coarsest level size solved directly (rows).
    pub coarse_size: usize,
    /// Upper limit on the number of levels.
    pub max_levels: usize,
}

impl AmgParams {
    /// The defaults for a PPE in `dimension` 2 or 3: a 3D row spreads the same diagonal over
    /// about four times the entries, so its weak couplings are dropped at a lower fraction
    /// (both keep the couplings out to about 1.5-2 l0; docs/decisions.md, "AMG on the
    /// thinned fine matrix").
    pub fn for_dimension(dimension: usize) -> Self {
        let drop = if dimension == 3 { 0.01 } else { 0.035 };
        AmgParams {
            drop,
            ..AmgParams::default()
        }
    }
}

impl Default for AmgParams {
    fn default() -> Self {
        AmgParams {
            drop: 0.035,
            theta: 0.02,
            smoother_degree: 2,
            smoother_ratio: 1.0 / 30.0,
            coarse_size: 400,
            max_levels: 20,
        }
    }
}

/// How the V-cycle stores its matrices and vectors.
type Low = f32;

/// One level of the hierarchy, stored as the V-cycle reads it.
#[derive(Clone, Debug)]
struct Level {
    /// This level's matrix; on level 0 the fine matrix without its weak couplings.
    a: CsrMatrix<Low>,
    /// Inverse diagonal of this level's matrix.
    inv_diag: Vec<Low>,
    /// Estimate of the largest eigenvalue of `D^-1 A` (padded by 10 %).
    lambda_max: f64,
    /// Prolongator to this level from the next coarser one (`n x n_coarse`).
    p: CsrMatrix<Low>,
    /// Restriction `P^T`.
    r: CsrMatrix<Low>,
}

/// Work vectors of one level.
#[derive(Clone, Debug, Default)]
struct Work {
    res: Vec<Low>,
    dir: Vec<Low>,
    b_coarse: Vec<Low>,
    x_coarse: Vec<Low>,
}

/// The V-cycle's work: one set per level, and the fine right-hand side and result.
#[derive(Debug, Default)]
struct Cycle {
    levels: Vec<Work>,
    b: Vec<Low>,
    x: Vec<Low>,
}

/// A smoothed-aggregation AMG hierarchy.
#[derive(Debug)]
pub struct Amg {
    levels: Vec<Level>,
    /// Dense Cholesky factor of the coarsest matrix (row-major lower triangle).
    coarse_factor: Vec<f64>,
    coarse_n: usize,
    coarse_nnz: usize,
    params: AmgParams,
    work: Mutex<Cycle>,
}

impl Clone for Amg {
    fn clone(&self) -> Self {
        Amg {
            levels: self.levels.clone(),
            coarse_factor: self.coarse_factor.clone(),
            coarse_n: self.coarse_n,
            coarse_nnz: self.coarse_nnz,
            params: self.params,
            work: Mutex::new(Cycle::default()),
        }
    }
}

/// Power iterations for `lambda_max` (an estimate suffices: it is padded by 10 %, and the
/// Chebyshev smoother only needs an upper bound; docs/decisions.md, "AMG parameters").
const POWER_ITERATIONS: usize = 15;

/// Largest eigenvalue of `D^-1 A` by power iteration from a fixed start vector, padded by
/// 10 % so it bounds the spectrum from above.
fn lambda_max(a: &CsrMatrix, inv_diag: &[f64]) -> f64 {
    let n = a.n();
    if n == 0 {
        return 1.0;
    }
    // A fixed, rough start vector (deterministic, not aligned with smooth modes).
    let mut v: Vec<f64> = (0..n)
        .map(|i| ((i as u64).wrapping_mul(2654435761) % 1000) as f64 / 1000.0 + 0.5)
        .collect();
    let mut w = vec![0.0; n];
    let mut lambda = 1.0;
    for _ in 0..POWER_ITERATIONS {
        a.spmv(&v, &mut w);
        w.par_iter_mut().zip(inv_diag).for_each(|(x, d)| *x *= d);
        // Rayleigh quotient in the D inner product: (v, D D^-1 A v) / (v, D v).
        let (num, den) = v
            .iter()
            .zip(&w)
            .zip(inv_diag)
            .fold((0.0, 0.0), |(p, q), ((vi, wi), di)| {
                (p + vi * wi / di, q + vi * vi / di)
            });
        lambda = num / den;
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(norm > 0.0) {
            break;
        }
        v.iter_mut().zip(&w).for_each(|(vi, wi)| *vi = wi / norm);
    }
    1.1 * lambda
}

/// Greedy aggregation over the strength graph; returns the aggregate of each row and the
/// number of aggregates.
fn aggregate(a: &CsrMatrix, theta: f64) -> (Vec<u32>, usize) {
    let n = a.n();
    let diag_values = a.diagonal();
    let diag = &diag_values;
    let strong = |i: usize| {
        let (c, v) = a.row(i);
        let di = diag[i];
        c.iter()
            .zip(v)
            .filter(move |(&j, &x)| {
                j as usize != i && x.abs() >= theta * (di * diag[j as usize]).abs().sqrt()
            })
            .map(|(&j, _)| j as usize)
    };
    const FREE: u32 = u32::MAX;
    let mut agg = vec![FREE; n];
    let mut count = 0u32;
    // Pass 1: roots whose whole strong neighbourhood is free.
    for i in 0..n {
        if agg[i] != FREE {
            continue;
        }
        if strong(i).all(|j| agg[j] == FREE) {
            agg[i] = count;
            for j in strong(i) {
                agg[j] = count;
            }
            count += 1;
        }
    }
    // Pass 2: free rows join the aggregate of a strong neighbour (the strongest one).
    let pass1 = agg.clone();
    for i in 0..n {
        if agg[i] != FREE {
            continue;
        }
        let (c, v) = a.row(i);
        let mut best = (0.0, FREE);
        for (&j, &x) in c.iter().zip(v) {
            let j = j as usize;
            if j != i && pass1[j] != FREE && x.abs() > best.0 {
                best = (x.abs(), pass1[j]);
            }
        }
        agg[i] = best.1;
    }
    // Pass 3: what is left (no aggregated neighbour) groups with its free strong neighbours.
    for i in 0..n {
        if agg[i] != FREE {
            continue;
        }
        agg[i] = count;
        for j in strong(i) {
            if agg[j] == FREE {
                agg[j] = count;
            }
        }
        count += 1;
    }
    (agg, count as usize)
}

/// Smoothed prolongator `(I - omega D^-1 A) T` for the aggregation `agg`.
fn smoothed_prolongator(
    a: &CsrMatrix,
    inv_diag: &[f64],
    lambda: f64,
    agg: &[u32],
    n_agg: usize,
) -> CsrMatrix {
    // Tentative prolongator: constant per aggregate, columns normalised to unit length.
    let mut size = vec![0usize; n_agg];
    for &g in agg {
        size[g as usize] += 1;
    }
    let omega = 4.0 / (3.0 * lambda);
    // Row i of (I - omega D^-1 A) T: entry for aggregate g is
    // t_g [i in g] - omega/a_ii sum_{j in g} a_ij t_g. Gathered in a scratch per piece of
    // rows (columns in order of first touch), counted, then written sorted in place.
    let gather = |s: &mut RowScratch, i: usize| {
        s.cols.clear();
        s.vals.clear();
        let gi = agg[i];
        s.add(gi, 1.0 / (size[gi as usize] as f64).sqrt());
        let (c, v) = a.row(i);
        for (&j, &x) in c.iter().zip(v) {
            let g = agg[j as usize];
            s.add(
                g,
                -omega * inv_diag[i] * x / (size[g as usize] as f64).sqrt(),
            );
        }
    };
    let mut p = CsrMatrix::default();
    build_rows_into(
        a.n(),
        &mut p,
        RowScratch::default,
        |s, i| {
            gather(s, i);
            s.cols.len() as u32
        },
        |s, i, cols, vals| {
            gather(s, i);
            s.order.clear();
            s.order.extend(0..s.cols.len());
            let by = &s.cols;
            s.order.sort_unstable_by_key(|&k| by[k]);
            for (n, &k) in s.order.iter().enumerate() {
                (cols[n], vals[n]) = (s.cols[k], s.vals[k]);
            }
        },
    );
    p
}

/// A row of the prolongator while it is gathered: its columns and values in order of first
/// touch, and the order that sorts them.
#[derive(Default)]
struct RowScratch {
    cols: Vec<u32>,
    vals: Vec<f64>,
    order: Vec<usize>,
}

impl RowScratch {
    /// Adds `x` to the entry of column `g`, a new entry if the row has none.
    fn add(&mut self, g: u32, x: f64) {
        match self.cols.iter().position(|&c| c == g) {
            Some(k) => self.vals[k] += x,
            None => {
                self.cols.push(g);
                self.vals.push(x);
            }
        }
    }
}

/// Dense Cholesky factor (row-major lower triangle) of a small SPD CSR matrix.
fn dense_cholesky(a: &CsrMatrix) -> Option<Vec<f64>> {
    let n = a.n();
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        let (c, v) = a.row(i);
        for (&j, &x) in c.iter().zip(v) {
            l[i * n + j as usize] = x;
        }
    }
    for j in 0..n {
        let mut d = l[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if !(d > 0.0) {
            return None;
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut s = l[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / d;
        }
    }
    Some(l)
}

fn inverse_diagonal<T: Stored, U: Stored>(a: &CsrMatrix<T>) -> Vec<U> {
    a.diagonal().iter().map(|d| U::put(1.0 / d)).collect()
}

impl Amg {
    /// Builds the hierarchy for the SPD matrix `a`; `None` if a coarse matrix is not SPD
    /// (the caller falls back to another preconditioner).
    pub fn new(a: &CsrMatrix, params: AmgParams) -> Option<Amg> {
        let mut levels: Vec<Level> = Vec::new();
        let mut current: Option<CsrMatrix> = (params.drop > 0.0).then(|| {
            let mut m = CsrMatrix::default();
            without_weak_into(a, params.drop, &mut m);
            m
        });
        loop {
            let m = current.as_ref().unwrap_or(a);
            let n = m.n();
            if n <= params.coarse_size || levels.len() + 1 >= params.max_levels {
                break;
            }
            let inv_diag = inverse_diagonal(m);
            let lambda = lambda_max(m, &inv_diag);
            let (agg, n_agg) = aggregate(m, params.theta);
            if n_agg == 0 || n_agg * 10 > n * 9 {
                // Coarsening stalled: solve this level directly if small enough.
                break;
            }
            let p = smoothed_prolongator(m, &inv_diag, lambda, &agg, n_agg);
            drop((inv_diag, agg));
            let ap = spgemm(m, &p, n_agg);
            // The level as the cycle stores it; its f64 matrix is let go before the coarse
            // product (the set-up's peak memory).
            let mut level = Level {
                a: CsrMatrix::default(),
                inv_diag: Vec::new(),
                lambda_max: lambda,
                p: CsrMatrix::default(),
                r: CsrMatrix::default(),
            };
            m.convert_into(&mut level.a);
            level.inv_diag = inverse_diagonal(&level.a);
            drop(current.take());
            let r = transpose(&p, n_agg);
            let coarse = spgemm(&r, &ap, n_agg);
            drop(ap);
            p.convert_into(&mut level.p);
            r.convert_into(&mut level.r);
            levels.push(level);
            current = Some(coarse);
        }
        // A matrix too small for a hierarchy is factored whole, weak couplings included.
        let last = match &current {
            Some(c) if !levels.is_empty() => c,
            _ => a,
        };
        if last.n() > 4000 {
            return None;
        }
        let coarse_factor = dense_cholesky(last)?;
        let coarse_n = last.n();
        let coarse_nnz = last.nnz();
        Some(Amg {
            levels,
            coarse_factor,
            coarse_n,
            coarse_nnz,
            params,
            work: Mutex::new(Cycle::default()),
        })
    }

    /// Number of levels including the coarsest.
    pub fn num_levels(&self) -> usize {
        self.levels.len() + 1
    }

    /// Rows of each level, finest first.
    pub fn level_sizes(&self, fine: usize) -> Vec<usize> {
        let mut s = vec![fine];
        s.extend(self.levels.iter().map(|l| l.r.n()));
        s
    }

    /// Operator complexity: stored entries of all levels over those of the fine matrix.
    pub fn operator_complexity(&self, a: &CsrMatrix) -> f64 {
        let coarse: usize =
            self.levels.iter().skip(1).map(|l| l.a.nnz()).sum::<usize>() + self.coarse_nnz;
        1.0 + coarse as f64 / a.nnz() as f64
    }

    /// Refreshes the fine-level smoother for a new fine matrix with the same unknowns,
    /// keeping the coarse levels (a cheap set-up for a matrix that changed little).
    pub fn refresh_fine(&mut self, a: &CsrMatrix) {
        let drop = self.params.drop;
        if let Some(l0) = self.levels.first_mut() {
            l0.set_fine(a, drop);
        }
    }

    /// Keeps the coarse levels for a fine matrix `a` whose unknowns differ from the
    /// hierarchy's by a few rows: row `k` of `a` is row `from[k]` of the old fine level, or
    /// new ([`u32::MAX`]: it gets no coarse correction, only smoothing); old rows not in
    /// `from` are dropped. The prolongator's rows move with their unknowns, the restriction
    /// follows, the fine smoother is refreshed (docs/decisions.md, "AMG reuse").
    pub fn remap_fine(&mut self, a: &CsrMatrix, from: &[u32]) {
        let Some(l0) = self.levels.first_mut() else {
            return;
        };
        let old = &l0.p;
        let mut p = CsrMatrix::<Low>::default();
        p.row_ptr.reserve(from.len() + 1);
        p.row_ptr.push(0);
        for &o in from {
            if (o as usize) < old.n() {
                let (c, v) = old.row(o as usize);
                p.col.extend_from_slice(c);
                p.val.extend_from_slice(v);
            }
            p.row_ptr.push(p.col.len() as u32);
        }
        let nc = l0.r.n();
        l0.r = transpose(&p, nc);
        l0.p = p;
        l0.set_fine(a, self.params.drop);
    }

    /// Chebyshev smoothing of `A x = b` on level `l` (`x` starts at 0 when `zero`). Each step
    /// is one pass over the rows: the residual of the iterate, the new direction and the
    /// next iterate, written into the other of `x` and `w.res` (so the last lands in `x`).
    fn smooth(&self, l: usize, b: &[Low], x: &mut [Low], zero: bool, w: &mut Work) {
        let lev = &self.levels[l];
        let (a, inv) = (&lev.a, &lev.inv_diag[..]);
        let hi = lev.lambda_max;
        let lo = hi * self.params.smoother_ratio;
        let theta = 0.5 * (hi + lo);
        let delta = 0.5 * (hi - lo);
        let sigma = theta / delta;
        let mut rho = 1.0 / sigma;
        let steps = self.params.smoother_degree.max(1);
        let (t, dir) = (&mut w.res[..], &mut w.dir[..]);
        // Where the current iterate is: in `x` or in `t`.
        let mut in_x;
        if zero {
            // The first iterate from 0 is the scaled residual b; it goes where an odd
            // number of further steps ends in `x`.
            in_x = steps % 2 == 1;
            let first = if in_x { &mut *x } else { &mut *t };
            first
                .par_iter_mut()
                .zip(dir.par_iter_mut())
                .zip(b.par_iter().zip(inv.par_iter()))
                .for_each(|((x, d), (b, di))| {
                    *d = Low::put(di.get() * b.get() / theta);
                    *x = *d;
                });
        } else {
            in_x = true;
            step_into(a, (b, inv), x, t, dir, |_, di, r| di * r / theta);
            in_x = !in_x;
        }
        for _ in 1..steps {
            let rho_new = 1.0 / (2.0 * sigma - rho);
            let (c1, c2) = (rho_new * rho, 2.0 * rho_new / delta);
            let next = |d: f64, di: f64, r: f64| c1 * d + c2 * di * r;
            if in_x {
                step_into(a, (b, inv), x, t, dir, next);
            } else {
                step_into(a, (b, inv), t, x, dir, next);
            }
            in_x = !in_x;
            rho = rho_new;
        }
        if !in_x {
            x.copy_from_slice(t);
        }
    }

    /// The dense direct solve of the coarsest level (in `f64`, whatever `x` stores).
    fn coarse_solve<X: Stored>(&self, b: &[X], x: &mut [X]) {
        let n = self.coarse_n;
        let l = &self.coarse_factor;
        for i in 0..n {
            let mut s = b[i].get();
            for k in 0..i {
                s -= l[i * n + k] * x[k].get();
            }
            x[i] = X::put(s / l[i * n + i]);
        }
        for i in (0..n).rev() {
            let mut s = x[i].get();
            for k in i + 1..n {
                s -= l[k * n + i] * x[k].get();
            }
            x[i] = X::put(s / l[i * n + i]);
        }
    }

    fn vcycle(&self, l: usize, b: &[Low], x: &mut [Low], work: &mut [Work]) {
        if l == self.levels.len() {
            self.coarse_solve(b, x);
            return;
        }
        let (w, rest) = work.split_first_mut().expect("one work set per level");
        self.smooth(l, b, x, true, w);
        let lev = &self.levels[l];
        lev.a
            .spmv_with(x, &mut w.res, |i, ax, r| *r = Low::put(b[i].get() - ax));
        lev.r
            .spmv_with(&w.res, &mut w.b_coarse, |_, rb, y| *y = Low::put(rb));
        w.x_coarse.iter_mut().for_each(|v| *v = 0.0);
        self.vcycle(l + 1, &w.b_coarse, &mut w.x_coarse, rest);
        // x += P x_coarse, in one pass.
        lev.p
            .spmv_with(&w.x_coarse, x, |_, px, x| *x = Low::put(x.get() + px));
        self.smooth(l, b, x, false, w);
    }

    /// `z = M^-1 r`: one V-cycle for the fine matrix `a` (`a` itself is not read: the
    /// hierarchy holds its own copy of it, thinned and in single precision). The cycle is
    /// linear, so it runs on `r` scaled to at most 1 in magnitude and its result is scaled
    /// back: no residual's units can leave the range of `f32`.
    pub fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        if self.levels.is_empty() {
            self.coarse_solve(r, z);
            return;
        }
        let scale = r.par_iter().map(|v| v.abs()).reduce(|| 0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            // A zero residual has a zero correction; a non-finite one is CG's to report.
            z.par_iter_mut().zip(r).for_each(|(z, r)| *z = r * 0.0);
            return;
        }
        let mut guard = self.work.lock().unwrap_or_else(|e| e.into_inner());
        let cycle = &mut *guard;
        if cycle.levels.len() != self.levels.len() || cycle.b.len() != r.len() {
            // Zeroed to the new sizes, in the old vectors' memory.
            cycle.levels.resize_with(self.levels.len(), Work::default);
            for (l, (lev, w)) in self.levels.iter().zip(cycle.levels.iter_mut()).enumerate() {
                let n = if l == 0 { r.len() } else { lev.a.n() };
                let nc = lev.r.n();
                for (v, len) in [
                    (&mut w.res, n),
                    (&mut w.dir, n),
                    (&mut w.b_coarse, nc),
                    (&mut w.x_coarse, nc),
                ] {
                    v.clear();
                    v.resize(len, 0.0);
                }
            }
            for v in [&mut cycle.b, &mut cycle.x] {
                v.clear();
                v.resize(r.len(), 0.0);
            }
        }
        let Cycle { levels, b, x } = cycle;
        let to_unit = 1.0 / scale;
        b.par_iter_mut()
            .zip(r)
            .for_each(|(b, r)| *b = Low::put(r * to_unit));
        self.vcycle(0, b, x, levels);
        z.par_iter_mut()
            .zip(&x[..])
            .for_each(|(z, x)| *z = x.get() * scale);
    }
}

impl Precondition for Amg {
    fn apply(&self, a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        Amg::apply(self, a, r, z)
    }
}

impl Level {
    /// Makes level 0 the new fine matrix `a` (its weak couplings dropped by `drop`) and
    /// refreshes its smoother; the estimate of `lambda_max` is kept.
    fn set_fine(&mut self, a: &CsrMatrix, drop: f64) {
        if drop > 0.0 {
            without_weak_into(a, drop, &mut self.a);
        } else {
            a.convert_into(&mut self.a);
        }
        self.inv_diag = inverse_diagonal(&self.a);
    }
}

/// `a` without its weak couplings, into `out` (its memory reused): every off-diagonal entry
/// with `|a_ij| < drop sqrt(a_ii a_jj)` is left out and added to the diagonal of its row, so
/// each row keeps its sum; the test is symmetric, so a symmetric `a` gives a symmetric
/// result. Rows must hold their diagonal.
fn without_weak_into<T: Stored>(a: &CsrMatrix, drop: f64, out: &mut CsrMatrix<T>) {
    let d = a.diagonal();
    let d2 = drop * drop;
    let kept = |i: usize, j: usize, x: f64| j == i || !(x * x < d2 * d[i] * d[j]);
    let len = |_: &mut (), i: usize| {
        let (c, v) = a.row(i);
        c.iter()
            .zip(v)
            .filter(|(&j, &x)| kept(i, j as usize, x))
            .count() as u32
    };
    let fill = |_: &mut (), i: usize, cols: &mut [u32], vals: &mut [T]| {
        let (c, v) = a.row(i);
        let (mut at, mut diag_at, mut dropped) = (0, usize::MAX, 0.0);
        for (&j, &x) in c.iter().zip(v) {
            if !kept(i, j as usize, x) {
                dropped += x;
                continue;
            }
            if j as usize == i {
                diag_at = at;
            }
            cols[at] = j;
            vals[at] = T::put(x);
            at += 1;
        }
        if diag_at != usize::MAX {
            // The row's sum kept in f64 before it is stored.
            let (c, v) = a.row(i);
            let d = c
                .iter()
                .position(|&j| j as usize == i)
                .map_or(0.0, |k| v[k]);
            vals[diag_at] = T::put(d + dropped);
        }
    };
    build_rows_into(a.n(), out, || (), len, fill);
}

/// One smoothing step in one pass over the rows: with `r = b - A x`, each row's direction
/// becomes `next(d, 1/a_ii, r)` (`inv` holds the `1/a_ii`) and the new iterate `out = x + d`.
fn step_into(
    a: &CsrMatrix<Low>,
    (b, inv): (&[Low], &[Low]),
    x: &[Low],
    out: &mut [Low],
    dir: &mut [Low],
    next: impl Fn(f64, f64, f64) -> f64 + Sync + Send,
) {
    const ROWS: usize = 1024;
    out.par_chunks_mut(ROWS)
        .zip(dir.par_chunks_mut(ROWS))
        .enumerate()
        .for_each(|(c, (out, dir))| {
            for (k, (o, d)) in out.iter_mut().zip(dir).enumerate() {
                let i = c * ROWS + k;
                let (cols, vals) = a.row(i);
                let r = b[i].get() - row_dot(cols, vals, x);
                let di = next(d.get(), inv[i].get(), r);
                *d = Low::put(di);
                *o = Low::put(x[i].get() + di);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::pcg::pcg;

    use crate::linalg::tests::laplace_2d;

    #[test]
    fn galerkin_operator_is_symmetric_and_coarsening_is_strong() {
        let a = laplace_2d(64);
        let amg = Amg::new(&a, AmgParams::default()).unwrap();
        let sizes = amg.level_sizes(a.n());
        assert!(sizes.len() >= 3, "{sizes:?}");
        for w in sizes.windows(2) {
            assert!(w[1] * 3 < w[0], "coarsening too slow: {sizes:?}");
        }
        for l in &amg.levels[1..] {
            // Stored in f32: symmetric to its rounding (a wrong product is off by O(1)).
            let max = l.a.val.iter().fold(0.0f64, |m, v| m.max(v.get().abs()));
            assert!(l.a.asymmetry() < 1e-6 * max);
        }
        assert!(amg.operator_complexity(&a) < 2.0);
    }

    /// The 5-point Laplacian (Dirichlet outside) on the grid points `pts`, in their order.
    fn laplace_on(m: usize, pts: &[(usize, usize)]) -> CsrMatrix {
        let mut row_of = vec![u32::MAX; m * m];
        for (k, &(x, y)) in pts.iter().enumerate() {
            row_of[y * m + x] = k as u32;
        }
        CsrMatrix::from_rows(pts.iter().map(|&(x, y)| {
            let mut row = vec![(row_of[y * m + x], 4.0)];
            for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (a, b) = (x as i64 + dx, y as i64 + dy);
                if (0..m as i64).contains(&a) && (0..m as i64).contains(&b) {
                    let r = row_of[b as usize * m + a as usize];
                    if r != u32::MAX {
                        row.push((r, -1.0));
                    }
                }
            }
            row.sort_unstable_by_key(|e| e.0);
            row
        }))
    }

    /// Thinning keeps symmetry and every row sum, leaves out exactly the couplings below the
    /// threshold (on the lattice: beyond sqrt(2) l0 at drop 0.035), and at drop 0 is the
    /// matrix itself.
    #[test]
    fn thinning_keeps_row_sums_symmetry_and_the_near_couplings() {
        let a = crate::linalg::sparse::tests::mps_lattice(20);
        let mut t = CsrMatrix::default();
        without_weak_into(&a, 0.035, &mut t);
        assert_eq!(t.n(), a.n());
        assert_eq!(t.asymmetry(), 0.0);
        let ones = vec![1.0; a.n()];
        let (mut sa, mut st) = (vec![0.0; a.n()], vec![0.0; a.n()]);
        a.spmv(&ones, &mut sa);
        t.spmv(&ones, &mut st);
        for i in 0..a.n() {
            assert!((sa[i] - st[i]).abs() < 1e-12 * a.get(i, i), "row {i}");
        }
        // An interior row keeps itself and its 8 neighbours within sqrt(2) l0.
        let mid = 10 * 20 + 10;
        assert_eq!(a.row(mid).0.len(), 29);
        assert_eq!(t.row(mid).0.len(), 9);
        assert!(t.get(mid, mid + 21) != 0.0 && t.get(mid, mid + 2) == 0.0);
        without_weak_into(&a, 0.0, &mut t);
        assert_eq!((&t.row_ptr, &t.col, &t.val), (&a.row_ptr, &a.col, &a.val));
    }

    /// Built on the MPS lattice Laplacian without its weak couplings, the hierarchy still
    /// preconditions the whole matrix: CG reaches the same solution in at most 1.5 times the
    /// iterations (each cheaper).
    #[test]
    fn a_hierarchy_of_the_thinned_matrix_preconditions_the_whole_one() {
        let a = crate::linalg::sparse::tests::mps_lattice(96);
        let b: Vec<f64> = (0..a.n()).map(|i| ((i * 7 % 13) as f64) - 6.0).collect();
        let solve = |drop: f64| {
            let pre = Amg::new(
                &a,
                AmgParams {
                    drop,
                    ..AmgParams::default()
                },
            )
            .unwrap();
            let mut x = vec![0.0; a.n()];
            let s = pcg(&a, &b, &mut x, &pre, 1e-10, 300).unwrap();
            (s.iterations, x)
        };
        let ((it_full, x_full), (it_thin, x_thin)) = (solve(0.0), solve(0.035));
        eprintln!("AMG-CG iterations: whole matrix {it_full}, thinned {it_thin}");
        assert!(2 * it_thin <= 3 * it_full, "{it_thin} vs {it_full}");
        let size = x_full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = x_full
            .iter()
            .zip(&x_thin)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(err < 1e-7 * size, "solutions differ by {err} (size {size})");
    }

    /// A hierarchy carried over to unknowns that are reordered, lost a few rows and gained
    /// a few (as free-surface flags change between steps) preconditions as well as a fresh
    /// one; carried over to the same rows it is the hierarchy refreshed in place, bit for bit.
    #[test]
    fn a_remapped_hierarchy_preconditions_the_changed_unknowns() {
        let m = 64;
        let old: Vec<(usize, usize)> = (0..m * (m - 2)).map(|i| (i % m, i / m)).collect();
        let a_old = laplace_on(m, &old);
        let gone = |&(x, y): &(usize, usize)| y == m - 3 && x % 3 == 0;
        let mut new: Vec<(usize, usize)> = old.iter().copied().filter(|p| !gone(p)).collect();
        new.extend((0..m).step_by(2).map(|x| (x, m - 2)));
        new.reverse();
        let a_new = laplace_on(m, &new);
        let at: std::collections::HashMap<(usize, usize), u32> = old
            .iter()
            .enumerate()
            .map(|(k, &p)| (p, k as u32))
            .collect();
        let from: Vec<u32> = new
            .iter()
            .map(|p| *at.get(p).unwrap_or(&u32::MAX))
            .collect();
        assert!(from.iter().filter(|&&o| o == u32::MAX).count() == m / 2);

        let mut carried = Amg::new(&a_old, AmgParams::default()).unwrap();
        carried.remap_fine(&a_new, &from);
        let fresh = Amg::new(&a_new, AmgParams::default()).unwrap();
        let b = vec![1.0; a_new.n()];
        let solve = |pre: &Amg| {
            let mut x = vec![0.0; a_new.n()];
            let s = pcg(&a_new, &b, &mut x, pre, 1e-8, 200).unwrap();
            (s.iterations, x)
        };
        let ((it_c, x_c), (it_f, x_f)) = (solve(&carried), solve(&fresh));
        assert!(
            it_c <= it_f + it_f / 4 + 1,
            "carried {it_c} vs fresh {it_f} iterations"
        );
        let err = x_c
            .iter()
            .zip(&x_f)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let size = x_f.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        assert!(err < 1e-6 * size, "solutions differ by {err} (size {size})");
        // Without it, no coarse correction: the carried hierarchy must be doing real work.
        let (it_none, _) = {
            let mut x = vec![0.0; a_new.n()];
            let d = crate::linalg::Jacobi::new(&a_new);
            (
                pcg(&a_new, &b, &mut x, &d, 1e-8, 400).unwrap().iterations,
                (),
            )
        };
        eprintln!("iterations: carried {it_c}, fresh {it_f}, Jacobi {it_none}");
        assert!(2 * it_c < it_none, "carried {it_c} vs Jacobi {it_none}");

        let identity: Vec<u32> = (0..a_old.n() as u32).collect();
        let (mut kept, mut same) = (
            Amg::new(&a_old, AmgParams::default()).unwrap(),
            Amg::new(&a_old, AmgParams::default()).unwrap(),
        );
        kept.refresh_fine(&a_old);
        same.remap_fine(&a_old, &identity);
        let r: Vec<f64> = (0..a_old.n())
            .map(|i| ((i * 7) % 13) as f64 - 6.0)
            .collect();
        let (mut z1, mut z2) = (vec![0.0; r.len()], vec![0.0; r.len()]);
        kept.apply(&a_old, &r, &mut z1);
        same.apply(&a_old, &r, &mut z2);
        assert_eq!(z1, z2);
    }

    /// The cycle runs on the residual scaled to 1, so its result is linear in the residual
    /// at any magnitude: without the scaling, residuals of 1e40 or 1e-50 (units that put a
    /// PPE out of `f32`'s range) would give infinities or zeros.
    #[test]
    fn the_single_precision_cycle_is_linear_at_any_scale() {
        let a = laplace_2d(40);
        let amg = Amg::new(&a, AmgParams::default()).unwrap();
        let r: Vec<f64> = (0..a.n()).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let mut z = vec![0.0; a.n()];
        amg.apply(&a, &r, &mut z);
        let norm = z.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(norm > 0.0);
        for s in [1e40, 1e-50, 3.0] {
            let rs: Vec<f64> = r.iter().map(|v| v * s).collect();
            let mut zs = vec![0.0; a.n()];
            amg.apply(&a, &rs, &mut zs);
            let err = z
                .iter()
                .zip(&zs)
                .map(|(u, v)| (u - v / s).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(err < 1e-6 * norm, "scale {s}: {err} of {norm}");
        }
        let mut zero = vec![1.0; a.n()];
        amg.apply(&a, &vec![0.0; a.n()], &mut zero);
        assert!(zero.iter().all(|&v| v == 0.0));
    }

    /// CG on the whole f64 matrix, preconditioned by the single-precision cycle, goes on
    /// converging well past the cycle's own precision (a relative residual of 1e-13 against
    /// f32's 6e-8) and its solution is the exact one to that accuracy.
    #[test]
    fn cg_converges_past_the_cycles_precision() {
        let a = crate::linalg::sparse::tests::mps_lattice(48);
        let exact: Vec<f64> = (0..a.n()).map(|i| (i as f64 * 0.013).sin() + 2.0).collect();
        let mut b = vec![0.0; a.n()];
        a.spmv(&exact, &mut b);
        let mut x = vec![0.0; a.n()];
        let pre = Amg::new(&a, AmgParams::for_dimension(2)).unwrap();
        let s = pcg(&a, &b, &mut x, &pre, 1e-13, 200).unwrap();
        let err = x
            .iter()
            .zip(&exact)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        assert!(
            err < 1e-9,
            "max error {err} after {} iterations",
            s.iterations
        );
        assert!(s.iterations <= 38, "{} iterations", s.iterations);
    }

    #[test]
    fn amg_cg_iterations_stay_flat_with_grid_size() {
        // Plain CG needs O(m) iterations here; AMG-CG a near-constant number.
        let mut its = Vec::new();
        for m in [32, 128] {
            let a = laplace_2d(m);
            let b = vec![1.0; a.n()];
            let mut x = vec![0.0; a.n()];
            let pre = Amg::new(&a, AmgParams::default()).unwrap();
            let s = pcg(&a, &b, &mut x, &pre, 1e-8, 200).unwrap();
            its.push(s.iterations);
        }
        assert!(its[1] <= its[0] + its[0] / 2 + 2 && its[1] <= 20, "{its:?}");
    }
}
