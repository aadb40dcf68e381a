//! Incomplete Cholesky IC(0) preconditioner: the Cholesky factor restricted to the sparsity
//! of the matrix's lower triangle (Meijerink & van der Vorst 1977).

use super::pcg::Precondition;
use super::sparse::CsrMatrix;
use std::ops::Range;

/// A row of a carried preconditioner's map that its factor does not know (a new unknown).
pub const NEW_ROW: u32 = u32::MAX;

/// Incomplete Cholesky factor `L` (lower triangle incl. diagonal, row-wise) with the
/// sparsity of the lower triangle of `A`: IC(0).
#[derive(Clone, Debug, Default)]
pub struct Ic0 {
    l: CsrMatrix,
    /// `1 / L_ii`, so the substitutions multiply instead of dividing on their critical path.
    inv_diag: Vec<f64>,
}

impl Ic0 {
    /// Factors `a`; `None` if a pivot is not positive.
    pub fn new(a: &CsrMatrix) -> Option<Ic0> {
        Ic0::of_lower(lower_triangle(a))
    }

    /// IC(0) of the matrix whose lower triangle (diagonal last in each row) is `l`.
    pub(crate) fn of_lower(mut l: CsrMatrix) -> Option<Ic0> {
        let n = l.n();
        // Row i's entries scattered by column (zero off its pattern), so that each entry's
        // sum over row k is a gather without a search (docs/decisions.md, "IC(0) set-up").
        let mut w = vec![0.0; n];
        for i in 0..n {
            let (start, end) = (l.row_ptr[i] as usize, l.row_ptr[i + 1] as usize);
            for p in start..end {
                let k = l.col[p] as usize;
                // s = sum_{m < k} L_im L_km: row k's entries left of its diagonal.
                let (ks, ke) = (l.row_ptr[k] as usize, l.row_ptr[k + 1] as usize);
                let mut s = 0.0;
                for q in ks..ke - 1 {
                    s += w[l.col[q] as usize] * l.val[q];
                }
                if k < i {
                    let lkk = l.val[ke - 1];
                    l.val[p] = (l.val[p] - s) / lkk;
                    w[k] = l.val[p];
                } else {
                    let d = l.val[p] - s;
                    if d <= 0.0 || !d.is_finite() {
                        return None;
                    }
                    l.val[p] = d.sqrt();
                }
            }
            for p in start..end {
                w[l.col[p] as usize] = 0.0;
            }
        }
        Some(Ic0::from_factor(l))
    }

    /// Modified IC(0) (Gustafsson 1978), relaxed by `omega` in [0, 1]: fill that IC(0) drops
    /// is moved, times `omega`, to the diagonals of its row and column, so that `L L^T` keeps
    /// the row sums of `a` (at `omega = 1`). Left-looking by columns: column `k` gathers the
    /// updates of the columns `m` in row `k`, its pattern marked in a dense array, so an
    /// update either lands on an entry or is dropped without a search (docs/decisions.md,
    /// "MIC(0)"). `None` if a pivot is not positive.
    pub fn modified(a: &CsrMatrix, omega: f64) -> Option<Ic0> {
        let mut f = Ic0::default();
        f.modify_from(a, omega, &mut Mic0Scratch::default())
            .then_some(f)
    }

    /// [`Ic0::modified`] into this factor's memory, with `scratch` for the column view:
    /// once warm, a set-up allocates nothing. False (the factor unusable) if a pivot is not
    /// positive.
    pub fn modify_from(&mut self, a: &CsrMatrix, omega: f64, scratch: &mut Mic0Scratch) -> bool {
        lower_triangle_into(a, &mut self.l);
        self.modify_lower(omega, scratch)
    }

    /// [`Ic0::modify_from`] of the matrix whose lower triangle (diagonal last in each row)
    /// this factor's memory holds.
    pub(crate) fn modify_lower(&mut self, omega: f64, scratch: &mut Mic0Scratch) -> bool {
        let l = &mut self.l;
        let n = l.n();
        let Mic0Scratch {
            start,
            below,
            cursor,
            slot,
        } = scratch;
        columns_below_into(l, start, below, cursor);
        // Per column, the first entry of `below` not yet passed by the sweep over k.
        cursor.clear();
        cursor.extend_from_slice(&start[..n]);
        // Position in `l.val` of entry (i, k) of the current column k, if in the pattern.
        slot.clear();
        slot.resize(n, u32::MAX);
        let diag = |l: &CsrMatrix, i: usize| l.row_ptr[i + 1] as usize - 1;
        for k in 0..n {
            let col = &below[start[k] as usize..start[k + 1] as usize];
            for &(i, p) in col {
                slot[i as usize] = p;
            }
            let dk = diag(l, k);
            let (rs, re) = (l.row_ptr[k] as usize, dk);
            for q in rs..re {
                let (m, lkm) = (l.col[q] as usize, l.val[q]);
                l.val[dk] -= lkm * lkm;
                let mut c = cursor[m] as usize;
                let end = start[m + 1] as usize;
                while c < end && below[c].0 as usize <= k {
                    c += 1;
                }
                cursor[m] = c as u32;
                for &(i, pim) in &below[c..end] {
                    let prod = l.val[pim as usize] * lkm;
                    match slot[i as usize] {
                        u32::MAX => {
                            let di = diag(l, i as usize);
                            l.val[di] -= omega * prod;
                            l.val[dk] -= omega * prod;
                        }
                        p => l.val[p as usize] -= prod,
                    }
                }
            }
            let d = l.val[dk];
            if d <= 0.0 || !d.is_finite() {
                return false;
            }
            let lkk = d.sqrt();
            l.val[dk] = lkk;
            for &(i, p) in col {
                l.val[p as usize] /= lkk;
                slot[i as usize] = u32::MAX;
            }
        }
        self.invert_diagonal();
        true
    }

