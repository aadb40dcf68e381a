//! The one neighbour-pair loop every pair formula runs over (as PySPH's `Equation.loop`
//! with its precomputed `XIJ`, `RIJ`, `WIJ`): for particle `i` and a kernel radius `re`, each
//! neighbour `j` with `0 < r_ij < re` and its geometry.
//!
//! Coincident particles (`r_ij = 0`) carry no weight (`w(0) = 0`) and are left out.

use super::kernel::weight;
use crate::particles::{NeighborList, Vector, View};

/// One neighbour `j` of particle `i`, with the pair geometry precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair<const D: usize> {
    /// Index of the neighbour.
    pub j: usize,
    /// `r_ij = x_j - x_i` (m).
    pub xij: Vector<D>,
    /// `|r_ij|^2` (m^2).
    pub r2: f64,
    /// `|r_ij|` (m).
    pub r: f64,
    /// `w(|r_ij|)` at the loop's radius (dimensionless, positive).
    pub w: f64,
}

/// The neighbours of `i` within `re` (m), from positions `pos` and neighbour list `nl`.
#[inline]
pub fn pairs<'a, const D: usize>(
    pos: &'a [Vector<D>],
    nl: &'a NeighborList,
    i: usize,
    re: f64,
) -> impl Iterator<Item = Pair<D>> + 'a {
    let nl = nl.for_radius(re);
    let xi = pos[i];
    nl.of(i)
        .iter()
        .filter_map(move |&j| pair_with(pos, xi, j as usize, re))
}

/// Listed neighbour `j` as a [`Pair`] of the particle at `xi` (m) if `0 < r_ij < re` (m).
/// The pair is symmetric bit for bit: `j`'s pair with `i` has the same `r`, `r2` and `w`.
#[inline]
pub fn pair_with<const D: usize>(
    pos: &[Vector<D>],
    xi: Vector<D>,
    j: usize,
    re: f64,
) -> Option<Pair<D>> {
    // Far neighbours (the list's skin, a smaller radius) are rejected before the square root;
    // the margin leaves the exact test `r < re` to decide at the rim.
    let far = re * re * (1.0 + 1e-9);
    let xij = pos[j] - xi;
    let r2 = xij.norm2();
    if r2 > far {
        return None;
    }
    let r = r2.sqrt();
    (r > 0.0 && r < re).then(|| Pair {
        j,
        xij,
        r2,
        r,
        w: weight(r, re),
    })
}

/// How many of the neighbours [`pairs`] gives for `i` within `re` (m) `keep` accepts,
/// counted without their geometry: a square root only where `r^2` lies within rounding of
/// `re^2` (so the count is that of [`pairs`] exactly).
#[inline]
pub fn count_pairs<const D: usize>(
    pos: &[Vector<D>],
    nl: &NeighborList,
    i: usize,
    re: f64,
    keep: impl Fn(usize) -> bool,
) -> usize {
    let nl = nl.for_radius(re);
    let xi = pos[i];
    // Without a branch on the tests that pass and fail at random (only the rare rim case
    // branches to its square root).
    let mut count = 0;
    for &j in nl.of(i) {
        let j = j as usize;
        count += (is_within((pos[j] - xi).norm2(), re) & keep(j)) as usize;
    }
    count
}

/// Whether a neighbour at squared distance `r2` (m^2) is a pair within `re` (m), `0 < r <
/// re`, exactly as [`pair_with`] decides it: a square root only where `r2` lies within
/// rounding of `re^2`.
#[inline]
pub fn is_within(r2: f64, re: f64) -> bool {
    let (far, near) = (re * re * (1.0 + 1e-9), re * re * (1.0 - 1e-9));
    let rim = (r2 >= near) & (r2 <= far);
    ((r2 > 0.0) & (r2 < near)) | (rim && r2.sqrt() < re)
}

impl<const D: usize> View<'_, D> {
    /// The neighbours of `i` within `re` (m) at the view's positions.
    #[inline]
    pub fn pairs(&self, i: usize, re: f64) -> impl Iterator<Item = Pair<D>> + '_ {
        pairs(self.pos, self.neighbors, i, re)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::neighbors::build_neighbor_list;

    #[test]
    fn pairs_are_the_neighbours_strictly_inside_the_radius() {
        let pos = vec![
            Vector([0.0, 0.0]),
            Vector([0.5, 0.0]),
            Vector([0.0, 0.0]),
            Vector([1.5, 0.0]),
        ];
        let nl = build_neighbor_list(&pos, 2.0);
        let got: Vec<Pair<2>> = pairs(&pos, &nl, 0, 1.0).collect();
        // The coincident particle 2 and the distant particle 3 are left out.
        assert_eq!(got.len(), 1);
        let p = got[0];
        assert_eq!((p.j, p.r, p.r2), (1, 0.5, 0.25));
        assert_eq!(p.xij, Vector([0.5, 0.0]));
        assert_eq!(p.w, weight(0.5, 1.0));
    }

    /// The count agrees with the pairs on points at, just inside and just outside the
    /// radius (the rounding band where the square root decides), coincident and far ones.
    #[test]
    fn count_pairs_counts_what_pairs_gives() {
        let re = 0.0155;
        let mut pos = vec![Vector([0.0, 0.0]), Vector([0.0, 0.0])];
        for k in -40..=40 {
            let r = re * (1.0 + k as f64 * 1e-12);
            let t = k as f64 * 0.07;
            pos.push(Vector([r * t.cos(), r * t.sin()]));
            pos.push(Vector([0.3 * r * t.cos(), 0.9 * r * t.sin()]));
        }
        let nl = build_neighbor_list(&pos, 1.2 * re);
        for i in [0, 5, 40] {
            let want = pairs(&pos, &nl, i, re).filter(|p| p.j % 3 != 0).count();
            assert_eq!(count_pairs(&pos, &nl, i, re, |j| j % 3 != 0), want);
        }
        let at_rim = pairs(&pos, &nl, 0, re).filter(|p| p.r > 0.99 * re).count();
        assert!(at_rim > 10 && at_rim < 70, "{at_rim}");
    }
}
