//! The distributed step's processes (feature `mpi`): a [`Domain`] over MPI.
//!
//! Each process owns the particles in its piece of the Morton cuts (`partition`) and holds,
//! after its own, a halo: the other processes' particles within [`halo_depth`] of one of its
//! own, with every field. Particles travel as rows of numbers (`Particles::pack`). After
//! each step the halo is dropped, particles that crossed a cut go to their new owner, the
//! cuts are recomputed when the largest piece exceeds the mean by more than 10 %, and the
//! halo is fetched afresh; between the stages only the fields a stage computed are refreshed
//! (`refresh_*`), each process sending its own particles' values in the order the receiver
//! holds them. The PPE's own rows, numbered globally in rank order, are solved by hypre.

use super::exchange::{cuts_of_keys, exchange_numbers};
use super::hypre::{self, LocalRows};
use super::partition::{owner_of, MortonGrid};
use crate::linalg::{NotConverged, SolveStats};
use crate::numerics::ppe::PressureSystem;
use crate::particles::fields::Packed;
use crate::particles::{Particles, Vector, NONE};
use crate::simulation::{Domain, Simulation};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Largest piece over the mean piece above which the cuts are recomputed.
const REBALANCE: f64 = 1.10;

/// How deep (m) a halo must reach for the step of `sim`: two interaction radii and the
/// neighbour skin, since some stages read the neighbours of a neighbour within one stage (a
/// wall particle's dry test and a surface particle's mean-surface value in the PPE
/// assembly), plus a skin for the motion within the step.
pub fn halo_depth<const D: usize>(sim: &Simulation<D>) -> f64 {
    let k = &sim.kernels;
    let skin = 0.3 * k.l0;
    2.0 * (k.grad.re.max(k.lap.re) + skin) + skin
}

/// One process of a distributed run.
pub struct MpiDomain<const D: usize> {
    world: SimpleCommunicator,
    /// Halo depth (m), also the Morton cell side.
    depth: f64,
    /// The cells, fixed at the first redistribution (or taken from a checkpoint).
    grid: Option<MortonGrid<D>>,
    /// Whether the first redistribution (every process holding the whole case) is done.
    started: bool,
    /// The Morton cuts (one piece per process).
    cuts: Vec<u64>,
    /// Own particles.
    owned: usize,
    /// Own particles (indices) whose values go to each process, in the order it holds them.
    send: Vec<Vec<u32>>,
    /// Halo particles from each process, held in process order after the own ones.
    recv: Vec<usize>,
    /// Recomputed cuts so far.
    rebalances: u64,
}

// SAFETY: the communicator is used only from the thread that runs the step (the stages'
// parallel loops never call the domain), which is the thread that initialised MPI.
unsafe impl<const D: usize> Send for MpiDomain<D> {}

impl<const D: usize> MpiDomain<D> {
    /// The domain of `world` for a run whose halo reaches `depth` (m, [`halo_depth`]);
    /// starts hypre (MPI must be initialised).
    pub fn new(world: SimpleCommunicator, depth: f64) -> Result<Self, String> {
        hypre::init().map_err(|e| e.to_string())?;
        let size = world.size() as usize;
        Ok(MpiDomain {
            world,
            depth,
            grid: None,
            started: false,
            cuts: Vec::new(),
            owned: 0,
            send: vec![Vec::new(); size],
            recv: vec![0; size],
            rebalances: 0,
        })
    }

    fn rank(&self) -> u32 {
        self.world.rank() as u32
    }

