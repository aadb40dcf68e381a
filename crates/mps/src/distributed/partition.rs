//! Domain decomposition along a space-filling curve (after Guo, Rogers, Lind & Stansby 2018,
//! who partition ISPH over cells ordered along a curve and reorder the particles so that
//! matrix rows stay local): cells of side `cell` (m, at least the interaction radius) are
//! ordered by their Morton (Z-order) key, and the ordered cells are cut into `pieces`
//! contiguous runs of about equal particle count, never inside a cell. A piece's halo is
//! the particles of other pieces within the interaction radius of one of its own.

use crate::particles::{NeighborList, Vector};

/// Bits per axis of the Morton key (2D: 2 x 32, 3D: 3 x 21 bits of a `u64`).
const fn bits(d: usize) -> u32 {
    if d == 2 {
        32
    } else {
        21
    }
}

/// Morton key of integer cell coordinates `c` (each at least 0): their bits interleaved,
/// axis 0 lowest.
pub fn morton<const D: usize>(c: [u64; D]) -> u64 {
    let mut key = 0u64;
    for b in 0..bits(D) {
        for (a, &x) in c.iter().enumerate() {
            key |= ((x >> b) & 1) << (b as usize * D + a);
        }
    }
    key
}

/// The cells of a decomposition: side `cell` (m) from the lower corner `lo` (m) of every
/// particle (the same on every process: a global minimum).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MortonGrid<const D: usize> {
    /// Lower corner (m).
    pub lo: [f64; D],
    /// Cell side (m), at least the interaction radius.
    pub cell: f64,
}

impl<const D: usize> MortonGrid<D> {
    /// The grid over `pos` (its own lower corner); `None` for no particle or a non-positive
    /// or non-finite cell size.
    pub fn over(pos: &[Vector<D>], cell: f64) -> Option<Self> {
        if pos.is_empty() || !(cell > 0.0) || !cell.is_finite() {
            return None;
        }
        let mut lo = [f64::INFINITY; D];
        for x in pos {
            for a in 0..D {
                lo[a] = lo[a].min(x[a]);
            }
        }
        Some(MortonGrid { lo, cell })
    }

    /// Integer cell coordinates of `x` (clamped to the key's range).
    fn cell_of(&self, x: &Vector<D>) -> [i64; D] {
        let limit = ((1u64 << bits(D)) - 1) as f64;
        let mut c = [0i64; D];
        for a in 0..D {
            c[a] = ((x[a] - self.lo[a]) / self.cell).floor().clamp(0.0, limit) as i64;
        }
        c
    }

    /// Morton key of the cell holding `x`.
    pub fn key(&self, x: &Vector<D>) -> u64 {
        morton(self.cell_of(x).map(|c| c as u64))
    }

    /// Keys of the cell holding `x` and of its neighbour cells (3^D, fewer at the grid's
    /// lower edges): every particle within one cell side of `x` lies in one of them.
    pub fn neighbour_keys(&self, x: &Vector<D>) -> Vec<u64> {
        let c = self.cell_of(x);
        let mut out = Vec::with_capacity(3usize.pow(D as u32));
        for code in 0..3usize.pow(D as u32) {
            let (mut rest, mut n, mut inside) = (code, [0u64; D], true);
            for a in 0..D {
                let v = c[a] + (rest % 3) as i64 - 1;
                rest /= 3;
                inside &= v >= 0;
                n[a] = v.max(0) as u64;
            }
            if inside {
                out.push(morton(n));
            }
        }
        out
    }
}

/// Where the Morton curve is cut into `pieces`: piece `p` owns the keys from `cuts[p]` up
/// to (not including) `cuts[p + 1]`, `cuts[pieces] = u64::MAX`. From every particle's key,
/// sorted: each cut at the first cell boundary past `k N / pieces` (a cell is never split).
pub fn splitters(sorted_keys: &[u64], pieces: usize) -> Vec<u64> {
    let n = sorted_keys.len();
    let mut cuts = vec![0u64];
    let mut piece = 0usize;
    for (k, &key) in sorted_keys.iter().enumerate() {
        let boundary = k > 0 && sorted_keys[k - 1] != key;
        while boundary && piece + 1 < pieces && k * pieces >= (piece + 1) * n {
            cuts.push(key);
            piece += 1;
        }
    }
    while cuts.len() < pieces {
        cuts.push(u64::MAX);
    }
    cuts.push(u64::MAX);
    cuts
}

/// The piece that owns `key` under `cuts` (from [`splitters`]).
pub fn owner_of(cuts: &[u64], key: u64) -> u32 {
    (cuts[1..cuts.len() - 1].partition_point(|&c| c <= key)) as u32
}

/// The pieces of a decomposition: the owning piece of every particle and each piece's size.
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// Piece of every particle.
    pub owner: Vec<u32>,
    /// Particles per piece.
    pub sizes: Vec<usize>,
}

impl Partition {
    /// Cells of side `cell` (m) along the Morton curve, cut into `pieces` runs of about equal
    /// particle count ([`splitters`]). `None` for no particle, no piece, or a non-positive or
    /// non-finite cell size.
    pub fn along_morton<const D: usize>(
        pos: &[Vector<D>],
        cell: f64,
        pieces: usize,
    ) -> Option<Partition> {
        let grid = MortonGrid::over(pos, cell)?;
        if pieces == 0 {
            return None;
        }
        let keys: Vec<u64> = pos.iter().map(|x| grid.key(x)).collect();
        let mut sorted = keys.clone();
        sorted.sort_unstable();
        let cuts = splitters(&sorted, pieces);
        let owner: Vec<u32> = keys.iter().map(|&k| owner_of(&cuts, k)).collect();
        let mut sizes = vec![0usize; pieces];
        for &o in &owner {
            sizes[o as usize] += 1;
        }
        Some(Partition { owner, sizes })
    }