    /// The factor's memory, for a caller that writes a lower triangle into it.
    pub(crate) fn lower_mut(&mut self) -> &mut CsrMatrix {
        &mut self.l
    }

    /// Rows in the factor.
    pub fn n(&self) -> usize {
        self.inv_diag.len()
    }

    /// Forward substitution `L y = r` over the factor's rows `rows`, whose entries left of
    /// the diagonal lie in columns already solved.
    ///
    /// # Safety
    /// `r` and `y` point to vectors of the factor's size; no other thread writes the
    /// entries of `y` these rows read or write until the caller's next barrier.
    pub(crate) unsafe fn forward_rows(&self, rows: Range<usize>, r: *const f64, y: *mut f64) {
        let l = &self.l;
        for i in rows {
            let (c, v) = l.row(i);
            let m = c.len() - 1;
            let (c, v) = (&c[..m], &v[..m]);
            let mut acc = [0.0; 4];
            let (cs, vs) = (c.chunks_exact(4), v.chunks_exact(4));
            let (cr, vr) = (cs.remainder(), vs.remainder());
            for (c, v) in cs.zip(vs) {
                for k in 0..4 {
                    acc[k] += v[k] * *y.add(c[k] as usize);
                }
            }
            for (c, v) in cr.iter().zip(vr) {
                acc[0] += *v * *y.add(*c as usize);
            }
            let s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
            *y.add(i) = (*r.add(i) - s) * self.inv_diag[i];
        }
    }

    /// Backward substitution `L^T z = y` in place over the factor's rows `rows`, last row
    /// first (each row's result subtracted from the entries left of its diagonal).
    ///
    /// # Safety
    /// `z` points to a vector of the factor's size; no other thread reads or writes the
    /// entries these rows touch until the caller's next barrier.
    pub(crate) unsafe fn backward_rows(&self, rows: Range<usize>, z: *mut f64) {
        let l = &self.l;
        for i in rows.rev() {
            let (c, v) = l.row(i);
            let zi = *z.add(i) * self.inv_diag[i];
            *z.add(i) = zi;
            for k in 0..c.len() - 1 {
                *z.add(c[k] as usize) -= v[k] * zi;
            }
        }
    }

    /// The preconditioner of factor `l` (diagonal last in each row).
    fn from_factor(l: CsrMatrix) -> Ic0 {
        let mut f = Ic0 {
            l,
            inv_diag: Vec::new(),
        };
        f.invert_diagonal();
        f
    }

    /// `inv_diag` from the factor's diagonal.
    fn invert_diagonal(&mut self) {
        let l = &self.l;
        self.inv_diag.clear();
        self.inv_diag
            .extend((0..l.n()).map(|i| 1.0 / l.val[l.row_ptr[i + 1] as usize - 1]));
    }

    /// `z = (L L^T)^-1 r`.
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        let n = r.len();
        let l = &self.l;
        for i in 0..n {
            let (c, v) = l.row(i);
            let m = c.len() - 1;
            let s = r[i] - super::sparse::row_dot(&c[..m], &v[..m], z);
            z[i] = s * self.inv_diag[i];
        }
        for i in (0..n).rev() {
            let (c, v) = l.row(i);
            let zi = z[i] * self.inv_diag[i];
            z[i] = zi;
            for k in 0..c.len() - 1 {
                z[c[k] as usize] -= v[k] * zi;
            }
        }
    }
}

/// The lower triangle of `a`, diagonal included (last in each row).
fn lower_triangle(a: &CsrMatrix) -> CsrMatrix {
    let mut l = CsrMatrix::default();
    lower_triangle_into(a, &mut l);
    l
}

