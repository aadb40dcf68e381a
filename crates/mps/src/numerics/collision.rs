//! Collision model of standard MPS (Koshizuka's reference code; equations.md s.5, step 2):
//! approaching pairs closer than `alpha l0` lose `(1 + e) m_j / (m_i + m_j)` of their normal
//! approach velocity; walls are immovable.
//!
//! Walls are also treated as the surface their particles stand for (a departure from the
//! reference code; docs/decisions.md, "A wall gap"): a wall row leaves gaps of `l0`, and a
//! particle heading for the middle of one stays `l0 / 2` from both wall particles, so at
//! `alpha = 0.5` no pair collides and a lone spray particle flies through the wall. A fluid
//! particle that no wall pair collided with, closer than `l0 / 4` to the local wall plane
//! (normal `n` from its wall and dummy neighbours within `1.5 l0`, pointing into the fluid;
//! the plane through the wall particle nearest along it), that moves into it loses `(1 + e)`
//! of that normal velocity, as against an immovable pair partner.

use crate::parallel;
use crate::particles::{Kind, Vector, View};

/// Collision model parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collision {
    /// Pairs closer than `alpha l0` are treated (dimensionless).
    pub alpha: f64,
    /// Coefficient of restitution (dimensionless).
    pub restitution: f64,
}

/// How far the wall plane's normal is gathered (in spacings).
const WALL_REACH: f64 = 1.5;

/// Distance from the wall plane (in spacings) at which a particle collides with it: a
/// quarter spacing, well inside the half spacing the wall particles' cells reach out (at
/// the pair model's half spacing the plane also caught the dam-break front's bottom row
/// and moved its front; docs/decisions.md, "A wall gap").
const WALL_PLANE: f64 = 0.25;

/// The plane collision needs a wall particle nearer than this (in spacings): a particle
/// entering a gap of the wall row within `l0 / 4` of it is at most 0.56 l0 from the two
/// beside it, while one in a corner, a spacing from both walls, has none nearer than `l0`
/// (there the plane through the nearest wall particle along the mean normal would lie on
/// the particle itself).
const WALL_NEAR: f64 = 0.75;

/// Velocities (m/s) after the collision model at distance `dist` (m) with restitution `e`
/// at spacing `l0` (m), into `vel`; returns the number of treated pairs.
pub fn collide<const D: usize>(
    v: &View<D>,
    (dist, e, l0): (f64, f64, f64),
    vel: &mut Vec<Vector<D>>,
) -> u64 {
    vel.clear();
    vel.resize(v.pos.len(), Vector::zero());
    let one = |i: usize, out: &mut Vector<D>| {
        if v.kind[i] != Kind::Fluid {
            *out = v.vel[i];
            return 0;
        }
        let (u, count) = collide_one(i, v, (dist, e, l0));
        *out = u;
        count
    };
    let treated = parallel::for_each_mut_reduce(vel, 0u64, one, |a, b| a + b);
    treated / 2
}

