//! The stages of the step, one method each, in step order. Every stage reads the particle
//! state through a [`View`] and hands its result to the next as a typed value.

use super::breakdown::{check_state, BreakdownReason, Failure};
use super::pressure_solver::{stopping_tolerance, SolveReport};
use super::{Simulation, Stage, StepReport};
use crate::numerics::collision::{collide, Collision};
use crate::numerics::density::smoothed_density;
use crate::numerics::free_surface_tension::{laplace_jump, particle_scale_tension};
use crate::numerics::gradient::{p_hat, pressure_acceleration, GradientModel};
use crate::numerics::interface_repulsion::interface_repulsion;
use crate::numerics::interfacial_tension::{surface_force, TensionInput};
use crate::numerics::operators::{laplacian_vector, number_density, number_density_and_closest};
use crate::numerics::ppe::{assemble_into, is_dirichlet, PressureReference, PressureSystem};
use crate::numerics::shifting::shift;
use crate::numerics::stabilization::{ds_acceleration, DsVelocity};
use crate::numerics::surface::{detect, SurfaceInput};
use crate::numerics::walls::{boundary_pressures, wall_densities};
use crate::parallel;
use crate::particles::{Kind, Vector, View, NONE};

/// Steps between reorderings of the particles along the cell list (memory locality; the
/// AMG hierarchy is rebuilt after each: docs/decisions.md, "Reordering").
const REORDER_EVERY: u64 = 20;

/// The intermediate state after the explicit stage: `r*`, `u*`.
#[derive(Clone, Debug)]
pub struct Predicted<const D: usize> {
    /// Positions `r*` (m).
    pub pos: Vec<Vector<D>>,
    /// Velocities `u*` (m/s).
    pub vel: Vec<Vector<D>>,
}

/// Number density and free-surface flags at `r*`.
#[derive(Clone, Debug)]
pub struct DensitySurface {
    /// Number density `n*` at re_grad (dimensionless).
    pub number_density: Vec<f64>,
    /// Free-surface flags.
    pub free_surface: Vec<bool>,
    /// Over the own fluid particles' pairs within re_grad: the smallest distance (m) and the
    /// number of pairs closer than 0.9 l0 (a fluid pair counted once).
    pub closest: (f64, u64),
}

/// Dynamic Stabilization's arrays for one step.
#[derive(Clone, Debug)]
pub struct DsArrays<const D: usize> {
    /// DS acceleration of every particle (m/s^2).
    pub acc: Vec<Vector<D>>,
    /// Velocity change of every particle (m/s) with inelastic velocities; with the paper's
    /// restoring velocities `None` (the velocity takes `dt acc`).
    pub dvel: Option<Vec<Vector<D>>>,
}

