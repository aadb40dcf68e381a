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
//!
//! The rows are taken in the twisted numbering of [`super::twisted`] (the second part of
//! the rows backwards, the band coupling the parts last): `L` is the part of each row that
//! comes before it in that numbering, so both substitutions run the two parts at once on a
//! team of two threads and only the band waits; the vectors keep the matrix's own order.
//! The numbering does not depend on the team, so one and two threads agree bit for bit.

use super::pcg::{converged, NotConverged, SolveStats};
use super::sparse::{row_dot, CsrMatrix};
use super::team::{blocks_of, residual, rows_of, run_team, total, Member, Shared, BLOCK};
use super::twisted::split;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// A row's entries as two pieces of columns and values.
type Pieces<'a> = [(&'a [u32], &'a [f64]); 2];

/// The modified D-ILU preconditioner of a symmetric matrix whose rows are sorted by column
/// and hold their diagonal, in the twisted numbering.
#[derive(Clone, Debug, Default)]
pub struct Dilu {
    /// First row of the second part (rows `m..n` numbered backwards).
    m: usize,
    /// Rows of the band `m..m + s` (numbered last).
    s: usize,
    /// Position of each row's diagonal entry in the matrix's `col`/`val`.
    diag_pos: Vec<u32>,
    /// Position of each row's first column of the second part (rows of the second part;
    /// the diagonal's for the first part's rows).
    mid_pos: Vec<u32>,
    /// `D` (the pivots).
    d: Vec<f64>,
    /// `1 / D`.
    inv_d: Vec<f64>,
    /// `K = 2 D - diag(A)`.
    k: Vec<f64>,
    /// Each row's sum over its part after it in the numbering (the set-up's scratch, kept).
    upper_sum: Vec<f64>,
}

impl Dilu {
    /// The pivots of `a` relaxed by `omega` in [0, 1]:
    /// `d_i = a_ii - sum_{j<i} (a_ij / d_j) (a_ij + omega (s_j - a_ij))`, `j < i` in the
    /// twisted numbering, `s_j` the sum of row `j`'s entries after its own. `None` if a row
    /// lacks its diagonal or a pivot is not positive.
    pub fn new(a: &CsrMatrix, omega: f64) -> Option<Dilu> {
        let mut m = Dilu::default();
        m.rebuild(a, omega).then_some(m)
    }

    /// [`Dilu::new`] in this preconditioner's memory; false (unusable) where `new` gives
    /// `None`.
    pub fn rebuild(&mut self, a: &CsrMatrix, omega: f64) -> bool {
        self.rebuild_on(a, omega, 1)
    }

