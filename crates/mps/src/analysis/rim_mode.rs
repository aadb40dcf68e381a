//! The centrifugal Rayleigh-Taylor instability of a rotating disc's free surface: the
//! measured growth of one azimuthal mode of the surface against linear theory.
//!
//! A disc of inviscid fluid in solid rotation at `Omega` with a free surface and no surface
//! tension is an exact steady state, but not a stable one: a surface displacement
//! `eta ~ exp(i (n theta - sigma t))` (rotating frame) with a potential perturbation obeys
//! `sigma^2 + 2 Omega sigma + n Omega^2 = 0`, so every mode `n >= 2` grows at
//! `gamma = Omega sqrt(n - 1)` (the surface-tension-free limit of Hocking & Michael 1959;
//! Dubey, Roy & Subramanian 2021, JFM, "Linear stability of a rotating liquid column
//! revisited": with viscosity stable only for `rho Omega^2 R^3 / gamma_s < n^2 - 1`). With a
//! surface tension the Young-Laplace jump adds `- T n (n^2 - 1)`, `T = gamma_s / (rho R^3)`,
//! and the inviscid planar mode grows at `sqrt((n - 1) (Omega^2 - T n (n + 1)))` (stable for
//! `rho Omega^2 R^3 / gamma_s < n (n + 1)`, derived here; [`linear_amplitude`]). From an
//! undisplaced surface with radial velocity amplitude `U` in mode `n`, `|eta_n(t)| = (U /
//! gamma) sinh(gamma t)`: the growing and the decaying root share the rotation `-Omega`.

use crate::particles::{Kind, Particles, Vector};
use std::collections::HashMap;

/// The particles of a disc's outermost row at `t = 0` and what the mode measure needs of
/// them: ids, initial radii (m) about `center` (m).
#[derive(Debug, Clone)]
pub struct RimMode<const D: usize> {
    /// Centre of the disc (m).
    pub center: Vector<D>,
    /// Azimuthal mode number `n`.
    pub mode: u32,
    /// Initial radius (m) of each rim particle, by id.
    initial: HashMap<u32, f64>,
    /// `U`: amplitude of mode `n` of the rim's initial radial velocity (m/s).
    pub initial_velocity: f64,
}

/// Polar coordinates `(r, theta)` of `x` about `c` in the x-y plane.
fn polar<const D: usize>(x: Vector<D>, c: Vector<D>) -> (f64, f64) {
    let (dx, dy) = (x[0] - c[0], x[1] - c[1]);
    (dx.hypot(dy), dy.atan2(dx))
}

/// `|(2/N) sum_k a_k exp(-i n theta_k)|` over `(a_k, theta_k)`: the amplitude of mode `n` of
/// a quantity sampled at angles `theta_k` around a circle.
fn mode_amplitude(samples: impl Iterator<Item = (f64, f64)>, n: u32) -> f64 {
    amplitude_of(mode_sums(samples, n))
}

/// The sums `[Re, Im, count]` (m, m, 1) of mode `n` over `(displacement, angle)` samples.
fn mode_sums(samples: impl Iterator<Item = (f64, f64)>, n: u32) -> [f64; 3] {
    let mut s = [0.0; 3];
    for (a, theta) in samples {
        let phase = n as f64 * theta;
        s[0] += a * phase.cos();
        s[1] -= a * phase.sin();
        s[2] += 1.0;
    }
    s
}

/// `|eta_n|` (m) from the sums of [`mode_sums`].
fn amplitude_of(s: [f64; 3]) -> f64 {
    if s[2] == 0.0 {
        return 0.0;
    }
    2.0 * s[0].hypot(s[1]) / s[2]
}

impl<const D: usize> RimMode<D> {
    /// The rim of `initial` (the case's particles at `t = 0`): fluid particles farther than
    /// `radius - l0` (m) from `center`.
    pub fn new(initial: &Particles<D>, center: Vector<D>, radius: f64, l0: f64, mode: u32) -> Self {
        let rim: Vec<usize> = (0..initial.len())
            .filter(|&i| {
                initial.kind[i] == Kind::Fluid && polar(initial.position[i], center).0 > radius - l0
            })
            .collect();
        let radial_velocity = rim.iter().map(|&i| {
            let (r, theta) = polar(initial.position[i], center);
            let d = initial.position[i] - center;
            let u = initial.velocity[i];
            let ur = if r > 0.0 {
                (u[0] * d[0] + u[1] * d[1]) / r
            } else {
                0.0
            };
            (ur, theta)
        });
        let initial_velocity = mode_amplitude(radial_velocity, mode);
        let initial = rim
            .iter()
            .map(|&i| (initial.id[i], polar(initial.position[i], center).0))
            .collect();
        RimMode {
            center,
            mode,
            initial,
            initial_velocity,
        }
    }

    /// Number of rim particles.
    pub fn len(&self) -> usize {
        self.initial.len()
    }

    /// Whether the rim is empty.
    pub fn is_empty(&self) -> bool {
        self.initial.is_empty()
    }

    /// `|eta_n|` (m): the amplitude of mode `n` of the rim particles' radial displacement from
    /// their initial radii (Lagrangian, so the lattice's staircase edge does not count).
    /// Particles no longer present (removed by outflow) are left out.
    pub fn amplitude(&self, p: &Particles<D>) -> f64 {
        amplitude_of(self.sums(p, p.len()))
    }

