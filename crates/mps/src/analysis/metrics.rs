//! Stability metrics every run records (cases.md, "Stability metrics"), one row of
//! `metrics.csv` per output.

use super::surface::surface_counts_of;
use crate::particles::Kind;
use crate::simulation::Simulation;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Metrics of the state at one output time. Energies and momenta are per unit depth in 2D
/// (particle mass `rho l0^d`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Simulated time (s).
    pub time: f64,
    /// Step number.
    pub step: u64,
    /// Last time step (s).
    pub dt: f64,
    /// Kinetic energy (J).
    pub kinetic_energy: f64,
    /// Potential energy relative to y = 0 (J).
    pub potential_energy: f64,
    /// Linear momentum x component (kg m/s).
    pub momentum_x: f64,
    /// Linear momentum y component (kg m/s).
    pub momentum_y: f64,
    /// Linear momentum z component (kg m/s; 0 in 2D).
    pub momentum_z: f64,
    /// Angular momentum about the origin, z component (kg m^2/s).
    pub angular_momentum: f64,
    /// Angular momentum about the origin, x component (kg m^2/s; 0 in 2D).
    pub angular_momentum_x: f64,
    /// Angular momentum about the origin, y component (kg m^2/s; 0 in 2D).
    pub angular_momentum_y: f64,
    /// Smallest fluid pair distance / l0 (of the last step).
    #[serde(rename = "min_pair_distance_l0")]
    pub min_pair_distance: f64,
    /// Pairs closer than 0.9 l0.
    pub close_pairs: u64,
    /// Mean of n/n0 over interior (non-surface) fluid particles.
    pub nd_mean: f64,
    /// Standard deviation of n/n0 over interior fluid particles.
    pub nd_spread: f64,
    /// PPE iterations of the last step.
    pub ppe_iterations: usize,
    /// PPE final relative residual of the last step.
    pub ppe_residual: f64,
    /// Largest fluid speed (m/s).
    pub max_speed: f64,
    /// Root-mean-square fluid speed (m/s).
    pub rms_speed: f64,
    /// DS-active pairs in the last step.
    pub ds_active: u64,
    /// Fluid particles on the free surface.
    pub surface_particles: usize,
    /// Fluid particles flagged free surface that lie deep inside the body (about 2 l0 or
    /// more, judged by geometry, not by the flag: `analysis::surface`).
    pub false_surface: usize,
    /// Flagged fluid particles with no unflagged fluid neighbour within re_grad.
    pub surface_skin: usize,
    /// Fluid particles with at most one fluid neighbour within re_grad.
    pub isolated: usize,
    /// Fluid particles removed so far after leaving the domain (`domain.outflow`).
    pub outflow_removed: u64,
}

/// Sums over fluid particles (energies, momenta, number-density moments).
#[derive(Default, Clone, Copy)]
struct Acc {
    ke: f64,
    u2: f64,
    n: f64,
    pe: f64,
    mom: [f64; 3],
    ang: [f64; 3],
    nd: f64,
    nd2: f64,
    count: f64,
    surf: usize,
}

impl Acc {
    /// The sums as numbers (to be summed over a distributed run's processes).
    fn to_array(self) -> [f64; 16] {
        let [m0, m1, m2] = self.mom;
        let [a0, a1, a2] = self.ang;
        [
            self.ke,
            self.u2,
            self.n,
            self.pe,
            m0,
            m1,
            m2,
            a0,
            a1,
            a2,
            self.nd,
            self.nd2,
            self.count,
            self.surf as f64,
            0.0,
            0.0,
        ]
    }

    /// The sums back from [`Self::to_array`].
    fn from_array(v: [f64; 16]) -> Acc {
        Acc {
            ke: v[0],
            u2: v[1],
            n: v[2],
            pe: v[3],
            mom: [v[4], v[5], v[6]],
            ang: [v[7], v[8], v[9]],
            nd: v[10],
            nd2: v[11],
            count: v[12],
            surf: v[13] as usize,
        }
    }

