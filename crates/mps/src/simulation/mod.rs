//! The semi-implicit MPS time step (equations.md section 5; paper section 2), as a list of
//! named stages in [`Simulation::advance`]; each stage is a method in `stages`.
//!
//! Owns the running state (particles, neighbour lists, the resolved scheme, the pressure
//! solver, the clock). May use `particles`, `numerics`, `linalg` and the case it was built
//! from (`input`); knows nothing of files or diagnostics.

pub mod breakdown;
pub mod domain;
pub mod memory;
pub mod pressure_solver;
pub mod relax;
mod spare;
mod stages;
pub mod time_step;
pub mod timers;

pub use breakdown::{Breakdown, BreakdownReason};
pub use domain::Domain;
pub use stages::{DensitySurface, DsArrays, Predicted};
pub use timers::{Stage, Timers};

use crate::error::CaseError;
use crate::input::case::Outflow;
use crate::input::Case;
use crate::linalg::SolveStats;
use crate::numerics::interfacial_tension::Interfaces;
use crate::numerics::ppe::PressureSystem;
use crate::numerics::{weight, Kernels, Scheme};
use crate::particles::{Kind, NeighborList, Particles, Vector, View};
use breakdown::{Failure, Limits};
use pressure_solver::PressureSolver;
use std::time::Instant;

/// Neighbour-list skin, fraction of l0: the list stays valid while particles move less than
/// half of it (docs/decisions.md, "Neighbour skin").
const SKIN: f64 = 0.3;

/// Default speed bound, multiple of the case's velocity scale (docs/decisions.md,
/// "Breakdown speed").
const SPEED_BOUND_FACTOR: f64 = 50.0;

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepReport {
    /// Time step used (s).
    pub dt: f64,
    /// PPE unknowns.
    pub unknowns: usize,
    /// PPE solver statistics.
    pub solve: SolveStats,
    /// True when the PPE preconditioner fell back to Jacobi this step.
    pub solver_fallback: bool,
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
    /// Fluid particles removed after leaving the domain (`domain.outflow = "remove"`).
    pub removed: u64,
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
    /// Interfacial tensions by phase (`numerics::interfacial_tension`; empty without).
    pub interfaces: Interfaces,
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
    /// The PPE of the last step (the next step assembles into its memory).
    pub last_system: Option<PressureSystem>,
    /// The pressure solver (its choice, kept set-up and fall-back count).
    pub solver: PressureSolver,
    /// Fluid particles removed so far after leaving the domain (`domain.outflow`).
    pub outflow_removed: u64,
    neighbors: NeighborList,
    /// The neighbour search's memory, kept between steps: its cell grid and particle masks.
    search: NeighborSearch<D>,
    /// The stages' vectors, kept between steps.
    spare: spare::Spare<D>,
    /// The memory of the last step's near lists (`NeighborList::near`), for the next step's.
    spare_near: Option<Box<NeighborList>>,
    /// What the running step changed in the particles before its end, undone on breakdown.
    undo: Undo,
    /// The densities before the step's stage 3 set the walls' (restored on breakdown).
    density_before: Vec<f64>,
    skin: f64,
    /// The positions (m) the neighbour lists were built at; empty when the lists must be
    /// built afresh at the next step (docs/decisions.md, "Neighbour lists kept").
    lists_built_at: Vec<Vector<D>>,
    /// The last PPE had no Dirichlet row (a closed domain, its level from the reference).
    closed: bool,
    /// The processes sharing a distributed run (`None` on one process): `domain.rs`.
    domain: std::sync::Mutex<Option<Box<dyn Domain<D>>>>,
    /// Own particles of a distributed run (the rest is halo); `None` on one process.
    owned: Option<usize>,
    /// The fluid fills a closed tank: no air, so no particle is ever free surface
    /// (docs/decisions.md, "Full closed containers").
    full: bool,
    /// A distributed run's layout of pieces from the checkpoint it restarts from (empty
    /// otherwise), handed to its domain when attached.
    pub layout: Vec<u64>,
}

