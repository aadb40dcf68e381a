//! Sparse matrices in compressed-sparse-row form, their products, and the dot product.
//! The leaf of `linalg`: every reduction runs in a fixed order (fixed-size chunks summed in
//! sequence), so results do not depend on the number of threads.

use rayon::prelude::*;

/// Elements per chunk of a deterministic parallel reduction (fixed, so results do not depend
/// on the thread count: docs/decisions.md, "Parallel chunk sizes").
pub const CHUNK: usize = 4096;

/// How a matrix entry or a vector element is stored: `f64`, or `f32` where half the bytes
/// streamed matter more than the digits (the AMG V-cycle: docs/decisions.md, "The V-cycle in
/// single precision"). Arithmetic is always `f64`.
pub trait Stored: Copy + Default + Send + Sync + 'static {
    /// The stored value as `f64`.
    fn get(self) -> f64;
    /// `x` rounded to this storage.
    fn put(x: f64) -> Self;
    /// The product `a b` (in this precision: a stored value has no more digits to give).
    fn mul(a: Self, b: Self) -> f64;
}

impl Stored for f64 {
    #[inline(always)]
    fn get(self) -> f64 {
        self
    }
    #[inline(always)]
    fn put(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn mul(a: Self, b: Self) -> f64 {
        a * b
    }
}

impl Stored for f32 {
    #[inline(always)]
    fn get(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn put(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn mul(a: Self, b: Self) -> f64 {
        (a * b) as f64
    }
}

/// A square sparse matrix in compressed-sparse-row form with `u32` column indices, its
/// values stored as `T`.
#[derive(Clone, Debug, Default)]
pub struct CsrMatrix<T = f64> {
    /// Row starts into `col`/`val` (length `n + 1`).
    pub row_ptr: Vec<u32>,
    /// Column index of each stored entry (sorted within a row).
    pub col: Vec<u32>,
    /// Value of each stored entry.
    pub val: Vec<T>,
}

impl<T: Stored> CsrMatrix<T> {
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
    pub fn row(&self, i: usize) -> (&[u32], &[T]) {
        let (a, b) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
        (&self.col[a..b], &self.val[a..b])
    }
    /// `f(i, (A x)_i, &mut y[i])` for every row `i`, parallel over rows: a product and
    /// what is done with it in one pass (sums in `f64` whatever the storage).
    pub fn spmv_with<Y: Send>(
        &self,
        x: &[T],
        y: &mut [Y],
        f: impl Fn(usize, f64, &mut Y) + Sync + Send,
    ) {
        y.par_chunks_mut(1024).enumerate().for_each(|(c, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                let i = c * 1024 + k;
                let (cols, vals) = self.row(i);
                f(i, row_dot(cols, vals, x), yi);
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
                    .map_or(0.0, |k| v[k].get())
            })
            .collect()
    }
    /// Value at `(i, j)`, 0 when not stored.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (c, v) = self.row(i);
        c.binary_search(&(j as u32)).map_or(0.0, |k| v[k].get())
    }
    /// Largest `|A_ij - A_ji|` over stored entries.
    pub fn asymmetry(&self) -> f64 {
        (0..self.n())
            .map(|i| {
                let (c, v) = self.row(i);
                c.iter()
                    .zip(v)
                    .map(|(&j, &a)| (a.get() - self.get(j as usize, i)).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }
    /// This matrix with its values rounded to `U`, into `out` (its memory reused).
    pub fn convert_into<U: Stored>(&self, out: &mut CsrMatrix<U>) {
        out.row_ptr.clone_from(&self.row_ptr);
        out.col.clone_from(&self.col);
        out.val.clear();
        out.val.extend(self.val.iter().map(|v| U::put(v.get())));
    }
}

impl CsrMatrix {
    /// A matrix from its rows, each a list of `(column, value)` sorted by column.
    pub fn from_rows(rows: impl IntoIterator<Item = Vec<(u32, f64)>>) -> CsrMatrix {
        let mut m = CsrMatrix {
            row_ptr: vec![0],
            ..Default::default()
        };
        for row in rows {
            for (c, v) in row {
                m.col.push(c);
                m.val.push(v);
            }
            m.row_ptr.push(m.col.len() as u32);
        }
        m
    }
    /// `y = A x`, parallel over rows.
    pub fn spmv(&self, x: &[f64], y: &mut [f64]) {
        self.spmv_split(x, y, 1)
    }
    /// `y = A x` in chunks of 1024 rows, handed to the pool in pieces of at least
    /// `min_chunks` chunks (`usize::MAX`: all on the calling thread); the same result either
    /// way.
    pub fn spmv_split(&self, x: &[f64], y: &mut [f64], min_chunks: usize) {
        y.par_chunks_mut(1024)
            .with_min_len(min_chunks)
            .enumerate()
            .for_each(|(c, ys)| {
                for (k, yi) in ys.iter_mut().enumerate() {
                    let (cols, vals) = self.row(c * 1024 + k);
                    *yi = row_dot(cols, vals, x);
                }
            });
    }
}

/// Transpose of an `n x ncols` CSR matrix (an `ncols x n` matrix, columns sorted).
pub fn transpose<T: Stored>(a: &CsrMatrix<T>, ncols: usize) -> CsrMatrix<T> {
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
    let mut val = vec![T::default(); a.nnz()];
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

/// Rows per piece of a matrix built in place ([`build_rows_into`]).
const BUILD_ROWS: usize = 1024;

/// Sizes an `n`-row matrix `out` in its own memory: its row offsets from each row's number
/// of entries, `len(scratch, i)` (computed in parallel, each piece of rows with a scratch
/// from `init`), and its columns and values zeroed to fit.
pub fn size_rows_into<S, T: Stored>(
    n: usize,
    out: &mut CsrMatrix<T>,
    init: impl Fn() -> S + Sync + Send,
    len: impl Fn(&mut S, usize) -> u32 + Sync + Send,
) {
    out.row_ptr.clear();
    out.row_ptr.resize(n + 1, 0);
    crate::parallel::for_each_mut_init(&mut out.row_ptr[1..], &init, |s, i, l| *l = len(s, i));
    for i in 0..n {
        out.row_ptr[i + 1] += out.row_ptr[i];
    }
    let nnz = out.row_ptr[n] as usize;
    // Every entry is written by the caller afterwards: the old ones are left as they are
    // and only new room is zeroed (not a sequential pass over every entry each time).
    out.col.resize(nnz, 0);
    out.val.resize(nnz, T::default());
}

/// Builds an `n`-row matrix into `out`, reusing its memory: `len(scratch, i)` gives row `i`'s
/// number of entries ([`size_rows_into`]), then `fill(scratch, i, cols, vals)` writes
/// exactly that many into the row's place, in parallel over pieces of [`BUILD_ROWS`] rows,
/// each with a scratch of its own from `init`. No row is built twice in memory (no per-row
/// or per-piece copies to join).
pub fn build_rows_into<S, T: Stored>(
    n: usize,
    out: &mut CsrMatrix<T>,
    init: impl Fn() -> S + Sync + Send,
    len: impl Fn(&mut S, usize) -> u32 + Sync + Send,
    fill: impl Fn(&mut S, usize, &mut [u32], &mut [T]) + Sync + Send,
) {
    size_rows_into(n, out, &init, len);
    // Each piece's entries, split off in order.
    let mut pieces = Vec::with_capacity(n.div_ceil(BUILD_ROWS));
    let (mut col, mut val) = (out.col.as_mut_slice(), out.val.as_mut_slice());
    for lo in (0..n).step_by(BUILD_ROWS) {
        let hi = (lo + BUILD_ROWS).min(n);
        let at = (out.row_ptr[hi] - out.row_ptr[lo]) as usize;
        let (c, c_rest) = col.split_at_mut(at);
        let (v, v_rest) = val.split_at_mut(at);
        pieces.push((lo, hi, c, v));
        (col, val) = (c_rest, v_rest);
    }
    let row_ptr = &out.row_ptr;
    pieces
        .into_par_iter()
        .for_each_init(&init, |s, (lo, hi, c, v)| {
            let base = row_ptr[lo] as usize;
            for i in lo..hi {
                let (a, b) = (row_ptr[i] as usize - base, row_ptr[i + 1] as usize - base);
                fill(s, i, &mut c[a..b], &mut v[a..b]);
            }
        });
}

/// Sparse product `A B` of CSR matrices, `B` with `ncols` columns; parallel over rows of
/// `A`, each row accumulated in a dense scratch row (Gustavson's algorithm), counted first
/// and then written in its place ([`build_rows_into`]).
pub fn spgemm(a: &CsrMatrix, b: &CsrMatrix, ncols: usize) -> CsrMatrix {
    // Scratch: the row that last touched each column, and each column's sum.
    let init = || (vec![u32::MAX; ncols], vec![0.0f64; ncols]);
    let len = |(mark, _): &mut (Vec<u32>, Vec<f64>), i: usize| {
        let mut count = 0;
        for &k in a.row(i).0 {
            for &j in b.row(k as usize).0 {
                if mark[j as usize] != i as u32 {
                    mark[j as usize] = i as u32;
                    count += 1;
                }
            }
        }
        count
    };
    let fill =
        |(mark, acc): &mut (Vec<u32>, Vec<f64>), i: usize, cols: &mut [u32], vals: &mut [f64]| {
            // (A scratch of this pass's own: the counting pass's marks are not seen here.)
            let tag = i as u32;
            let mut count = 0;
            let (ca, va) = a.row(i);
            for (&k, &x) in ca.iter().zip(va) {
                let (cb, vb) = b.row(k as usize);
                for (&j, &y) in cb.iter().zip(vb) {
                    let j = j as usize;
                    if mark[j] != tag {
                        mark[j] = tag;
                        acc[j] = 0.0;
                        cols[count] = j as u32;
                        count += 1;
                    }
                    acc[j] += x * y;
                }
            }
            cols.sort_unstable();
            for (v, &j) in vals.iter_mut().zip(cols.iter()) {
                *v = acc[j as usize];
            }
        };
    let mut out = CsrMatrix::default();
    build_rows_into(a.n(), &mut out, init, len, fill);
    out
}

/// `sum_k vals[k] x[cols[k]]` with four partial sums, so a row's products do not wait on
/// each other's additions (a fixed order: the same on any number of threads), in `f64`
/// whatever the storage.
#[inline]
pub fn row_dot<T: Stored>(cols: &[u32], vals: &[T], x: &[T]) -> f64 {
    let mut acc = [0.0; 4];
    let (cs, vs) = (cols.chunks_exact(4), vals.chunks_exact(4));
    let (cr, vr) = (cs.remainder(), vs.remainder());
    for (c, v) in cs.zip(vs) {
        for k in 0..4 {
            acc[k] += T::mul(v[k], x[c[k] as usize]);
        }
    }
    for (c, v) in cr.iter().zip(vr) {
        acc[0] += T::mul(*v, x[*c as usize]);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Dot product in a fixed summation order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    dot_split(a, b, 1)
}

/// [`dot`] with its chunks handed to the pool in pieces of at least `min_chunks` chunks
/// (`usize::MAX`: all on the calling thread); the same result either way.
pub fn dot_split(a: &[f64], b: &[f64], min_chunks: usize) -> f64 {
    let m = a.len().div_ceil(CHUNK);
    if min_chunks >= m {
        // One piece: the pool would run it here anyway.
        return a.chunks(CHUNK).zip(b.chunks(CHUNK)).map(chunk_dot).sum();
    }
    summed_parts(m, |parts| {
        parts
            .par_iter_mut()
            .zip(a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)))
            .with_min_len(min_chunks)
            .for_each(|(p, c)| *p = chunk_dot(c))
    })
}

/// `sum_k a_k b_k` of one chunk, in sequence: the order of every reduction here.
#[inline]
pub fn chunk_dot((a, b): (&[f64], &[f64])) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>()
}

/// `f(c, y_c)` for each chunk `c` of [`CHUNK`] entries of `y` (which `f` writes), returning
/// the sum of what `f` returns in chunk order: a pass that writes a vector and reduces over
/// it while the chunk is in cache, in [`dot_split`]'s order and with its pieces.
pub fn write_and_sum(
    y: &mut [f64],
    min_chunks: usize,
    f: impl Fn(usize, &mut [f64]) -> f64 + Sync + Send,
) -> f64 {
    let m = y.len().div_ceil(CHUNK);
    if min_chunks >= m {
        return y
            .chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, ys)| f(c, ys))
            .sum();
    }
    summed_parts(m, |parts| {
        parts
            .par_iter_mut()
            .zip(y.par_chunks_mut(CHUNK))
            .enumerate()
            .with_min_len(min_chunks)
            .for_each(|(c, (p, ys))| *p = f(c, ys))
    })
}

/// `y = A x` and `x . y` in one pass over the rows: the result of
/// [`CsrMatrix::spmv_split`] followed by [`dot_split`], bit for bit.
pub fn spmv_dot(a: &CsrMatrix, x: &[f64], y: &mut [f64], min_chunks: usize) -> f64 {
    write_and_sum(y, min_chunks, |c, ys| {
        let i0 = c * CHUNK;
        for (k, yi) in ys.iter_mut().enumerate() {
            let (cols, vals) = a.row(i0 + k);
            *yi = row_dot(cols, vals, x);
        }
        chunk_dot((&x[i0..i0 + ys.len()], ys))
    })
}

/// The sum, in order, of `m` partial sums that `fill` writes; they are kept on the stack (no
/// allocation inside CG) up to 64 parts.
pub fn summed_parts(m: usize, fill: impl FnOnce(&mut [f64])) -> f64 {
    const ON_STACK: usize = 64;
    let (mut stack, mut heap) = ([0.0; ON_STACK], Vec::new());
    let parts: &mut [f64] = if m <= ON_STACK {
        &mut stack[..m]
    } else {
        heap.resize(m, 0.0);
        &mut heap
    };
    fill(parts);
    parts.iter().sum()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `spmv` with four partial sums per row agrees with the plain sum to round-off, on rows
    /// of every length 0 to 9 (each remainder of the four-way split).
    #[test]
    fn spmv_agrees_with_the_plain_row_sum() {
        let n = 10;
        let (mut row_ptr, mut col, mut val) = (vec![0u32], Vec::new(), Vec::new());
        for i in 0..n {
            for k in 0..i {
                col.push(((k * 7 + i) % n) as u32);
                val.push(1.0 / (1.0 + (i * n + k) as f64) - 0.03 * k as f64);
            }
            row_ptr.push(col.len() as u32);
        }
        let a = CsrMatrix { row_ptr, col, val };
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut y = vec![f64::NAN; n];
        a.spmv(&x, &mut y);
        for i in 0..n {
            let (c, v) = a.row(i);
            let want: f64 = c.iter().zip(v).map(|(&j, &w)| w * x[j as usize]).sum();
            assert!(
                (y[i] - want).abs() <= 1e-15 * (1.0 + want.abs()),
                "row {i}: {} vs {want}",
                y[i]
            );
        }
        assert_eq!(y[0], 0.0);
    }

    /// `spgemm` built in place against the dense product, on a rectangular `B` and with rows
    /// of `A` of every length 0 to 2999 (so the pieces of `BUILD_ROWS` rows split unevenly).
    #[test]
    fn spgemm_agrees_with_the_dense_product() {
        let (n, m) = (3000, 7);
        let mut a = CsrMatrix {
            row_ptr: vec![0],
            ..Default::default()
        };
        for i in 0..n {
            let len = (i * 13) % 5;
            let mut cols: Vec<u32> = (0..len).map(|k| ((i + 3 * k) % n) as u32).collect();
            cols.sort_unstable();
            cols.dedup();
            for &j in &cols {
                a.col.push(j);
                a.val.push(1.0 + (i as f64 - j as f64) * 0.01);
            }
            a.row_ptr.push(a.col.len() as u32);
        }
        let b = CsrMatrix::from_rows((0..n).map(|k| {
            (0..m as u32)
                .filter(|j| !(k + *j as usize).is_multiple_of(3))
                .map(|j| (j, 0.5 + (k % 11) as f64 - j as f64))
                .collect::<Vec<_>>()
        }));
        let c = spgemm(&a, &b, m);
        assert_eq!(c.n(), n);
        for i in 0..n {
            let (ci, vi) = c.row(i);
            assert!(ci.windows(2).all(|w| w[0] < w[1]), "row {i} unsorted");
            let mut dense = vec![0.0; m];
            let mut touched = vec![false; m];
            let (ca, va) = a.row(i);
            for (&k, &x) in ca.iter().zip(va) {
                let (cb, vb) = b.row(k as usize);
                for (&j, &y) in cb.iter().zip(vb) {
                    dense[j as usize] += x * y;
                    touched[j as usize] = true;
                }
            }
            let want: Vec<u32> = (0..m as u32).filter(|&j| touched[j as usize]).collect();
            assert_eq!(ci, want.as_slice(), "row {i}");
            for (&j, &v) in ci.iter().zip(vi) {
                assert!((v - dense[j as usize]).abs() < 1e-12, "row {i} col {j}");
            }
        }
    }

    /// The MPS Laplacian (weights `re/r - 1`, re = 3.1 l0) on an `m x m` lattice, the
    /// missing neighbourhood beyond its edges on the diagonal (Dirichlet air).
    pub(crate) fn mps_lattice(m: usize) -> CsrMatrix {
        let re = 3.1f64;
        let full: f64 = (-3i64..=3)
            .flat_map(|dy| (-3i64..=3).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| ((dx * dx + dy * dy) as f64).sqrt())
            .filter(|&r| r > 0.0 && r < re)
            .map(|r| re / r - 1.0)
            .sum();
        CsrMatrix::from_rows((0..m * m).map(|i| {
            let (x, y) = ((i % m) as i64, (i / m) as i64);
            let mut row = Vec::new();
            for dy in -3i64..=3 {
                for dx in -3i64..=3 {
                    let r = ((dx * dx + dy * dy) as f64).sqrt();
                    let (a, b) = (x + dx, y + dy);
                    let inside = (0..m as i64).contains(&a) && (0..m as i64).contains(&b);
                    if r == 0.0 {
                        row.push((i as u32, full));
                    } else if r < re && inside {
                        row.push(((b * m as i64 + a) as u32, -(re / r - 1.0)));
                    }
                }
            }
            row
        }))
    }
}
