//! MIC(0) in the twisted numbering (van der Vorst 1987, Parallel Computing 5:45-54, "burn
//! at both ends"), and the CG that applies it on a team of two threads.
//!
//! The rows keep their (cell) order in a first part `0..m` and are numbered backwards in the
//! rest, so that the rows of the second part coupled to the first, a band `m..m + s` right
//! after `m`, come last. With `A` the first part, `B` the second part's far rows and `S` the
//! band, no entry couples `A` and `B`: the forward substitution does `A` and `B` at once,
//! then `S`; the backward one `S`, then `A` and `B` at once. The factor is MIC(0) of the
//! matrix in that numbering, a preconditioner as good as MIC(0) in the cell order
//! (docs/decisions.md, "MIC(0) in the twisted numbering"). The numbering does not depend on
//! the number of threads, so one and two threads give the same results bit for bit.

use super::ic0::{lower_triangle_twisted_into, Ic0, Mic0Scratch, NEW_ROW};
use super::pcg::{converged, NotConverged, SolveStats};
use super::sparse::{row_dot, CsrMatrix};
use super::team::{blocks_of, residual, rows_of, run_team, total, Member, Shared, BLOCK};
use std::ops::Range;
use std::sync::Mutex;

/// Below this many rows the system is not split (one part, no band).
const SPLIT_FROM: usize = 64;

/// A MIC(0) factor in the twisted numbering of the system it was built for.
#[derive(Clone, Debug, Default)]
pub struct Twisted {
    factor: Ic0,
    /// Rows of the system it was built for.
    n: usize,
    /// First row of the second part (system numbering).
    m: usize,
    /// Rows of the band: the factor's last `s` rows.
    s: usize,
}

impl Twisted {
    /// Factors `a` (rows in cell order) in the twisted numbering, in this factor's memory:
    /// MIC(0) relaxed by `omega`, plain IC(0) where a relaxed pivot is not positive. False
    /// (unusable) where neither can be built.
    pub fn rebuild(&mut self, a: &CsrMatrix, omega: f64, scratch: &mut Mic0Scratch) -> bool {
        let (m, s) = split(a);
        (self.n, self.m, self.s) = (a.n(), m, s);
        lower_triangle_twisted_into(a, m, self.factor.lower_mut());
        if self.factor.modify_lower(omega, scratch) {
            return true;
        }
        let mut l = CsrMatrix::default();
        lower_triangle_twisted_into(a, m, &mut l);
        match Ic0::of_lower(l) {
            Some(f) => {
                self.factor = f;
                true
            }
            None => false,
        }
    }

    /// The factor's row of row `i` of the system it was built for.
    #[inline]
    pub fn row(&self, i: usize) -> usize {
        if i < self.m {
            i
        } else {
            self.m + self.n - 1 - i
        }
    }

    /// The factor's rows of the two parts that are solved at once, and of the band.
    fn parts(&self) -> [Range<usize>; 3] {
        let b = self.n - self.s;
        [0..self.m, self.m..b, b..self.n]
    }

    /// Rows of the band (solved by one thread).
    pub fn band(&self) -> usize {
        self.s
    }
}

/// The first row `m` of the second part and the band's rows `s`: `m` about halves the rows
/// outside the band; the band holds every second-part row coupled to the first part.
pub(crate) fn split(a: &CsrMatrix) -> (usize, usize) {
    let n = a.n();
    if n < SPLIT_FROM {
        return (n, 0);
    }
    // The second-part rows up to the last column any first-part row reaches.
    let band = |m: usize| {
        let reach = (0..m)
            .map(|i| a.row(i).0.last().map_or(0, |&c| c as usize + 1))
            .max()
            .unwrap_or(0);
        reach.saturating_sub(m).min(n - m)
    };
    let m = (n - band(n / 2)) / 2;
    let m = m.max(1);
    (m, band(m))
}

/// The work vectors of [`twisted_cg_in`], kept between solves.
#[derive(Clone, Debug, Default)]
pub struct TwistedCgVectors {
    r: Vec<f64>,
    z: Vec<f64>,
    q: Vec<f64>,
    p: Vec<f64>,
    /// The residual and its preconditioned value in the factor's numbering.
    ro: Vec<f64>,
    zo: Vec<f64>,
    /// Per-block partial sums of the three dot products.
    parts: Vec<f64>,
}