/// True when the fluid of `p` fills a tank of `case` closed on every side: the fluid's
/// volume (`l0^D` per particle) is the tank's inner volume within 0.1 %. Such a container
/// holds no air, so it has no free surface.
pub fn fills_a_closed_tank<const D: usize>(case: &Case, p: &Particles<D>) -> bool {
    let l0 = case.particles.spacing;
    let fluid = p.count(Kind::Fluid) as f64 * l0.powi(D as i32);
    case.walls.iter().any(|w| match &w.shape {
        crate::input::case::ShapeSpec::Tank {
            min,
            max,
            open_top: false,
        } => {
            let volume: f64 = min.iter().zip(max).map(|(a, b)| b - a).product();
            volume > 0.0 && (fluid / volume - 1.0).abs() < 1e-3
        }
        _ => false,
    })
}

/// The interfaces of `case` by phase, with each tension (N/m) and density factor
/// `2 / (rho_a + rho_b)` (m^3/kg).
fn interfaces_of(case: &Case) -> Interfaces {
    let index = |name: &str| case.phases.iter().position(|p| p.name == name);
    let mut of_phase = vec![Vec::new(); case.phases.len()];
    for f in &case.interfaces {
        if let (Some(a), Some(b)) = (index(&f.phases[0]), index(&f.phases[1])) {
            let factor = 2.0 / (case.phases[a].density + case.phases[b].density);
            of_phase[a].push((b as u16, f.tension, factor));
            of_phase[b].push((a as u16, f.tension, factor));
        }
    }
    let free_surface = case.phases.iter().map(|p| p.surface_tension).collect();
    Interfaces {
        of_phase,
        free_surface,
    }
}

impl<const D: usize> Simulation<D> {
    /// Builds the particles of `case` and prepares the run; `label` names the case in errors.
    pub fn new(case: Case, label: &str) -> Result<Self, CaseError> {
        memory::keep_freed_memory();
        if case.dimension != D {
            let msg = format!("a {D}D simulation cannot run this case");
            return Err(CaseError::new(
                label,
                "dimension",
                case.dimension.to_string(),
                msg,
            ));
        }
        let particles = crate::input::setup::build_particles::<D>(&case, label)?;
        let scheme = case.scheme(label)?;
        let l0 = case.particles.spacing;
        let kernels = Kernels::new::<D>(l0, case.particles.re_grad, case.particles.re_lap);
        let gravity = Vector::from_slice(&case.physics.gravity).expect("validated");
        let g = gravity.norm();
        let dt_max = time_step::largest_time_step(&case, &particles, g, label)?;
        let u_scale =
            time_step::velocity_scale(&particles, g, l0).max(time_step::capillary_speed(&case));
        let max_speed_bound = case.breakdown.max_speed.unwrap_or(if u_scale > 0.0 {
            SPEED_BOUND_FACTOR * u_scale
        } else {
            f64::INFINITY
        });
        let mut sim = Simulation {
            phase_viscosity: case.phases.iter().map(|p| p.viscosity).collect(),
            interfaces: interfaces_of(&case),
            solver: PressureSolver::new(&case.solver, D),
            case,
            particles,
            scheme,
            kernels,
            gravity,
            time: 0.0,
            step_count: 0,
            dt_max,
            max_speed_bound,
            timers: Timers::default(),
            last: StepReport::default(),
            last_system: None,
            neighbors: NeighborList::default(),
            undo: Undo::default(),
            density_before: Vec::new(),
            skin: SKIN * l0,
            lists_built_at: Vec::new(),
            spare_near: None,
            search: NeighborSearch::default(),
            spare: Default::default(),
            outflow_removed: 0,
            closed: false,
            domain: std::sync::Mutex::new(None),
            owned: None,
            full: false,
            layout: Vec::new(),
        };
        sim.full = fills_a_closed_tank(&sim.case, &sim.particles);
        sim.reorder();
        sim.refresh_diagnostic_fields();
        Ok(sim)
    }

