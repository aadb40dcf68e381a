//! The pressure solver: owns the solver choice, the preconditioner, the kept AMG hierarchy
//! and its reuse policy, and counts preconditioner fall-backs (an AMG or IC(0) set-up that
//! fails falls back to Jacobi; every such step is reported, never silent).

use crate::input::case::SolverSpec;
use crate::linalg::{
    dilu_cg_in, pcg_in, twisted_cg_in, Amg, AmgParams, CgVectors, Dilu, DiluCgVectors, Ic0,
    Identity, Jacobi, Mic0Scratch, NotConverged, SolveStats, Twisted, TwistedCgVectors, TwistedPre,
    DILU_OMEGA, MIC_OMEGA, NEW_ROW,
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

/// Steps a MIC(0) factor is carried over to later systems whose unknowns are the same
/// particles or nearly so (docs/decisions.md, "MIC(0) carried over").
const MIC_MAX_AGE: u32 = 10;

/// The particle ids of a kept preconditioner's unknowns.
#[derive(Debug, Default)]
struct RowKeys {
    /// The particle ids of its unknowns (row -> id).
    ids: Vec<u32>,
    /// Its row of each particle id ([`NONE`] for none).
    row_of_id: Vec<u32>,
}

impl RowKeys {
    /// Makes `ids` (row -> particle id) the kept unknowns.
    fn rekey(&mut self, ids: &[u32]) {
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
        self.ids.clear();
        self.ids.extend_from_slice(ids);
    }

    /// The kept row of each of `row_ids`' particles ([`NONE`] for a new one) into `from`,
    /// and how many rows joined or left.
    fn map_into(&self, row_ids: &[u32], from: &mut Vec<u32>) -> usize {
        from.clear();
        from.extend(
            row_ids
                .iter()
                .map(|&id| self.row_of_id.get(id as usize).copied().unwrap_or(NONE)),
        );
        let kept = from.iter().filter(|&&o| o != NONE).count();
        (row_ids.len() - kept) + (self.ids.len() - kept)
    }
}

/// A MIC(0) factor kept from an earlier step, with its unknowns.
#[derive(Debug, Default)]
struct MicCache {
    keys: RowKeys,
    /// CG iterations of the solve right after its set-up.
    setup_iterations: usize,
    /// Steps it has been carried over.
    age: u32,
    /// Whether `PressureSolver::mic` holds a factor of `keys`' unknowns.
    valid: bool,
    /// Set-ups so far (tells a step that failed after a set-up from one that did not).
    generation: u64,
    /// The factor's row of each row of the current system (the carried map's memory).
    from: Vec<u32>,
    /// The current system's row ids (memory kept between steps).
    row_ids: Vec<u32>,
}

/// What one solve is asked: the system, every particle's id (by particle index), the
/// relative residual to reach and when the solve began.
#[derive(Clone, Copy)]
struct Task<'a> {
    sys: &'a PressureSystem,
    ids: &'a [u32],
    tol: f64,
    t0: Instant,
}

/// [`MicCache`]'s bookkeeping after the last step that succeeded.
#[derive(Clone, Copy, Debug, Default)]
struct Committed {
    valid: bool,
    generation: u64,
    age: u32,
    setup_iterations: usize,
    last_iterations: usize,
}

/// An AMG hierarchy kept from an earlier step.
#[derive(Debug)]
struct AmgCache {
    /// The particle ids of its unknowns.
    keys: RowKeys,
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
    max_iterations: usize,
    amg: Option<AmgCache>,
    /// The last MIC(0) factor and its set-up's scratch, whose memory the next set-up uses.
    mic: Twisted,
    cg_twisted: TwistedCgVectors,
    mic_scratch: Mic0Scratch,
    /// What the last factor was built for, so it can be carried over.
    mic_cache: MicCache,
    /// The carried factor's bookkeeping as it stood after the last step that succeeded.
    committed: Committed,
    /// CG's work vectors.
    cg: CgVectors,
    /// The last D-ILU preconditioner and its CG's work vectors, whose memory the next uses.
    dilu: Dilu,
    dilu_cg: DiluCgVectors,
    last_iterations: usize,
    /// Steps whose preconditioner fell back to Jacobi.
    pub fallbacks: u64,
}

