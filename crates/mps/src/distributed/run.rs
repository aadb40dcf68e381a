//! `mpirun -np N mps run CASE` (feature `mpi`): every process builds the same case, keeps
//! its piece ([`super::step`]) and runs the serial run loop on it (`run::run_from`): metrics,
//! probes, groups, fronts and validations are sums, extremes or gathers over the processes'
//! own particles, the first process writes the shared files (series, `.pvd`, `.pvtu`
//! indices, the checkpoint's index, the summary), each process the pieces of its own
//! particles (`particles_NNNNNN_pRANK.vtu`, `checkpoint_STEP_pRANK.bin`). No process ever
//! holds the whole run after the start.

use super::step::{halo_depth, MpiDomain};
use crate::analysis::RunSummary;
use crate::error::CaseError;
use crate::run::{run_from, Observer};
use crate::simulation::Simulation;
use mpi::environment::Universe;
use mpi::traits::*;
use std::path::Path;

/// The MPI processes of a run.
pub struct Processes {
    universe: Universe,
}

impl Processes {
    /// Initialises MPI (once per program); `None` when it cannot be.
    pub fn start() -> Option<Self> {
        mpi::initialize().map(|universe| Processes { universe })
    }

    /// This process's rank (0 for the first).
    pub fn rank(&self) -> usize {
        self.universe.world().rank() as usize
    }

    /// True when `ok` holds on every process (collective).
    pub fn all(&self, ok: bool) -> bool {
        let mut failed = 0u32;
        self.universe.world().all_reduce_into(
            &(!ok as u32),
            &mut failed,
            mpi::collective::SystemOperation::sum(),
        );
        failed == 0
    }

    /// Number of processes.
    pub fn size(&self) -> usize {
        self.universe.world().size() as usize
    }

    /// Refuses a case whose pieces would be narrower than their halo is deep: each process
    /// must own at least `(2 depth / l0)^D` particles on average; and a free surface under
    /// tension, whose smoothed curvature reaches about 10 l0, beyond the halo.
    pub fn check_size<const D: usize>(
        &self,
        sim: &Simulation<D>,
        label: &str,
    ) -> Result<(), CaseError> {
        let several = self.size() > 1;
        let mut phases = sim.case.phases.iter().enumerate();
        if let Some((k, p)) = phases.find(|(_, p)| several && p.surface_tension > 0.0) {
            return Err(CaseError::new(
                label,
                format!("phases.{k}.surface_tension"),
                p.surface_tension.to_string(),
                "a free surface under tension runs on one process only (its curvature reaches beyond the halo)",
            ));
        }
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
    /// into `out`: each process steps and records its piece (`run::run_from`, every
    /// measurement taken over the processes), the first writes the shared files. Returns
    /// the run's summary (on every process).
    pub fn run<const D: usize>(
        &self,
        mut sim: Simulation<D>,
        out: &Path,
        resumed: Option<&Path>,
        observer: &mut dyn Observer,
    ) -> crate::error::Result<RunSummary> {
        let depth = halo_depth(&sim);
        let domain = MpiDomain::<D>::new(self.universe.world(), depth).map_err(|e| {
            crate::error::Error::Format {
                path: out.to_path_buf(),
                message: format!("hypre could not start: {e}"),
            }
        })?;
        sim.attach(Box::new(domain))
            .map_err(|e| crate::error::Error::Format {
                path: out.to_path_buf(),
                message: format!("the particles could not be shared out: {e}"),
            })?;
        run_from(&mut sim, out, resumed, observer)
    }
}