    /// Particle spacing `l0` (m).
    pub fn l0(&self) -> f64 {
        self.kernels.l0
    }

    /// Advances one step, stopping at `until` (s) if it comes first. On breakdown the
    /// particles are restored to the last good state and the reason is returned.
    pub fn step(&mut self, until: f64) -> Result<StepReport, Breakdown> {
        self.undo = Undo::default();
        // The pool's other worker waits for the step's parallel pieces by spinning.
        match crate::parallel::with_helper(|| self.advance(until)) {
            Ok(r) => {
                self.solver.commit();
                self.last = r;
                self.step_count += 1;
                self.time += r.dt;
                if let Err(why) = self.redistribute() {
                    return Err(Breakdown {
                        time: self.time,
                        step: self.step_count,
                        reason: BreakdownReason::Distributed(why),
                        particles: Vec::new(),
                    });
                }
                Ok(r)
            }
            Err(f) => {
                self.solver.rollback();
                self.undo_step();
                // A stage that failed after stage 3 leaves the near lists cut at r*.
                self.drop_near_lists();
                Err(Breakdown {
                    time: self.time,
                    step: self.step_count + 1,
                    reason: f.reason,
                    particles: f.particles,
                })
            }
        }
    }

    /// One step of the semi-implicit algorithm (paper section 2, equations.md s.5).
    fn advance(&mut self, until: f64) -> Result<StepReport, Failure> {
        let dt = self.time_step(until)?;
        let mut report = StepReport {
            dt,
            ..Default::default()
        };
        // (On several processes, each refresh_* below brings the halo's copies of what the
        // stage before computed from their owners: domain.rs.)
        // 1. Neighbours at r^n (reordered for locality now and then).
        self.timed(Stage::Neighbors, |s| s.update_neighbors());
        // 2. Explicit forces: u* = u + dt (nu lap u + g), r* = r + dt u*; optional collisions.
        let mut pred = self.timed(Stage::Explicit, |s| s.predict(dt));
        self.refresh_predicted(&mut pred);
        self.keep_neighbors_valid(&pred)?;
        if let Some(c) = self.scheme.collision {
            report.collisions = self.collide_near(&mut pred, c, dt);
            self.refresh_predicted(&mut pred);
        }
        // 3. Number density n*, free surface, the closest pairs, wall and dummy densities.
        let mut surf = self.timed(Stage::DensitySurface, |s| s.density_and_surface(&pred.pos));
        self.refresh_surface(&mut surf);
        let (m, c) = surf.closest;
        (report.min_pair_distance, report.close_pairs) = (self.min(m), self.sum(c));
        self.timed(Stage::DensitySurface, |s| s.update_wall_density(&pred.pos));
        // 4. Pressure Poisson equation at r*, u*.
        let mut density = self.ppe_density(&pred, &surf);
        self.refresh_density(&mut density);
        let sys = self.timed(Stage::PpeAssembly, |s| {
            s.assemble(&pred, &surf, &density, dt)
        });
        report.unknowns = self.own_unknowns(&sys);
        let mut pressure = self.solve_pressure(sys, dt, &mut report)?;
        self.refresh_scalars(&mut pressure);
        // 5. Boundary pressures, pressure acceleration, Dynamic Stabilization, shifting.
        let (acc, ds_acc, shifts) = self.timed(Stage::Gradient, |s| {
            let mut carries = s.boundary_pressures(&pred, &surf, &mut pressure);
            s.refresh_scalars(&mut pressure);
            s.refresh_flags(&mut carries);
            let mut acc = s.pressure_acceleration(&pred, &surf, &density, &pressure, carries);
            s.refresh_vectors(&mut acc);
            let (ds_acc, ds_active) = s.stabilize(&pred, &surf, &acc, dt);
            report.ds_active = s.sum(ds_active);
            (acc, ds_acc, s.shift(&pred, &surf, dt))
        });
        // 6. Correction u = u* + dt a, r = r* + dt^2 a (+ shift), and the breakdown checks.
        let min_pair = report.min_pair_distance;
        report.max_speed = self.timed(Stage::Correction, |s| {
            s.correct(
                (pred, surf),
                (&acc, ds_acc.as_ref(), shifts.as_deref()),
                pressure,
                min_pair,
                dt,
            )
        })?;
        self.recycle([Some(acc), shifts], ds_acc, density);
        // 7. Outflow: fluid beyond the domain leaves the run (when the case says so).
        report.removed = self.timed(Stage::Correction, |s| s.remove_outflow());
        Ok(report)
    }