/// [`lower_triangle`] into `l`, reusing its memory.
fn lower_triangle_into(a: &CsrMatrix, l: &mut CsrMatrix) {
    lower_triangle_twisted_into(a, a.n(), l)
}

/// The lower triangle (diagonal last in each row) of `a` in the twisted numbering with the
/// second part from `m` (`m = n`: the plain order), into `l` (linalg/twisted.rs).
pub(crate) fn lower_triangle_twisted_into(a: &CsrMatrix, m: usize, l: &mut CsrMatrix) {
    let n = a.n();
    let CsrMatrix { row_ptr, col, val } = l;
    row_ptr.clear();
    col.clear();
    val.clear();
    row_ptr.reserve(n + 1);
    col.reserve(a.nnz() / 2 + n);
    val.reserve(a.nnz() / 2 + n);
    row_ptr.push(0u32);
    let flip = (m + n).saturating_sub(1);
    for k in 0..n {
        let o = if k < m { k } else { flip - k };
        let (c, v) = a.row(o);
        // Columns of the first part keep their numbers (all below a second-part row).
        let first = c.partition_point(|&j| (j as usize) < m);
        if k < m {
            for (&j, &x) in c.iter().zip(v).take_while(|(&j, _)| j as usize <= k) {
                col.push(j);
                val.push(x);
            }
        } else {
            col.extend_from_slice(&c[..first]);
            val.extend_from_slice(&v[..first]);
            // Second-part columns `j >= o` become `flip - j <= k`: last column first.
            let from = c.partition_point(|&j| (j as usize) < o).max(first);
            for p in (from..c.len()).rev() {
                col.push((flip - c[p] as usize) as u32);
                val.push(v[p]);
            }
        }
        row_ptr.push(col.len() as u32);
    }
}

/// The memory of a MIC(0) set-up's column view, kept between set-ups.
#[derive(Clone, Debug, Default)]
pub struct Mic0Scratch {
    /// `start[k]..start[k + 1]` indexes `below` for column `k`.
    start: Vec<u32>,
    /// `(row, position in l.val)` of each column's entries, rows ascending.
    below: Vec<(u32, u32)>,
    /// Per column, a cursor into `below` (also the fill counters of the column view).
    cursor: Vec<u32>,
    /// Per row, the position of the current column's entry in `l.val`, if any.
    slot: Vec<u32>,
}

/// Column view of the strict lower triangle of `l`: `start[k]..start[k + 1]` indexes
/// `below`, the `(row, position in l.val)` of column `k`'s entries, rows ascending.
#[cfg(test)]
fn columns_below(l: &CsrMatrix) -> (Vec<u32>, Vec<(u32, u32)>) {
    let (mut start, mut below) = (Vec::new(), Vec::new());
    columns_below_into(l, &mut start, &mut below, &mut Vec::new());
    (start, below)
}

