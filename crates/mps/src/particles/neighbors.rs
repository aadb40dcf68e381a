//! Neighbour search with a uniform cell list, and particle reordering along the cells.
//!
//! Each particle's neighbour list is stored in one flat array (CSR layout). The list is built
//! with a cut-off slightly larger than the largest kernel radius (a "skin"), so it stays valid
//! while particles move less than half the skin; every operator filters by its own radius.

use super::vector::Vector;
use crate::parallel::{self, Shared};

/// Neighbour lists of all particles: particle `i`'s neighbours are `indices[spans[i][0]..
/// spans[i][1]]`. The lists are built by chunks of particles in parallel, each chunk into its
/// own region of `indices`, sized from the last build's lists with a little room, so a build
/// writes every list in place: no list is copied and, once warm, nothing is allocated
/// (docs/decisions.md, "A step without allocations").
#[derive(Clone, Debug, Default)]
pub struct NeighborList {
    /// Each particle's range in `indices`.
    spans: Vec<[u32; 2]>,
    /// Neighbour indices, grouped by particle and by chunk (regions may leave room between).
    indices: Vec<u32>,
    /// Directed pairs held.
    pairs: usize,
    /// Start of each chunk's region in `indices`, and the end (a build's scratch, kept).
    regions: Vec<usize>,
    /// Cut-off radius used to build the list (m).
    pub cutoff: f64,
    /// The same lists cut to a smaller radius at the positions of the stages now running
    /// (each particle's neighbours within `near.cutoff`, in the same order), or none. The
    /// step sets them at `r*` for its stages and clears them before the particles move.
    pub near: Option<Box<NeighborList>>,
}

impl NeighborList {
    /// The neighbours of particle `i`.
    #[inline]
    pub fn of(&self, i: usize) -> &[u32] {
        let [a, b] = self.spans[i];
        &self.indices[a as usize..b as usize]
    }
    /// Total number of (directed) neighbour pairs.
    pub fn pairs(&self) -> usize {
        self.pairs
    }

    /// The number of particles the lists are for.
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// True when the lists are for no particle.
    pub fn is_empty(&self) -> bool {
        self.spans.is_empty()
    }

    /// The lists to scan for the pairs within `re` (m): the near lists when they reach that
    /// far, these otherwise.
    #[inline]
    pub fn for_radius(&self, re: f64) -> &NeighborList {
        match &self.near {
            Some(near) if re <= near.cutoff => near,
            _ => self,
        }
    }

    /// These lists cut to `radius` (m) at positions `pos`: every neighbour `j` of `i` with
    /// `|x_j - x_i|^2 <= radius^2 (1 + 1e-9)` (the margin of the pair loop's own test, so a
    /// pair loop at any radius up to `radius` finds the same pairs in the same order).
    pub fn cut_to<const D: usize>(&self, pos: &[Vector<D>], radius: f64) -> NeighborList {
        let mut out = NeighborList::default();
        self.cut_into(pos, radius, &mut out);
        out
    }

    /// [`NeighborList::cut_to`] into `out`, reusing its memory.
    pub fn cut_into<const D: usize>(&self, pos: &[Vector<D>], radius: f64, out: &mut NeighborList) {
        let far = radius * radius * (1.0 + 1e-9);
        // The share of the full lists expected within `radius` (by volume), with a margin.
        let share = 1.2 * (radius / self.cutoff).min(1.0).powi(D as i32);
        let full = |a: usize, b: usize| self.chunk_entries(a, b);
        out.fill_by_chunks(
            self.len(),
            |a, b| (share * full(a, b) as f64) as usize + 16,
            |i, sink| {
                let xi = pos[i];
                for &j in self.of(i) {
                    sink.push_if(j, (pos[j as usize] - xi).norm2() <= far);
                }
            },
        );
        out.cutoff = radius;
        out.near = None;
    }

    /// Entries the lists of particles `a..b` (one chunk) hold: they lie together in its region.
    fn chunk_entries(&self, a: usize, b: usize) -> usize {
        if a >= b {
            return 0;
        }
        (self.spans[b - 1][1] - self.spans[a][0]) as usize
    }