    /// Keeps the step's accelerations, shifts and smoothed densities for the next step.
    fn recycle(
        &self,
        vectors: [Option<Vec<Vector<D>>>; 2],
        ds: Option<DsArrays<D>>,
        density: Option<Vec<f64>>,
    ) {
        let (ds_acc, ds_dvel) = ds.map_or((None, None), |d| (Some(d.acc), d.dvel));
        for v in vectors.into_iter().chain([ds_acc, ds_dvel]).flatten() {
            self.spare.give(v);
        }
        if let Some(d) = density {
            self.spare.give(d);
        }
    }

    /// Restores the particles to the state before a step that failed: the step wrote them
    /// only in its reordering (stage 1) and the walls' densities (stage 3); its results
    /// (stage 6) are written only when the new state passed its checks.
    fn undo_step(&mut self) {
        if self.undo.density {
            std::mem::swap(&mut self.particles.density, &mut self.density_before);
        }
        if self.undo.reordered {
            self.particles.permute(&self.search.inverse);
            // The lists were built in the reordered numbering.
            self.rebuild_neighbors();
        }
        self.undo = Undo::default();
    }

    /// Runs `f` and adds its wall-clock time to `stage`.
    fn timed<T>(&mut self, stage: Stage, f: impl FnOnce(&mut Self) -> T) -> T {
        let t = Instant::now();
        let r = f(self);
        self.timers.add(stage, t.elapsed());
        r
    }

    /// The box (m) the neighbour grid may cover: the domain padded by every wall and dummy
    /// layer (at most 9 l0) and a margin; a particle beyond it has left the domain.
    fn grid_bounds(&self) -> Option<(Vector<D>, Vector<D>)> {
        let pad = Vector([12.0 * self.l0() + self.cutoff(); D]);
        let lo = Vector::<D>::from_slice(&self.case.domain.min)?;
        let hi = Vector::<D>::from_slice(&self.case.domain.max)?;
        Some((lo - pad, hi + pad))
    }

    fn cutoff(&self) -> f64 {
        self.kernels.grad.re.max(self.kernels.lap.re) + self.skin
    }

    /// Drops any kept solver set-up (the AMG hierarchy), so the next step builds it afresh;
    /// called where a checkpoint is written, so a restarted run continues bit-identically.
    pub fn reset_solver_cache(&mut self) {
        self.solver.reset();
        self.lists_built_at.clear();
    }

