//! The semi-implicit MPS time step (equations.md section 5), calling each stage in order:
//! neighbours -> explicit forces -> number density and free surface -> PPE -> pressure
//! gradient and stabilization -> correction -> breakdown checks.

use crate::amg::{Amg, AmgParams};
use crate::case::{Case, CaseError, GradientModel, SolverKind, WallPressure};
use crate::fields::{Fields, Kernels};
use crate::gradient::{p_hat, pressure_acceleration};
use crate::kernel::weight;
use crate::linsolve::{pcg, Ic0, Preconditioner, SolveStats};
use crate::neighbors::{build_neighbor_list, locality_order, NeighborList};
use crate::operators::{laplacian_vector, number_density};
use crate::particles::{Kind, Particles, NONE};
use crate::ppe::assemble;
use crate::scheme::Scheme;
use crate::stabilization::ds_acceleration;
use crate::vector::Vector;
use crate::walls::extrapolated_pressure;
use rayon::prelude::*;
use std::fmt;
use std::time::{Duration, Instant};

/// Steps between reorderings of the particles along the cell list.
const REORDER_EVERY: u64 = 20;

/// Wall-clock time spent in each stage of the step.
#[derive(Clone, Copy, Debug, Default)]
pub struct Timers {
    /// Neighbour search and reordering.
    pub neighbors: Duration,
    /// Viscosity, gravity and the collision model.
    pub explicit: Duration,
    /// Number density, free surface, wall densities.
    pub density_surface: Duration,
    /// PPE assembly.
    pub ppe_assembly: Duration,
    /// Preconditioner set-up (IC(0) factorisation, AMG hierarchy).
    pub ppe_setup: Duration,
    /// CG iterations.
    pub ppe_solve: Duration,
    /// Pressure gradient and DS.
    pub gradient: Duration,
    /// Velocity/position correction and breakdown checks.
    pub correction: Duration,
}

impl Timers {
    /// Sum of all stages.
    pub fn total(&self) -> Duration {
        self.neighbors
            + self.explicit
            + self.density_surface
            + self.ppe_assembly
            + self.ppe_setup
            + self.ppe_solve
            + self.gradient
            + self.correction
    }
    /// (name, duration) of each stage, in step order.
    pub fn stages(&self) -> [(&'static str, Duration); 8] {
        [
            ("neighbour search", self.neighbors),
            ("explicit forces", self.explicit),
            ("number density + surface", self.density_surface),
            ("PPE assembly", self.ppe_assembly),
            ("PPE solver set-up", self.ppe_setup),
            ("PPE solve", self.ppe_solve),
            ("pressure gradient + DS", self.gradient),
            ("correction + checks", self.correction),
        ]
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepReport {
    /// Time step used (s).
    pub dt: f64,
    /// PPE unknowns.
    pub unknowns: usize,
    /// PPE solver statistics.
    pub solve: SolveStats,
    /// DS-active pairs.
    pub ds_active: u64,
    /// Smallest distance between a fluid particle and any neighbour (m).
    pub min_pair_distance: f64,
    /// Pairs closer than 0.9 l0.
    pub close_pairs: u64,
    /// Largest fluid speed after the step (m/s).
    pub max_speed: f64,
    /// Pairs treated by the collision model.
    pub collisions: u64,
}

/// Why a run broke down (cases.md, "Breakdown").
#[derive(Clone, Debug, PartialEq)]
pub enum BreakdownReason {
    /// A NaN or infinity appeared.
    NotFinite,
    /// The PPE solver did not converge.
    SolverDiverged {
        /// Iterations taken.
        iterations: usize,
        /// Relative residual reached.
        residual: f64,
    },
    /// A particle left the domain.
    LeftDomain,
    /// Two particles came closer than the stated fraction of l0.
    Penetration {
        /// Closest distance / l0.
        distance_l0: f64,
    },
    /// The largest speed passed its bound.
    SpeedBlowUp {
        /// Speed reached (m/s).
        speed: f64,
        /// Bound (m/s).
        bound: f64,
    },
    /// The Courant time step fell below its floor.
    TimeStepCollapse {
        /// The step the Courant limit asked for (s).
        dt: f64,
    },
}

/// A breakdown: when, why, and which particles (ids) were involved.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakdown {
    /// Simulated time of the last good state (s).
    pub time: f64,
    /// Step number that failed.
    pub step: u64,
    /// The reason.
    pub reason: BreakdownReason,
    /// Ids of the particles involved (at most a few).
    pub particles: Vec<u32>,
}

impl fmt::Display for Breakdown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let why = match &self.reason {
            BreakdownReason::NotFinite => "NaN or infinity in the particle state".to_string(),
            BreakdownReason::SolverDiverged {
                iterations,
                residual,
            } => format!(
                "pressure solver did not converge ({iterations} iterations, residual {residual:.2e})"
            ),
            BreakdownReason::LeftDomain => "a particle left the domain".to_string(),
            BreakdownReason::Penetration { distance_l0 } => {
                format!("particles interpenetrated (pair at {distance_l0:.3} l0)")
            }
            BreakdownReason::SpeedBlowUp { speed, bound } => {
                format!("speed blew up ({speed:.3e} m/s > bound {bound:.3e} m/s)")
            }
            BreakdownReason::TimeStepCollapse { dt } => {
                format!("time step collapsed (dt = {dt:.3e} s)")
            }
        };
        write!(
            f,
            "breakdown at t = {:.6} s (step {}): {why}",
            self.time, self.step
        )
    }
}