/// What the preconditioner is applied with: the factor and, for a system other than the
/// one it was built for, the factor system's row of each row ([`NEW_ROW`] for none).
#[derive(Clone, Copy)]
pub struct TwistedPre<'a> {
    /// The factor.
    pub factor: &'a Twisted,
    /// Row map to the factor's system (`None`: the same system).
    pub from: Option<&'a [u32]>,
}

/// The team's shared vectors.
#[derive(Clone, Copy)]
struct Vectors {
    x: Shared,
    r: Shared,
    z: Shared,
    q: Shared,
    p: Shared,
    ro: Shared,
    zo: Shared,
    parts: [Shared; 3],
}

/// PCG for SPD `a` from `x` (warm start) to the relative residual `tol`, preconditioned by
/// `pre`, on a team of up to `team` threads (the same results for any team).
pub fn twisted_cg_in(
    a: &CsrMatrix,
    b: &[f64],
    x: &mut [f64],
    pre: TwistedPre,
    (tol, max_iter, team): (f64, usize, usize),
    work: &mut TwistedCgVectors,
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let blocks = n.div_ceil(BLOCK);
    let nf = pre.factor.n;
    let TwistedCgVectors {
        r,
        z,
        q,
        p,
        ro,
        zo,
        parts,
    } = work;
    for v in [&mut *r, &mut *z, &mut *q, &mut *p] {
        v.clear();
        v.resize(n, 0.0);
    }
    for v in [&mut *ro, &mut *zo] {
        v.clear();
        v.resize(nf, 0.0);
    }
    parts.clear();
    parts.resize(3 * blocks, 0.0);
    let (pq_parts, rest) = parts.split_at_mut(blocks);
    let (rr_parts, rz_parts) = rest.split_at_mut(blocks);
    let v = Vectors {
        x: Shared::new(x),
        r: Shared::new(r),
        z: Shared::new(z),
        q: Shared::new(q),
        p: Shared::new(p),
        ro: Shared::new(ro),
        zo: Shared::new(zo),
        parts: [
            Shared::new(pq_parts),
            Shared::new(rr_parts),
            Shared::new(rz_parts),
        ],
    };
    let result = Mutex::new(Err(NotConverged::at(max_iter, f64::NAN)));
    let team = if n < 2 * BLOCK { 1 } else { team };
    run_team(team, |m| {
        let got = member_cg(m, a, b, pre, v, (tol, max_iter));
        if m.index == 0 {
            *result.lock().unwrap_or_else(|e| e.into_inner()) = got;
        }
    });
    result.into_inner().unwrap_or_else(|e| e.into_inner())
}

/// One member's part of [`twisted_cg_in`]; every member computes the same scalars and
/// takes the same branches.
///
/// SAFETY (every `part` and `all` here and in [`apply_pre`]): a member writes only its own
/// rows and blocks between barriers, reads other members' entries only after a barrier and
/// before they are written again, and holds no two views of one vector at once.
fn member_cg(
    m: &Member,
    a: &CsrMatrix,
    b: &[f64],
    pre: TwistedPre,
    v: Vectors,
    (tol, max_iter): (f64, usize),
) -> Result<SolveStats, NotConverged> {
    let n = b.len();
    let mine = m.share(n.div_ceil(BLOCK));
    let own = rows_of(&mine, n);
    let [pq_parts, rr_parts, rz_parts] = v.parts;
    // SAFETY: x is not written here; r's rows and the sums' blocks are this member's.
    unsafe { residual(a, b, (v.x, v.r), (Some(pq_parts), rr_parts), &mine) };
    m.wait();
    let bnorm = unsafe { total(pq_parts) }.sqrt();
    let mut rnorm = unsafe { total(rr_parts) }.sqrt();
    if bnorm == 0.0 {
        unsafe { v.x.part(own) }.iter_mut().for_each(|v| *v = 0.0);
        return Ok(SolveStats::default());
    }
    if let Some(done) = converged(0, rnorm, bnorm, tol) {
        return Ok(done);
    }
    apply_pre(m, a, pre, v, &mine);
    unsafe { v.p.part(own.clone()) }.copy_from_slice(unsafe { v.z.part(own.clone()) });
    m.wait();
    let mut rz = unsafe { total(rz_parts) };
    for it in 1..=max_iter {
        product(a, v, &mine);
        m.wait();
        let pq = unsafe { total(pq_parts) };
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        update(alpha, v, &mine, n);
        m.wait();
        rnorm = unsafe { total(rr_parts) }.sqrt();
        if !rnorm.is_finite() {
            break;
        }
        if let Some(done) = converged(it, rnorm, bnorm, tol) {
            return Ok(done);
        }
        apply_pre(m, a, pre, v, &mine);
        let rz_new = unsafe { total(rz_parts) };
        let beta = rz_new / rz;
        rz = rz_new;
        let (p, z) = unsafe { (v.p.part(own.clone()), v.z.part(own.clone())) };
        for (pk, zk) in p.iter_mut().zip(z.iter()) {
            *pk = zk + beta * *pk;
        }
        m.wait();
    }
    Err(NotConverged::at(max_iter, rnorm / bnorm))
}