    /// [`Dilu::rebuild`] on a team of up to `team` threads, with the same pivots for any
    /// team: the rows' positions and sums split by blocks, the two parts' pivots at once,
    /// then the band's.
    pub fn rebuild_on(&mut self, a: &CsrMatrix, omega: f64, team: usize) -> bool {
        let n = a.n();
        (self.m, self.s) = split(a);
        for v in [&mut self.diag_pos, &mut self.mid_pos] {
            v.clear();
            v.resize(n, 0);
        }
        for v in [
            &mut self.d,
            &mut self.inv_d,
            &mut self.k,
            &mut self.upper_sum,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        let [first, second, band] = self.forward_order();
        let m = self.m;
        let v = self.shared();
        // One flag per phase, each read only after the barrier that ends its phase.
        let (placed, pivoted) = (AtomicBool::new(true), AtomicBool::new(true));
        let blocks = n.div_ceil(BLOCK);
        let team = if n < 2 * BLOCK { 1 } else { team };
        run_team(team, |t| {
            let own = rows_of(&t.share(blocks), n);
            // SAFETY (every access through `v` here): a member writes only its own rows
            // between barriers, or the rows of its part of the pivots, and reads other
            // members' rows only after the barrier that ends their writing.
            unsafe {
                if !own.clone().all(|i| v.place(a, m, i)) {
                    placed.store(false, Ordering::Relaxed);
                }
                t.wait();
                if !placed.load(Ordering::Relaxed) {
                    return;
                }
                let mut ok = true;
                if t.index == 0 {
                    ok &= first.clone().all(|i| v.pivot(a, m, i, omega));
                }
                if t.index == 1 || t.size == 1 {
                    ok &= second.clone().rev().all(|i| v.pivot(a, m, i, omega));
                }
                t.wait();
                if t.index == 0 && ok {
                    ok &= band.clone().rev().all(|i| v.pivot(a, m, i, omega));
                }
                if !ok {
                    pivoted.store(false, Ordering::Relaxed);
                }
                t.wait();
                if !pivoted.load(Ordering::Relaxed) {
                    return;
                }
                for i in own {
                    v.k.set(i, 2.0 * v.d.get(i) - a.val[v.diag_pos.get(i) as usize]);
                }
            }
        });
        placed.into_inner() && pivoted.into_inner()
    }

    /// The set-up's vectors for a team (valid while they are not resized).
    fn shared(&mut self) -> SetUp {
        SetUp {
            diag_pos: Shared::new(&mut self.diag_pos),
            mid_pos: Shared::new(&mut self.mid_pos),
            d: Shared::new(&mut self.d),
            inv_d: Shared::new(&mut self.inv_d),
            k: Shared::new(&mut self.k),
            upper_sum: Shared::new(&mut self.upper_sum),
        }
    }

    /// The rows of the first part, the second part's far rows and the band, each range in
    /// ascending order: the forward substitution takes the first ascending, then the others
    /// descending; the backward one the band ascending, then the first descending and the
    /// second ascending.
    fn forward_order(&self) -> [Range<usize>; 3] {
        let n = self.d.len();
        [0..self.m, self.m + self.s..n, self.m..self.m + self.s]
    }

    /// The part of row `i` of `a` before it in the numbering ([`lower_of`]).
    #[cfg(test)]
    fn lower<'a>(&self, a: &'a CsrMatrix, i: usize) -> Pieces<'a> {
        let (mid, p) = (self.mid_pos[i] as usize, self.diag_pos[i] as usize);
        lower_of(a, self.m, i, (mid, p))
    }

    /// The part of row `i` of `a` after it in the numbering ([`upper_of`]).
    #[inline(always)]
    fn upper<'a>(&self, a: &'a CsrMatrix, i: usize) -> Pieces<'a> {
        let (mid, p) = (self.mid_pos[i] as usize, self.diag_pos[i] as usize);
        upper_of(a, self.m, i, (mid, p))
    }

    /// `u_i = (v(i) - L_i u) / d_i` over rows `rows`, all of one part, in the order the
    /// forward substitution takes them: the first part ascending, the second part and the
    /// band (both numbered backwards) descending. Each part has a loop of its own: the
    /// rows' two pieces read only where a row can have both, the band (docs/decisions.md,
    /// "The twisted substitutions' loops per part").
    ///
    /// # Safety
    /// `v` and `u` read and write vectors of the matrix's size; no other thread writes what
    /// these rows read or reads what they write until the caller's next barrier.
    unsafe fn forward_rows(
        &self,
        a: &CsrMatrix,
        rows: Range<usize>,
        v: impl Fn(usize) -> f64,
        u: *mut f64,
    ) {
        let (rp, dp, mp) = (&a.row_ptr, &self.diag_pos, &self.mid_pos);
        let (col, val, inv_d) = (&a.col[..], &a.val[..], &self.inv_d[..]);
        if rows.end <= self.m {
            // The first part: the columns below the diagonal.
            for i in rows {
                let (s, p) = (rp[i] as usize, dp[i] as usize);
                *u.add(i) = (v(i) - last_after(&col[s..p], &val[s..p], u)) * inv_d[i];
            }
        } else if rows.start >= self.m + self.s {
            // The second part outside the band: no first-part columns, only those above the
            // diagonal (the first part's backward rows, mirrored).
            for i in rows.rev() {
                let (p, e) = (dp[i] as usize + 1, rp[i + 1] as usize);
                *u.add(i) = (v(i) - first_after(&col[p..e], &val[p..e], u)) * inv_d[i];
            }
        } else {
            // The band: the first part's columns and those above the diagonal.
            for i in rows.rev() {
                let (s, mid) = (rp[i] as usize, mp[i] as usize);
                let (p, e) = (dp[i] as usize + 1, rp[i + 1] as usize);
                let near = first_after(&col[p..e], &val[p..e], u);
                *u.add(i) = (v(i) - ptr_dot(&col[s..mid], &val[s..mid], u) - near) * inv_d[i];
            }
        }
    }

    /// `w_i = (v_i - U_i w) / d_i` over rows `rows`, all of one part, in the order the
    /// backward substitution takes them (the reverse of [`Dilu::forward_rows`]'s).
    ///
    /// # Safety
    /// As for [`Dilu::forward_rows`].
    unsafe fn backward_rows(&self, a: &CsrMatrix, rows: Range<usize>, v: *const f64, w: *mut f64) {
        let (rp, dp, mp) = (&a.row_ptr, &self.diag_pos, &self.mid_pos);
        let (col, val, inv_d) = (&a.col[..], &a.val[..], &self.inv_d[..]);
        if rows.end <= self.m {
            // The first part: the columns above the diagonal.
            for i in rows.rev() {
                let (p, e) = (dp[i] as usize + 1, rp[i + 1] as usize);
                *w.add(i) = (*v.add(i) - first_after(&col[p..e], &val[p..e], w)) * inv_d[i];
            }
        } else {
            // The second part and the band: the second part's columns below the diagonal.
            for i in rows {
                let (mid, p) = (mp[i] as usize, dp[i] as usize);
                *w.add(i) = (*v.add(i) - last_after(&col[mid..p], &val[mid..p], w)) * inv_d[i];
            }
        }
    }

    /// `u = T^-1 v` (forward substitution) on this thread.
    pub fn forward(&self, a: &CsrMatrix, v: &[f64], u: &mut [f64]) {
        let [first, second, band] = self.forward_order();
        let (src, dst) = (|i: usize| v[i], u.as_mut_ptr());
        // SAFETY: one thread, vectors of the matrix's size.
        unsafe {
            self.forward_rows(a, first, src, dst);
            self.forward_rows(a, second, src, dst);
            self.forward_rows(a, band, src, dst);
        }
    }

    /// `w = T^-T v` (backward substitution over the rows' upper parts, `A` symmetric) on
    /// this thread.
    pub fn backward(&self, a: &CsrMatrix, v: &[f64], w: &mut [f64]) {
        let [first, second, band] = self.forward_order();
        let (src, dst) = (v.as_ptr(), w.as_mut_ptr());
        // SAFETY: as for `forward`.
        unsafe {
            self.backward_rows(a, band, src, dst);
            self.backward_rows(a, first, src, dst);
            self.backward_rows(a, second, src, dst);
        }
    }

    /// `y = T^T x` over rows `rows`, into `y` (the rows' entries).
    fn upper_times_rows(&self, a: &CsrMatrix, x: &[f64], rows: Range<usize>, y: &mut [f64]) {
        let first = rows.start;
        for i in rows {
            let [(c1, x1), (c2, x2)] = self.upper(a, i);
            y[i - first] = self.d[i] * x[i] + row_dot(c1, x1, x) + row_dot(c2, x2, x);
        }
    }

    /// `y = T^T x`.
    pub fn upper_times(&self, a: &CsrMatrix, x: &[f64], y: &mut [f64]) {
        self.upper_times_rows(a, x, 0..x.len(), y);
    }

    /// `q = T^-1 A T^-T p` by Eisenstat's trick; `w` receives `T^-T p`.
    #[cfg(test)]
    fn operator(&self, a: &CsrMatrix, p: &[f64], w: &mut [f64], q: &mut [f64]) {
        self.backward(a, p, w);
        // u = T^-1 (p - K w), held in q while it is built; then q = w + u.
        let [first, second, band] = self.forward_order();
        let src = |i: usize| p[i] - self.k[i] * w[i];
        // SAFETY: one thread, vectors of the matrix's size.
        unsafe {
            self.forward_rows(a, first, src, q.as_mut_ptr());
            self.forward_rows(a, second, src, q.as_mut_ptr());
            self.forward_rows(a, band, src, q.as_mut_ptr());
        }
        for (qi, wi) in q.iter_mut().zip(w.iter()) {
            *qi += wi;
        }
    }
}