impl<const D: usize> Simulation<D> {
    /// The view of the intermediate state: positions and velocities `pos`, `vel`, the surface
    /// of `surf` (the stored one if `None`), densities `density` (the particles' if `None`).
    fn view_of<'a>(
        &'a self,
        pos: &'a [Vector<D>],
        vel: &'a [Vector<D>],
        surf: Option<&'a DensitySurface>,
        density: Option<&'a [f64]>,
    ) -> View<'a, D> {
        let p = &self.particles;
        View {
            pos,
            vel,
            kind: &p.kind,
            density: density.unwrap_or(&p.density),
            free_surface: surf.map_or(&p.free_surface, |s| &s.free_surface),
            number_density: surf.map_or(&p.number_density, |s| &s.number_density),
            neighbors: &self.neighbors,
        }
    }

    /// Sorts the particles along the cells of the neighbour grid.
    pub(super) fn reorder(&mut self) {
        let mut search = std::mem::take(&mut self.search);
        let grid = &mut search.grid;
        grid.rebuild(&self.particles.position, self.cutoff(), self.grid_bounds());
        search.order.clear();
        search.order.extend_from_slice(grid.cell_order());
        let (order, inverse) = (&search.order, &mut search.inverse);
        let mut spare = self.spare.lock();
        self.particles.permute_into(order, &mut spare, inverse);
        drop(spare);
        self.search = search;
        self.undo.reordered = true;
    }

    /// Stage 1: neighbour lists at `r^n` (with a skin), reordering every few steps.
    pub(super) fn update_neighbors(&mut self) {
        // A distributed run's order is its domain's (own particles first, then the halo).
        if self.is_distributed() {
            // Built at these positions after the last redistribution (domain.rs).
            return;
        }
        if self.step_count.is_multiple_of(REORDER_EVERY) {
            self.reorder();
            self.lists_built_at.clear();
        }
        // Kept while every particle lies within half the skin of where they were built.
        if 2.0 * self.moved_since_lists(&self.particles.position) < self.skin {
            return;
        }
        // Built into the old lists' memory (a fresh list of a million particles would be
        // faulted in page by page every step: docs/decisions.md, "Neighbour lists in place").
        let pos = std::mem::take(&mut self.particles.position);
        self.renew_neighbors(&pos);
        self.particles.position = pos;
    }

    /// Stage 2: `u* = u + dt (nu lap u + g + a_tension + a_repulsion)`, `r* = r + dt u*` for
    /// fluid particles (`a_tension` from `numerics::interfacial_tension` where the case has
    /// interfaces and the particle-scale part of `numerics::free_surface_tension` where a
    /// phase's free surface has tension, `a_repulsion` from `numerics::interface_repulsion`
    /// where the scheme has it).
    pub(super) fn predict(&self, dt: f64) -> Predicted<D> {
        let p = &self.particles;
        let k = &self.kernels.lap;
        let g = self.gravity;
        let tension = self.surface_tension();
        let string = self.particle_scale_tension();
        let at_r = self.view_of(&p.position, &p.velocity, None, None);
        let mut pred = Predicted {
            pos: self.spare.take(),
            vel: self.spare.take(),
        };
        let (vel, pos) = (&mut pred.vel, &mut pred.pos);
        parallel::unzip_into(vel, pos, p.len(), |i| {
            if p.kind[i] != Kind::Fluid {
                return (p.velocity[i], p.position[i]);
            }
            let nu = self.phase_viscosity[p.phase[i] as usize];
            let mut a = g;
            if nu > 0.0 {
                a += laplacian_vector(i, &p.position, &p.velocity, &self.neighbors, k) * nu;
            }
            if let Some(t) = &tension {
                a += t[i];
            }
            if let Some(t) = &string {
                a += t[i];
            }
            if let Some(r) = &self.scheme.interface_repulsion {
                a += interface_repulsion(i, &at_r, &p.phase, &self.kernels, r);
            }
            let u = p.velocity[i] + a * dt;
            (u, p.position[i] + u * dt)
        });
        pred
    }

    /// Stage 2a: the interfacial-tension accelerations at `r` (`None` without interfaces).
    fn surface_tension(&self) -> Option<Vec<Vector<D>>> {
        if self.interfaces.is_empty() {
            return None;
        }
        let p = &self.particles;
        let fluid = self.fluid_mask();
        let inp = self.tension_input(&p.position, &p.free_surface, &fluid);
        Some(surface_force(&inp, &self.interfaces))
    }

    /// Stage 2b: the particle-scale part of the free surface's tension at `r` with the last
    /// step's flags (`None` where no phase's free surface has tension).
    fn particle_scale_tension(&self) -> Option<Vec<Vector<D>>> {
        let free = &self.interfaces.free_surface;
        if free.iter().all(|&sigma| sigma == 0.0) {
            return None;
        }
        let p = &self.particles;
        let fluid = self.fluid_mask();
        let inp = self.tension_input(&p.position, &p.free_surface, &fluid);
        particle_scale_tension(&inp, free, &p.density)
    }

    /// Which particles are fluid, for the tension models.
    fn fluid_mask(&self) -> Vec<bool> {
        self.particles
            .kind
            .iter()
            .map(|k| *k == Kind::Fluid)
            .collect()
    }

    /// The tension models' inputs at positions `pos` with free-surface flags `surface`.
    fn tension_input<'a>(
        &'a self,
        pos: &'a [Vector<D>],
        surface: &'a [bool],
        fluid: &'a [bool],
    ) -> TensionInput<'a, D> {
        TensionInput {
            pos,
            nl: &self.neighbors,
            re: self.kernels.lap.re,
            re_near: self.kernels.grad.re,
            l0: self.kernels.l0,
            phase: &self.particles.phase,
            fluid,
            s0: self.kernels.lap.s0_smooth,
            surface,
        }
    }

    /// Rebuilds the neighbour lists at `r*` when a particle lies more than half the skin from
    /// where they were built.
    pub(super) fn keep_neighbors_valid(&mut self, pred: &Predicted<D>) -> Result<(), Failure> {
        let (old, built) = (&self.particles.position, &self.lists_built_at);
        // On one process the lists may date from an earlier step (`update_neighbors`): the
        // largest moves since this step's start and since the lists, in one pass.
        let since_lists = !self.is_distributed() && built.len() == old.len();
        let moves = |i: usize| {
            let x = pred.pos[i];
            let b = if since_lists {
                (x - built[i]).norm2()
            } else {
                0.0
            };
            ((x - old[i]).norm(), b)
        };
        let larger = |a: (f64, f64), b: (f64, f64)| (a.0.max(b.0), a.1.max(b.1));
        let (max_move, since) = parallel::map_reduce(pred.pos.len(), (0.0, 0.0), moves, larger);
        let max_move = self.max(max_move);
        if !max_move.is_finite() {
            return Err(BreakdownReason::NotFinite.into());
        }
        let moved = match (self.is_distributed(), since_lists) {
            (true, _) => max_move,
            (false, true) => since.sqrt(),
            (false, false) => f64::INFINITY,
        };
        if 2.0 * moved > self.skin {
            self.timed(Stage::Neighbors, |s| s.renew_neighbors(&pred.pos));
        }
        Ok(())
    }

    /// Stage 2b: the collision model on `u*`, moving `r*` by the velocity change; returns
    /// the number of treated pairs. It reads the near lists cut at `r*` (timed with stage 3,
    /// which keeps them when the model moved no particle, as in most steps).
    pub(super) fn collide_near(&mut self, pred: &mut Predicted<D>, c: Collision, dt: f64) -> u64 {
        self.timed(Stage::DensitySurface, |s| s.cut_near_lists(&pred.pos));
        let (n, moved) = self.timed(Stage::Explicit, |s| s.collide(pred, c, dt));
        // Another process's collisions move this one's halo copies (`refresh_predicted`).
        if moved || self.is_distributed() {
            self.drop_near_lists();
        }
        n
    }

    /// [`Self::collide_near`]'s model: the number of treated pairs and whether any
    /// particle's velocity (and so position) changed.
    fn collide(&self, pred: &mut Predicted<D>, c: Collision, dt: f64) -> (u64, bool) {
        let v = self.view_of(&pred.pos, &pred.vel, None, None);
        let mut vel = self.spare.take();
        let n = collide(
            &v,
            (c.alpha * self.l0(), c.restitution, self.l0()),
            &mut vel,
        );
        let mut moved = false;
        for i in 0..pred.pos.len() {
            moved |= vel[i] != pred.vel[i];
            pred.pos[i] += (vel[i] - pred.vel[i]) * dt;
        }
        self.spare.give(std::mem::replace(&mut pred.vel, vel));
        (n, moved)
    }

    /// The neighbour lists cut to re_grad at positions `pos` for the pair loops that follow
    /// (the same pairs in the same order, a third of the candidates in 2D), until the
    /// particles move: the collision model's, if it moved none, and those of stages 3 to 5;
    /// dropped when the particles move (`correct`, a collision, a failed step).
    pub(super) fn cut_near_lists(&mut self, pos: &[Vector<D>]) {
        self.drop_near_lists();
        let mut near = self.spare_near.take().unwrap_or_default();
        self.neighbors
            .cut_into(pos, self.kernels.grad.re, &mut near);
        self.neighbors.near = Some(near);
    }

    /// Stage 3: number density at re_grad, free-surface flags and the closest pairs at
    /// positions `pos`, on the near lists cut at `pos` (cut here unless the collision
    /// model's are still in place).
    pub(super) fn density_and_surface(&mut self, pos: &[Vector<D>]) -> DensitySurface {
        let re = self.kernels.grad.re;
        if self.neighbors.near.is_none() {
            self.cut_near_lists(pos);
        }
        let mut nd = self.spare.take();
        nd.resize(pos.len(), 0.0);
        let (kind, owned, nl) = (&self.particles.kind, self.owned(), &self.neighbors);
        let radii = (re, 0.9 * self.l0());
        // The pair metrics of the own fluid particles from the same pairs.
        let density_and_closest = |i: usize, n: &mut f64| {
            if kind[i] != Kind::Fluid || i >= owned {
                *n = number_density(i, pos, nl, re);
                return (f64::INFINITY, 0);
            }
            let counts = |j: usize| kind[j] != Kind::Fluid || i < j;
            let (sum, m, c) = number_density_and_closest(i, pos, nl, radii, counts);
            *n = sum;
            (m, c)
        };
        let closest = parallel::for_each_mut_reduce(
            &mut nd,
            (f64::INFINITY, 0),
            density_and_closest,
            |a, b| (a.0.min(b.0), a.1 + b.1),
        );
        let input = SurfaceInput {
            pos,
            neighbors: &self.neighbors,
            number_density: &nd,
            kernels: &self.kernels,
        };
        let s = &self.scheme;
        let mut free_surface = self.spare.take();
        if self.full {
            free_surface.resize(pos.len(), false);
        } else {
            detect(
                &s.surface,
                &input,
                &self.particles.kind,
                s.wall_surface_test,
                &mut free_surface,
            );
        }
        DensitySurface {
            number_density: nd,
            free_surface,
            closest,
        }
    }

    /// Takes the near lists out of use (the particles moved, or the step failed), keeping
    /// their memory for the next step's.
    pub(super) fn drop_near_lists(&mut self) {
        if let Some(near) = self.neighbors.near.take() {
            self.spare_near = Some(near);
        }
    }

    /// Stage 3b: densities of wall and dummy particles from the fluid at `pos`.
    pub(super) fn update_wall_density(&mut self, pos: &[Vector<D>]) {
        let v = self.view_of(pos, pos, None, None);
        let (mut walls, mut density) = (self.spare.take(), self.spare.take());
        let bw = &self.particles.backing_wall;
        wall_densities(&v, bw, &self.kernels, &mut walls, &mut density);
        self.spare.give(walls);
        self.refresh_scalars(&mut density);
        // The step's only change to the particles before stage 6: undone on breakdown.
        let old = std::mem::replace(&mut self.particles.density, density);
        self.spare
            .give(std::mem::replace(&mut self.density_before, old));
        self.undo.density = true;
    }

    /// The densities of the PPE coefficient and the gradient: smoothed when the scheme says
    /// so, else `None` (the particles' own).
    pub(super) fn ppe_density(
        &self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
    ) -> Option<Vec<f64>> {
        self.scheme.density_smoothing.then(|| {
            let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
            smoothed_density(&v, &self.kernels)
        })
    }

    /// Stage 4: the PPE at the intermediate state, in the memory of the last step's system.
    pub(super) fn assemble(
        &mut self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
        density: &Option<Vec<f64>>,
        dt: f64,
    ) -> PressureSystem {
        let mut sys = self.last_system.take().unwrap_or_default();
        let open_elsewhere = self.open_elsewhere(pred, surf);
        let mut reference = self.pressure_reference();
        reference.open_elsewhere = open_elsewhere;
        if self.is_distributed() && !open_elsewhere {
            reference.at = Some(self.reference_particle(&pred.pos, &reference));
        }
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), density.as_deref());
        let previous = &self.particles.pressure;
        sys.surface_jump = self.surface_jump(pred, surf).unwrap_or_default();
        assemble_into(
            &v,
            previous,
            &self.kernels,
            &self.scheme,
            (self.gravity, dt),
            &reference,
            &mut sys,
        );
        if reference.at.is_some() {
            self.consistent_across(&mut sys);
        }
        sys
    }

    /// The Young-Laplace jump (Pa) of every free-surface particle at `r*` under its phase's
    /// free-surface tension (`None` where no phase has one).
    fn surface_jump(&self, pred: &Predicted<D>, surf: &DensitySurface) -> Option<Vec<f64>> {
        if self
            .interfaces
            .free_surface
            .iter()
            .all(|&sigma| sigma == 0.0)
        {
            return None;
        }
        let fluid = self.fluid_mask();
        let inp = self.tension_input(&pred.pos, &surf.free_surface, &fluid);
        laplace_jump(&inp, &self.interfaces.free_surface)
    }

    /// A distributed closed domain's reference particle: over every process's own fluid
    /// particles the one nearest to the reference position (or the highest), ties to the
    /// smallest id; its index here (own or halo), `NONE` where another process holds it.
    fn reference_particle(&mut self, pos: &[Vector<D>], r: &PressureReference<D>) -> u32 {
        let p = &self.particles;
        let key = |i: usize| match r.position {
            Some(x) => -(pos[i] - x).norm2(),
            None => pos[i][D - 1],
        };
        let fluid = |i: &usize| p.kind[*i] == Kind::Fluid;
        let own = self.owned();
        let best = (0..own)
            .filter(fluid)
            .map(key)
            .fold(f64::NEG_INFINITY, f64::max);
        let best = self.max(best);
        let p = &self.particles;
        let id = (0..own)
            .filter(|i| p.kind[*i] == Kind::Fluid && key(*i) == best)
            .map(|i| p.id[i] as f64)
            .fold(f64::INFINITY, f64::min);
        let id = self.min(id);
        let p = &self.particles;
        (0..p.len())
            .find(|&i| p.id[i] as f64 == id)
            .map_or(NONE, |i| i as u32)
    }

    /// A distributed closed domain's sources made consistent over the processes: their
    /// mean over every own row and the reference particle's own row removed (as
    /// `assemble_into` does on one process).
    fn consistent_across(&mut self, sys: &mut PressureSystem) {
        if sys.level.is_none() {
            return;
        }
        let owned = self.owned() as u32;
        let own_rows = sys.particle_of.partition_point(|&i| i < owned);
        let held = sys.level.is_some_and(|(r, _)| r != NONE && r < owned);
        let mut sums = [
            sys.rhs[..own_rows].iter().sum::<f64>() + sys.level_source * held as u8 as f64,
            (own_rows + held as usize) as f64,
        ];
        self.sum_over_processes(&mut sums);
        let mean = sums[0] / sums[1];
        sys.rhs.iter_mut().for_each(|b| *b -= mean);
    }

    /// The relative residual the PPE of a step `dt` (s) is solved to: the case's
    /// `solver.tolerance`, loosened by its volume rule ([`stopping_tolerance`]),
    /// from the right-hand side's norm over every process's own rows.
    fn solve_tolerance(&mut self, sys: &PressureSystem, dt: f64) -> f64 {
        let (tol, volume) = (self.case.solver.tolerance, self.case.solver.volume_rule());
        if volume <= 0.0 {
            return tol;
        }
        let owned = self.owned() as u32;
        let own_rows = sys.particle_of.partition_point(|&i| i < owned);
        let b = &sys.rhs[..own_rows];
        let mut sums = [b.iter().map(|v| v * v).sum::<f64>(), own_rows as f64];
        self.sum_over_processes(&mut sums);
        stopping_tolerance(tol, volume, sums[0].sqrt(), sums[1], dt)
    }

    /// Stage 4b: solves the PPE of a step `dt` (s) (warm start from the last pressures) and
    /// returns every particle's pressure (Pa): the Dirichlet value (0 or the mean-surface
    /// one) for Dirichlet and dummy particles, clamped if the scheme says so.
    pub(super) fn solve_pressure(
        &mut self,
        sys: PressureSystem,
        dt: f64,
        report: &mut StepReport,
    ) -> Result<Vec<f64>, Failure> {
        let tol = self.solve_tolerance(&sys, dt);
        let p = &self.particles;
        let mut x: Vec<f64> = self.spare.take();
        x.extend(sys.particle_of.iter().map(|&i| p.pressure[i as usize]));
        let t = std::time::Instant::now();
        let (result, solved) = match self.solve_across(&sys, &mut x, tol) {
            Some(r) => {
                let stats = r.unwrap_or_else(|e| e.stats);
                let solve = t.elapsed();
                (
                    r,
                    SolveReport {
                        stats,
                        solve,
                        ..Default::default()
                    },
                )
            }
            None => self.solver.solve(&sys, &mut x, &self.particles.id, tol),
        };
        self.timers.add(Stage::PpeSetup, solved.setup);
        self.timers.add(Stage::PpeSolve, solved.solve);
        report.solve = solved.stats;
        report.solver_fallback = solved.fallback;
        if result.is_err() {
            self.spare.give(x);
            return Err(BreakdownReason::SolverDiverged {
                iterations: solved.stats.iterations,
                residual: solved.stats.residual,
            }
            .into());
        }
        let clamp = self.scheme.clamp_negative_pressure;
        // A closed domain's level: every unknown offset by the reference value, which the
        // reference particle takes.
        self.closed = sys.level.is_some();
        let (reference, offset) = match sys.level {
            Some((r, value)) => (r as usize, value),
            None => (usize::MAX, 0.0),
        };
        let mut pressure = self.spare.take();
        parallel::map_into(&mut pressure, sys.row_of.len(), |i| {
            let p = match sys.row_of[i] {
                NONE if i == reference => offset,
                NONE => sys.dirichlet_value.get(i).copied().unwrap_or(0.0),
                r if sys.level.is_some() => x[r as usize] + offset,
                r => x[r as usize],
            };
            if clamp {
                p.max(0.0)
            } else {
                p
            }
        });
        self.spare.give(x);
        // Kept: the next step assembles into its memory (docs/decisions.md, "Reused PPE
        // buffers"), and benchmarks read it.
        self.last_system = Some(sys);
        Ok(pressure)
    }

    /// In a distributed run: true when another process's own particles hold a Dirichlet
    /// row (a free-surface fluid particle or an open or dry wall particle).
    fn open_elsewhere(&mut self, pred: &Predicted<D>, surf: &DensitySurface) -> bool {
        let Some(owned) = self.owned else {
            return false;
        };
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let re = self.kernels.lap.re;
        let local = (0..owned).any(|i| v.kind[i] != Kind::Dummy && is_dirichlet(i, &v, re));
        self.any(local)
    }

    /// Where a closed domain's pressure level is set (the case's `domain.pressure_reference`).
    fn pressure_reference(&self) -> PressureReference<D> {
        match &self.case.domain.pressure_reference {
            Some(r) => PressureReference {
                position: r.position.as_deref().and_then(Vector::from_slice),
                value: r.value,
                open_elsewhere: false,
                at: None,
            },
            None => PressureReference {
                position: None,
                value: 0.0,
                open_elsewhere: false,
                at: None,
            },
        }
    }

    /// Stage 5a: pressures of wall and dummy particles for the gradient, and which
    /// particles carry pressure into its stencil.
    pub(super) fn boundary_pressures(
        &self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
        pressure: &mut [f64],
    ) -> Vec<bool> {
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let s = &self.scheme;
        let (model, clamp) = (s.wall_pressure, s.clamp_negative_pressure);
        let bw = &self.particles.backing_wall;
        let (g, k) = (self.gravity, &self.kernels);
        let (mut carries, mut values) = (self.spare.take(), self.spare.take());
        let model = (model, clamp, self.closed);
        boundary_pressures(&v, bw, model, g, k, pressure, &mut values, &mut carries);
        self.spare.give(values);
        carries
    }

    /// Stage 5b: pressure acceleration `-grad p / rho` of every fluid particle (m/s^2);
    /// `carries` (stage 5a's) is kept for the next step.
    pub(super) fn pressure_acceleration(
        &self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
        density: &Option<Vec<f64>>,
        pressure: &[f64],
        carried: Vec<bool>,
    ) -> Vec<Vector<D>> {
        let carries: &[bool] = &carried;
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let vc = self.view_of(&pred.pos, &pred.vel, Some(surf), density.as_deref());
        let (k, s) = (&self.kernels, &self.scheme);
        let n = pred.pos.len();
        let mut ph = self.spare.take();
        if s.gradient.model != GradientModel::Taylor {
            parallel::map_into(&mut ph, n, |i| p_hat(i, &v, pressure, carries, k.grad.re));
        }
        let mut acc = self.spare.take();
        parallel::map_into(&mut acc, n, |i| {
            if v.kind[i] == Kind::Fluid {
                pressure_acceleration(i, &vc, pressure, &ph, carries, k, &s.gradient)
            } else {
                Vector::zero()
            }
        });
        self.spare.give(ph);
        self.spare.give(carried);
        acc
    }

    /// Stage 5c: Dynamic Stabilization (paper Eq. 7-19): the DS acceleration of every
    /// particle (m/s^2) and, with inelastic velocities, its velocity change (m/s), if the
    /// scheme has DS, and the number of active pairs.
    pub(super) fn stabilize(
        &self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
        acc: &[Vector<D>],
        dt: f64,
    ) -> (Option<DsArrays<D>>, u64) {
        let Some(ds) = &self.scheme.ds else {
            return (None, 0);
        };
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let owned = self.owned();
        let n = pred.pos.len();
        let (mut a, mut dv) = (self.spare.take(), self.spare.take());
        a.resize(n, Vector::zero());
        let inelastic = ds.velocity == DsVelocity::Inelastic;
        dv.resize(if inelastic { n } else { 0 }, Vector::zero());
        // Active pairs counted over the own particles (an integer sum: any order).
        let count = |i: usize, ai: &mut Vector<D>, dvi: Option<&mut Vector<D>>| {
            if v.kind[i] != Kind::Fluid {
                return 0;
            }
            let c = ds_acceleration(i, &v, acc, ds, &self.kernels, dt);
            *ai = c.acc;
            if let Some(d) = dvi {
                *d = c.dvel;
            }
            if i < owned {
                c.active as u64
            } else {
                0
            }
        };
        let add = |x: u64, y: u64| x + y;
        let active = if inelastic {
            let with_dv = |i, ai: &mut _, d: &mut _| count(i, ai, Some(d));
            parallel::for_each_mut2_reduce(&mut a, &mut dv, 0, with_dv, add)
        } else {
            parallel::for_each_mut_reduce(&mut a, 0, |i, ai| count(i, ai, None), add)
        };
        let dvel = inelastic.then_some(dv);
        (Some(DsArrays { acc: a, dvel }), active)
    }

    /// Stage 5d: particle shifting (beyond the paper, `numerics::shifting`) at `r*`: every
    /// particle's shift (m), if the scheme has it, for a step whose largest travel is the
    /// largest fluid speed `|u*|` times `dt`.
    pub(super) fn shift(
        &mut self,
        pred: &Predicted<D>,
        surf: &DensitySurface,
        dt: f64,
    ) -> Option<Vec<Vector<D>>> {
        let s = self.scheme.shifting?;
        let kind = &self.particles.kind;
        let speed = |i: usize| match kind[i] {
            Kind::Fluid => pred.vel[i].norm(),
            _ => 0.0,
        };
        let u_max = parallel::map_reduce(self.owned(), 0.0, speed, f64::max);
        let travel = self.max(u_max) * dt;
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let phase = &self.particles.phase;
        let mut shifts = self.spare.take();
        parallel::map_into(&mut shifts, pred.pos.len(), |i| {
            shift(i, &v, phase, &self.kernels, &s, travel)
        });
        Some(shifts)
    }

    /// Ids of a fluid particle and its neighbour at distance `r` (m), the closest pair of
    /// [`Self::pair_metrics`] (for the breakdown record).
    fn pair_at(&self, pred: &Predicted<D>, surf: &DensitySurface, r: f64) -> Vec<u32> {
        let v = self.view_of(&pred.pos, &pred.vel, Some(surf), None);
        let re = self.kernels.grad.re;
        (0..pred.pos.len())
            .filter(|&i| v.kind[i] == Kind::Fluid)
            .find_map(|i| v.pairs(i, re).find(|q| q.r == r).map(|q| (i, q.j)))
            .map_or_else(Vec::new, |(i, j)| {
                vec![self.particles.id[i], self.particles.id[j]]
            })
    }

    /// Stage 7: with `domain.outflow = "remove"`, fluid particles more than l0 beyond the
    /// domain box are removed (counted in [`Simulation::outflow_removed`]); the neighbour
    /// list and any kept solver set-up refer to the old numbering and are rebuilt. Returns
    /// the number removed this step.
    pub(super) fn remove_outflow(&mut self) -> u64 {
        let lim = self.limits();
        if !lim.outflow {
            return 0;
        }
        let p = &self.particles;
        let mut keep = Vec::new();
        parallel::map_into(&mut keep, p.len(), |i| {
            let x = p.position[i];
            p.kind[i] != Kind::Fluid || (0..D).all(|k| x[k] >= lim.lo[k] && x[k] <= lim.hi[k])
        });
        // On several processes: each removes its own and its halo's leavers alike (the same
        // positions), and counts its own.
        let own = self.owned();
        let own_removed = keep[..own].iter().filter(|&&k| !k).count();
        let removed = self.sum(own_removed as u64);
        self.outflow_removed += removed;
        if keep.iter().all(|&k| k) {
            return removed;
        }
        self.particles.retain(&keep);
        if let Some(owned) = &mut self.owned {
            *owned -= own_removed;
        }
        self.solver.reset();
        self.rebuild_neighbors();
        removed
    }

    /// Stage 6: `u = u* + dt a`, `r = r* + dt^2 a + delta r` with `a` the pressure and DS
    /// accelerations and `delta r` the shift, if any; the new state is checked and stored
    /// (the step restores the old one on failure). Returns the largest fluid speed (m/s).
    pub(super) fn correct(
        &mut self,
        (pred, surf): (Predicted<D>, DensitySurface),
        (acc, ds, shifts): (&[Vector<D>], Option<&DsArrays<D>>, Option<&[Vector<D>]>),
        pressure: Vec<f64>,
        min_pair: f64,
        dt: f64,
    ) -> Result<f64, Failure> {
        let lim = self.limits();
        // The closest pair's ids for the breakdown record, found at r* before r* is
        // overwritten by the corrected positions.
        let pair = (min_pair < lim.min_pair).then(|| self.pair_at(&pred, &surf, min_pair));
        // u = u* + dt a, r = r* + dt^2 a (+ shift), written over u* and r* (no new vectors).
        let Predicted { mut pos, mut vel } = pred;
        let p = &self.particles;
        parallel::for_each_mut2(&mut pos, &mut vel, |i, x, u| {
            if p.kind[i] != Kind::Fluid {
                return;
            }
            let a = match ds {
                Some(ds) => acc[i] + ds.acc[i],
                None => acc[i],
            };
            *x += a * (dt * dt);
            if let Some(d) = shifts {
                *x += d[i];
            }
            match ds.and_then(|d| d.dvel.as_deref()) {
                Some(dv) => *u += acc[i] * dt + dv[i],
                None => *u += a * dt,
            }
        });
        let own = self.owned();
        let (o_pos, o_vel, o_p) = (&pos[..own], &vel[..own], &pressure[..own]);
        let mut result = check_state(p, o_pos, o_vel, o_p, min_pair, &lim);
        if let Err(f) = &mut result {
            if matches!(f.reason, BreakdownReason::Penetration { .. }) {
                f.particles = pair.unwrap_or_default();
            }
        }
        if self.is_distributed() {
            // Every process learns whether any broke down, and the largest speed.
            let failed = self.any(result.is_err());
            result = match result {
                Ok(_) if failed => Err(BreakdownReason::Elsewhere.into()),
                Ok(u) => Ok(self.max(u)),
                e => e,
            };
        }
        // The near lists were cut at r*: the particles now leave it.
        self.drop_near_lists();
        let spare = &self.spare;
        if result.is_err() {
            // The particles stay as they were (the step undoes its other changes).
            for v in [pos, vel] {
                spare.give(v);
            }
            spare.give(pressure);
            spare.give(surf.number_density);
            spare.give(surf.free_surface);
            return result;
        }
        let p = &mut self.particles;
        spare.give(std::mem::replace(&mut p.velocity, vel));
        spare.give(std::mem::replace(&mut p.position, pos));
        spare.give(std::mem::replace(&mut p.pressure, pressure));
        spare.give(std::mem::replace(
            &mut p.number_density,
            surf.number_density,
        ));
        spare.give(std::mem::replace(&mut p.free_surface, surf.free_surface));
        result
    }
}
