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
    /// the current positions with every field. `owned`: the own particles now (fewer than
    /// after the last call when some left the domain; all of them before the first). The
    /// particle order changes.
    fn redistribute(&mut self, p: &mut Particles<D>, owned: usize) -> Result<(), String>;
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
    /// Every process's `v` summed, element by element, into `v` (the same length on all).
    fn sum_reals(&mut self, v: &mut [f64]);
    /// Every process's `v`, one after the other in rank order.
    fn all_gather(&mut self, v: &[f64]) -> Vec<f64>;
    /// This process's rank (0 for the first) and the number of processes.
    fn process(&self) -> (usize, usize);
    /// The pieces' layout (cells and cuts) as numbers, kept in a checkpoint so that a
    /// restart on as many processes cuts the same pieces.
    fn layout(&self) -> Vec<u64>;
    /// Takes a checkpoint's layout before the first redistribution; false (and ignored) when
    /// it was made for another number of processes or dimension.
    fn adopt(&mut self, layout: &[u64]) -> bool;
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

use super::stages::{DensitySurface, Predicted};
use super::Simulation;

impl<const D: usize> Simulation<D> {
    /// Makes this simulation one process's part of a distributed run: every process built
    /// the same case; `domain` keeps this process's piece and its halo.
    pub fn attach(&mut self, mut domain: Box<dyn Domain<D>>) -> Result<(), String> {
        if !self.layout.is_empty() {
            domain.adopt(&self.layout);
        }
        let all = self.particles.len();
        domain.redistribute(&mut self.particles, all)?;
        self.owned = Some(domain.owned());
        self.domain = std::sync::Mutex::new(Some(domain));
        self.solver.reset();
        // Every field was computed on the whole (at the start, or kept by the checkpoint)
        // and travelled with the particles: only the neighbour lists are new.
        self.rebuild_neighbors();
        Ok(())
    }

    /// This process's rank and the number of processes (`(0, 1)` on one process).
    pub fn process(&self) -> (usize, usize) {
        self.with_domain(|d| d.process()).unwrap_or((0, 1))
    }

    /// True on the process that writes a run's shared files (the only one, or rank 0).
    pub fn is_first_process(&self) -> bool {
        self.process().0 == 0
    }

    /// `v` summed element by element over the processes (collective; nothing on one).
    pub fn sum_over_processes(&self, v: &mut [f64]) {
        self.with_domain(|d| d.sum_reals(v));
    }

    /// The largest `x` over the processes (collective).
    pub fn max_over_processes(&self, x: f64) -> f64 {
        self.with_domain(|d| d.max(x)).unwrap_or(x)
    }

    /// Every process's `v` in rank order (collective; `v` itself on one process).
    pub fn gather_over_processes(&self, v: &[f64]) -> Vec<f64> {
        self.with_domain(|d| d.all_gather(v))
            .unwrap_or_else(|| v.to_vec())
    }

    /// Particles of `kind` over every process's own ones.
    pub fn count_over_processes(&self, kind: crate::particles::Kind) -> usize {
        let p = &self.particles;
        let own = (0..self.owned()).filter(|&i| p.kind[i] == kind).count();
        let mut n = [own as f64];
        self.sum_over_processes(&mut n);
        n[0] as usize
    }

    /// Waits until every process has come here (collective; nothing on one process).
    pub fn barrier(&self) {
        self.sum_over_processes(&mut [0.0]);
    }

    /// The pieces' layout to keep in a checkpoint (empty on one process).
    pub fn layout(&self) -> Vec<u64> {
        self.with_domain(|d| d.layout()).unwrap_or_default()
    }

    fn with_domain<R>(&self, f: impl FnOnce(&mut (dyn Domain<D> + 'static)) -> R) -> Option<R> {
        let mut guard = self.domain.lock().unwrap_or_else(|e| e.into_inner());
        guard.as_deref_mut().map(f)
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
        let owned = self.owned();
        let r = match self.domain_mut() {
            Some(d) => d.redistribute(&mut p, owned).map(|_| Some(d.owned())),
            None => Ok(None),
        };
        self.particles = p;
        if let Some(owned) = r? {
            self.owned = Some(owned);
            // The particle order changed: the lists the diagnostics after the step and the
            // next step read are built here, at the same positions.
            self.rebuild_neighbors();
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

    /// On several processes: the PPE solved across them to the relative residual `tol`
    /// (`None` on one process).
    pub(super) fn solve_across(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        tol: f64,
    ) -> Option<Result<SolveStats, NotConverged>> {
        let it = self.case.solver.max_iterations;
        self.domain_mut().map(|d| d.solve(sys, x, tol, it))
    }
}