    /// Builds the lists of `n` particles by chunks of [`CHUNK`] in parallel: `fill(i, sink)`
    /// pushes particle `i`'s neighbours. Each chunk writes into its region, sized from the
    /// last build's lists of that chunk (with room for 3 % more), or `estimate(a, b)` entries
    /// for particles `a..b` on a first build; a chunk that outgrows its region is built again
    /// in a region of its counted size after the others. The lists do not depend on the
    /// regions or the number of threads.
    fn fill_by_chunks(
        &mut self,
        n: usize,
        estimate: impl Fn(usize, usize) -> usize + Sync,
        fill: impl Fn(usize, &mut ChunkSink) + Sync,
    ) {
        let chunks = n.div_ceil(CHUNK);
        let again = self.spans.len() == n;
        let mut regions = std::mem::take(&mut self.regions);
        let sizes = |c: usize| {
            let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(n));
            if again {
                let last = self.chunk_entries(a, b);
                last + last / 32 + 16
            } else {
                estimate(a, b)
            }
        };
        parallel::map_into(&mut regions, chunks, sizes);
        let mut total = 0;
        for r in regions.iter_mut() {
            (*r, total) = (total, total + *r);
        }
        regions.push(total);
        self.regions = regions;
        self.spans.resize(n, [0, 0]);
        self.room_for(total);
        fill_regions(
            0,
            &self.regions,
            &mut self.indices[..total],
            &mut self.spans,
            &fill,
        );
        // Chunks that outgrew their regions: again, in regions of their counted size.
        self.pairs = 0;
        let mut end = total;
        for c in 0..chunks {
            let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(n));
            let (start, room) = (self.regions[c], self.regions[c + 1] - self.regions[c]);
            let need = self.spans[b - 1][1] as usize - start;
            self.pairs += need;
            if need > room {
                // After the regions (and the chunks built again before it).
                let at = end;
                end = at + need;
                self.room_for(end);
                fill_regions(
                    c,
                    &[at, at + need],
                    &mut self.indices[at..at + need],
                    &mut self.spans[a..b],
                    &fill,
                );
            }
        }
        // A first build's estimate may leave far more room than the lists need: give it
        // back.
        let want = end.max(total + total / 8);
        if self.indices.len() > 2 * want.max(4096) {
            self.indices.truncate(want);
            self.indices.shrink_to(want);
        }
    }

    /// Makes `indices` at least `len` long, with room to grow by a sixteenth before it must
    /// move again.
    fn room_for(&mut self, len: usize) {
        if self.indices.len() < len {
            let cap = len + len / 16;
            self.indices
                .reserve_exact(cap.saturating_sub(self.indices.len()));
            self.indices.resize(len, 0);
        }
    }
}

/// Where a chunk's lists go while they are built: its region of the index array, counted
/// beyond its end (what does not fit is not written; the chunk is then built again).
pub struct ChunkSink<'a> {
    region: &'a mut [u32],
    len: usize,
}

impl ChunkSink<'_> {
    /// Appends neighbour `j` to the list being built.
    #[inline]
    pub fn push(&mut self, j: u32) {
        if let Some(slot) = self.region.get_mut(self.len) {
            *slot = j;
        }
        self.len += 1;
    }

    /// Appends neighbour `j` if `keep`, without a branch on `keep` (a cut whose tests fail
    /// and pass at random): the slot after the list is written either way and counts only
    /// when kept.
    #[inline]
    pub fn push_if(&mut self, j: u32, keep: bool) {
        if let Some(slot) = self.region.get_mut(self.len) {
            *slot = j;
        }
        self.len += keep as usize;
    }
}