/// A running simulation: the particles, the resolved scheme and everything the step needs.
pub struct Simulation<const D: usize> {
    /// The case it was built from.
    pub case: Case,
    /// The particles.
    pub particles: Particles<D>,
    /// The resolved scheme.
    pub scheme: Scheme,
    /// Kernel constants and spacing.
    pub kernels: Kernels,
    /// Gravity (m/s^2).
    pub gravity: Vector<D>,
    /// Kinematic viscosity per phase (m^2/s).
    pub phase_viscosity: Vec<f64>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step_count: u64,
    /// Largest time step (s).
    pub dt_max: f64,
    /// Speed above which the run counts as blown up (m/s).
    pub max_speed_bound: f64,
    /// Time per stage.
    pub timers: Timers,
    /// Report of the last step.
    pub last: StepReport,
    /// Keep each step's assembled PPE in `last_system` (for benchmarks and solver tests).
    pub keep_system: bool,
    /// The PPE of the last step, when `keep_system` is set.
    pub last_system: Option<crate::ppe::PressureSystem>,
    neighbors: NeighborList,
    skin: f64,
    amg_cache: Option<AmgCache>,
}

/// An AMG hierarchy kept from an earlier step and the rule for reusing it.
#[derive(Debug)]
struct AmgCache {
    /// The unknowns it was built for (row -> particle).
    particle_of: Vec<u32>,
    /// The hierarchy.
    amg: Amg,
    /// CG iterations of the solve right after the set-up.
    setup_iterations: usize,
    /// Steps it has been reused.
    age: u32,
}

/// Steps an AMG hierarchy may be reused for when the unknowns are unchanged.
const AMG_MAX_AGE: u32 = 10;

impl<const D: usize> Simulation<D> {
    /// Builds the particles of `case` and prepares the run; `label` names the case in errors.
    pub fn new(case: Case, label: &str) -> Result<Self, CaseError> {
        let particles = crate::setup::build_particles::<D>(&case, label)?;
        let mut scheme = Scheme::from_spec(&case.scheme).map_err(|e| CaseError {
            file: label.into(),
            field: e.0,
            value: e.1,
            message: e.2,
        })?;
        // Paper Eq. 9: alpha_DS + alpha_dt = 1, alpha_dt the Courant number of the time
        // step, so a pair is treated once it closes by more than one step's travel. Applies
        // when the case gives no threshold and the step follows the Courant condition.
        if let Some(ds) = scheme.ds.as_mut() {
            if case.scheme.ds.alpha.is_none() && case.time.dt_fixed.is_none() {
                ds.alpha = (1.0 - case.time.courant).clamp(0.5, 0.99);
            }
        }
        let l0 = case.particles.spacing;
        let kernels = Kernels::new::<D>(l0, case.particles.re_grad, case.particles.re_lap);
        let gravity = Vector::from_slice(&case.physics.gravity).expect("validated");
        let g = gravity.norm();
        let mut u0 = 0.0f64;
        let (mut ylo, mut yhi) = (f64::MAX, f64::MIN);
        for i in 0..particles.len() {
            if particles.kind[i] == Kind::Fluid {
                u0 = u0.max(particles.velocity[i].norm());
                ylo = ylo.min(particles.position[i][D - 1]);
                yhi = yhi.max(particles.position[i][D - 1]);
            }
        }
        let u_scale = u0.max((2.0 * g * (yhi - ylo + l0)).sqrt());
        let courant = case.time.courant;
        let dt_max = match (case.time.dt_fixed, case.time.dt_max) {
            (Some(f), _) => f,
            (None, Some(m)) => m,
            (None, None) if g > 0.0 => courant * (l0 / g).sqrt(),
            (None, None) if u0 > 0.0 => courant * l0 / u0,
            _ => {
                return Err(CaseError {
                    file: label.into(),
                    field: "time.dt_max".into(),
                    value: String::new(),
                    message: "needed: no gravity and no initial velocity give no time scale".into(),
                })
            }
        };
        let max_speed_bound = case.breakdown.max_speed.unwrap_or(if u_scale > 0.0 {
            50.0 * u_scale
        } else {
            f64::INFINITY
        });
        let phase_viscosity = case.phases.iter().map(|p| p.viscosity).collect();
        let mut sim = Simulation {
            case,
            particles,
            scheme,
            kernels,
            gravity,
            phase_viscosity,
            time: 0.0,
            step_count: 0,
            dt_max,
            max_speed_bound,
            timers: Timers::default(),
            last: StepReport::default(),
            neighbors: NeighborList::default(),
            skin: 0.3 * l0,
            amg_cache: None,
            keep_system: false,
            last_system: None,
        };
        sim.reorder();
        sim.refresh_diagnostic_fields();
        Ok(sim)
    }