/// The relative residual `|b - A p| / |b|` a PPE is solved to: `tol`, or the looser value at
/// which the residual's volume error over a step `dt` (s), `dt^2 RMS(b - A p)`
/// (dimensionless: the relative volume change the residual leaves a particle, `b` in 1/s^2),
/// falls below `volume` (docs/decisions.md, "PPE stopping rule"). `bnorm`: `|b|` over the
/// `rows` unknowns; `volume` 0 (off) or a zero right-hand side give `tol`. At most 0.5.
pub fn stopping_tolerance(tol: f64, volume: f64, bnorm: f64, rows: f64, dt: f64) -> f64 {
    if !(volume > 0.0 && bnorm > 0.0 && dt > 0.0) {
        return tol;
    }
    // |b - A p| <= volume sqrt(rows) / dt^2, as a fraction of |b|.
    let loose = volume * rows.sqrt() / (dt * dt * bnorm);
    tol.max(loose.min(0.5))
}

/// Threads that solve a MIC(0) system together ([`twisted_cg_in`]).
const MIC_TEAM: usize = 2;

/// Runs the twisted MIC(0)-CG from `x` with `pre`, timing it.
fn timed_twisted(
    sys: &PressureSystem,
    x: &mut [f64],
    pre: TwistedPre,
    (tol, max_iter): (f64, usize),
    work: &mut TwistedCgVectors,
) -> (Result<SolveStats, NotConverged>, Duration) {
    let t = Instant::now();
    let lim = (tol, max_iter, MIC_TEAM);
    let r = twisted_cg_in(&sys.matrix, &sys.rhs, x, pre, lim, work);
    (r, t.elapsed())
}

/// Runs PCG from `x` with preconditioner `m`, timing it.
fn timed_pcg(
    sys: &PressureSystem,
    x: &mut [f64],
    m: &(impl Precondition + ?Sized),
    (tol, max_iter): (f64, usize),
    work: &mut CgVectors,
) -> (Result<SolveStats, NotConverged>, Duration) {
    let t = Instant::now();
    let r = pcg_in(&sys.matrix, &sys.rhs, x, m, (tol, max_iter), work);
    (r, t.elapsed())
}

impl PressureSolver {
    /// A solver as the case's `[solver]` table asks, for a run in `dimension` 2 or 3.
    pub fn new(spec: &SolverSpec, dimension: usize) -> Self {
        PressureSolver {
            kind: spec.kind,
            dimension,
            max_iterations: spec.max_iterations,
            amg: None,
            mic: Twisted::default(),
            cg_twisted: TwistedCgVectors::default(),
            mic_scratch: Mic0Scratch::default(),
            mic_cache: MicCache::default(),
            committed: Committed::default(),
            cg: CgVectors::default(),
            dilu: Dilu::default(),
            dilu_cg: DiluCgVectors::default(),
            last_iterations: 0,
            fallbacks: 0,
        }
    }

    /// Drops any kept set-up, so the next solve builds it afresh (at checkpoints, so a
    /// restarted run continues bit-identically).
    pub fn reset(&mut self) {
        self.amg = None;
        self.mic_cache.valid = false;
        self.committed.valid = false;
    }

    /// The step that used the last solve succeeded: what it decided stands.
    pub fn commit(&mut self) {
        let c = &self.mic_cache;
        self.committed = Committed {
            valid: c.valid,
            generation: c.generation,
            age: c.age,
            setup_iterations: c.setup_iterations,
            last_iterations: self.last_iterations,
        };
    }

    /// The step that used the last solve failed: its retry decides as the failed try did
    /// (set up afresh if the failed try did), so a run that recovers from a failed step
    /// goes on as if the step had not been tried.
    pub fn rollback(&mut self) {
        let k = self.committed;
        let c = &mut self.mic_cache;
        c.valid = k.valid && k.generation == c.generation;
        c.age = k.age;
        c.setup_iterations = k.setup_iterations;
        self.last_iterations = k.last_iterations;
    }

