//! The pressure solver: owns the solver choice, the preconditioner, the kept AMG hierarchy
//! and its reuse policy, and counts preconditioner fall-backs (an AMG or IC(0) set-up that
//! fails falls back to Jacobi; every such step is reported, never silent).

use crate::input::case::SolverSpec;
use crate::linalg::{
    dilu_cg, pcg, Amg, AmgParams, Dilu, Ic0, Identity, Jacobi, NotConverged, SolveStats,
    DILU_OMEGA, MIC_OMEGA,
};
use crate::linalg::{Precondition, SolverKind};
use crate::numerics::ppe::PressureSystem;
use crate::particles::NONE;
use std::time::{Duration, Instant};

/// Steps an AMG hierarchy is reused for while the unknowns are the same or nearly the same
/// particles (docs/decisions.md, "AMG reuse").
const AMG_MAX_AGE: u32 = 10;

/// Largest share of a kept hierarchy's rows that may have joined or left the unknowns (free
/// surface flags, wall particles getting wet or dry) for it to be carried over to the new
/// set (docs/decisions.md, "AMG reuse").
const AMG_MAX_CHANGED_SHARE: f64 = 0.05;

/// An AMG hierarchy kept from an earlier step.
#[derive(Debug)]
struct AmgCache {
    /// The particle ids of its unknowns (row -> id).
    ids: Vec<u32>,
    /// Its row of each particle id ([`NONE`] for none).
    row_of_id: Vec<u32>,
    /// The hierarchy.
    amg: Amg,
    /// CG iterations of the solve right after the set-up.
    setup_iterations: usize,
    /// Steps it has been reused.
    age: u32,
}

/// What one solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveReport {
    /// Iterations and final residual.
    pub stats: SolveStats,
    /// Preconditioner set-up time.
    pub setup: Duration,
    /// CG time.
    pub solve: Duration,
    /// True when the chosen preconditioner could not be built and Jacobi was used.
    pub fallback: bool,
}

/// The PPE solver of a simulation.
#[derive(Debug)]
pub struct PressureSolver {
    kind: SolverKind,
    /// 2 or 3: what `auto` chooses depends on it.
    dimension: usize,
    tolerance: f64,
    max_iterations: usize,
    amg: Option<AmgCache>,
    last_iterations: usize,
    /// Steps whose preconditioner fell back to Jacobi.
    pub fallbacks: u64,
}

/// Runs PCG from `x` with preconditioner `m`, timing it.
fn timed_pcg(
    sys: &PressureSystem,
    x: &mut [f64],
    m: &(impl Precondition + ?Sized),
    tol: f64,
    max_iter: usize,
) -> (Result<SolveStats, NotConverged>, Duration) {
    let t = Instant::now();
    let r = pcg(&sys.matrix, &sys.rhs, x, m, tol, max_iter);
    (r, t.elapsed())
}

impl PressureSolver {
    /// A solver as the case's `[solver]` table asks, for a run in `dimension` 2 or 3.
    pub fn new(spec: &SolverSpec, dimension: usize) -> Self {
        PressureSolver {
            kind: spec.kind,
            dimension,
            tolerance: spec.tolerance,
            max_iterations: spec.max_iterations,
            amg: None,
            last_iterations: 0,
            fallbacks: 0,
        }
    }

    /// Drops any kept set-up, so the next solve builds it afresh (at checkpoints, so a
    /// restarted run continues bit-identically).
    pub fn reset(&mut self) {
        self.amg = None;
    }