    /// Particle spacing `l0` (m).
    pub fn l0(&self) -> f64 {
        self.kernels.l0
    }

    fn cutoff(&self) -> f64 {
        self.kernels.grad.re.max(self.kernels.lap.re) + self.skin
    }

    /// Drops any kept solver set-up (the AMG hierarchy), so the next step builds it afresh;
    /// called where a checkpoint is written, so a restarted run continues bit-identically.
    pub fn reset_solver_cache(&mut self) {
        self.amg_cache = None;
    }

    fn reorder(&mut self) {
        let order = locality_order(&self.particles.position, self.cutoff());
        self.particles.permute(&order);
    }

    /// Rebuilds the neighbour lists at the current positions (after a restore).
    pub fn rebuild_neighbors(&mut self) {
        self.neighbors = build_neighbor_list(&self.particles.position, self.cutoff());
    }

    /// Recomputes number density, free-surface flags and wall pressures at the current
    /// positions (for output of the initial state and after a restart).
    pub fn refresh_diagnostic_fields(&mut self) {
        self.neighbors = build_neighbor_list(&self.particles.position, self.cutoff());
        let (nd, fs) = self.density_and_surface(&self.particles.position.clone());
        self.particles.number_density = nd;
        self.particles.free_surface = fs;
        if self.scheme.wall_pressure == WallPressure::Extrapolated {
            let f = self.fields();
            let re = self.kernels.lap.re;
            let p = &self.particles;
            let walls: Vec<(usize, f64)> = (0..p.len())
                .filter(|&i| p.kind[i] != Kind::Fluid)
                .map(|i| {
                    let v = extrapolated_pressure(i, &f, &p.pressure, self.gravity, re);
                    (i, v.unwrap_or(0.0).max(0.0))
                })
                .collect();
            for (i, v) in walls {
                self.particles.pressure[i] = v;
            }
        }
    }

    /// The time step (s): fixed, or `min(dt_max, C l0 / u_max, 0.1 l0^2 / nu)`.
    /// Returns (step to take, Courant step before clamping to `until`).
    fn time_step(&self, until: f64) -> (f64, f64) {
        let c = &self.case.time;
        let dt = if let Some(f) = c.dt_fixed {
            f
        } else {
            let p = &self.particles;
            let umax = (0..p.len())
                .into_par_iter()
                .filter(|&i| p.kind[i] == Kind::Fluid)
                .map(|i| p.velocity[i].norm())
                .reduce(|| 0.0, f64::max);
            let l0 = self.l0();
            let mut dt = self.dt_max;
            if umax > 0.0 {
                dt = dt.min(c.courant * l0 / umax);
            }
            let nu = self.phase_viscosity.iter().cloned().fold(0.0, f64::max);
            if nu > 0.0 {
                dt = dt.min(0.1 * l0 * l0 / nu);
            }
            dt
        };
        let remaining = until - self.time;
        // Land exactly on `until` (the end time) without a sliver of a last step: the drift
        // term of the source scales as 1/dt^2, so a step of 1e-3 dt kicked every particle
        // (the RMS speed of the settling case at its end time came out 1.4x, its
        // particle-scale velocity noise 3.7x). The last two steps share what is left.
        let step = if remaining < dt * 1.000_001 {
            remaining.max(dt * 1e-6)
        } else if remaining < 2.0 * dt {
            0.5 * remaining
        } else {
            dt
        };
        (step, dt)
    }