/// The part of row `i` of `a` before it in the twisted numbering whose second part starts
/// at row `m` (columns ascending in each piece), the row's first column of the second part
/// and its diagonal at positions `mid` and `p`: columns below `i` in the first part; in the
/// second, those of the first part and those above `i`.
#[inline(always)]
fn lower_of(a: &CsrMatrix, m: usize, i: usize, (mid, p): (usize, usize)) -> Pieces<'_> {
    let (s, e) = (a.row_ptr[i] as usize, a.row_ptr[i + 1] as usize);
    let e = if i < m { p + 1 } else { e };
    [
        (&a.col[s..mid], &a.val[s..mid]),
        (&a.col[p + 1..e], &a.val[p + 1..e]),
    ]
}

/// The part of row `i` of `a` after it in the numbering (as [`lower_of`]): columns above
/// `i` in the first part; in the second, those of the second part below `i`.
#[inline(always)]
fn upper_of(a: &CsrMatrix, m: usize, i: usize, (mid, p): (usize, usize)) -> Pieces<'_> {
    let e = a.row_ptr[i + 1] as usize;
    let e = if i < m { e } else { p + 1 };
    [
        (&a.col[mid..p], &a.val[mid..p]),
        (&a.col[p + 1..e], &a.val[p + 1..e]),
    ]
}