    /// The mode's amplitude (m) over every process's own particles of `sim`.
    pub fn amplitude_in(&self, sim: &crate::simulation::Simulation<D>) -> f64 {
        let mut s = self.sums(&sim.particles, sim.owned());
        sim.sum_over_processes(&mut s);
        amplitude_of(s)
    }

    /// The mode's sums over the rim particles among `0 .. n` of `p`.
    fn sums(&self, p: &Particles<D>, n: usize) -> [f64; 3] {
        let samples = (0..n).filter_map(|i| {
            let r0 = self.initial.get(&p.id[i])?;
            let (r, theta) = polar(p.position[i], self.center);
            Some((r - r0, theta))
        });
        mode_sums(samples, self.mode)
    }
}

/// Linear theory: `|eta_n(t)| = (U / gamma) sinh(gamma t)` (m) for an undisplaced surface
/// whose radial velocity has amplitude `U` (m/s) in mode `n`, with
/// `gamma^2 = (n - 1) (Omega^2 - T n (n + 1))` and `T = sigma / (rho R^3)` (1/s^2) the
/// surface tension's share (0 without): the Young-Laplace jump `sigma (n^2 - 1) eta / R^2`
/// added to the relation above turns it into `s^2 + 2 Omega s + n Omega^2 - T n (n^2 - 1) =
/// 0`. Where `gamma^2 < 0` the mode oscillates: `(U / w) |sin(w t)|`, `w^2 = -gamma^2`.
pub fn linear_amplitude(u: f64, (omega, tension): (f64, f64), mode: u32, t: f64) -> f64 {
    let n = f64::from(mode);
    let g2 = (n - 1.0).max(0.0) * (omega * omega - tension * n * (n + 1.0));
    if g2 > 0.0 {
        let gamma = g2.sqrt();
        u / gamma * (gamma * t).sinh()
    } else if g2 < 0.0 {
        let w = (-g2).sqrt();
        u / w * (w * t).sin().abs()
    } else {
        u * t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::NewParticle;

    /// A lattice disc whose rim particles are moved out by `eps cos(n theta)` and given the
    /// radial velocity `U cos(n theta)` reads back `eps` and `U`; another mode reads about 0.
    #[test]
    fn mode_of_a_displaced_rim() {
        let (l0, radius, n, eps, u) = (0.01, 0.5, 6u32, 2e-3, 0.01);
        let mut p = Particles::<2>::default();
        for a in -60..60 {
            for b in -60..60 {
                let x = Vector([(a as f64 + 0.5) * l0, (b as f64 + 0.5) * l0]);
                if x.norm() < radius {
                    let theta = x[1].atan2(x[0]);
                    let e = x * (1.0 / x.norm());
                    p.push(NewParticle {
                        position: x,
                        velocity: e * (u * (n as f64 * theta).cos()),
                        kind: Kind::Fluid,
                        phase: 0,
                        density: 1.0,
                    });
                }
            }
        }
        let rim = RimMode::new(&p, Vector::zero(), radius, l0, n);
        assert!(rim.len() > 100, "{}", rim.len());
        assert!(
            (rim.initial_velocity - u).abs() < 0.02 * u,
            "{}",
            rim.initial_velocity
        );
        assert_eq!(rim.amplitude(&p), 0.0);
        for i in 0..p.len() {
            let x = p.position[i];
            let theta = x[1].atan2(x[0]);
            let e = x * (1.0 / x.norm());
            p.position[i] = x + e * (eps * (n as f64 * theta).cos());
        }
        let a = rim.amplitude(&p);
        assert!((a - eps).abs() < 0.02 * eps, "{a}");
        let other = RimMode::new(&p, Vector::zero(), radius, l0, 5);
        assert!(other.initial_velocity < 0.05 * u);
    }

    /// `sinh` growth at `Omega sqrt(n - 1)`, slower under tension; the neutral mode 1 moves
    /// at `U t`.
    #[test]
    fn linear_growth() {
        let a = linear_amplitude(0.01, (1.0, 0.0), 6, 1.0);
        let g = 5f64.sqrt();
        assert!((a - 0.01 / g * g.sinh()).abs() < 1e-15);
        assert!((linear_amplitude(0.01, (-2.0, 0.0), 2, 0.5) - 0.005 * 1f64.sinh()).abs() < 1e-15);
        assert_eq!(linear_amplitude(0.01, (1.0, 0.0), 1, 2.0), 0.02);
        // Tension at T n (n + 1) = Omega^2 / 2 halves gamma^2; at Omega = 0 the mode is a
        // capillary wave, w^2 = T n (n^2 - 1) (Rayleigh).
        let t = 0.5 / 42.0;
        let g = 2.5f64.sqrt();
        assert!((linear_amplitude(0.01, (1.0, t), 6, 1.0) - 0.01 / g * g.sinh()).abs() < 1e-15);
        let w = (t * 6.0 * 35.0f64).sqrt();
        let a = linear_amplitude(0.01, (0.0, t), 6, 1.0);
        assert!((a - 0.01 / w * w.sin().abs()).abs() < 1e-15);
    }
}