    /// Number density at re_grad and free-surface flags at positions `pos`.
    fn density_and_surface(&self, pos: &[Vector<D>]) -> (Vec<f64>, Vec<bool>) {
        let k = &self.kernels;
        let s = &self.scheme;
        let kind = &self.particles.kind;
        let nl = &self.neighbors;
        let n0 = k.grad.n0;
        let count_floor = s
            .surface_count_ratio
            .map(|r| r * k.grad.neighbours as f64)
            .unwrap_or(0.0);
        (0..pos.len())
            .into_par_iter()
            .map(|i| {
                let nd = number_density(i, pos, nl.of(i), k.grad.re);
                let tested = match kind[i] {
                    Kind::Fluid => true,
                    Kind::Wall => s.wall_surface_test,
                    Kind::Dummy => false,
                };
                let surface = tested
                    && (nd < s.surface_beta * n0
                        || (count_floor > 0.0 && {
                            let re2 = k.grad.re * k.grad.re;
                            let c = nl
                                .of(i)
                                .iter()
                                .filter(|&&j| (pos[j as usize] - pos[i]).norm2() < re2)
                                .count();
                            (c as f64) < count_floor
                        }));
                (nd, surface)
            })
            .unzip()
    }

    /// Advances one step, stopping at `until` (s) if it comes first. On breakdown the
    /// particles are restored to the last good state and the reason is returned.
    pub fn step(&mut self, until: f64) -> Result<StepReport, Breakdown> {
        let backup = self.particles.clone();
        match self.advance(until) {
            Ok(r) => {
                self.last = r;
                self.step_count += 1;
                self.time += r.dt;
                Ok(r)
            }
            Err((reason, ids)) => {
                self.particles = backup;
                Err(Breakdown {
                    time: self.time,
                    step: self.step_count + 1,
                    reason,
                    particles: ids,
                })
            }
        }
    }