/// The set-up's vectors, shared by the members of its team.
#[derive(Clone, Copy)]
struct SetUp {
    diag_pos: Shared<u32>,
    mid_pos: Shared<u32>,
    d: Shared,
    inv_d: Shared,
    k: Shared,
    upper_sum: Shared,
}

impl SetUp {
    /// Row `i`'s diagonal position, first column of the second part and sum after it in
    /// the numbering; false where the row lacks its diagonal.
    ///
    /// # Safety
    /// No other thread touches row `i`'s entries meanwhile.
    unsafe fn place(&self, a: &CsrMatrix, m: usize, i: usize) -> bool {
        let (start, end) = (a.row_ptr[i] as usize, a.row_ptr[i + 1] as usize);
        let p = start + a.col[start..end].partition_point(|&c| (c as usize) < i);
        if p == end || a.col[p] as usize != i {
            return false;
        }
        let mid = match i < m {
            true => p,
            false => start + a.col[start..p].partition_point(|&c| (c as usize) < m),
        };
        let [(_, x), (_, y)] = upper_of(a, m, i, (mid, p));
        self.diag_pos.set(i, p as u32);
        self.mid_pos.set(i, mid as u32);
        self.upper_sum
            .set(i, x.iter().sum::<f64>() + y.iter().sum::<f64>());
        true
    }

    /// Row `i`'s pivot from those of the rows before it in the numbering; false where it
    /// is not positive.
    ///
    /// # Safety
    /// Every row's place is set; no other thread writes row `i` or the rows before it, or
    /// reads row `i`, meanwhile.
    unsafe fn pivot(&self, a: &CsrMatrix, m: usize, i: usize, omega: f64) -> bool {
        let p = self.diag_pos.get(i) as usize;
        let mid = self.mid_pos.get(i) as usize;
        let mut di = a.val[p];
        for (c, x) in lower_of(a, m, i, (mid, p)) {
            for (&j, &aij) in c.iter().zip(x) {
                let j = j as usize;
                let sj = self.upper_sum.get(j);
                di -= aij * self.inv_d.get(j) * (aij + omega * (sj - aij));
            }
        }
        if !(di > 0.0) || !di.is_finite() {
            return false;
        }
        self.d.set(i, di);
        self.inv_d.set(i, 1.0 / di);
        true
    }
}