/// [`columns_below`] into `start` and `below`, with `fill` as the per-column counters.
fn columns_below_into(
    l: &CsrMatrix,
    start: &mut Vec<u32>,
    below: &mut Vec<(u32, u32)>,
    fill: &mut Vec<u32>,
) {
    let n = l.n();
    start.clear();
    start.resize(n + 1, 0);
    for i in 0..n {
        let (c, _) = l.row(i);
        for &k in &c[..c.len() - 1] {
            start[k as usize + 1] += 1;
        }
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    fill.clear();
    fill.extend_from_slice(start);
    // Every entry is written below: only new room is zeroed.
    below.resize(start[n] as usize, (0, 0));
    for i in 0..n {
        let s = l.row_ptr[i] as usize;
        let (c, _) = l.row(i);
        for (q, &k) in c[..c.len() - 1].iter().enumerate() {
            below[fill[k as usize] as usize] = (i as u32, (s + q) as u32);
            fill[k as usize] += 1;
        }
    }
}

impl Precondition for Ic0 {
    fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        Ic0::apply(self, r, z)
    }
    fn sequential(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::pcg::pcg;
    use crate::linalg::tests::laplace_2d as laplacian;

    /// `(L L^T) 1`.
    fn row_sums(f: &Ic0) -> Vec<f64> {
        let l = &f.l;
        let n = l.n();
        let mut y = vec![0.0; n];
        for i in 0..n {
            let (c, v) = l.row(i);
            for (&j, &x) in c.iter().zip(v) {
                y[j as usize] += x;
            }
        }
        (0..n)
            .map(|i| {
                let (c, v) = l.row(i);
                c.iter().zip(v).map(|(&j, &x)| x * y[j as usize]).sum()
            })
            .collect()
    }

    /// The right-looking MIC(0) this module used before (reference for the left-looking
    /// one): column k's pairs of rows update each other, a merge walk per row.
    fn modified_right_looking(a: &CsrMatrix, omega: f64) -> Ic0 {
        let mut l = lower_triangle(a);
        let (start, below) = columns_below(&l);
        let diag = |l: &CsrMatrix, i: usize| l.row_ptr[i + 1] as usize - 1;
        for k in 0..a.n() {
            let dk = diag(&l, k);
            let lkk = l.val[dk].sqrt();
            l.val[dk] = lkk;
            let col = &below[start[k] as usize..start[k + 1] as usize];
            for &(_, p) in col {
                l.val[p as usize] /= lkk;
            }
            for (x, &(i, pi)) in col.iter().enumerate() {
                let (i, lik) = (i as usize, l.val[pi as usize]);
                let di = diag(&l, i);
                l.val[di] -= lik * lik;
                let mut q = l.row_ptr[i] as usize;
                for &(j, pj) in &col[..x] {
                    let prod = lik * l.val[pj as usize];
                    while q < di && l.col[q] < j {
                        q += 1;
                    }
                    if q < di && l.col[q] == j {
                        l.val[q] -= prod;
                    } else {
                        l.val[di] -= omega * prod;
                        let dj = diag(&l, j as usize);
                        l.val[dj] -= omega * prod;
                    }
                }
            }
        }
        Ic0::from_factor(l)
    }

    /// The left-looking factor equals the right-looking one to round-off (the same updates,
    /// summed in another order) on a Laplacian whose IC(0) drops fill, with a shuffled
    /// numbering so columns have entries at many distances, and on the plain numbering.
    #[test]
    fn left_and_right_looking_mic0_agree() {
        let a = laplacian(30);
        let n = a.n();
        // Permute the unknowns: p(i) = 7 i mod n (n = 900 is prime to 7).
        let perm: Vec<usize> = (0..n).map(|i| (7 * i) % n).collect();
        let mut inv = vec![0; n];
        for (i, &p) in perm.iter().enumerate() {
            inv[p] = i;
        }
        let (mut row_ptr, mut col, mut val) = (vec![0u32], Vec::new(), Vec::new());
        for i in 0..n {
            let (c, v) = a.row(perm[i]);
            let mut r: Vec<(u32, f64)> = c
                .iter()
                .zip(v)
                .map(|(&j, &x)| (inv[j as usize] as u32, x))
                .collect();
            r.sort_by_key(|e| e.0);
            for (j, x) in r {
                col.push(j);
                val.push(x);
            }
            row_ptr.push(col.len() as u32);
        }
        let b = CsrMatrix { row_ptr, col, val };
        // (At omega = 1 this numbering loses positive pivots, in either form.)
        for omega in [0.0, 0.5, 0.97] {
            let right = modified_right_looking(&b, omega);
            let left = Ic0::modified(&b, omega).unwrap();
            assert_eq!(left.l.col, right.l.col);
            for (p, q) in left.l.val.iter().zip(&right.l.val) {
                assert!(
                    (p - q).abs() < 1e-12 * q.abs().max(1.0),
                    "omega {omega}: {p} vs {q}"
                );
            }
        }
        let (left, right) = (
            Ic0::modified(&a, 1.0).unwrap(),
            modified_right_looking(&a, 1.0),
        );
        for (p, q) in left.l.val.iter().zip(&right.l.val) {
            assert!(
                (p - q).abs() < 1e-12 * q.abs().max(1.0),
                "omega 1: {p} vs {q}"
            );
        }
    }

    /// MIC(0) at omega = 1 keeps the row sums of the matrix (what makes it "modified"); at
    /// omega = 0 it is IC(0); relaxed (omega = 0.97) it needs fewer CG iterations than IC(0)
    /// on a Laplacian.
    #[test]
    fn modified_ic0_keeps_row_sums_and_converges_faster() {
        let a = laplacian(40);
        let n = a.n();
        let ones = vec![1.0; n];
        let mut want = vec![0.0; n];
        a.spmv(&ones, &mut want);
        let mic = Ic0::modified(&a, 1.0).expect("MIC(0) of a Laplacian");
        for (got, want) in row_sums(&mic).iter().zip(&want) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        let ic = Ic0::new(&a).unwrap();
        let plain = Ic0::modified(&a, 0.0).unwrap();
        for (p, q) in plain.l.val.iter().zip(&ic.l.val) {
            assert!((p - q).abs() < 1e-12 * q.abs().max(1.0), "{p} vs {q}");
        }
        let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let its = |f: &Ic0| {
            let mut x = vec![0.0; n];
            pcg(&a, &b, &mut x, f, 1e-8, 1000).unwrap().iterations
        };
        let relaxed = Ic0::modified(&a, 0.97).unwrap();
        let (i_ic, i_mic) = (its(&ic), its(&relaxed));
        assert!(i_mic * 4 < i_ic * 3, "MIC {i_mic} vs IC {i_ic} iterations");
    }
}