/// Fluid particle `i`'s velocity after the model and its number of treated pairs and planes.
fn collide_one<const D: usize>(
    i: usize,
    v: &View<D>,
    (dist, e, l0): (f64, f64, f64),
) -> (Vector<D>, u64) {
    let (reach, near) = (WALL_REACH * l0, WALL_NEAR * l0);
    let mut u = v.vel[i];
    let mut count = 0;
    let mut hit_wall = false;
    // One scan of the list for the pairs within `dist` and the wall plane's sums within
    // `reach`, each radius tested as the pair loop tests it (the same pairs, the same values).
    let mut sum = Vector::<D>::zero();
    let mut nearest = f64::INFINITY;
    let (far_pair, far_wall) = (dist * dist * (1.0 + 1e-9), reach * reach * (1.0 + 1e-9));
    let far = far_pair.max(far_wall);
    let xi = v.pos[i];
    for &j in v.neighbors.for_radius(dist.max(reach)).of(i) {
        let j = j as usize;
        let xij = v.pos[j] - xi;
        let r2 = xij.norm2();
        if r2 > far {
            continue;
        }
        let r = r2.sqrt();
        if r2 <= far_pair && r > 0.0 && r < dist {
            let en = xij / r;
            let vn = (v.vel[j] - v.vel[i]).dot(&en);
            if vn < 0.0 {
                let share = if v.kind[j] == Kind::Fluid {
                    v.density[j] / (v.density[i] + v.density[j])
                } else {
                    hit_wall = true;
                    1.0
                };
                u += en * ((1.0 + e) * share * vn);
                count += 1;
            }
        }
        if r2 <= far_wall && r > 0.0 && r < reach && v.kind[j] != Kind::Fluid {
            // xij = x_j - x_i: from i to the wall particle; weighted toward the nearest.
            sum -= xij * (1.0 / (r * r));
            nearest = nearest.min(r);
        }
    }
    if !hit_wall {
        if let Some(n) = wall_plane(i, v, (sum, nearest), reach, WALL_PLANE * l0, near) {
            let vn = u.dot(&n);
            if vn < 0.0 {
                u -= n * ((1.0 + e) * vn);
                count += 1;
            }
        }
    }
    (u, count)
}

/// The unit normal (into the fluid) of the wall plane that fluid particle `i` is closer to
/// than `dist` (m), from the sums over its wall and dummy neighbours within `reach` (m) of
/// `-x_ij / r^2` and of the nearest distance; `None` when it has none, none nearer than
/// `near` (m), or is farther.
fn wall_plane<const D: usize>(
    i: usize,
    v: &View<D>,
    (sum, nearest): (Vector<D>, f64),
    reach: f64,
    dist: f64,
    near: f64,
) -> Option<Vector<D>> {
    let len = sum.norm();
    if nearest >= near || len == 0.0 {
        return None;
    }
    let n = sum * (1.0 / len);
    let gap = v
        .pairs(i, reach)
        .filter(|q| v.kind[q.j] != Kind::Fluid)
        .map(|q| -q.xij.dot(&n))
        .fold(f64::INFINITY, f64::min);
    (gap < dist).then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::view::Cloud;

    /// A wall of three rows (x = 0, -l0, -2 l0, spaced l0 in y) and one fluid particle
    /// heading at 1 m/s for the middle of a gap of its first row, `d` l0 in front of it.
    fn shot(d: f64) -> Vector<2> {
        let l0 = 0.01;
        let mut pos = Vec::new();
        for a in 0..3 {
            for b in -3..=3 {
                pos.push(Vector([-(a as f64) * l0, b as f64 * l0]));
            }
        }
        let walls = pos.len();
        pos.push(Vector([d * l0, 0.5 * l0]));
        let n = pos.len();
        let mut vel = vec![Vector::zero(); n];
        vel[walls] = Vector([-1.0, 0.0]);
        let mut cloud = Cloud::new(pos, vel, vec![1000.0; n], 0.0, 3.1 * l0);
        cloud.set_walls(|x| x[0] < 0.1 * l0);
        let mut out = Vec::new();
        collide(&cloud.view(), (0.5 * l0, 0.2, l0), &mut out);
        out[walls]
    }

    /// The particle 0.2 l0 in front of the gap is 0.54 l0 from both wall particles (no pair
    /// collides, and none would before it reached the wall row), yet within a quarter
    /// spacing of the wall: it rebounds at `e` of its speed. At 0.4 l0 it is left alone.
    #[test]
    fn a_particle_shot_at_a_wall_gap_rebounds() {
        let u = shot(0.2);
        assert!((u[0] - 0.2).abs() < 1e-12 && u[1].abs() < 1e-12, "{u:?}");
        assert_eq!(shot(0.4), Vector([-1.0, 0.0]));
    }
}