    /// Solves `sys` from the warm start `x`; on success `x` holds the solution. `ids` holds
    /// every particle's id (by particle index), which a kept AMG hierarchy is keyed on.
    pub fn solve(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        ids: &[u32],
    ) -> (Result<SolveStats, NotConverged>, SolveReport) {
        let t0 = Instant::now();
        let (tol, max_iter) = (self.tolerance, self.max_iterations);
        let mut report = SolveReport::default();
        // `None`: the chosen preconditioner could not be built.
        let attempt = match self.kind.for_size(sys.matrix.n(), self.dimension) {
            SolverKind::AmgCg => self.solve_amg(sys, x, ids, t0, &mut report),
            SolverKind::Ic0Cg => Ic0::new(&sys.matrix).map(|f| {
                report.setup = t0.elapsed();
                timed_pcg(sys, x, &f, tol, max_iter)
            }),
            // Modified IC(0); where a relaxed pivot is not positive, plain IC(0).
            SolverKind::Mic0Cg => Ic0::modified(&sys.matrix, MIC_OMEGA)
                .or_else(|| Ic0::new(&sys.matrix))
                .map(|f| {
                    report.setup = t0.elapsed();
                    timed_pcg(sys, x, &f, tol, max_iter)
                }),
            // Modified D-ILU; where a relaxed pivot is not positive, plain D-ILU.
            SolverKind::DiluCg => Dilu::new(&sys.matrix, DILU_OMEGA)
                .or_else(|| Dilu::new(&sys.matrix, 0.0))
                .map(|m| {
                    report.setup = t0.elapsed();
                    let t = Instant::now();
                    let r = dilu_cg(&sys.matrix, &sys.rhs, x, &m, tol, max_iter);
                    (r, t.elapsed())
                }),
            SolverKind::Cg => {
                report.setup = t0.elapsed();
                Some(timed_pcg(sys, x, &Identity, tol, max_iter))
            }
            _ => None,
        };
        let (result, solve) = attempt.unwrap_or_else(|| {
            if self.kind.for_size(sys.matrix.n(), self.dimension) != SolverKind::JacobiCg {
                self.fallbacks += 1;
                report.fallback = true;
            }
            let pre = Jacobi::new(&sys.matrix);
            report.setup = t0.elapsed();
            timed_pcg(sys, x, &pre, tol, max_iter)
        });
        self.finish(result, solve, report)
    }

    fn finish(
        &mut self,
        result: Result<SolveStats, NotConverged>,
        solve: Duration,
        mut report: SolveReport,
    ) -> (Result<SolveStats, NotConverged>, SolveReport) {
        report.solve = solve;
        report.stats = match &result {
            Ok(s) => *s,
            Err(e) => e.stats,
        };
        self.last_iterations = report.stats.iterations;
        (result, report)
    }

    /// AMG-CG: reuse the kept hierarchy while it still converges nearly as fast as right
    /// after its set-up and its unknowns are the same particles, or nearly so (their rows
    /// carried over by particle id); rebuild otherwise.
    fn solve_amg(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        ids: &[u32],
        t0: Instant,
        report: &mut SolveReport,
    ) -> Option<(Result<SolveStats, NotConverged>, Duration)> {
        let (tol, max_iter) = (self.tolerance, self.max_iterations);
        let last = self.last_iterations;
        let mut row_ids: Vec<u32> = sys.particle_of.iter().map(|&i| ids[i as usize]).collect();
        let healthy =
            |c: &AmgCache| c.age < AMG_MAX_AGE && 2 * last <= 3 * c.setup_iterations.max(4);
        if let Some(c) = self.amg.as_mut().filter(|c| healthy(c)) {
            let reused = if c.ids == row_ids {
                c.amg.refresh_fine(&sys.matrix);
                true
            } else {
                let from: Vec<u32> = row_ids
                    .iter()
                    .map(|&id| c.row_of_id.get(id as usize).copied().unwrap_or(NONE))
                    .collect();
                let kept = from.iter().filter(|&&o| o != NONE).count();
                let changed = (row_ids.len() - kept) + (c.ids.len() - kept);
                let small = changed as f64 <= AMG_MAX_CHANGED_SHARE * row_ids.len() as f64;
                if small {
                    c.amg.remap_fine(&sys.matrix, &from);
                    c.rekey(std::mem::take(&mut row_ids));
                }
                small
            };
            if reused {
                c.age += 1;
                report.setup = t0.elapsed();
                return Some(timed_pcg(sys, x, &c.amg, tol, max_iter));
            }
        }
        self.amg = None;
        let amg = Amg::new(&sys.matrix, AmgParams::for_dimension(self.dimension))?;
        report.setup = t0.elapsed();
        let (r, solve) = timed_pcg(sys, x, &amg, tol, max_iter);
        if let Ok(st) = r {
            let mut cache = AmgCache {
                ids: Vec::new(),
                row_of_id: Vec::new(),
                amg,
                setup_iterations: st.iterations,
                age: 0,
            };
            cache.rekey(row_ids);
            self.amg = Some(cache);
        }
        Some((r, solve))
    }
}

impl AmgCache {
    /// Makes `ids` (row -> particle id) the hierarchy's unknowns.
    fn rekey(&mut self, ids: Vec<u32>) {
        for &id in &self.ids {
            self.row_of_id[id as usize] = NONE;
        }
        let top = ids.iter().map(|&id| id as usize + 1).max().unwrap_or(0);
        if self.row_of_id.len() < top {
            self.row_of_id.resize(top, NONE);
        }
        for (k, &id) in ids.iter().enumerate() {
            self.row_of_id[id as usize] = k as u32;
        }
        self.ids = ids;
    }
}
