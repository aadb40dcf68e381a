//! What the step asks of the processes that share a run (the distributed run, issue 16).
//!
//! A process holds its own particles first and then its halo: copies of the other
//! processes' particles near its own. Every stage runs over all of them; where a stage has
//! computed a field that a later stage reads at the neighbours, the halo's copies are
//! refreshed from their owners (`refresh_*`), and every sum, maximum and minimum over the
//! particles is taken over the own ones and then over the processes. The PPE's rows of the
//! own particles are solved together across the processes. A run on one process has no
//! [`Domain`] and the step is the serial one, bit for bit.

use crate::linalg::{NotConverged, SolveStats};
use crate::numerics::ppe::PressureSystem;
use crate::particles::{Particles, Vector};

/// The processes that share a run, as the step sees them.
pub trait Domain<const D: usize>: Send {
    /// Particles `0 .. owned()` are this process's own; the rest is its halo.
    fn owned(&self) -> usize;
    /// After a step (and before the first): hands particles that left this process's piece
    /// to their owners, rebalances the pieces when they drift apart, and appends the halo at
    /// the current positions with every field. The particle order changes.
    fn redistribute(&mut self, p: &mut Particles<D>) -> Result<(), String>;
    /// The halo's copies of a vector field from their owners.
    fn refresh_vectors(&mut self, v: &mut [Vector<D>]);
    /// The halo's copies of a scalar field from their owners.
    fn refresh_scalars(&mut self, v: &mut [f64]);
    /// The halo's copies of a flag from their owners.
    fn refresh_flags(&mut self, v: &mut [bool]);
    /// How many times the pieces were cut afresh to rebalance them.
    fn rebalances(&self) -> u64;
    /// The largest of every process's `x`.
    fn max(&mut self, x: f64) -> f64;
    /// The smallest of every process's `x`.
    fn min(&mut self, x: f64) -> f64;
    /// The sum of every process's `x`.
    fn sum(&mut self, x: u64) -> u64;
    /// True when any process's `x` is.
    fn any(&mut self, x: bool) -> bool;
    /// Solves the rows of the own particles of `sys` together with the other processes',
    /// `x` (one value per row of `sys`) the first guess of the own rows and their solution
    /// after; the halo's rows are left as they are. Relative residual `tol`.
    fn solve(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        tol: f64,
        max_iter: usize,
    ) -> Result<SolveStats, NotConverged>;
}

use super::breakdown::{BreakdownReason, Failure};
use super::stages::{DensitySurface, Predicted};
use super::Simulation;

impl<const D: usize> Simulation<D> {
    /// Makes this simulation one process's part of a distributed run: every process built
    /// the same case; `domain` keeps this process's piece and its halo. Refused for what the
    /// distributed step does not do yet (outflow removal).
    pub fn attach(&mut self, mut domain: Box<dyn Domain<D>>) -> Result<(), String> {
        if self.case.domain.outflow == crate::input::case::Outflow::Remove {
            return Err("domain.outflow = \"remove\" does not run on several processes yet".into());
        }
        domain.redistribute(&mut self.particles)?;
        self.owned = Some(domain.owned());
        self.domain = std::sync::Mutex::new(Some(domain));
        self.solver.reset();
        self.refresh_diagnostic_fields();
        Ok(())
    }

    /// How many times a distributed run's pieces were cut afresh (0 on one process).
    pub fn rebalances(&mut self) -> u64 {
        self.domain_mut().map_or(0, |d| d.rebalances())
    }

    /// True when the run is shared by several processes.
    pub fn is_distributed(&self) -> bool {
        self.owned.is_some()
    }

    /// This process's own particles `0 .. owned()` (all of them on one process).
    pub fn owned(&self) -> usize {
        self.owned.unwrap_or(self.particles.len())
    }

    fn domain_mut(&mut self) -> Option<&mut (dyn Domain<D> + 'static)> {
        self.domain
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .as_deref_mut()
    }

