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
    /// particle count (each cut at the first cell boundary past `k N / pieces`). `None` for
    /// no particle, no piece, or a non-positive or non-finite cell size.
    pub fn along_morton<const D: usize>(
        pos: &[Vector<D>],
        cell: f64,
        pieces: usize,
    ) -> Option<Partition> {
        if pos.is_empty() || pieces == 0 || !(cell > 0.0) || !cell.is_finite() {
            return None;
        }
        let mut lo = [f64::INFINITY; D];
        for x in pos {
            for a in 0..D {
                lo[a] = lo[a].min(x[a]);
            }
        }
        let limit = ((1u64 << bits(D)) - 1) as f64;
        let key = |x: &Vector<D>| {
            let mut c = [0u64; D];
            for a in 0..D {
                c[a] = ((x[a] - lo[a]) / cell).floor().clamp(0.0, limit) as u64;
            }
            morton(c)
        };
        let mut order: Vec<(u64, usize)> =
            pos.iter().enumerate().map(|(i, x)| (key(x), i)).collect();
        order.sort_unstable();
        let n = pos.len();
        let mut owner = vec![0u32; n];
        let mut sizes = vec![0usize; pieces];
        let mut piece = 0usize;
        for (k, &(cell_key, i)) in order.iter().enumerate() {
            // Move to the next piece at a cell boundary once this one has its share.
            let boundary = k > 0 && order[k - 1].0 != cell_key;
            while boundary && piece + 1 < pieces && k * pieces >= (piece + 1) * n {
                piece += 1;
            }
            owner[i] = piece as u32;
            sizes[piece] += 1;
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