/// `q = A p` on the own rows of blocks `mine`, with `p . q` in the first partial sums.
fn product(a: &CsrMatrix, v: Vectors, mine: &Range<usize>) {
    let n = a.n();
    let own = rows_of(mine, n);
    let ps = unsafe { v.p.all() };
    let q = unsafe { v.q.part(own.clone()) };
    let pq_own = unsafe { v.parts[0].part(mine.clone()) };
    for (k, rows) in blocks_of(mine, n) {
        let mut pq = 0.0;
        for i in rows {
            let (c, w) = a.row(i);
            let qi = row_dot(c, w, ps);
            q[i - own.start] = qi;
            pq += ps[i] * qi;
        }
        pq_own[k] = pq;
    }
}

/// `x += alpha p`, `r -= alpha q` on the own rows of blocks `mine` (of `n` rows), with
/// `r . r` in the second partial sums.
fn update(alpha: f64, v: Vectors, mine: &Range<usize>, n: usize) {
    let own = rows_of(mine, n);
    let (x, r) = unsafe { (v.x.part(own.clone()), v.r.part(own.clone())) };
    let (p, q) = unsafe { (v.p.part(own.clone()), v.q.part(own.clone())) };
    let rr_own = unsafe { v.parts[1].part(mine.clone()) };
    for (k, rows) in blocks_of(mine, n) {
        let mut rr = 0.0;
        for i in rows {
            let l = i - own.start;
            x[l] += alpha * p[l];
            r[l] -= alpha * q[l];
            rr += r[l] * r[l];
        }
        rr_own[k] = rr;
    }
}