    /// Solves `sys` from the warm start `x` to the relative residual `tol`; on success `x`
    /// holds the solution. `ids` holds every particle's id (by particle index), which a kept
    /// AMG hierarchy is keyed on.
    pub fn solve(
        &mut self,
        sys: &PressureSystem,
        x: &mut [f64],
        ids: &[u32],
        tol: f64,
    ) -> (Result<SolveStats, NotConverged>, SolveReport) {
        let t0 = Instant::now();
        let task = Task { sys, ids, tol, t0 };
        let max_iter = self.max_iterations;
        let mut report = SolveReport::default();
        // `None`: the chosen preconditioner could not be built.
        let attempt = match self.kind.for_size(sys.matrix.n(), self.dimension) {
            SolverKind::AmgCg => self.solve_amg(task, x, &mut report),
            SolverKind::Ic0Cg => Ic0::new(&sys.matrix).map(|f| {
                report.setup = t0.elapsed();
                timed_pcg(sys, x, &f, (tol, max_iter), &mut self.cg)
            }),
            // Modified IC(0); where a relaxed pivot is not positive, plain IC(0).
            SolverKind::Mic0Cg => Some(self.solve_mic(task, x, &mut report)),
            // Modified D-ILU; where a relaxed pivot is not positive, plain D-ILU.
            SolverKind::DiluCg => {
                // Set up in the last preconditioner's memory.
                let m = &mut self.dilu;
                let (a, team) = (&sys.matrix, MIC_TEAM);
                let ok = m.rebuild_on(a, DILU_OMEGA, team) || m.rebuild_on(a, 0.0, team);
                ok.then(|| {
                    report.setup = t0.elapsed();
                    let t = Instant::now();
                    let (a, b, w) = (&sys.matrix, &sys.rhs, &mut self.dilu_cg);
                    let r = dilu_cg_in(a, b, x, &self.dilu, (tol, max_iter, MIC_TEAM), w);
                    (r, t.elapsed())
                })
            }
            SolverKind::Cg => {
                report.setup = t0.elapsed();
                Some(timed_pcg(sys, x, &Identity, (tol, max_iter), &mut self.cg))
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
            timed_pcg(sys, x, &pre, (tol, max_iter), &mut self.cg)
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

    /// MIC(0)-CG: carry the last factor over while it still converges nearly as fast as
    /// right after its set-up and the unknowns are the same particles, or nearly so;
    /// otherwise set up afresh (in the last factor's memory), plain IC(0) where a relaxed
    /// pivot is not positive, Jacobi where neither can be built.
    fn solve_mic(
        &mut self,
        task: Task,
        x: &mut [f64],
        report: &mut SolveReport,
    ) -> (Result<SolveStats, NotConverged>, Duration) {
        let Task { sys, ids, tol, t0 } = task;
        let max_iter = self.max_iterations;
        let c = &mut self.mic_cache;
        c.row_ids.clear();
        c.row_ids
            .extend(sys.particle_of.iter().map(|&i| ids[i as usize]));
        let healthy = c.valid
            && c.age < MIC_MAX_AGE
            && 2 * self.last_iterations <= 3 * c.setup_iterations.max(4);
        if healthy {
            let changed = c.keys.map_into(&c.row_ids, &mut c.from);
            if changed as f64 <= AMG_MAX_CHANGED_SHARE * c.row_ids.len() as f64 {
                c.age += 1;
                report.setup = t0.elapsed();
                let same = changed == 0 && c.from.iter().enumerate().all(|(k, &o)| o as usize == k);
                c.from
                    .iter_mut()
                    .filter(|o| **o == NONE)
                    .for_each(|o| *o = NEW_ROW);
                let pre = TwistedPre {
                    factor: &self.mic,
                    // The same unknowns in the same order: the factor as it is.
                    from: (!same).then_some(&c.from[..]),
                };
                return timed_twisted(sys, x, pre, (tol, max_iter), &mut self.cg_twisted);
            }
        }
        // Set up in the last factor's memory.
        let built = self
            .mic
            .rebuild(&sys.matrix, MIC_OMEGA, &mut self.mic_scratch);
        let c = &mut self.mic_cache;
        c.valid = false;
        c.generation += 1;
        if !built {
            self.fallbacks += 1;
            report.fallback = true;
            let pre = Jacobi::new(&sys.matrix);
            report.setup = t0.elapsed();
            return timed_pcg(sys, x, &pre, (tol, max_iter), &mut self.cg);
        }
        report.setup = t0.elapsed();
        let pre = TwistedPre {
            factor: &self.mic,
            from: None,
        };
        let solved = timed_twisted(sys, x, pre, (tol, max_iter), &mut self.cg_twisted);
        if let Ok(st) = &solved.0 {
            c.keys.rekey(&c.row_ids);
            c.setup_iterations = st.iterations;
            c.age = 0;
            c.valid = true;
        }
        solved
    }

    /// AMG-CG: reuse the kept hierarchy while it still converges nearly as fast as right
    /// after its set-up and its unknowns are the same particles, or nearly so (their rows
    /// carried over by particle id); rebuild otherwise.
    fn solve_amg(
        &mut self,
        task: Task,
        x: &mut [f64],
        report: &mut SolveReport,
    ) -> Option<(Result<SolveStats, NotConverged>, Duration)> {
        let Task { sys, ids, tol, t0 } = task;
        let max_iter = self.max_iterations;
        let last = self.last_iterations;
        let row_ids: Vec<u32> = sys.particle_of.iter().map(|&i| ids[i as usize]).collect();
        let healthy =
            |c: &AmgCache| c.age < AMG_MAX_AGE && 2 * last <= 3 * c.setup_iterations.max(4);
        if let Some(c) = self.amg.as_mut().filter(|c| healthy(c)) {
            let reused = if c.keys.ids == row_ids {
                c.amg.refresh_fine(&sys.matrix);
                true
            } else {
                let mut from = Vec::new();
                let changed = c.keys.map_into(&row_ids, &mut from);
                let small = changed as f64 <= AMG_MAX_CHANGED_SHARE * row_ids.len() as f64;
                if small {
                    c.amg.remap_fine(&sys.matrix, &from);
                    c.keys.rekey(&row_ids);
                }
                small
            };
            if reused {
                c.age += 1;
                report.setup = t0.elapsed();
                return Some(timed_pcg(sys, x, &c.amg, (tol, max_iter), &mut self.cg));
            }
        }
        self.amg = None;
        let amg = Amg::new(&sys.matrix, AmgParams::for_dimension(self.dimension))?;
        report.setup = t0.elapsed();
        let (r, solve) = timed_pcg(sys, x, &amg, (tol, max_iter), &mut self.cg);
        if let Ok(st) = r {
            let mut cache = AmgCache {
                keys: RowKeys::default(),
                amg,
                setup_iterations: st.iterations,
                age: 0,
            };
            cache.keys.rekey(&row_ids);
            self.amg = Some(cache);
        }
        Some((r, solve))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{pcg, CsrMatrix};

    /// An MPS-like 2D Laplacian (unit coefficients on the 8 nearest lattice neighbours plus a
    /// small diagonal shift, `m x m` unknowns) and a right-hand side of a relative density
    /// error of about 3e-3 per step of `dt` (1/s^2), as measured on the dam break.
    fn system(m: usize, dt: f64) -> (CsrMatrix, Vec<f64>) {
        let a = CsrMatrix::from_rows((0..m * m).map(|i| {
            let (x, y) = ((i % m) as i64, (i / m) as i64);
            let mut row = vec![(i as u32, 8.5)];
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (u, v) = (x + dx, y + dy);
                    if (dx, dy) != (0, 0)
                        && (0..m as i64).contains(&u)
                        && (0..m as i64).contains(&v)
                    {
                        row.push(((v * m as i64 + u) as u32, -1.0));
                    }
                }
            }
            row.sort_by_key(|e| e.0);
            row
        }));
        let b = (0..m * m)
            .map(|i| 3e-3 * ((i as f64 * 0.7).sin() + 0.2) / (dt * dt))
            .collect();
        (a, b)
    }

    /// The rule loosens the relative tolerance exactly to where the residual's volume error
    /// `dt^2 RMS(r)` meets `volume`, is never tighter than `tol`, and is off at 0; a solve to
    /// it leaves at most that volume error and takes fewer iterations than one to 1e-8.
    #[test]
    fn the_volume_rule_bounds_the_residual_volume_error() {
        let (m, dt) = (40, 2e-4);
        let (a, b) = system(m, dt);
        let n = (m * m) as f64;
        let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert_eq!(stopping_tolerance(1e-8, 0.0, bnorm, n, dt), 1e-8);
        assert_eq!(stopping_tolerance(1e-8, 1e-6, 0.0, n, dt), 1e-8);
        assert_eq!(stopping_tolerance(1e-2, 1e-12, bnorm, n, dt), 1e-2);
        let volume = 1e-7;
        let tol = stopping_tolerance(1e-8, volume, bnorm, n, dt);
        let rms_b = bnorm / n.sqrt();
        assert!((tol * rms_b * dt * dt - volume).abs() < 1e-12 * volume.max(1.0));
        let solve = |tol: f64| {
            let mut x = vec![0.0; m * m];
            let s = pcg(&a, &b, &mut x, &Jacobi::new(&a), tol, 10_000).unwrap();
            let mut r = vec![0.0; m * m];
            a.spmv(&x, &mut r);
            let rms = (r
                .iter()
                .zip(&b)
                .map(|(ax, bi)| (bi - ax).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
            (s.iterations, rms * dt * dt)
        };
        let (loose_it, loose_volume) = solve(tol);
        let (tight_it, tight_volume) = solve(1e-8);
        assert!(loose_volume <= volume, "{loose_volume} > {volume}");
        assert!(tight_volume < loose_volume);
        assert!(loose_it < tight_it, "{loose_it} vs {tight_it}");
    }
}