    /// Every own particle's row with its cell key; on the first call (every process holds
    /// the whole case) the grid and cuts are made from all particles.
    fn own_rows(&mut self, p: &Particles<D>) -> Vec<OwnRow> {
        let first = !self.started;
        if first && self.grid.is_none() {
            let lo: [f64; D] = std::array::from_fn(|a| {
                p.position
                    .iter()
                    .map(|x| x[a])
                    .fold(f64::INFINITY, f64::min)
                    - 2.0 * self.depth
            });
            let grid = MortonGrid {
                lo,
                cell: self.depth,
            };
            let mut keys: Vec<u64> = p.position.iter().map(|x| grid.key(x)).collect();
            keys.sort_unstable();
            self.cuts = super::partition::splitters(&keys, self.world.size() as usize);
            self.grid = Some(grid);
        }
        if first {
            self.owned = p.len();
            self.started = true;
        }
        let grid = self.grid.expect("set above");
        let me = self.rank();
        (0..self.owned)
            .filter(|&i| !first || owner_of(&self.cuts, grid.key(&p.position[i])) == me)
            .map(|i| {
                let mut row = Vec::with_capacity(Particles::<D>::packed_width());
                p.pack(i, &mut row);
                (grid.key(&p.position[i]), p.id[i], row)
            })
            .collect()
    }

    /// Recomputes the cuts when the largest piece exceeds the mean by more than 10 %.
    fn rebalance(&mut self, keys: &[u64]) {
        let mut sum = 0u64;
        let mut max = 0u64;
        let n = keys.len() as u64;
        self.world
            .all_reduce_into(&n, &mut sum, SystemOperation::sum());
        self.world
            .all_reduce_into(&n, &mut max, SystemOperation::max());
        let mean = sum as f64 / self.world.size() as f64;
        if max as f64 > REBALANCE * mean {
            self.cuts = cuts_of_keys(&self.world, keys);
            self.rebalances += 1;
        }
    }

    /// Sends each own row to the owner of its cell; returns the rows this process owns.
    fn migrate(&mut self, rows: Vec<OwnRow>) -> Vec<OwnRow> {
        let size = self.world.size() as usize;
        let me = self.rank() as usize;
        let width = Particles::<D>::packed_width();
        let mut out = vec![Vec::new(); size];
        let mut mine = Vec::with_capacity(rows.len());
        for r in rows {
            let q = owner_of(&self.cuts, r.0) as usize;
            if q == me {
                mine.push(r);
            } else {
                out[q].extend_from_slice(&r.2);
            }
        }
        let (received, _) = exchange_numbers(&self.world, &out);
        let grid = self.grid.expect("set");
        for row in received.chunks_exact(width) {
            mine.push((
                grid.key(&row_position::<D>(row)),
                row_id::<D>(row),
                row.to_vec(),
            ));
        }
        mine
    }
}

/// The position (m) in a packed row.
fn row_position<const D: usize>(row: &[f64]) -> Vector<D> {
    let at = Particles::<D>::PACKED_POSITION;
    Vector(std::array::from_fn(|a| row[at + a]))
}

/// The id in a packed row.
fn row_id<const D: usize>(row: &[f64]) -> u32 {
    row[Particles::<D>::PACKED_ID] as u32
}

/// An own particle on its way: its cell key, id and packed row.
type OwnRow = (u64, u32, Vec<f64>);