    /// Largest piece over the mean piece (1 for a perfect balance); rebalance above 1.1.
    pub fn imbalance(&self) -> f64 {
        let total: usize = self.sizes.iter().sum();
        let mean = total as f64 / self.sizes.len().max(1) as f64;
        let max = self.sizes.iter().copied().max().unwrap_or(0) as f64;
        if mean > 0.0 {
            max / mean
        } else {
            1.0
        }
    }

    /// The halo of `piece`: particles of other pieces within `radius` (m) of one of its own,
    /// in increasing index order (`nl` must list every pair within `radius`).
    pub fn halo<const D: usize>(
        &self,
        piece: u32,
        pos: &[Vector<D>],
        nl: &NeighborList,
        radius: f64,
    ) -> Vec<usize> {
        let mut mark = vec![false; pos.len()];
        let r2 = radius * radius;
        for i in (0..pos.len()).filter(|&i| self.owner[i] == piece) {
            for &j in nl.of(i) {
                let j = j as usize;
                if self.owner[j] != piece && (pos[j] - pos[i]).norm2() < r2 {
                    mark[j] = true;
                }
            }
        }
        (0..pos.len()).filter(|&j| mark[j]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::neighbors::build_neighbor_list;

    /// A dam-break-like block of particles: a column and a thin layer along the floor.
    fn block() -> Vec<Vector<2>> {
        let l0 = 0.01;
        let mut p = Vec::new();
        for a in 0..40 {
            for b in 0..80 {
                p.push(Vector([a as f64 * l0, b as f64 * l0]));
            }
        }
        for a in 40..150 {
            for b in 0..6 {
                p.push(Vector([a as f64 * l0, b as f64 * l0]));
            }
        }
        p
    }

    /// Every point within one cell side of `x` lies in one of `x`'s neighbour cells.
    #[test]
    fn neighbour_cells_hold_every_close_point() {
        let pos = block();
        let grid = MortonGrid::over(&pos, 0.031).unwrap();
        for (k, x) in pos.iter().enumerate().step_by(7) {
            let near = grid.neighbour_keys(x);
            assert!(near.len() <= 9 && near.contains(&grid.key(x)));
            for y in pos.iter().skip(k % 5).step_by(11) {
                if (*y - *x).norm() < 0.031 {
                    assert!(near.contains(&grid.key(y)), "{x:?} {y:?}");
                }
            }
        }
    }

    #[test]
    fn morton_interleaves_bits() {
        assert_eq!(morton([0b11u64, 0b00]), 0b0101);
        assert_eq!(morton([0b00u64, 0b11]), 0b1010);
        assert_eq!(morton([1u64, 1, 1]), 0b111);
        assert_eq!(morton([2u64, 0, 0]), 0b1000);
    }

    /// Every particle in exactly one piece; pieces balanced within a cell's worth; pieces
    /// are compact (most of a piece's neighbours are its own).
    #[test]
    fn pieces_are_balanced_and_compact() {
        let pos = block();
        let (l0, re) = (0.01, 0.031);
        for pieces in [1, 2, 4, 7] {
            let p = Partition::along_morton(&pos, re, pieces).unwrap();
            assert_eq!(p.sizes.iter().sum::<usize>(), pos.len());
            assert_eq!(p.sizes.len(), pieces);
            for k in 0..pieces {
                let counted = p.owner.iter().filter(|&&o| o == k as u32).count();
                assert_eq!(counted, p.sizes[k]);
            }
            // A cell holds at most 16 particles at this spacing.
            let mean = pos.len() as f64 / pieces as f64;
            assert!(
                p.imbalance() <= (mean + 16.0) / mean + 1e-12,
                "{pieces}: {:?}",
                p.sizes
            );
            let nl = build_neighbor_list(&pos, re);
            if pieces > 1 {
                let halo: usize = (0..pieces as u32)
                    .map(|k| p.halo(k, &pos, &nl, re).len())
                    .sum();
                // Against pieces dealt out by index (every particle's neighbours elsewhere),
                // the curve's halo is a thin skin around compact pieces.
                let dealt = Partition {
                    owner: (0..pos.len()).map(|i| (i % pieces) as u32).collect(),
                    sizes: vec![0; pieces],
                };
                let worst: usize = (0..pieces as u32)
                    .map(|k| dealt.halo(k, &pos, &nl, re).len())
                    .sum();
                assert!(halo * 4 < worst, "{pieces}: halo {halo} against {worst}");
            }
            assert!(l0 > 0.0);
        }
        assert!(Partition::along_morton(&pos, 0.0, 2).is_none());
        assert!(Partition::along_morton::<2>(&[], 0.03, 2).is_none());
        assert!(Partition::along_morton(&pos, 0.03, 0).is_none());
    }

    /// The halo is exactly the set of other pieces' particles within the radius of one of
    /// the piece's own, by brute force.
    #[test]
    fn halo_matches_brute_force() {
        let pos = block();
        let re = 0.021;
        let p = Partition::along_morton(&pos, re, 3).unwrap();
        let nl = build_neighbor_list(&pos, re);
        for piece in 0..3u32 {
            let halo = p.halo(piece, &pos, &nl, re);
            let brute: Vec<usize> = (0..pos.len())
                .filter(|&j| {
                    p.owner[j] != piece
                        && (0..pos.len())
                            .any(|i| p.owner[i] == piece && (pos[j] - pos[i]).norm2() < re * re)
                })
                .collect();
            assert_eq!(halo, brute, "piece {piece}");
            assert!(!halo.is_empty());
        }
    }
}