    /// After a step of a distributed run: migration, rebalancing and the new halo.
    pub(super) fn redistribute(&mut self) -> Result<(), String> {
        let mut p = std::mem::take(&mut self.particles);
        let r = match self.domain_mut() {
            Some(d) => d.redistribute(&mut p).map(|_| Some(d.owned())),
            None => Ok(None),
        };
        self.particles = p;
        if let Some(owned) = r? {
            self.owned = Some(owned);
        }
        Ok(())
    }

    /// The halo's `r*` and `u*` from their owners.
    pub(super) fn refresh_predicted(&mut self, pred: &mut Predicted<D>) {
        if let Some(d) = self.domain_mut() {
            d.refresh_vectors(&mut pred.pos);
            d.refresh_vectors(&mut pred.vel);
        }
    }

    /// The halo's number densities and free-surface flags from their owners.
    pub(super) fn refresh_surface(&mut self, surf: &mut DensitySurface) {
        if let Some(d) = self.domain_mut() {
            d.refresh_scalars(&mut surf.number_density);
            d.refresh_flags(&mut surf.free_surface);
        }
    }

    /// The halo's smoothed densities, if any, from their owners.
    pub(super) fn refresh_density(&mut self, density: &mut Option<Vec<f64>>) {
        if let Some(v) = density {
            self.refresh_scalars(v);
        }
    }

    /// The halo's copies of a vector field from their owners.
    pub(super) fn refresh_vectors(&mut self, v: &mut [Vector<D>]) {
        if let Some(d) = self.domain_mut() {
            d.refresh_vectors(v);
        }
    }

    /// The halo's copies of a scalar field from their owners.
    pub(super) fn refresh_scalars(&mut self, v: &mut [f64]) {
        if let Some(d) = self.domain_mut() {
            d.refresh_scalars(v);
        }
    }

    /// The halo's copies of a flag from their owners.
    pub(super) fn refresh_flags(&mut self, v: &mut [bool]) {
        if let Some(d) = self.domain_mut() {
            d.refresh_flags(v);
        }
    }

    /// The largest `x` over the processes.
    pub(super) fn max(&mut self, x: f64) -> f64 {
        self.domain_mut().map_or(x, |d| d.max(x))
    }

    /// The smallest `x` over the processes.
    pub(super) fn min(&mut self, x: f64) -> f64 {
        self.domain_mut().map_or(x, |d| d.min(x))
    }

    /// The sum of `x` over the processes.
    pub(super) fn sum(&mut self, x: u64) -> u64 {
        self.domain_mut().map_or(x, |d| d.sum(x))
    }

    /// True when `x` holds on any process.
    pub(super) fn any(&mut self, x: bool) -> bool {
        self.domain_mut().map_or(x, |d| d.any(x))
    }

    /// The PPE unknowns of the own particles, over the processes.
    pub(super) fn own_unknowns(&mut self, sys: &PressureSystem) -> usize {
        let owned = self.owned() as u32;
        let own = sys.particle_of.iter().filter(|&&i| i < owned).count();
        self.sum(own as u64) as usize
    }

    /// On several processes, a closed domain (no Dirichlet row on any process) is refused:
    /// its level would be fixed on every process at once (not done yet).
    pub(super) fn refuse_closed_across(&mut self, sys: &PressureSystem) -> Result<(), Failure> {
        if self.is_distributed() && self.any(sys.level.is_some()) {
            let why = "a closed domain (no free surface) does not run on several processes yet";
            return Err(BreakdownReason::Distributed(why.into()).into());
        }
        Ok(())
    }

    /// On several processes: the PPE solved across them (`None` on one process).
    pub(super) fn solve_across(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
    ) -> Option<Result<SolveStats, NotConverged>> {
        let (tol, it) = (self.case.solver.tolerance, self.case.solver.max_iterations);
        self.domain_mut().map(|d| d.solve(sys, x, tol, it))
    }
}