/// Runs `fill` over the chunks `first..` whose regions start at `starts[..k]` (absolute,
/// `starts[k]` the end; `indices` the slice from `starts[0]` to it, `spans` their particles),
/// in parallel over the chunks.
fn fill_regions(
    first: usize,
    starts: &[usize],
    indices: &mut [u32],
    spans: &mut [[u32; 2]],
    fill: &(impl Fn(usize, &mut ChunkSink) + Sync),
) {
    let (shared_indices, shared_spans) = (Shared::new(indices), Shared::new(spans));
    let n = shared_spans.len();
    parallel::for_ranges_by(starts.len() - 1, 1, |chunks| {
        for c in chunks {
            let (lo, hi) = (starts[c] - starts[0], starts[c + 1] - starts[0]);
            let rows = (c * CHUNK).min(n)..((c + 1) * CHUNK).min(n);
            let a = (first + c) * CHUNK;
            // SAFETY: the chunks' regions and spans are disjoint.
            let (region, spans) = unsafe { (shared_indices.part(lo..hi), shared_spans.part(rows)) };
            let mut sink = ChunkSink { region, len: 0 };
            for (k, span) in spans.iter_mut().enumerate() {
                let start = sink.len;
                fill(a + k, &mut sink);
                *span = [(starts[c] + start) as u32, (starts[c] + sink.len) as u32];
            }
        }
    });
}

/// Particles per parallel work unit of the list builders (docs/decisions.md, "Parallel chunk
/// sizes").
const CHUNK: usize = 512;

/// A uniform grid of cells of side `cell` covering the particles' bounding box.
#[derive(Clone, Debug)]
pub struct CellGrid<const D: usize> {
    origin: Vector<D>,
    cell: f64,
    dims: [usize; D],
    /// `start[c]..start[c+1]` indexes `sorted` for cell `c`.
    start: Vec<u32>,
    /// Particle indices sorted by cell.
    sorted: Vec<u32>,
    /// The points in that order (m), so a search streams through memory.
    sorted_points: Vec<Vector<D>>,
    /// Each point's cell (a build's scratch, kept).
    keys: Vec<u32>,
    /// Each cell's next free slot while binning (a build's scratch, kept).
    next: Vec<u32>,
    /// Per cell, whether it holds a marked point (`mark_cells_holding`).
    holding: Vec<bool>,
}

impl<const D: usize> Default for CellGrid<D> {
    fn default() -> Self {
        CellGrid {
            origin: Vector([0.0; D]),
            cell: 1.0,
            dims: [1; D],
            start: Vec::new(),
            sorted: Vec::new(),
            sorted_points: Vec::new(),
            keys: Vec::new(),
            next: Vec::new(),
            holding: Vec::new(),
        }
    }
}

/// Most cells a grid may have; a larger extent (a runaway particle) coarsens the cells.
const MAX_CELLS: f64 = 5e7;

impl<const D: usize> CellGrid<D> {
    /// Bins the points into cells of side `cell` (m). The grid covers the points' extent
    /// within `bounds` (m), when given: points beyond it (particles that left the domain) go
    /// to the border cells, so a runaway particle cannot size the grid.
    pub fn build(points: &[Vector<D>], cell: f64, bounds: Option<(Vector<D>, Vector<D>)>) -> Self {
        let mut grid = CellGrid::default();
        grid.rebuild(points, cell, bounds);
        grid
    }

    /// [`CellGrid::build`] into this grid, reusing its memory.
    pub fn rebuild(
        &mut self,
        points: &[Vector<D>],
        cell: f64,
        bounds: Option<(Vector<D>, Vector<D>)>,
    ) {
        let far = (Vector([f64::MAX; D]), Vector([f64::MIN; D]));
        let bounds_of = |i: usize| match points[i].is_finite() {
            true => (points[i], points[i]),
            false => far,
        };
        let widest = |(lo_a, hi_a): (Vector<D>, Vector<D>),
                      (lo_b, hi_b): (Vector<D>, Vector<D>)| {
            (lo_a.min(&lo_b), hi_a.max(&hi_b))
        };
        let (mut lo, mut hi) = parallel::map_reduce(points.len(), far, bounds_of, widest);
        if let Some((blo, bhi)) = bounds {
            lo = lo.max(&blo);
            hi = hi.min(&bhi);
        }
        for k in 0..D {
            if !(lo[k] <= hi[k]) {
                (lo[k], hi[k]) = (0.0, 0.0);
            }
        }
        let span: f64 = (0..D).map(|k| (hi[k] - lo[k]) / cell + 1.0).product();
        let cell = if span > MAX_CELLS {
            cell * (span / MAX_CELLS).powf(1.0 / D as f64)
        } else {
            cell
        };
        let mut dims = [1usize; D];
        for k in 0..D {
            dims[k] = (((hi[k] - lo[k]) / cell).floor() as usize + 1).max(1);
        }
        (self.origin, self.cell, self.dims) = (lo, cell, dims);
        let ncell: usize = dims.iter().product();
        let mut keys = std::mem::take(&mut self.keys);
        parallel::map_into(&mut keys, points.len(), |i| self.cell_of(&points[i]) as u32);
        let count = &mut self.start;
        count.clear();
        count.resize(ncell + 1, 0);
        for &k in &keys {
            count[k as usize + 1] += 1;
        }
        for c in 0..ncell {
            count[c + 1] += count[c];
        }
        self.next.clear();
        self.next.extend_from_slice(count);
        self.sorted.clear();
        self.sorted.resize(points.len(), 0);
        for (i, &k) in keys.iter().enumerate() {
            self.sorted[self.next[k as usize] as usize] = i as u32;
            self.next[k as usize] += 1;
        }
        self.keys = keys;
        let sorted = &self.sorted;
        parallel::map_into(&mut self.sorted_points, sorted.len(), |k| {
            points[sorted[k] as usize]
        });
    }

