//! Collision model of standard MPS (Koshizuka's reference code; equations.md s.5, step 2):
//! approaching pairs closer than `alpha l0` lose `(1 + e) m_j / (m_i + m_j)` of their normal
//! approach velocity; walls are immovable.

use crate::particles::{Kind, Vector, View};
use rayon::prelude::*;

/// Collision model parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collision {
    /// Pairs closer than `alpha l0` are treated (dimensionless).
    pub alpha: f64,
    /// Coefficient of restitution (dimensionless).
    pub restitution: f64,
}

/// Velocities (m/s) after the collision model at distance `dist` (m), into `vel`; returns
/// the number of treated pairs.
pub fn collide<const D: usize>(v: &View<D>, dist: f64, e: f64, vel: &mut Vec<Vector<D>>) -> u64 {
    vel.clear();
    vel.resize(v.pos.len(), Vector::zero());
    let treated: u64 = vel
        .par_iter_mut()
        .enumerate()
        .map(|(i, out)| {
            if v.kind[i] != Kind::Fluid {
                *out = v.vel[i];
                return 0;
            }
            let mut u = v.vel[i];
            let mut count = 0;
            for q in v.pairs(i, dist) {
                let en = q.xij / q.r;
                let vn = (v.vel[q.j] - v.vel[i]).dot(&en);
                if vn >= 0.0 {
                    continue;
                }
                let share = if v.kind[q.j] == Kind::Fluid {
                    v.density[q.j] / (v.density[i] + v.density[q.j])
                } else {
                    1.0
                };
                u += en * ((1.0 + e) * share * vn);
                count += 1;
            }
            *out = u;
            count
        })
        .sum();
    treated / 2
}
