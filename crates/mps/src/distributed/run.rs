//! `mpirun -np N mps run CASE` (feature `mpi`): every process builds the same case and
//! steps its piece ([`super::step`]); after every step the first process gathers every
//! process's own particles into its copy of the whole run, which the serial run loop records
//! (`run::run_stepped`): snapshots, metrics, probes, groups, checkpoints, validations and the
//! summary are those of a serial run, written by one process. The other processes follow
//! the first one's loop step by step (it broadcasts the time to step towards, or the end).
//!
//! Gathering the whole every step costs the first process `N` particles of memory and
//! traffic per step; writing pieces per process is the scalable replacement.

use super::step::{halo_depth, MpiDomain};
use crate::analysis::RunSummary;
use crate::error::CaseError;
use crate::particles::Particles;
use crate::run::{run_stepped, Observer};
use crate::simulation::Simulation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::traits::*;
use std::path::Path;

/// The MPI processes of a run.
pub struct Processes {
    universe: Universe,
}

/// Broadcast in place of a time when the first process's loop has ended.
const STOP: f64 = f64::NEG_INFINITY;

impl Processes {
    /// Initialises MPI (once per program); `None` when it cannot be.
    pub fn start() -> Option<Self> {
        mpi::initialize().map(|universe| Processes { universe })
    }

    /// This process's rank (0 for the first).
    pub fn rank(&self) -> usize {
        self.universe.world().rank() as usize
    }

    /// Number of processes.
    pub fn size(&self) -> usize {
        self.universe.world().size() as usize
    }

    /// Refuses a case whose pieces would be narrower than their halo is deep: each process
    /// must own at least `(2 depth / l0)^D` particles on average.
    pub fn check_size<const D: usize>(
        &self,
        sim: &Simulation<D>,
        label: &str,
    ) -> Result<(), CaseError> {
        let least = (2.0 * halo_depth(sim) / sim.l0()).powi(D as i32).ceil() as usize;
        let (n, p) = (sim.particles.len(), self.size());
        if n < least * p {
            return Err(CaseError::new(
                label,
                "particles",
                n.to_string(),
                format!(
                    "too few for {p} processes: each piece must hold at least {least} particles (twice its halo's depth across); run on at most {} processes",
                    (n / least).max(1)
                ),
            ));
        }
        Ok(())
    }

    /// Runs `sim` (built alike on every process, restored from the same checkpoint if any)
    /// into `out`; `whole` is the first process's copy of the same simulation, which is
    /// recorded (`None` on the others). Returns the summary on the first process.
    pub fn run<const D: usize>(
        &self,
        mut sim: Simulation<D>,
        whole: Option<Simulation<D>>,
        out: &Path,
        resumed: Option<&Path>,
        observer: &mut dyn Observer,
    ) -> crate::error::Result<Option<RunSummary>> {
        let world = self.universe.world();
        let depth = halo_depth(&sim);
        let domain = MpiDomain::<D>::new(self.universe.world(), depth).map_err(|e| {
            crate::error::Error::Format {
                path: out.to_path_buf(),
                message: format!("hypre could not start: {e}"),
            }
        })?;
        sim.attach(Box::new(domain))
            .map_err(|e| CaseError::new("case", "domain.outflow", "remove", e))?;
        let root = world.process_at_rank(0);
        let Some(mut whole) = whole else {
            gather(&sim, &world, None);
            loop {
                let mut until = 0.0f64;
                root.broadcast_into(&mut until);
                if until == STOP {
                    return Ok(None);
                }
                // A breakdown is every process's (the first one records it).
                let _ = sim.step(until);
                gather(&sim, &world, None);
            }
        };
        gather(&sim, &world, Some(&mut whole));
        let mut stepper = |w: &mut Simulation<D>, until: f64| {
            let mut t = until;
            root.broadcast_into(&mut t);
            let r = sim.step(until);
            gather(&sim, &world, Some(w));
            r
        };
        let summary = run_stepped(&mut whole, out, resumed, observer, &mut stepper);
        let mut stop = STOP;
        root.broadcast_into(&mut stop);
        summary.map(Some)
    }
}

/// Every process's own particles of `sim` into `whole` on the first process (in id order),
/// with its clock and last step report (collective; `whole` is `None` on the others).
fn gather<const D: usize>(
    sim: &Simulation<D>,
    world: &mpi::topology::SimpleCommunicator,
    whole: Option<&mut Simulation<D>>,
) {
    let width = Particles::<D>::packed_width();
    let mut rows = Vec::with_capacity(sim.owned() * width);
    for i in 0..sim.owned() {
        sim.particles.pack(i, &mut rows);
    }
    let root = world.process_at_rank(0);
    let Some(w) = whole else {
        root.gather_into(&(rows.len() as i32));
        root.gather_varcount_into(&rows[..]);
        return;
    };
    let mut counts = vec![0i32; world.size() as usize];
    root.gather_into_root(&(rows.len() as i32), &mut counts[..]);
    let displs: Vec<i32> = (0..counts.len())
        .map(|q| counts[..q].iter().sum())
        .collect();
    let mut all = vec![0.0f64; counts.iter().sum::<i32>() as usize];
    {
        let mut part = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        root.gather_varcount_into_root(&rows[..], &mut part);
    }
    let mut p = Particles::<D>::default();
    for row in all.chunks_exact(width) {
        // Rows packed by this program read back.
        let _ = p.push_packed(row);
    }
    p.ids_to_indices();
    let mut order: Vec<u32> = (0..p.len() as u32).collect();
    order.sort_unstable_by_key(|&k| p.id[k as usize]);
    p.permute(&order);
    w.particles = p;
    // The diagnostics read neighbour lists (surface skin, isolated particles).
    w.rebuild_neighbors();
    w.time = sim.time;
    w.step_count = sim.step_count;
    w.last = sim.last;
    w.timers = sim.timers;
}