impl<const D: usize> MpiDomain<D> {
    /// The halo of the own rows `own` (sorted): each own particle goes to the other owners of
    /// the cells next to its own; each receiver keeps those within the depth of one of its
    /// own and tells the sender which, so that later refreshes send only those. Returns the
    /// kept rows, in process order.
    fn halo(&mut self, own: &[OwnRow]) -> Vec<f64> {
        let size = self.world.size() as usize;
        let me = self.rank();
        let grid = self.grid.expect("set");
        let width = Particles::<D>::packed_width();
        let mut out = vec![Vec::new(); size];
        for (k, (_, _, row)) in own.iter().enumerate() {
            let x = row_position::<D>(row);
            let mut owners: Vec<u32> = grid
                .neighbour_keys(&x)
                .into_iter()
                .map(|key| owner_of(&self.cuts, key))
                .filter(|&q| q != me)
                .collect();
            owners.sort_unstable();
            owners.dedup();
            for q in owners {
                out[q as usize].push(k as f64);
                out[q as usize].extend_from_slice(row);
            }
        }
        let (candidates, counts) = exchange_numbers(&self.world, &out);
        let own_pos: Vec<Vector<D>> = own.iter().map(|r| row_position::<D>(&r.2)).collect();
        let mut cells: std::collections::HashMap<u64, Vec<usize>> = Default::default();
        for (i, r) in own.iter().enumerate() {
            cells.entry(r.0).or_default().push(i);
        }
        let r2 = self.depth * self.depth;
        let near = |x: &Vector<D>| {
            grid.neighbour_keys(x).iter().any(|key| {
                cells
                    .get(key)
                    .is_some_and(|v| v.iter().any(|&i| (own_pos[i] - *x).norm2() < r2))
            })
        };
        let mut kept = Vec::new();
        let mut reply = vec![Vec::new(); size];
        let mut at = 0;
        for q in 0..size {
            for rec in candidates[at..at + counts[q]].chunks_exact(width + 1) {
                if near(&row_position::<D>(&rec[1..])) {
                    reply[q].push(rec[0]);
                    kept.extend_from_slice(&rec[1..]);
                }
            }
            self.recv[q] = reply[q].len();
            at += counts[q];
        }
        let (back, back_counts) = exchange_numbers(&self.world, &reply);
        let mut at = 0;
        for q in 0..size {
            self.send[q] = back[at..at + back_counts[q]]
                .iter()
                .map(|&k| k as u32)
                .collect();
            at += back_counts[q];
        }
        kept
    }

    /// The halo's copies of `v` from their owners.
    fn refresh<T: Packed>(&mut self, v: &mut [T]) {
        let out: Vec<Vec<f64>> = self
            .send
            .iter()
            .map(|list| {
                let mut o = Vec::with_capacity(list.len() * T::WIDTH);
                for &i in list {
                    v[i as usize].pack(&mut o);
                }
                o
            })
            .collect();
        let (got, _) = exchange_numbers(&self.world, &out);
        for (k, c) in got.chunks_exact(T::WIDTH).enumerate() {
            if let (Some(x), Some(slot)) = (T::unpack(c), v.get_mut(self.owned + k)) {
                *slot = x;
            }
        }
    }

    fn reduce<T: Equivalence + Default + Copy>(&self, x: T, op: SystemOperation) -> T {
        let mut r = T::default();
        self.world.all_reduce_into(&x, &mut r, op);
        r
    }
}

impl<const D: usize> Domain<D> for MpiDomain<D> {
    fn owned(&self) -> usize {
        self.owned
    }

    fn redistribute(&mut self, p: &mut Particles<D>, owned: usize) -> Result<(), String> {
        let first = !self.started;
        // Own particles removed by outflow since the last call are gone from the front.
        self.owned = owned.min(p.len());
        let rows = self.own_rows(p);
        let mut rows = if first {
            rows
        } else {
            let keys: Vec<u64> = rows.iter().map(|r| r.0).collect();
            self.rebalance(&keys);
            self.migrate(rows)
        };
        rows.sort_unstable_by_key(|r| (r.0, r.1));
        let halo = self.halo(&rows);
        let mut q = Particles::<D>::default();
        let bad = || {
            format!(
                "a particle row of {} numbers could not be read",
                Particles::<D>::packed_width()
            )
        };
        for r in &rows {
            q.push_packed(&r.2).ok_or_else(bad)?;
        }
        for row in halo.chunks_exact(Particles::<D>::packed_width()) {
            q.push_packed(row).ok_or_else(bad)?;
        }
        q.ids_to_indices();
        self.owned = rows.len();
        *p = q;
        Ok(())
    }

    fn refresh_vectors(&mut self, v: &mut [Vector<D>]) {
        self.refresh(v);
    }

    fn rebalances(&self) -> u64 {
        self.rebalances
    }

    fn refresh_scalars(&mut self, v: &mut [f64]) {
        self.refresh(v);
    }

    fn refresh_flags(&mut self, v: &mut [bool]) {
        self.refresh(v);
    }

    fn max(&mut self, x: f64) -> f64 {
        self.reduce(x, SystemOperation::max())
    }

    fn min(&mut self, x: f64) -> f64 {
        self.reduce(x, SystemOperation::min())
    }