    #[allow(clippy::type_complexity)]
    fn advance(&mut self, until: f64) -> Result<StepReport, (BreakdownReason, Vec<u32>)> {
        let (dt, dt_courant) = self.time_step(until);
        if dt_courant < self.case.breakdown.min_dt_ratio * self.dt_max {
            return Err((BreakdownReason::TimeStepCollapse { dt: dt_courant }, vec![]));
        }
        let l0 = self.l0();
        let mut report = StepReport {
            dt,
            ..Default::default()
        };

        // 1. Neighbours at r^n (with a skin), reordering for locality now and then.
        let t0 = Instant::now();
        if self.step_count.is_multiple_of(REORDER_EVERY) {
            self.reorder();
        }
        // The old list goes first, so the two never coexist (peak memory).
        self.neighbors = NeighborList::default();
        self.neighbors = build_neighbor_list(&self.particles.position, self.cutoff());
        self.timers.neighbors += t0.elapsed();

        // 2. Explicit forces: u* = u + dt (nu lap u + g), r* = r + dt u*.
        let t0 = Instant::now();
        let (mut vel, mut pos) = self.explicit_stage(dt);
        self.timers.explicit += t0.elapsed();
        let max_move = (0..pos.len())
            .into_par_iter()
            .map(|i| (pos[i] - self.particles.position[i]).norm())
            .reduce(|| 0.0, f64::max);
        if !max_move.is_finite() {
            return Err((BreakdownReason::NotFinite, vec![]));
        }
        if 2.0 * max_move > self.skin {
            let t0 = Instant::now();
            self.neighbors = NeighborList::default();
            self.neighbors = build_neighbor_list(&pos, self.cutoff());
            self.timers.neighbors += t0.elapsed();
        }

        // 2b. Optional collision model.
        if let Some(col) = self.scheme.collision {
            let t0 = Instant::now();
            let (v, n) = self.collision_stage(&pos, &vel, col.alpha * l0, col.restitution);
            for i in 0..pos.len() {
                pos[i] += (v[i] - vel[i]) * dt;
            }
            vel = v;
            report.collisions = n;
            self.timers.explicit += t0.elapsed();
        }

        // 3. Number density n*, free surface, densities of wall and dummy particles.
        let t0 = Instant::now();
        let (nd, surface) = self.density_and_surface(&pos);
        self.update_wall_density(&pos);
        self.timers.density_surface += t0.elapsed();

        let p = &self.particles;
        let f = Fields {
            pos: &pos,
            vel: &vel,
            kind: &p.kind,
            density: &p.density,
            free_surface: &surface,
            number_density: &nd,
            neighbors: &self.neighbors,
        };

        // Optional density smoothing for the PPE coefficient and the gradient (s.7).
        let smoothed: Vec<f64> = if self.scheme.density_smoothing {
            let re = self.kernels.grad.re;
            let n0 = self.kernels.grad.n0;
            (0..pos.len())
                .into_par_iter()
                .map(|i| {
                    let (mut sw, mut swr) = (n0, n0 * p.density[i]);
                    for &j in self.neighbors.of(i) {
                        let j = j as usize;
                        if p.kind[j] != Kind::Dummy {
                            let w = weight((pos[j] - pos[i]).norm(), re);
                            sw += w;
                            swr += w * p.density[j];
                        }
                    }
                    swr / sw
                })
                .collect()
        } else {
            Vec::new()
        };
        let fc = if smoothed.is_empty() {
            f
        } else {
            Fields {
                density: &smoothed,
                ..f
            }
        };

        // 4. Pressure Poisson equation.
        let t0 = Instant::now();
        let sys = assemble(&fc, &self.kernels, &self.scheme, self.gravity, dt);
        report.unknowns = sys.particle_of.len();
        self.timers.ppe_assembly += t0.elapsed();
        let t0 = Instant::now();
        let mut x: Vec<f64> = sys
            .particle_of
            .iter()
            .map(|&i| p.pressure[i as usize])
            .collect();
        let tol = self.case.solver.tolerance;
        let max_iter = self.case.solver.max_iterations;
        let jacobi = |m: &crate::linsolve::CsrMatrix| {
            Preconditioner::Jacobi(m.diagonal().iter().map(|d| 1.0 / d).collect())
        };
        let kind = match self.case.solver.kind {
            SolverKind::Auto if sys.matrix.n() >= crate::case::AUTO_AMG_UNKNOWNS => {
                SolverKind::AmgCg
            }
            SolverKind::Auto => SolverKind::Ic0Cg,
            k => k,
        };
        let solve = match kind {
            SolverKind::AmgCg => {
                // Reuse the hierarchy while the unknowns are the same particles and it still
                // converges as fast as right after its set-up; rebuild otherwise.
                let reusable = self.amg_cache.as_ref().is_some_and(|c| {
                    c.particle_of == sys.particle_of
                        && c.age < AMG_MAX_AGE
                        && 2 * self.last.solve.iterations <= 3 * c.setup_iterations.max(4)
                });
                if reusable {
                    let c = self.amg_cache.as_mut().expect("checked");
                    c.amg.refresh_fine(&sys.matrix);
                    c.age += 1;
                    self.timers.ppe_setup += t0.elapsed();
                    let t1 = Instant::now();
                    let s = pcg(&sys.matrix, &sys.rhs, &mut x, &c.amg, tol, max_iter);
                    self.timers.ppe_solve += t1.elapsed();
                    s
                } else {
                    self.amg_cache = None;
                    match Amg::new(&sys.matrix, AmgParams::default()) {
                        Some(amg) => {
                            self.timers.ppe_setup += t0.elapsed();
                            let t1 = Instant::now();
                            let s = pcg(&sys.matrix, &sys.rhs, &mut x, &amg, tol, max_iter);
                            self.timers.ppe_solve += t1.elapsed();
                            if let Ok(st) = s {
                                self.amg_cache = Some(AmgCache {
                                    particle_of: sys.particle_of.clone(),
                                    amg,
                                    setup_iterations: st.iterations,
                                    age: 0,
                                });
                            }
                            s
                        }
                        None => {
                            let pre = jacobi(&sys.matrix);
                            self.timers.ppe_setup += t0.elapsed();
                            let t1 = Instant::now();
                            let s = pcg(&sys.matrix, &sys.rhs, &mut x, &pre, tol, max_iter);
                            self.timers.ppe_solve += t1.elapsed();
                            s
                        }
                    }
                }
            }
            kind => {
                let pre = match kind {
                    SolverKind::Cg => Preconditioner::Identity,
                    SolverKind::Ic0Cg => match Ic0::new(&sys.matrix) {
                        Some(f) => Preconditioner::Ic0(f),
                        None => jacobi(&sys.matrix),
                    },
                    _ => jacobi(&sys.matrix),
                };
                self.timers.ppe_setup += t0.elapsed();
                let t1 = Instant::now();
                let s = pcg(&sys.matrix, &sys.rhs, &mut x, &pre, tol, max_iter);
                self.timers.ppe_solve += t1.elapsed();
                s
            }
        };
        report.solve = match solve {
            Ok(s) => s,
            Err(e) => {
                return Err((
                    BreakdownReason::SolverDiverged {
                        iterations: e.stats.iterations,
                        residual: e.stats.residual,
                    },
                    vec![],
                ))
            }
        };

        // 5. Pressure gradient (scheme's model) and Dynamic Stabilization.
        let t0 = Instant::now();
        let n = pos.len();
        let clamp = self.scheme.clamp_negative_pressure;
        let mut pressure: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                let r = sys.row_of[i];
                if r == NONE {
                    0.0
                } else if clamp {
                    x[r as usize].max(0.0)
                } else {
                    x[r as usize]
                }
            })
            .collect();
        // The PPE is done with: keep it when asked, free it otherwise (lower peak memory).
        let kept_system = self.keep_system.then_some(sys);
        // Pressures of wall and dummy particles for the gradient (module `walls`).
        let wall_model = self.scheme.wall_pressure;
        let g = self.gravity;
        let boundary: Vec<(usize, f64)> = match wall_model {
            WallPressure::Extrapolated => {
                let re = self.kernels.lap.re;
                (0..n)
                    .into_par_iter()
                    .filter(|&i| p.kind[i] != Kind::Fluid)
                    .map(|i| {
                        (
                            i,
                            extrapolated_pressure(i, &f, &pressure, g, re).unwrap_or(0.0),
                        )
                    })
                    .collect()
            }
            WallPressure::Hydrostatic => (0..n)
                .into_par_iter()
                .filter(|&i| p.kind[i] == Kind::Dummy && p.backing_wall[i] != NONE)
                .map(|i| {
                    let w = p.backing_wall[i] as usize;
                    (i, pressure[w] + p.density[i] * g.dot(&(pos[i] - pos[w])))
                })
                .collect(),
            WallPressure::None => Vec::new(),
        };
        let mut carries: Vec<bool> = p
            .kind
            .iter()
            .map(|k| *k != Kind::Dummy || wall_model != WallPressure::None)
            .collect();
        for (i, v) in boundary {
            if wall_model == WallPressure::Extrapolated {
                // A wall particle with no fluid pressure behind it (above the waterline the
                // extrapolation turns negative) is in air: it neither pushes nor pulls and
                // leaves the gradient stencil, as the air on the fluid side does.
                carries[i] = v > 0.0;
                pressure[i] = v.max(0.0);
            } else {
                pressure[i] = if clamp { v.max(0.0) } else { v };
            }
        }
        let ph: Vec<f64> = if matches!(self.scheme.gradient, GradientModel::Taylor) {
            Vec::new()
        } else {
            (0..n)
                .into_par_iter()
                .map(|i| p_hat(i, &f, &pressure, &carries, self.kernels.grad.re))
                .collect()
        };
        let k = &self.kernels;
        let s = &self.scheme;
        let acc: Vec<Vector<D>> = (0..n)
            .into_par_iter()
            .map(|i| {
                if p.kind[i] == Kind::Fluid {
                    pressure_acceleration(i, &fc, &pressure, &ph, &carries, k, s)
                } else {
                    Vector::zero()
                }
            })
            .collect();
        let (ds_acc, ds_active): (Vec<Vector<D>>, Vec<u32>) = match &s.ds {
            Some(ds) => (0..n)
                .into_par_iter()
                .map(|i| {
                    if p.kind[i] == Kind::Fluid {
                        ds_acceleration(i, &f, &acc, ds, k, dt)
                    } else {
                        (Vector::zero(), 0)
                    }
                })
                .unzip(),
            None => (Vec::new(), Vec::new()),
        };
        report.ds_active = ds_active.iter().map(|&a| a as u64).sum();
        let (min_d, close) = self.pair_metrics(&f);
        report.min_pair_distance = min_d;
        report.close_pairs = close;
        self.timers.gradient += t0.elapsed();

        // 6. Correction: u = u* + dt a, r = r* + dt (u - u*).
        let t0 = Instant::now();
        let has_ds = !ds_acc.is_empty();
        let (new_vel, new_pos): (Vec<Vector<D>>, Vec<Vector<D>>) = (0..n)
            .into_par_iter()
            .map(|i| {
                if p.kind[i] != Kind::Fluid {
                    return (vel[i], pos[i]);
                }
                let a = if has_ds { acc[i] + ds_acc[i] } else { acc[i] };
                (vel[i] + a * dt, pos[i] + a * (dt * dt))
            })
            .unzip();
        let result = self.check(&new_pos, &new_vel, &pressure, min_d);
        let p = &mut self.particles;
        p.velocity = new_vel;
        p.position = new_pos;
        p.pressure = pressure;
        p.number_density = nd;
        p.free_surface = surface;
        self.timers.correction += t0.elapsed();
        report.max_speed = result?;
        if kept_system.is_some() {
            self.last_system = kept_system;
        }
        Ok(report)
    }

    /// `u* = u + dt (nu lap u + g)` for fluid particles, `r* = r + dt u*`.
    fn explicit_stage(&self, dt: f64) -> (Vec<Vector<D>>, Vec<Vector<D>>) {
        let p = &self.particles;
        let k = &self.kernels.lap;
        let g = self.gravity;
        (0..p.len())
            .into_par_iter()
            .map(|i| {
                if p.kind[i] != Kind::Fluid {
                    return (p.velocity[i], p.position[i]);
                }
                let nu = self.phase_viscosity[p.phase[i] as usize];
                let mut a = g;
                if nu > 0.0 {
                    a +=
                        laplacian_vector(i, &p.position, &p.velocity, self.neighbors.of(i), k) * nu;
                }
                let u = p.velocity[i] + a * dt;
                (u, p.position[i] + u * dt)
            })
            .unzip()
    }

    /// Collision model (equations.md s.5 step 2): approaching pairs closer than `dist` (m)
    /// lose `(1+e) m_j/(m_i+m_j)` of their normal approach velocity (walls: immovable).
    fn collision_stage(
        &self,
        pos: &[Vector<D>],
        vel: &[Vector<D>],
        dist: f64,
        e: f64,
    ) -> (Vec<Vector<D>>, u64) {
        let p = &self.particles;
        let nl = &self.neighbors;
        let (v, c): (Vec<Vector<D>>, Vec<u32>) = (0..pos.len())
            .into_par_iter()
            .map(|i| {
                if p.kind[i] != Kind::Fluid {
                    return (vel[i], 0);
                }
                let mut u = vel[i];
                let mut count = 0;
                for &j in nl.of(i) {
                    let j = j as usize;
                    let rij = pos[j] - pos[i];
                    let r = rij.norm();
                    if r >= dist || r == 0.0 {
                        continue;
                    }
                    let en = rij / r;
                    let vn = (vel[j] - vel[i]).dot(&en);
                    if vn >= 0.0 {
                        continue;
                    }
                    let share = if p.kind[j] == Kind::Fluid {
                        p.density[j] / (p.density[i] + p.density[j])
                    } else {
                        1.0
                    };
                    u += en * ((1.0 + e) * share * vn);
                    count += 1;
                }
                (u, count)
            })
            .unzip();
        (v, c.iter().map(|&x| x as u64).sum::<u64>() / 2)
    }

    /// Walls take the density of their nearest fluid particle within re_lap, dummies that of
    /// their backing wall (equations.md s.4, s.7).
    fn update_wall_density(&mut self, pos: &[Vector<D>]) {
        let p = &self.particles;
        let re2 = self.kernels.lap.re.powi(2);
        let nl = &self.neighbors;
        let walls: Vec<f64> = (0..p.len())
            .into_par_iter()
            .map(|i| {
                if p.kind[i] != Kind::Wall {
                    return p.density[i];
                }
                let mut best = (re2, p.density[i]);
                for &j in nl.of(i) {
                    let j = j as usize;
                    if p.kind[j] == Kind::Fluid {
                        let d2 = (pos[j] - pos[i]).norm2();
                        if d2 < best.0 {
                            best = (d2, p.density[j]);
                        }
                    }
                }
                best.1
            })
            .collect();
        let dens: Vec<f64> = (0..p.len())
            .map(|i| match p.kind[i] {
                Kind::Dummy if p.backing_wall[i] != NONE => walls[p.backing_wall[i] as usize],
                _ => walls[i],
            })
            .collect();
        self.particles.density = dens;
    }

    /// Smallest fluid-neighbour distance (m) and the number of pairs closer than 0.9 l0.
    fn pair_metrics(&self, f: &Fields<D>) -> (f64, u64) {
        let lim = 0.9 * self.l0();
        let re = self.kernels.grad.re;
        let (m, c) = (0..f.pos.len())
            .into_par_iter()
            .filter(|&i| f.kind[i] == Kind::Fluid)
            .map(|i| {
                let mut m = f64::INFINITY;
                let mut c = 0u64;
                for &j in f.neighbors.of(i) {
                    let j = j as usize;
                    let r = (f.pos[j] - f.pos[i]).norm();
                    if r < re {
                        m = m.min(r);
                        if r < lim && (f.kind[j] != Kind::Fluid || i < j) {
                            c += 1;
                        }
                    }
                }
                (m, c)
            })
            .reduce(|| (f64::INFINITY, 0), |a, b| (a.0.min(b.0), a.1 + b.1));
        (m, c)
    }

    /// Breakdown checks on the new state; returns the largest fluid speed.
    fn check(
        &self,
        pos: &[Vector<D>],
        vel: &[Vector<D>],
        pressure: &[f64],
        min_pair: f64,
    ) -> Result<f64, (BreakdownReason, Vec<u32>)> {
        let p = &self.particles;
        let l0 = self.l0();
        let ids = |pred: &dyn Fn(usize) -> bool| -> Vec<u32> {
            (0..pos.len())
                .filter(|&i| pred(i))
                .take(8)
                .map(|i| p.id[i])
                .collect()
        };
        let bad = (0..pos.len())
            .into_par_iter()
            .any(|i| !(pos[i].is_finite() && vel[i].is_finite() && pressure[i].is_finite()));
        if bad {
            return Err((
                BreakdownReason::NotFinite,
                ids(&|i| !(pos[i].is_finite() && vel[i].is_finite() && pressure[i].is_finite())),
            ));
        }
        // A particle centre may come within l0/2 of a wall surface without penetrating it;
        // it has left once it is a full spacing beyond the domain box (past the wall row).
        let pad = Vector([l0; D]);
        let lo = Vector::<D>::from_slice(&self.case.domain.min).unwrap() - pad;
        let hi = Vector::<D>::from_slice(&self.case.domain.max).unwrap() + pad;
        let outside = |i: usize| {
            p.kind[i] == Kind::Fluid && (0..D).any(|k| pos[i][k] < lo[k] || pos[i][k] > hi[k])
        };
        if (0..pos.len()).into_par_iter().any(outside) {
            return Err((BreakdownReason::LeftDomain, ids(&outside)));
        }
        if min_pair < self.case.breakdown.min_pair_distance * l0 {
            return Err((
                BreakdownReason::Penetration {
                    distance_l0: min_pair / l0,
                },
                vec![],
            ));
        }
        let umax = (0..pos.len())
            .into_par_iter()
            .filter(|&i| p.kind[i] == Kind::Fluid)
            .map(|i| vel[i].norm())
            .reduce(|| 0.0, f64::max);
        if umax > self.max_speed_bound {
            let bound = self.max_speed_bound;
            return Err((
                BreakdownReason::SpeedBlowUp { speed: umax, bound },
                ids(&|i| vel[i].norm() > bound),
            ));
        }
        Ok(umax)
    }

    /// The shared read-only view of the current state (positions, velocities, ...).
    pub fn fields(&self) -> Fields<'_, D> {
        let p = &self.particles;
        Fields {
            pos: &p.position,
            vel: &p.velocity,
            kind: &p.kind,
            density: &p.density,
            free_surface: &p.free_surface,
            number_density: &p.number_density,
            neighbors: &self.neighbors,
        }
    }

    /// Shepard-weighted pressure (Pa) at point `x` from fluid and wall particles within re_grad;
    /// `None` when no particle is in range.
    pub fn sample_pressure(&self, x: &Vector<D>) -> Option<f64> {
        let p = &self.particles;
        let re = self.kernels.grad.re;
        let (mut sw, mut swp) = (0.0, 0.0);
        for i in 0..p.len() {
            if p.kind[i] == Kind::Dummy {
                continue;
            }
            let w = weight((p.position[i] - *x).norm(), re);
            if w > 0.0 {
                sw += w;
                swp += w * p.pressure[i];
            }
        }
        (sw > 0.0).then(|| swp / sw)
    }
}