    /// The sums of `self` and `a`.
    fn plus(mut self, a: &Acc) -> Acc {
        self.ke += a.ke;
        self.u2 += a.u2;
        self.n += a.n;
        self.pe += a.pe;
        for k in 0..3 {
            self.mom[k] += a.mom[k];
            self.ang[k] += a.ang[k];
        }
        self.nd += a.nd;
        self.nd2 += a.nd2;
        self.count += a.count;
        self.surf += a.surf;
        self
    }
}

impl Metrics {
    /// Measures the current state of a simulation (over every process's own particles).
    pub fn measure<const D: usize>(sim: &Simulation<D>) -> Metrics {
        let p = &sim.particles;
        let l0 = sim.l0();
        let vol = l0.powi(D as i32);
        let g = sim.gravity;
        let n0 = sim.kernels.grad.n0;
        let idx: Vec<usize> = (0..sim.owned())
            .filter(|&i| p.kind[i] == Kind::Fluid)
            .collect();
        // Fixed-order reduction: chunks in parallel, summed in sequence.
        let parts: Vec<Acc> = idx
            .par_chunks(4096)
            .map(|c| {
                let mut a = Acc::default();
                for &i in c {
                    let m = p.density[i] * vol;
                    let u = p.velocity[i];
                    let x = p.position[i];
                    a.ke += 0.5 * m * u.norm2();
                    a.u2 += u.norm2();
                    a.n += 1.0;
                    a.pe -= m * g.dot(&x);
                    let (um, l) = (u.padded(), x.cross3(&u));
                    for k in 0..3 {
                        a.mom[k] += m * um[k];
                        a.ang[k] += m * l[k];
                    }
                    if p.free_surface[i] {
                        a.surf += 1;
                    } else {
                        let r = p.number_density[i] / n0;
                        a.nd += r;
                        a.nd2 += r * r;
                        a.count += 1.0;
                    }
                }
                a
            })
            .collect();
        let mut sums = parts.iter().fold(Acc::default(), Acc::plus).to_array();
        sim.sum_over_processes(&mut sums);
        let t = Acc::from_array(sums);
        let mean = if t.count > 0.0 { t.nd / t.count } else { 0.0 };
        let var = if t.count > 0.0 {
            (t.nd2 / t.count - mean * mean).max(0.0)
        } else {
            0.0
        };
        let r = &sim.last;
        let sc = surface_counts_of(sim);
        Metrics {
            time: sim.time,
            step: sim.step_count,
            dt: r.dt,
            kinetic_energy: t.ke,
            potential_energy: t.pe,
            momentum_x: t.mom[0],
            momentum_y: t.mom[1],
            momentum_z: t.mom[2],
            angular_momentum: t.ang[2],
            angular_momentum_x: t.ang[0],
            angular_momentum_y: t.ang[1],
            min_pair_distance: if r.min_pair_distance > 0.0 {
                r.min_pair_distance / l0
            } else {
                f64::NAN
            },
            close_pairs: r.close_pairs,
            nd_mean: mean,
            nd_spread: var.sqrt(),
            ppe_iterations: r.solve.iterations,
            ppe_residual: r.solve.residual,
            max_speed: r.max_speed,
            rms_speed: if t.n > 0.0 { (t.u2 / t.n).sqrt() } else { 0.0 },
            ds_active: r.ds_active,
            surface_particles: t.surf,
            false_surface: sc.false_surface,
            surface_skin: sc.surface_skin,
            isolated: sc.isolated,
            outflow_removed: sim.outflow_removed,
        }
    }
}

/// The dam-break surge front (m): the largest x of a fluid particle that belongs to the
/// continuous body, i.e. has at least two fluid neighbours within re_grad. Single particles
/// skidding ahead along the floor are spray, not the front an experiment records.
pub fn front_position<const D: usize>(sim: &Simulation<D>) -> f64 {
    front_among(sim, FRONT_CANDIDATES)
}

/// How many of the fluid particles farthest along x [`front_position`] tries in turn before
/// it tests every fluid particle (recorded every step: the test of every particle cost the
/// `dam_break` example 8 % of its run; docs/decisions.md, "The front from its candidates").
const FRONT_CANDIDATES: usize = 16;