    fn sum(&mut self, x: u64) -> u64 {
        self.reduce(x, SystemOperation::sum())
    }

    fn any(&mut self, x: bool) -> bool {
        self.reduce(x as u32, SystemOperation::max()) > 0
    }

    fn sum_reals(&mut self, v: &mut [f64]) {
        let mine = v.to_vec();
        self.world
            .all_reduce_into(&mine[..], v, SystemOperation::sum());
    }

    fn all_gather(&mut self, v: &[f64]) -> Vec<f64> {
        let size = self.world.size() as usize;
        let (all, _) = exchange_numbers(&self.world, &vec![v.to_vec(); size]);
        all
    }

    fn process(&self) -> (usize, usize) {
        (self.world.rank() as usize, self.world.size() as usize)
    }

    fn layout(&self) -> Vec<u64> {
        let Some(grid) = self.grid else {
            return Vec::new();
        };
        let mut out = vec![D as u64, self.world.size() as u64, grid.cell.to_bits()];
        out.extend(grid.lo.iter().map(|x| x.to_bits()));
        out.extend_from_slice(&self.cuts);
        out
    }

    fn adopt(&mut self, layout: &[u64]) -> bool {
        let size = self.world.size() as usize;
        let fits = layout.len() == 3 + D + size + 1
            && layout[0] == D as u64
            && layout[1] == size as u64
            && f64::from_bits(layout[2]) == self.depth;
        if fits && self.grid.is_none() {
            self.grid = Some(MortonGrid {
                lo: std::array::from_fn(|a| f64::from_bits(layout[3 + a])),
                cell: self.depth,
            });
            self.cuts = layout[3 + D..].to_vec();
        }
        fits
    }

    fn solve(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        tol: f64,
        max_iter: usize,
    ) -> Result<SolveStats, NotConverged> {
        let failed = NotConverged::at(0, f64::NAN);
        let owned = self.owned as u32;
        // Rows follow the particle order: the own particles' rows come first.
        let k = sys.particle_of.partition_point(|&i| i < owned);
        let size = self.world.size() as usize;
        let mut counts = vec![0u64; size];
        self.world.all_gather_into(&(k as u64), &mut counts[..]);
        let first: u64 = counts[..self.rank() as usize].iter().sum();
        let mut global = vec![-1.0f64; sys.row_of.len()];
        for i in 0..self.owned {
            if sys.row_of[i] != NONE {
                global[i] = (first + sys.row_of[i] as u64) as f64;
            }
        }
        self.refresh(&mut global);
        let (mut row_ptr, mut cols, mut vals) = (vec![0usize], Vec::new(), Vec::new());
        let mut mismatch = false;
        for r in 0..k {
            let (c, v) = sys.matrix.row(r);
            for (&cj, &val) in c.iter().zip(v) {
                let g = global[sys.particle_of[cj as usize] as usize];
                // A halo unknown that its owner holds as Dirichlet: the halo is too shallow.
                mismatch |= g < 0.0;
                cols.push(g.max(0.0) as usize);
                vals.push(val);
            }
            row_ptr.push(cols.len());
        }
        if self.any(mismatch) {
            return Err(failed);
        }
        let rows = LocalRows {
            first: first as usize,
            row_ptr: &row_ptr,
            cols: &cols,
            vals: &vals,
        };
        let solved =
            hypre::pcg_boomeramg(&self.world, rows, &sys.rhs[..k], &mut x[..k], tol, max_iter);
        let ok = !self.any(solved.is_err());
        match solved {
            Ok(s) if ok => Ok(SolveStats {
                iterations: s.iterations,
                residual: s.relative_residual,
            }),
            Ok(s) => Err(NotConverged::at(s.iterations, s.relative_residual)),
            Err(_) => Err(failed),
        }
    }
}

impl<const D: usize> Drop for MpiDomain<D> {
    fn drop(&mut self) {
        // hypre ends before MPI does (the universe outlives the domain).
        let _ = hypre::finalize();
    }
}