/// `z = M^-1 r` on the team, with `r . z` in the blocks' partial sums; ends past a barrier.
fn apply_pre(m: &Member, a: &CsrMatrix, pre: TwistedPre, v: Vectors, mine: &Range<usize>) {
    let n = a.n();
    let f = pre.factor;
    let own = rows_of(mine, n);
    let known = |k: usize| match pre.from {
        Some(from) => from[k] as usize,
        None => k,
    };
    // Gather into the factor's numbering (distinct rows: the map is one to one).
    let r = unsafe { v.r.all() };
    for k in own.clone() {
        let o = known(k);
        if o != NEW_ROW as usize {
            // SAFETY: row `f.row(o)` is this row's alone.
            unsafe { *v.ro.ptr().add(f.row(o)) = r[k] };
        }
    }
    m.wait();
    let [first, second, band] = f.parts();
    let (ro, zo) = (v.ro.ptr() as *const f64, v.zo.ptr());
    // SAFETY: the two parts couple to neither each other nor the band's results here.
    unsafe {
        if m.index == 0 {
            f.factor.forward_rows(first.clone(), ro, zo);
        }
        if m.index == 1 || m.size == 1 {
            f.factor.forward_rows(second.clone(), ro, zo);
        }
    }
    m.wait();
    if m.index == 0 {
        // SAFETY: the other members wait at the next barrier.
        unsafe {
            f.factor.forward_rows(band.clone(), ro, zo);
            f.factor.backward_rows(band, zo);
        }
    }
    m.wait();
    // SAFETY: as for the forward parts.
    unsafe {
        if m.index == 0 {
            f.factor.backward_rows(first, zo);
        }
        if m.index == 1 || m.size == 1 {
            f.factor.backward_rows(second, zo);
        }
    }
    m.wait();
    let zo = unsafe { v.zo.all() };
    let z = unsafe { v.z.part(own.clone()) };
    let rz_own = unsafe { v.parts[2].part(mine.clone()) };
    for (kb, rows) in blocks_of(mine, n) {
        let mut rz = 0.0;
        for k in rows {
            let o = known(k);
            let zk = if o != NEW_ROW as usize {
                zo[f.row(o)]
            } else {
                let (c, w) = a.row(k);
                let d = c
                    .iter()
                    .position(|&j| j as usize == k)
                    .map_or(1.0, |p| w[p]);
                r[k] / d
            };
            z[k - own.start] = zk;
            rz += r[k] * zk;
        }
        rz_own[kb] = rz;
    }
    m.wait();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::pcg::pcg;
    use crate::linalg::sparse::tests::mps_lattice;
    use crate::linalg::tests::laplace_2d;
    use crate::linalg::tests::laplace_2d as laplacian;

    fn solve_on(threads: usize, a: &CsrMatrix, b: &[f64], f: &Twisted) -> (Vec<f64>, usize) {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut x = vec![0.0; b.len()];
        let pre = TwistedPre {
            factor: f,
            from: None,
        };
        let s = pool.install(|| {
            let mut w = TwistedCgVectors::default();
            twisted_cg_in(a, b, &mut x, pre, (1e-10, 500, 2), &mut w).unwrap()
        });
        (x, s.iterations)
    }

    /// The twisted lower triangle is the lower triangle of `P A P^T`: every entry of `a`
    /// lands once, at its permuted place, diagonal last.
    #[test]
    fn the_twisted_triangle_is_the_permuted_matrix() {
        let a = mps_lattice(20);
        let n = a.n();
        let (m, s) = split(&a);
        assert!(m > n / 3 && s > 0 && m + s < n, "m {m} s {s} of {n}");
        let mut l = CsrMatrix::default();
        lower_triangle_twisted_into(&a, m, &mut l);
        let f = Twisted {
            n,
            m,
            s,
            ..Default::default()
        };
        let mut entries = 0;
        for k in 0..n {
            let (c, v) = l.row(k);
            assert_eq!(*c.last().unwrap() as usize, k);
            assert!(c.windows(2).all(|w| w[0] < w[1]));
            for (&j, &x) in c.iter().zip(v) {
                assert_eq!(a.get(f.row(k), f.row(j as usize)), x);
            }
            entries += c.len();
        }
        assert_eq!(2 * entries - n, a.nnz());
        // No entry couples the two parts solved at once.
        let [first, second, _] = f.parts();
        for k in second {
            let (c, _) = l.row(k);
            assert!(c.iter().all(|&j| !first.contains(&(j as usize))));
        }
    }

    /// The twisted MIC(0) preconditions as well as MIC(0) in the plain order (CG iterations
    /// within 15 %), solves to the tolerance, and one and two threads agree bit for bit.
    #[test]
    fn the_twisted_factor_preconditions_as_mic0_does() {
        for a in [laplace_2d(60), mps_lattice(50)] {
            let n = a.n();
            let xs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut b = vec![0.0; n];
            a.spmv(&xs, &mut b);
            let mut f = Twisted::default();
            assert!(f.rebuild(&a, 0.97, &mut Mic0Scratch::default()));
            let plain = Ic0::modified(&a, 0.97).unwrap();
            let mut x0 = vec![0.0; n];
            let it_plain = pcg(&a, &b, &mut x0, &plain, 1e-10, 500).unwrap().iterations;
            let (x1, it1) = solve_on(1, &a, &b, &f);
            let (x2, it2) = solve_on(2, &a, &b, &f);
            eprintln!("n {n}: band {} twisted {it1} plain {it_plain}", f.band());
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
    }

    /// A twisted factor carried over to a system whose unknowns are nearly the same: the Laplacian
    /// of a 40 x 40 grid, then the same grid in reverse order with 20 nodes of its top row
    /// gone (Dirichlet, as free-surface particles flag) and 30 new ones (a 41st column, as
    /// particles join): 3 % of the rows changed.
    /// CG with the carried factor reaches the same solution (the preconditioner stays SPD)
    /// in at most twice the iterations of a fresh MIC(0) and a third of Jacobi's, on one and
    /// two threads alike.
    #[test]
    fn a_carried_factor_preconditions_a_nearly_equal_system() {
        use crate::linalg::pcg::{Jacobi, Precondition};
        let m = 40;
        let old = laplacian(m);
        let mut f = Twisted::default();
        assert!(f.rebuild(&old, 0.97, &mut Mic0Scratch::default()));
        // Node ids: (x, y) -> y * 41 + x on a 41-wide grid; the old system holds x < 40.
        let old_row_of = |id: usize| {
            let (x, y) = (id % 41, id / 41);
            (x < m && y < m).then_some((y * m + x) as u32)
        };
        let gone = |x: usize, y: usize| y == m - 1 && x.is_multiple_of(2);
        let mut ids: Vec<usize> = (0..m)
            .flat_map(|y| (0..=m).map(move |x| (x, y)))
            .filter(|&(x, y)| !gone(x, y) && (x < m || y < 30))
            .map(|(x, y)| y * 41 + x)
            .collect();
        ids.reverse();
        let row_of_id = |id: usize| ids.iter().position(|&k| k == id);
        let a = CsrMatrix::from_rows(ids.iter().map(|&id| {
            let (x, y) = ((id % 41) as i64, (id / 41) as i64);
            let mut row = vec![];
            for (dx, dy, v) in [
                (0, -1, -1.0),
                (-1, 0, -1.0),
                (0, 0, 4.0),
                (1, 0, -1.0),
                (0, 1, -1.0),
            ] {
                let (u, w) = (x + dx, y + dy);
                if u < 0 || w < 0 || u > m as i64 {
                    continue;
                }
                if let Some(k) = row_of_id((w * 41 + u) as usize) {
                    row.push((k as u32, v));
                }
            }
            row.sort_by_key(|e| e.0);
            row
        }));
        let from: Vec<u32> = ids
            .iter()
            .map(|&id| old_row_of(id).unwrap_or(NEW_ROW))
            .collect();
        let new = from.iter().filter(|&&o| o == NEW_ROW).count();
        assert_eq!((a.n(), new), (m * m - 20 + 30, 30));
        let n = a.n();
        let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let check = |x: &[f64]| {
            let mut ax = vec![0.0; n];
            a.spmv(x, &mut ax);
            let res = ax
                .iter()
                .zip(&b)
                .map(|(p, q)| (p - q).powi(2))
                .sum::<f64>()
                .sqrt();
            let bn = b.iter().map(|q| q * q).sum::<f64>().sqrt();
            assert!(res < 1e-9 * bn, "residual {res} of {bn}");
        };
        let solve = |p: &dyn Precondition| {
            let mut x = vec![0.0; n];
            let it = pcg(&a, &b, &mut x, p, 1e-10, 5000).unwrap().iterations;
            check(&x);
            it
        };
        // Carried, on one and two threads: the same iterates.
        let mut xs = Vec::new();
        let mut i_carried = 0;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut x = vec![0.0; n];
            let pre = TwistedPre {
                factor: &f,
                from: Some(&from),
            };
            let s = pool.install(|| {
                let mut w = TwistedCgVectors::default();
                twisted_cg_in(&a, &b, &mut x, pre, (1e-10, 5000, 2), &mut w).unwrap()
            });
            check(&x);
            xs.push(x);
            i_carried = s.iterations;
        }
        assert!(xs[0] == xs[1], "1 and 2 threads differ");
        let fresh = Ic0::modified(&a, 0.97).unwrap();
        let (i_fresh, i_jacobi) = (solve(&fresh), solve(&Jacobi::new(&a)));
        eprintln!("carried {i_carried} fresh {i_fresh} jacobi {i_jacobi}");
        assert!(
            i_carried <= 2 * i_fresh && 3 * i_carried < i_jacobi,
            "carried {i_carried}, fresh {i_fresh}, Jacobi {i_jacobi}"
        );
    }
}