/// [`front_position`] from the `n` (at most [`FRONT_CANDIDATES`]) farthest fluid
/// particles, farthest first; where none of them is in the body, from every fluid particle.
fn front_among<const D: usize>(sim: &Simulation<D>, n: usize) -> f64 {
    let p = &sim.particles;
    let v = sim.view();
    let re = sim.kernels.grad.re;
    let in_body = |i: usize| {
        let fluid = v.pairs(i, re).filter(|q| p.kind[q.j] == Kind::Fluid);
        fluid.take(2).count() >= 2
    };
    // The farthest fluid particles by insertion, farthest first (a position that is not a
    // number has no neighbours: never in the body).
    let n = n.clamp(1, FRONT_CANDIDATES);
    let mut far = [(f64::NEG_INFINITY, 0); FRONT_CANDIDATES];
    let mut held = 0;
    for i in 0..sim.owned() {
        let x = p.position[i][0];
        if p.kind[i] != Kind::Fluid || x.is_nan() || (held == n && x <= far[n - 1].0) {
            continue;
        }
        held = (held + 1).min(n);
        let mut k = held - 1;
        while k > 0 && far[k - 1].0 < x {
            far[k] = far[k - 1];
            k -= 1;
        }
        far[k] = (x, i);
    }
    let own = match far[..held].iter().find(|c| in_body(c.1)) {
        Some(c) => c.0,
        None if held < n => f64::MIN,
        None => (0..sim.owned())
            .into_par_iter()
            .filter(|&i| p.kind[i] == Kind::Fluid && in_body(i))
            .map(|i| p.position[i][0])
            .reduce(|| f64::MIN, f64::max),
    };
    sim.max_over_processes(own)
}

/// Largest x of any fluid particle (m).
pub fn leading_particle<const D: usize>(sim: &Simulation<D>) -> f64 {
    let p = &sim.particles;
    let own = (0..sim.owned())
        .filter(|&i| p.kind[i] == Kind::Fluid)
        .map(|i| p.position[i][0])
        .fold(f64::MIN, f64::max);
    sim.max_over_processes(own)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::Case;

    /// The front by its definition, over every pair of particles (no lists).
    fn front_by_every_pair(sim: &Simulation<2>) -> f64 {
        let p = &sim.particles;
        let re = sim.kernels.grad.re;
        let fluid = |i: usize| p.kind[i] == Kind::Fluid;
        (0..p.len())
            .filter(|&i| fluid(i))
            .filter(|&i| {
                let near = |j: usize| {
                    let r = (p.position[j] - p.position[i]).norm();
                    r > 0.0 && r < re
                };
                (0..p.len()).filter(|&j| fluid(j) && near(j)).count() >= 2
            })
            .map(|i| p.position[i][0])
            .fold(f64::MIN, f64::max)
    }

    /// The farthest fluid particle made spray (its fluid neighbours turned to walls): the
    /// front from the candidates and from every particle (one candidate: the fallback) is
    /// the body's, as by the definition over every pair.
    #[test]
    fn the_front_skips_spray_ahead_of_the_body() {
        let text = crate::input::examples::example("dam_break").expect("built in");
        let case = Case::from_str_named(text, "dam_break", &[]).expect("valid");
        let mut sim = Simulation::<2>::new(case, "dam_break").expect("builds");
        sim.step(f64::INFINITY).expect("a step");
        let body = front_by_every_pair(&sim);
        assert_eq!(front_among(&sim, FRONT_CANDIDATES), body);
        // The farthest fluid particle loses its fluid neighbours.
        let re = sim.kernels.grad.re;
        let p = &mut sim.particles;
        let fluid = (0..p.len()).filter(|&i| p.kind[i] == Kind::Fluid);
        let f = fluid.max_by(|&a, &b| p.position[a][0].total_cmp(&p.position[b][0]));
        let f = f.expect("fluid");
        for j in 0..p.len() {
            let r = (p.position[j] - p.position[f]).norm();
            if j != f && r < re && p.kind[j] == Kind::Fluid {
                p.kind[j] = Kind::Wall;
            }
        }
        let front = front_by_every_pair(&sim);
        let farthest = sim.particles.position[f][0];
        assert!(
            front < farthest && front < body,
            "{front} {farthest} {body}"
        );
        assert_eq!(front_among(&sim, FRONT_CANDIDATES), front);
        assert_eq!(front_among(&sim, 1), front);
        assert_eq!(front_position(&sim), front);
    }
}