    /// A settled start: positions, velocities and pressures from `settled` (the particles of
    /// another run of the same geometry), matched by id; phases, groups and densities stay
    /// this case's, the clock at 0. Refused when the particle sets differ (count, ids, kinds,
    /// or a wall or dummy particle elsewhere).
    pub fn start_from(&mut self, settled: &Particles<D>) -> Result<(), String> {
        let p = &mut self.particles;
        if settled.len() != p.len() {
            let n = settled.len();
            return Err(format!(
                "it holds {n} particles, this case builds {}",
                p.len()
            ));
        }
        let mut at = vec![u32::MAX; p.len()];
        for (k, &id) in settled.id.iter().enumerate() {
            match at.get_mut(id as usize) {
                Some(slot) if *slot == u32::MAX => *slot = k as u32,
                _ => return Err(format!("particle id {id} out of range or repeated")),
            }
        }
        for i in 0..p.len() {
            let k = at[p.id[i] as usize] as usize;
            if settled.kind[k] != p.kind[i]
                || (p.kind[i] != Kind::Fluid && settled.position[k] != p.position[i])
            {
                let id = p.id[i];
                return Err(format!(
                    "particle {id} differs in kind or wall position: another geometry"
                ));
            }
            p.position[i] = settled.position[k];
            p.velocity[i] = settled.velocity[k];
            p.pressure[i] = settled.pressure[k];
        }
        self.solver.reset();
        self.reorder();
        self.refresh_diagnostic_fields();
        Ok(())
    }

    /// Rebuilds the neighbour lists at the current positions (after a restore).
    pub fn rebuild_neighbors(&mut self) {
        self.neighbors = self.neighbors_at(&self.particles.position);
        self.lists_built_at.clear();
    }

    /// Neighbour lists at positions `pos` (m) for the fluid and every wall or dummy particle
    /// within its reach (a dummy's without the other dummies); the others, which no
    /// pair loop visits, get none (docs/decisions.md, "Lists only within the fluid's reach").
    fn neighbors_at(&self, pos: &[Vector<D>]) -> NeighborList {
        let mut out = NeighborList::default();
        self.neighbors_into(pos, &mut NeighborSearch::default(), &mut out);
        out
    }

    /// [`Self::neighbors_at`] into `out`, reusing the memory of the lists it held and of
    /// `search`.
    fn neighbors_into(
        &self,
        pos: &[Vector<D>],
        search: &mut NeighborSearch<D>,
        out: &mut NeighborList,
    ) {
        let kind = &self.particles.kind;
        let NeighborSearch {
            grid, fluid, dummy, ..
        } = search;
        crate::parallel::map_into(fluid, kind.len(), |i| kind[i] == Kind::Fluid);
        crate::parallel::map_into(dummy, kind.len(), |i| kind[i] == Kind::Dummy);
        let needs = crate::particles::neighbors::ListNeeds {
            moving: fluid,
            apart: dummy,
        };
        crate::particles::neighbors::build_neighbor_list_near_into(
            pos,
            self.cutoff(),
            self.grid_bounds(),
            needs,
            grid,
            out,
        );
    }

    /// Rebuilds the neighbour lists at positions `pos` (m) in their own memory.
    fn renew_neighbors(&mut self, pos: &[Vector<D>]) {
        let mut lists = std::mem::take(&mut self.neighbors);
        let mut search = std::mem::take(&mut self.search);
        self.neighbors_into(pos, &mut search, &mut lists);
        (self.neighbors, self.search) = (lists, search);
        if !self.is_distributed() {
            self.lists_built_at.clear();
            self.lists_built_at.extend_from_slice(pos);
        }
    }

    /// The largest distance (m) a particle of `pos` lies from where the neighbour lists
    /// were built (infinite when they must be built afresh).
    fn moved_since_lists(&self, pos: &[Vector<D>]) -> f64 {
        let built = &self.lists_built_at;
        if built.len() != pos.len() {
            return f64::INFINITY;
        }
        let moved = |i: usize| (pos[i] - built[i]).norm2();
        crate::parallel::map_reduce(pos.len(), 0.0, moved, f64::max).sqrt()
    }

