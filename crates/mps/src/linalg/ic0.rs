//! Incomplete Cholesky IC(0) preconditioner: the Cholesky factor restricted to the sparsity
//! of the matrix's lower triangle (Meijerink & van der Vorst 1977).

use super::pcg::Precondition;
use super::sparse::CsrMatrix;

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

impl Precondition for Ic0 {
    fn apply(&self, _a: &CsrMatrix, r: &[f64], z: &mut [f64]) {
        Ic0::apply(self, r, z)
    }
}