    #[inline]
    fn coords_of(&self, p: &Vector<D>) -> [i64; D] {
        let mut c = [0i64; D];
        for k in 0..D {
            c[k] = ((p[k] - self.origin[k]) / self.cell).floor() as i64;
        }
        c
    }

    #[inline]
    fn linear(&self, c: &[i64; D]) -> Option<usize> {
        let mut idx = 0usize;
        for k in (0..D).rev() {
            if c[k] < 0 || c[k] >= self.dims[k] as i64 {
                return None;
            }
            idx = idx * self.dims[k] + c[k] as usize;
        }
        Some(idx)
    }

    #[inline]
    fn cell_of(&self, p: &Vector<D>) -> usize {
        let mut c = self.coords_of(p);
        for k in 0..D {
            c[k] = c[k].clamp(0, self.dims[k] as i64 - 1);
        }
        self.linear(&c).unwrap_or(0)
    }

    /// Marks, per cell, whether it holds a point with `marked[i]` (for `block_holds`).
    fn mark_cells_holding(&mut self, marked: &[bool]) {
        let ncell = self.start.len() - 1;
        let mut holding = std::mem::take(&mut self.holding);
        parallel::map_into(&mut holding, ncell, |c| {
            let (a, b) = (self.start[c] as usize, self.start[c + 1] as usize);
            self.sorted[a..b].iter().any(|&i| marked[i as usize])
        });
        self.holding = holding;
    }

    /// Whether any of the 3^D cells around `p` holds a marked point (`mark_cells_holding`):
    /// with cells of the cut-off's side, false means no marked point within the cut-off.
    fn block_holds(&self, p: &Vector<D>) -> bool {
        let cells = &self.holding;
        let c = self.coords_of(p);
        (0..3usize.pow(D as u32)).any(|n| {
            let mut rem = n;
            let mut cc = c;
            for item in cc.iter_mut() {
                *item = item.saturating_add((rem % 3) as i64 - 1);
                rem /= 3;
            }
            self.linear(&cc).is_some_and(|k| cells[k])
        })
    }

    /// Particle indices in cell order (the order used for memory locality).
    pub fn cell_order(&self) -> &[u32] {
        &self.sorted
    }

    /// Calls `f(j)` for every point `j` within `sqrt(r2)` (m) of `p`, scanning the 3^D cells
    /// around it: each run of three cells along the first axis is contiguous in cell order,
    /// so the scan is one pass over `sorted_points` per run. The order of the calls is the
    /// cells' order, then the order within each cell (deterministic).
    #[inline]
    pub fn for_each_within(&self, p: &Vector<D>, r2: f64, mut f: impl FnMut(u32)) {
        self.for_each_candidate(p, r2, |j, within| {
            if within {
                f(j)
            }
        })
    }