    /// Recomputes number density, free-surface flags and wall pressures at the current
    /// positions (for output of the initial state and after a restart).
    pub fn refresh_diagnostic_fields(&mut self) {
        self.rebuild_neighbors();
        let pos = self.particles.position.clone();
        let mut surf = self.density_and_surface(&pos);
        self.drop_near_lists();
        self.refresh_surface(&mut surf);
        self.particles.number_density = surf.number_density;
        self.particles.free_surface = surf.free_surface;
        // As the step does: no free surface, no clamp of the walls' extrapolated pressures.
        let own = self.owned();
        let closed = !self.any(self.particles.free_surface[..own].iter().any(|&f| f));
        if self.scheme.wall_pressure == crate::numerics::walls::WallPressure::Extrapolated {
            let v = self.view();
            let p = &self.particles;
            let re = self.kernels.lap.re;
            let walls: Vec<(usize, f64)> = (0..p.len())
                .filter(|&i| p.kind[i] != Kind::Fluid)
                .map(|i| {
                    let e = crate::numerics::walls::extrapolated_pressure(
                        i,
                        &v,
                        &p.pressure,
                        self.gravity,
                        re,
                    );
                    let p = e.unwrap_or(0.0);
                    (i, if closed { p } else { p.max(0.0) })
                })
                .collect();
            for (i, v) in walls {
                self.particles.pressure[i] = v;
            }
            let mut pressure = std::mem::take(&mut self.particles.pressure);
            self.refresh_scalars(&mut pressure);
            self.particles.pressure = pressure;
        }
    }

    /// The shared read-only view of the current state (positions, velocities, ...).
    pub fn view(&self) -> View<'_, D> {
        let p = &self.particles;
        View {
            pos: &p.position,
            vel: &p.velocity,
            kind: &p.kind,
            density: &p.density,
            free_surface: &p.free_surface,
            number_density: &p.number_density,
            neighbors: &self.neighbors,
        }
    }

    /// The breakdown limits of this case.
    fn limits(&self) -> Limits<D> {
        let l0 = self.l0();
        // A particle centre may come within l0/2 of a wall surface without penetrating it;
        // it has left once it is a full spacing beyond the domain box (past the wall row).
        let pad = Vector([l0; D]);
        Limits {
            lo: Vector::<D>::from_slice(&self.case.domain.min).expect("validated") - pad,
            hi: Vector::<D>::from_slice(&self.case.domain.max).expect("validated") + pad,
            min_pair: self.case.breakdown.min_pair_distance * l0,
            l0,
            max_speed: self.max_speed_bound,
            outflow: self.case.domain.outflow == Outflow::Remove,
        }
    }

    /// Shepard-weighted pressure (Pa) at point `x` from fluid and wall particles within
    /// re_grad (every process's own ones); `None` when no particle is in range.
    pub fn sample_pressure(&self, x: &Vector<D>) -> Option<f64> {
        let p = &self.particles;
        let re = self.kernels.grad.re;
        let (mut sw, mut swp) = (0.0, 0.0);
        for i in 0..self.owned() {
            if p.kind[i] == Kind::Dummy {
                continue;
            }
            let w = weight((p.position[i] - *x).norm(), re);
            if w > 0.0 {
                sw += w;
                swp += w * p.pressure[i];
            }
        }
        if self.is_distributed() {
            let mut s = [sw, swp];
            self.sum_over_processes(&mut s);
            [sw, swp] = s;
        }
        (sw > 0.0).then(|| swp / sw)
    }
}

/// What a step changed in the particles before its end (undone on breakdown).
#[derive(Clone, Copy, Debug, Default)]
struct Undo {
    /// Stage 1 reordered them (by `NeighborSearch::order`).
    reordered: bool,
    /// Stage 3 set the walls' densities (the old ones in `Simulation::density_before`).
    density: bool,
}

/// The memory of the neighbour search and the reordering, kept between steps.
#[derive(Default)]
struct NeighborSearch<const D: usize> {
    /// The cell grid.
    grid: crate::particles::neighbors::CellGrid<D>,
    /// Which particles are fluid (they always get lists).
    fluid: Vec<bool>,
    /// Which particles are dummies (their lists leave out the other dummies).
    dummy: Vec<bool>,
    /// The last reordering (new index -> old index) and its inverse.
    order: Vec<u32>,
    inverse: Vec<u32>,
}