/// `sum_k x_k u_{c_k}` in four partial sums (as `row_dot`), reading `u` through a pointer
/// (other threads write other entries of it meanwhile).
///
/// # Safety
/// `u` is valid for every column, none of them written meanwhile.
#[inline]
unsafe fn ptr_dot(c: &[u32], x: &[f64], u: *const f64) -> f64 {
    let mut acc = [0.0; 4];
    let (cs, xs) = (c.chunks_exact(4), x.chunks_exact(4));
    let (cr, xr) = (cs.remainder(), xs.remainder());
    for (c, x) in cs.zip(xs) {
        for k in 0..4 {
            acc[k] += x[k] * *u.add(c[k] as usize);
        }
    }
    for (c, x) in cr.iter().zip(xr) {
        acc[0] += *x * *u.add(*c as usize);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// A substitution's sum over a piece whose last column is the row just solved: that entry
/// is added after the others, so that only one product waits on it (the rows' dependency
/// chain sets the substitution's speed).
///
/// # Safety
/// As for [`ptr_dot`].
#[inline]
unsafe fn last_after(c: &[u32], x: &[f64], u: *const f64) -> f64 {
    match c.len() {
        0 => 0.0,
        m => ptr_dot(&c[..m - 1], &x[..m - 1], u) + x[m - 1] * *u.add(c[m - 1] as usize),
    }
}

/// The same over a piece whose first column is the row just solved.
///
/// # Safety
/// As for [`ptr_dot`].
#[inline]
unsafe fn first_after(c: &[u32], x: &[f64], w: *const f64) -> f64 {
    match c.len() {
        0 => 0.0,
        _ => ptr_dot(&c[1..], &x[1..], w) + x[0] * *w.add(c[0] as usize),
    }
}

/// `r = b - A x`; returns `|r|`.
#[cfg(test)]
fn true_residual(a: &CsrMatrix, b: &[f64], x: &[f64], r: &mut [f64]) -> f64 {
    a.spmv(x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    r.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// PCG on the SPD matrix `a` (rows sorted, symmetric) with the modified D-ILU
/// preconditioner `m`, from the warm start `x`, to the relative residual `tol`
/// (module docs), on this thread.
pub fn dilu_cg(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &Dilu,
    tol: f64,
    max_iter: usize,
) -> Result<SolveStats, NotConverged> {
    dilu_cg_in(
        a,
        b,
        x,
        m,
        (tol, max_iter, 1),
        &mut DiluCgVectors::default(),
    )
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
    /// Per-block partial sums of the dot products.
    parts: Vec<f64>,
}

/// The team's shared vectors.
#[derive(Clone, Copy)]
struct Vectors {
    x: Shared,
    r: Shared,
    y: Shared,
    rh: Shared,
    z: Shared,
    p: Shared,
    w: Shared,
    q: Shared,
    parts: [Shared; 2],
}

/// [`dilu_cg`] to `(tol, max_iter)` on a team of up to `team` threads (the same results for
/// any team), in the memory of `work`.
pub fn dilu_cg_in(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    m: &Dilu,
    (tol, max_iter, team): (f64, usize, usize),
    work: &mut DiluCgVectors,
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let blocks = n.div_ceil(BLOCK);
    let DiluCgVectors {
        r,
        y,
        rh,
        z,
        p,
        w,
        q,
        parts,
    } = work;
    for v in [
        &mut *r, &mut *y, &mut *rh, &mut *z, &mut *p, &mut *w, &mut *q,
    ] {
        v.clear();
        v.resize(n, 0.0);
    }
    parts.clear();
    parts.resize(2 * blocks, 0.0);
    let (first, second) = parts.split_at_mut(blocks);
    let v = Vectors {
        x: Shared::new(x),
        r: Shared::new(r),
        y: Shared::new(y),
        rh: Shared::new(rh),
        z: Shared::new(z),
        p: Shared::new(p),
        w: Shared::new(w),
        q: Shared::new(q),
        parts: [Shared::new(first), Shared::new(second)],
    };
    let result = Mutex::new(Err(NotConverged::at(max_iter, f64::NAN)));
    let team = if n < 2 * BLOCK { 1 } else { team };
    run_team(team, |t| {
        let got = member_cg(t, a, b, m, v, (tol, max_iter));
        if t.index == 0 {
            *result.lock().unwrap_or_else(|e| e.into_inner()) = got;
        }
    });
    result.into_inner().unwrap_or_else(|e| e.into_inner())
}

/// One member's part of [`dilu_cg_in`] (the algorithm of the module docs); every member
/// computes the same scalars and takes the same branches.
///
/// SAFETY (every `part` and `all` here and in the passes it calls): a member writes only
/// its own rows and blocks between barriers, or the rows of its part of a substitution,
/// reads other members' entries only after a barrier and before they are written again,
/// and holds no two views of one vector at once.
fn member_cg(
    t: &Member,
    a: &CsrMatrix,
    b: &[f64],
    m: &Dilu,
    v: Vectors,
    (tol, max_iter): (f64, usize),
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let mine = t.share(n.div_ceil(BLOCK));
    let own = rows_of(&mine, n);
    let [s0, s1] = v.parts;
    // r = b - A x, with |b|^2 and |r|^2.
    // SAFETY (here and below): x is not written meanwhile; r's rows and the sums' blocks
    // are this member's.
    unsafe { residual(a, b, (v.x, v.r), (Some(s0), s1), &mine) };
    t.wait();
    let bnorm = unsafe { total(s0) }.sqrt();
    let mut rnorm = unsafe { total(s1) }.sqrt();
    if bnorm == 0.0 {
        unsafe { v.x.part(own) }.iter_mut().for_each(|v| *v = 0.0);
        return Ok(SolveStats::default());
    }
    if let Some(done) = converged(0, rnorm, bnorm, tol) {
        return Ok(done);
    }
    let goal = tol * bnorm;
    // Transformed unknowns y = T^T x and residual r^ = T^-1 r; z = D r^.
    m.upper_times_rows(a, unsafe { v.x.all() }, own.clone(), unsafe {
        v.y.part(own.clone())
    });
    let r = v.r.ptr() as *const f64;
    // SAFETY: `r` was written before the last barrier and is not written in the pass.
    forward(t, a, m, |i| unsafe { *r.add(i) }, v.rh.ptr());
    scaled(m, v, &mine, 0.0, false);
    t.wait();
    let mut rz = unsafe { total(s1) };
    // The M^-1 norm must fall by the factor the true residual has to.
    let mut target = rz.sqrt() * goal / rnorm;
    unsafe { v.p.part(own.clone()) }.copy_from_slice(unsafe { v.z.part(own.clone()) });
    t.wait();
    for it in 1..=max_iter {
        // q = T^-1 A T^-T p = w + T^-1 (p - K w), w = T^-T p; then p . q.
        backward(t, a, m, v.p.ptr(), v.w.ptr());
        let (p, w) = (v.p.ptr() as *const f64, v.w.ptr() as *const f64);
        // SAFETY: `p` and `w` are complete (past a barrier) and not written in the pass.
        let src = |i: usize| unsafe { *p.add(i) - m.k[i] * *w.add(i) };
        forward(t, a, m, src, v.q.ptr());
        with_w_added(v, &mine, n);
        t.wait();
        let pq = unsafe { total(s0) };
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        scaled(m, v, &mine, alpha, true);
        t.wait();
        let rz_new = unsafe { total(s1) };
        if !rz_new.is_finite() {
            break;
        }
        if rz_new.sqrt() <= target {
            backward(t, a, m, v.y.ptr(), v.x.ptr());
            unsafe { residual(a, b, (v.x, v.r), (None, s1), &mine) };
            t.wait();
            rnorm = unsafe { total(s1) }.sqrt();
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
        let (p, z) = unsafe { (v.p.part(own.clone()), v.z.part(own.clone())) };
        for (pk, zk) in p.iter_mut().zip(z.iter()) {
            *pk = zk + beta * *pk;
        }
        t.wait();
    }
    backward(t, a, m, v.y.ptr(), v.x.ptr());
    unsafe { residual(a, b, (v.x, v.r), (None, s1), &mine) };
    t.wait();
    rnorm = unsafe { total(s1) }.sqrt();
    Err(NotConverged::at(max_iter, rnorm / bnorm))
}

/// With `step`, `y += alpha p` and `r^ -= alpha q` first; then `z = D r^` on the own rows
/// of blocks `mine`, `r^ . z` in the second partial sums.
fn scaled(m: &Dilu, v: Vectors, mine: &Range<usize>, alpha: f64, step: bool) {
    let n = m.d.len();
    let own = rows_of(mine, n);
    let (y, rh) = unsafe { (v.y.part(own.clone()), v.rh.part(own.clone())) };
    let (z, p, q) = unsafe {
        (
            v.z.part(own.clone()),
            v.p.part(own.clone()),
            v.q.part(own.clone()),
        )
    };
    let rz_own = unsafe { v.parts[1].part(mine.clone()) };
    for (k, rows) in blocks_of(mine, n) {
        let l = rows.start - own.start..rows.end - own.start;
        let (rh, z, d) = (&mut rh[l.clone()], &mut z[l.clone()], &m.d[rows]);
        if step {
            let (y, p, q) = (&mut y[l.clone()], &p[l.clone()], &q[l]);
            for (((yk, rk), pk), qk) in y.iter_mut().zip(rh.iter_mut()).zip(p).zip(q) {
                *yk += alpha * pk;
                *rk -= alpha * qk;
            }
        }
        let mut rz = 0.0;
        for ((zk, rk), dk) in z.iter_mut().zip(rh.iter()).zip(d) {
            *zk = dk * rk;
            rz += rk * *zk;
        }
        rz_own[k] = rz;
    }
}

/// `q += w` on the own rows of blocks `mine`, `p . q` in the first partial sums.
fn with_w_added(v: Vectors, mine: &Range<usize>, n: usize) {
    let own = rows_of(mine, n);
    let (q, w, p) = unsafe {
        (
            v.q.part(own.clone()),
            v.w.part(own.clone()),
            v.p.part(own.clone()),
        )
    };
    let pq_own = unsafe { v.parts[0].part(mine.clone()) };
    for (k, rows) in blocks_of(mine, n) {
        let l = rows.start - own.start..rows.end - own.start;
        let mut pq = 0.0;
        for ((qk, wk), pk) in q[l.clone()].iter_mut().zip(&w[l.clone()]).zip(&p[l]) {
            *qk += wk;
            pq += pk * *qk;
        }
        pq_own[k] = pq;
    }
}

/// `u = T^-1 v` on the team: the two parts at once, then the band; ends past a barrier.
fn forward(t: &Member, a: &CsrMatrix, m: &Dilu, v: impl Fn(usize) -> f64 + Copy, u: *mut f64) {
    let [first, second, band] = m.forward_order();
    t.wait();
    // SAFETY: the parts couple to neither each other nor the band's results.
    unsafe {
        if t.index == 0 {
            m.forward_rows(a, first, v, u);
        }
        if t.index == 1 || t.size == 1 {
            m.forward_rows(a, second, v, u);
        }
    }
    t.wait();
    if t.index == 0 {
        // SAFETY: the other members wait at the next barrier.
        unsafe { m.forward_rows(a, band, v, u) };
    }
    t.wait();
}

/// `w = T^-T v` on the team: the band, then the two parts at once; ends past a barrier.
fn backward(t: &Member, a: &CsrMatrix, m: &Dilu, v: *const f64, w: *mut f64) {
    let [first, second, band] = m.forward_order();
    t.wait();
    if t.index == 0 {
        // SAFETY: the other members wait at the next barrier.
        unsafe { m.backward_rows(a, band, v, w) };
    }
    t.wait();
    // SAFETY: as for the forward parts.
    unsafe {
        if t.index == 0 {
            m.backward_rows(a, first, v, w);
        }
        if t.index == 1 || t.size == 1 {
            m.backward_rows(a, second, v, w);
        }
    }
    t.wait();
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
                let [(c1, x1), (c2, x2)] = m.lower(a, i);
                m.d[i] * t[i] + row_dot(c1, x1, &t) + row_dot(c2, x2, &t)
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

    /// The D-ILU of `a` in the plain order (no second part): what the twisted numbering is
    /// measured against.
    fn plain(a: &CsrMatrix, omega: f64) -> Dilu {
        let m = Dilu::new(a, omega).unwrap();
        let n = a.n();
        let mut p = Dilu {
            m: n,
            s: 0,
            ..Default::default()
        };
        p.diag_pos = m.diag_pos.clone();
        p.mid_pos = m.diag_pos.clone();
        (p.d, p.inv_d, p.upper_sum) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let [(_, x), (_, y)] = p.upper(a, i);
            p.upper_sum[i] = x.iter().sum::<f64>() + y.iter().sum::<f64>();
        }
        let v = p.shared();
        for i in 0..n {
            // SAFETY: one thread, every row placed.
            assert!(unsafe { v.pivot(a, n, i, omega) });
        }
        p.k = (0..n).map(|i| 2.0 * p.d[i] - a.get(i, i)).collect();
        p
    }

    /// On an MPS lattice Laplacian of 2 500 rows the twisted numbering splits the rows (a
    /// band of a few per cent), preconditions as well as the plain order (CG iterations
    /// within 15 %), reaches the tolerance, and one and two threads agree bit for bit.
    #[test]
    fn the_twisted_numbering_preconditions_as_the_plain_order_on_one_or_two_threads() {
        use crate::linalg::sparse::tests::mps_lattice;
        let a = mps_lattice(50);
        let n = a.n();
        let xs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; n];
        a.spmv(&xs, &mut b);
        let m = Dilu::new(&a, 0.99).unwrap();
        assert!(
            m.m > n / 3 && m.s > 0 && m.s < n / 10,
            "m {} s {} of {n}",
            m.m,
            m.s
        );
        let solve = |threads: usize, pre: &Dilu| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut x = vec![0.0; n];
            let st = pool.install(|| {
                let mut w = DiluCgVectors::default();
                dilu_cg_in(&a, &b, &mut x, pre, (1e-10, 500, 2), &mut w).unwrap()
            });
            (x, st.iterations)
        };
        // The set-up on a team of two gives the pivots bit for bit (started when no other
        // test's team holds the pool).
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build();
        let mut m2 = Dilu::default();
        crate::linalg::team::wait_for_no_team();
        assert!(pool.unwrap().install(|| m2.rebuild_on(&a, 0.99, 2)));
        assert!(m2.d == m.d && m2.k == m.k && m2.upper_sum == m.upper_sum);
        let (x1, it1) = solve(1, &m);
        let (x2, it2) = solve(2, &m2);
        let (_, it_plain) = solve(1, &plain(&a, 0.99));
        eprintln!("band {} of {n}: twisted {it1}, plain {it_plain}", m.s);
        assert_eq!(it1, it2);
        assert!(x1 == x2, "1 and 2 threads differ");
        assert!(
            (it1 as f64) <= 1.15 * it_plain as f64,
            "twisted {it1} against {it_plain}"
        );
        let err = x1
            .iter()
            .zip(&xs)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-6, "error {err}");
    }

    /// A row without its diagonal is refused.
    #[test]
    fn a_missing_diagonal_is_refused() {
        let a = CsrMatrix::from_rows(vec![vec![(1, -1.0)], vec![(0, -1.0), (1, 2.0)]]);
        assert!(Dilu::new(&a, 0.0).is_none());
    }
}