    /// [`Self::for_each_within`] over every point of the cells scanned, `f(j, within)`
    /// telling which lie within `sqrt(r2)` (m): a caller that stores `j` either way and
    /// counts it only when within needs no branch on it.
    #[inline]
    pub fn for_each_candidate(&self, p: &Vector<D>, r2: f64, mut f: impl FnMut(u32, bool)) {
        let c = self.coords_of(p);
        let (x_lo, x_hi) = (
            (c[0] - 1).clamp(0, self.dims[0] as i64 - 1),
            (c[0] + 1).clamp(0, self.dims[0] as i64 - 1),
        );
        if c[0] < -1 || c[0] > self.dims[0] as i64 {
            return;
        }
        let rows = 3usize.pow(D as u32 - 1);
        for n in 0..rows {
            let mut rem = n;
            let mut cc = c;
            for item in cc.iter_mut().skip(1) {
                *item = item.saturating_add((rem % 3) as i64 - 1);
                rem /= 3;
            }
            cc[0] = x_lo;
            let Some(first) = self.linear(&cc) else {
                continue;
            };
            let last = first + (x_hi - x_lo) as usize;
            let (a, b) = (self.start[first] as usize, self.start[last + 1] as usize);
            let points = self.sorted_points[a..b].iter();
            for (q, &j) in points.zip(&self.sorted[a..b]) {
                f(j, (*q - *p).norm2() < r2);
            }
        }
    }
}

/// Builds the neighbour lists of all points within `cutoff` (m), excluding the point itself.
/// The result is independent of the number of threads.
pub fn build_neighbor_list<const D: usize>(points: &[Vector<D>], cutoff: f64) -> NeighborList {
    build_neighbor_list_within(points, cutoff, None)
}

/// [`build_neighbor_list`] on a grid limited to `bounds` (m): points beyond it find only the
/// neighbours in the border cells.
pub fn build_neighbor_list_within<const D: usize>(
    points: &[Vector<D>],
    cutoff: f64,
    bounds: Option<(Vector<D>, Vector<D>)>,
) -> NeighborList {
    let mut out = NeighborList::default();
    build_lists(
        points,
        cutoff,
        bounds,
        None,
        &mut CellGrid::default(),
        &mut out,
    );
    out
}

/// Which points need which lists (for [`build_neighbor_list_near`]).
#[derive(Clone, Copy)]
pub struct ListNeeds<'a> {
    /// The points that move (the fluid): they always get their lists.
    pub moving: &'a [bool],
    /// Fixed points whose lists leave out the other such points (dummy particles, which look
    /// for fluid and wall particles only).
    pub apart: &'a [bool],
}

/// [`build_neighbor_list_within`] for the points that need lists: those with `moving[i]`
/// (the fluid) and every other point with a moving one in the cells around it, which holds
/// every point with a moving one within `cutoff` (m); an `apart` point's list leaves out the
/// other `apart` points (the rest in the same order). The rest (wall and dummy particles out of the
/// fluid's reach, which no pair loop of the step visits) get empty lists.
pub fn build_neighbor_list_near<const D: usize>(
    points: &[Vector<D>],
    cutoff: f64,
    bounds: Option<(Vector<D>, Vector<D>)>,
    needs: ListNeeds,
) -> NeighborList {
    let mut out = NeighborList::default();
    build_lists(
        points,
        cutoff,
        bounds,
        Some(needs),
        &mut CellGrid::default(),
        &mut out,
    );
    out
}

/// [`build_neighbor_list_near`] into `out`, reusing the memory of the lists it held (a
/// list of a million particles is larger than the blocks the allocator keeps, and a fresh
/// one is faulted in page by page; its old lists, near lists included, are dropped), on
/// `grid`'s memory.
pub fn build_neighbor_list_near_into<const D: usize>(
    points: &[Vector<D>],
    cutoff: f64,
    bounds: Option<(Vector<D>, Vector<D>)>,
    needs: ListNeeds,
    grid: &mut CellGrid<D>,
    out: &mut NeighborList,
) {
    build_lists(points, cutoff, bounds, Some(needs), grid, out);
}

