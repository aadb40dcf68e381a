//! Diagnostics of fluid groups (settling and surfacing blobs, layers): centroid, velocity,
//! stray particles, and pressure noise near the groups (issue 4).

use crate::particles::{Kind, Vector, NO_GROUP};
use crate::simulation::Simulation;

/// State of one group at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupState<const D: usize> {
    /// Mass-weighted centroid (m).
    pub centroid: Vector<D>,
    /// Mean velocity (m/s).
    pub velocity: Vector<D>,
    /// Number of particles.
    pub count: usize,
    /// Particles with no neighbour of the same phase within re_grad (numerical mixing).
    pub stray: usize,
}

/// The state of every group (indexed by group number) at the simulation's current time,
/// over every process's own particles.
pub fn group_states<const D: usize>(sim: &Simulation<D>, groups: usize) -> Vec<GroupState<D>> {
    let p = &sim.particles;
    let v = sim.view();
    let re = sim.kernels.grad.re;
    let mut out: Vec<GroupState<D>> = (0..groups)
        .map(|_| GroupState {
            centroid: Vector::zero(),
            velocity: Vector::zero(),
            count: 0,
            stray: 0,
        })
        .collect();
    for i in 0..sim.owned() {
        let g = p.group[i];
        if g == NO_GROUP || p.kind[i] != Kind::Fluid || g as usize >= groups {
            continue;
        }
        let s = &mut out[g as usize];
        s.centroid += p.position[i];
        s.velocity += p.velocity[i];
        s.count += 1;
        let has_mate = v
            .pairs(i, re)
            .any(|q| p.kind[q.j] == Kind::Fluid && p.phase[q.j] == p.phase[i]);
        if !has_mate {
            s.stray += 1;
        }
    }
    summed_over_processes(sim, &mut out);
    for s in &mut out {
        if s.count > 0 {
            s.centroid = s.centroid / s.count as f64;
            s.velocity = s.velocity / s.count as f64;
        }
    }
    out
}

/// The groups' sums (centroid and velocity sums, counts) over the processes.
fn summed_over_processes<const D: usize>(sim: &Simulation<D>, out: &mut [GroupState<D>]) {
    if !sim.is_distributed() {
        return;
    }
    let mut v: Vec<f64> = Vec::with_capacity(out.len() * (2 * D + 2));
    for s in out.iter() {
        v.extend_from_slice(&s.centroid.0);
        v.extend_from_slice(&s.velocity.0);
        v.extend([s.count as f64, s.stray as f64]);
    }
    sim.sum_over_processes(&mut v);
    for (s, c) in out.iter_mut().zip(v.chunks_exact(2 * D + 2)) {
        s.centroid = Vector(std::array::from_fn(|a| c[a]));
        s.velocity = Vector(std::array::from_fn(|a| c[D + a]));
        s.count = c[2 * D] as usize;
        s.stray = c[2 * D + 1] as usize;
    }
}

/// Pressure noise near the groups (Pa): RMS over group particles and their fluid neighbours
/// within re_grad of `p_i - pbar_i`, `pbar_i` the kernel-weighted mean pressure of i's fluid neighbours
/// within re_grad. A smooth (e.g. hydrostatic) field gives a small value.
pub fn pressure_noise<const D: usize>(sim: &Simulation<D>) -> f64 {
    let p = &sim.particles;
    let v = sim.view();
    let re = sim.kernels.grad.re;
    let in_group = |i: usize| p.group[i] != NO_GROUP && p.kind[i] == Kind::Fluid;
    // A group particle, or a fluid particle with one within re_grad (the pairs are mutual).
    let near = |i: usize| {
        in_group(i) || (p.kind[i] == Kind::Fluid && v.pairs(i, re).any(|q| in_group(q.j)))
    };
    let (mut s2, mut n) = (0.0, 0usize);
    for i in (0..sim.owned()).filter(|&i| near(i)) {
        let (mut sw, mut swp) = (0.0, 0.0);
        for q in v.pairs(i, re) {
            if p.kind[q.j] == Kind::Fluid {
                sw += q.w;
                swp += q.w * p.pressure[q.j];
            }
        }
        if sw > 0.0 {
            s2 += (p.pressure[i] - swp / sw).powi(2);
            n += 1;
        }
    }
    let mut sums = [s2, n as f64];
    sim.sum_over_processes(&mut sums);
    if sums[1] == 0.0 {
        0.0
    } else {
        (sums[0] / sums[1]).sqrt()
    }
}