fn build_lists<const D: usize>(
    points: &[Vector<D>],
    cutoff: f64,
    bounds: Option<(Vector<D>, Vector<D>)>,
    needs: Option<ListNeeds>,
    grid: &mut CellGrid<D>,
    out: &mut NeighborList,
) {
    out.near = None;
    grid.rebuild(points, cutoff, bounds);
    if let Some(nd) = needs {
        grid.mark_cells_holding(nd.moving);
    }
    let grid = &*grid;
    let n = points.len();
    let c2 = cutoff * cutoff;
    // Room for the lists of a chunk on a first build: the mean points per cell times the
    // share of the 3^D cells scanned that the cut-off sphere covers (0.35 in 2D, 0.16 in
    // 3D), with a margin; at least 40 a point.
    let per_cell = n as f64 / (grid.start.len() - 1).max(1) as f64;
    let share = if D == 3 { 0.16 } else { 0.35 };
    let expected = (1.3 * share * per_cell * 3f64.powi(D as i32)).ceil() as usize + 8;
    out.fill_by_chunks(
        n,
        |a, b| (b - a) * expected.clamp(40, 4096),
        |i, sink| {
            if let Some(nd) = &needs {
                if !nd.moving[i] && !grid.block_holds(&points[i]) {
                    return;
                }
                if nd.apart[i] {
                    grid.for_each_within(&points[i], c2, |j| {
                        if !nd.apart[j as usize] {
                            sink.push(j);
                        }
                    });
                    return;
                }
            }
            grid.for_each_candidate(&points[i], c2, |j, within| {
                sink.push_if(j, within && j as usize != i)
            })
        },
    );
    out.cutoff = cutoff;
}

/// The order (new index -> old index) that sorts points along the cells of side `cell` (m),
/// the grid limited to `bounds` (m) when given.
pub fn locality_order<const D: usize>(
    points: &[Vector<D>],
    cell: f64,
    bounds: Option<(Vector<D>, Vector<D>)>,
) -> Vec<u32> {
    CellGrid::build(points, cell, bounds).cell_order().to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` points spread evenly at random over [0, 1] x [0, 0.5] (a fixed LCG from `seed`).
    fn random_points(n: usize, seed: u64) -> Vec<Vector<2>> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(|_| Vector([next(), next() * 0.5])).collect()
    }

    /// A runaway particle far outside the bounds (or not finite) neither sizes the grid nor
    /// breaks the search; the others still find each other.
    #[test]
    fn a_runaway_particle_does_not_size_the_grid() {
        let pts = vec![
            Vector([0.0, 0.0]),
            Vector([0.05, 0.0]),
            Vector([1e300, -1e300]),
            Vector([f64::NAN, 0.0]),
        ];
        let bounds = Some((Vector([-1.0, -1.0]), Vector([1.0, 1.0])));
        let nl = build_neighbor_list_within(&pts, 0.07, bounds);
        assert_eq!(nl.of(0), &[1]);
        assert_eq!(nl.of(1), &[0]);
        let unbounded = build_neighbor_list(&pts, 0.07);
        assert_eq!(unbounded.of(0), &[1]);
    }

    /// Lists cut to a smaller radius hold every neighbour within it (up to the pair loop's
    /// margin), in the full lists' order, and a pair loop at that radius or below reads them
    /// and finds the same pairs in the same order as on the full lists; a loop at a larger
    /// radius reads the full lists.
    #[test]
    fn near_lists_give_the_pair_loop_the_same_pairs_in_the_same_order() {
        let pts = random_points(400, 987654321);
        let mut nl = build_neighbor_list(&pts, 0.1);
        let near = nl.cut_to(&pts, 0.06);
        for i in 0..pts.len() {
            let want: Vec<u32> = nl
                .of(i)
                .iter()
                .copied()
                .filter(|&j| (pts[j as usize] - pts[i]).norm() < 0.06)
                .collect();
            assert_eq!(near.of(i), &want[..], "particle {i}");
        }
        let loop_at = |nl: &NeighborList, re: f64| -> Vec<(usize, usize, f64)> {
            (0..pts.len())
                .flat_map(|i| {
                    crate::numerics::pairs::pairs(&pts, nl, i, re).map(move |q| (i, q.j, q.w))
                })
                .collect()
        };
        let (full_small, full_large) = (loop_at(&nl, 0.05), loop_at(&nl, 0.08));
        nl.near = Some(Box::new(near));
        assert!(std::ptr::eq(
            nl.for_radius(0.05),
            nl.near.as_deref().unwrap()
        ));
        assert!(std::ptr::eq(nl.for_radius(0.08), &nl));
        assert_eq!(loop_at(&nl, 0.05), full_small);
        assert_eq!(loop_at(&nl, 0.08), full_large);
    }

    /// Lists for the moving points and what they reach: a moving point, and a fixed point
    /// with a moving one within the cut-off, keep the full lists; a fixed point out of every
    /// moving point's reach has none.
    #[test]
    fn fixed_points_out_of_reach_get_no_lists() {
        let l0 = 0.01;
        let mut pts = Vec::new();
        for a in 0..30 {
            for b in 0..6 {
                pts.push(Vector([a as f64 * l0, b as f64 * l0]));
            }
        }
        // The fluid: the first five columns.
        let moving: Vec<bool> = pts.iter().map(|p| p[0] < 4.5 * l0).collect();
        let cutoff = 3.4 * l0;
        let full = build_neighbor_list(&pts, cutoff);
        let fixed = vec![false; pts.len()];
        let needs = ListNeeds {
            moving: &moving,
            apart: &fixed,
        };
        let near = build_neighbor_list_near(&pts, cutoff, None, needs);
        let mut kept = 0;
        for i in 0..pts.len() {
            let reach = (0..pts.len()).any(|j| moving[j] && (pts[j] - pts[i]).norm() < cutoff);
            if moving[i] || reach {
                assert_eq!(near.of(i), full.of(i), "point {i}");
                kept += 1;
            } else if pts[i][0] > 4.0 * l0 + 2.0 * cutoff {
                // Beyond the cells around every moving point: certainly out of reach.
                assert!(near.of(i).is_empty(), "point {i}");
            }
        }
        assert!(kept >= 5 * 6 && near.pairs() < full.pairs() / 2);
    }

    /// Lists rebuilt into the memory of earlier ones equal fresh lists, whether they grew
    /// past their regions' room (those chunks built again at the end), shrank, or the
    /// particle count changed; the same for lists cut into reused memory.
    #[test]
    fn lists_rebuilt_in_place_equal_fresh_ones() {
        let pts = random_points(3000, 424242);
        let (mut nl, mut cut, mut grid) = (
            NeighborList::default(),
            NeighborList::default(),
            CellGrid::default(),
        );
        let same = |a: &NeighborList, b: &NeighborList| {
            assert_eq!((a.len(), a.pairs()), (b.len(), b.pairs()));
            for i in 0..a.len() {
                assert_eq!(a.of(i), b.of(i), "particle {i}");
            }
        };
        for (n, cutoff) in [
            (3000, 0.03),
            (3000, 0.05),
            (3000, 0.02),
            (1000, 0.04),
            (3000, 0.04),
        ] {
            let p = &pts[..n];
            build_lists(p, cutoff, None, None, &mut grid, &mut nl);
            let fresh = build_neighbor_list(p, cutoff);
            same(&nl, &fresh);
            nl.cut_into(p, 0.6 * cutoff, &mut cut);
            same(&cut, &fresh.cut_to(p, 0.6 * cutoff));
        }
    }

    #[test]
    fn cell_list_finds_the_same_pairs_as_brute_force() {
        let mut pts = Vec::new();
        let mut s = 12345u64;
        for _ in 0..500 {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = (s >> 11) as f64 / (1u64 << 53) as f64;
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let y = (s >> 11) as f64 / (1u64 << 53) as f64;
            pts.push(Vector([x, y * 0.5]));
        }
        let nl = build_neighbor_list(&pts, 0.07);
        // A grid limited to a box holding every point finds the same pairs.
        let within =
            build_neighbor_list_within(&pts, 0.07, Some((Vector([0.0, 0.0]), Vector([1.0, 0.5]))));
        assert_eq!(within.pairs(), nl.pairs());
        for i in 0..pts.len() {
            let mut got: Vec<u32> = nl.of(i).to_vec();
            got.sort();
            let want: Vec<u32> = (0..pts.len() as u32)
                .filter(|&j| j as usize != i && (pts[j as usize] - pts[i]).norm() < 0.07)
                .collect();
            assert_eq!(got, want, "particle {i}");
        }
    }
}
