//! Exact solutions of free bodies of fluid and the measurements that compare a run with them:
//! the rotating disc (tension, steady) and the elliptic drop (strong strain, Monaghan 1994).

use crate::particles::{Kind, Particles, Vector};

/// Semi-axes `(a, b)` (m) of the elliptic drop at times `times` (s): the solution of
/// `a' = A a`, `A' = A^2 (b^2 - a^2) / (a^2 + b^2)`, `b = R^2 / a`, from `a = R`, `A = A0`
/// (inviscid, pressure `p0 (1 - x^2/a^2 - y^2/b^2)`), by RK4 with 2000 steps per unit `A0 t`
/// (at most a million steps in all: an absurd strain rate or time gives a coarse answer, not
/// an endless loop).
pub fn elliptic_drop(radius: f64, strain_rate: f64, times: &[f64]) -> Vec<(f64, f64)> {
    let rhs = |a: f64, big_a: f64| {
        let b = radius * radius / a;
        (big_a * a, big_a * big_a * (b * b - a * a) / (a * a + b * b))
    };
    let (mut t, mut a, mut big_a) = (0.0, radius, strain_rate);
    let span = times.iter().fold(0.0f64, |m, &t| m.max(t));
    let h_max = (1.0 / (2000.0 * strain_rate.abs().max(1e-12))).max(span / 1e6);
    let mut out = Vec::with_capacity(times.len());
    for &target in times {
        while t < target {
            let h = (target - t).min(h_max);
            if t + h <= t {
                break;
            }
            let k1 = rhs(a, big_a);
            let k2 = rhs(a + 0.5 * h * k1.0, big_a + 0.5 * h * k1.1);
            let k3 = rhs(a + 0.5 * h * k2.0, big_a + 0.5 * h * k2.1);
            let k4 = rhs(a + h * k3.0, big_a + h * k3.1);
            a += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            big_a += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            t += h;
        }
        out.push((a, radius * radius / a));
    }
    out
}

/// Semi-axes (m) along x and y of the fluid about `center` (m), from the second moments of
/// the particle positions: a uniform ellipse has `<x^2> = a^2 / 4`.
pub fn semi_axes<const D: usize>(p: &Particles<D>, center: Vector<D>) -> (f64, f64) {
    semi_axes_from(second_moments(p, p.len(), center))
}

/// The sums `[x^2, y^2, count]` (m^2, m^2, 1) over the fluid particles `0 .. n` of `p`
/// about `center` (m), which [`semi_axes_from`] turns into semi-axes (summed first over a
/// distributed run's processes).
pub fn second_moments<const D: usize>(p: &Particles<D>, n: usize, center: Vector<D>) -> [f64; 3] {
    let mut m = [0.0; 3];
    for i in (0..n).filter(|&i| p.kind[i] == Kind::Fluid) {
        let r = p.position[i] - center;
        m[0] += r[0] * r[0];
        m[1] += r[1] * r[1];
        m[2] += 1.0;
    }
    m
}

/// Semi-axes (m) from [`second_moments`].
pub fn semi_axes_from(m: [f64; 3]) -> (f64, f64) {
    let [sx, sy, n] = m;
    if n == 0.0 {
        return (0.0, 0.0);
    }
    (2.0 * (sx / n).sqrt(), 2.0 * (sy / n).sqrt())
}

/// The radius (m) within which 99 % of the fluid particles lie, from their distances `r`
/// (m) to the centre.
pub fn radius_99(mut r: Vec<f64>) -> f64 {
    if r.is_empty() {
        return 0.0;
    }
    r.sort_by(f64::total_cmp);
    r[((r.len() - 1) as f64 * 0.99).round() as usize]
}

/// The steady pressure (Pa) at the centre of a disc of radius `radius` (m) in solid rotation
/// at `omega` (rad/s), with `p = 0` at the surface particles' centres, half a spacing `l0` (m)
/// inside the edge: `-rho omega^2 (R - l0/2)^2 / 2`.
pub fn rotating_disc_centre_pressure(rho: f64, omega: f64, radius: f64, l0: f64) -> f64 {
    let rs = radius - 0.5 * l0;
    -0.5 * rho * omega * omega * rs * rs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::NewParticle;

    /// The drop's semi-axes conserve area and match Monaghan's (1994) figures: with
    /// `A0 = 100 /s`, `R = 1 m`, the semi-major axis reaches about 1.9 m by `t = 0.0076 s`
    /// (his Fig. 2), and for small times `a = R (1 + A0 t)` to first order.
    #[test]
    fn elliptic_drop_solution_ends_for_any_input() {
        for (a0, t) in [
            (1e308, 0.01),
            (-1e308, 1.0),
            (100.0, 1e30),
            (1e-300, 1e300),
            (1e6, 5.0),
        ] {
            let r = elliptic_drop(1.0, a0, &[0.0, t / 2.0, t]);
            assert_eq!(r.len(), 3);
        }
    }

    #[test]
    fn elliptic_drop_solution() {
        let times = [1e-5, 0.0076];
        let ab = elliptic_drop(1.0, 100.0, &times);
        assert!((ab[0].0 - (1.0 + 100.0 * 1e-5)).abs() < 1e-6);
        for &(a, b) in &ab {
            assert!((a * b - 1.0).abs() < 1e-12);
        }
        assert!(ab[1].0 > 1.8 && ab[1].0 < 2.0, "a(0.0076) = {}", ab[1].0);
        // Without strain the drop stays a circle.
        assert_eq!(elliptic_drop(0.5, 0.0, &[1.0]), vec![(0.5, 0.5)]);
    }

    /// The second moments of a lattice disc give back its radius to within a fraction of the
    /// spacing.
    #[test]
    fn semi_axes_of_a_lattice_disc() {
        let l0 = 0.01;
        let mut p = Particles::<2>::default();
        for a in -60..60 {
            for b in -60..60 {
                let x = Vector([(a as f64 + 0.5) * l0, (b as f64 + 0.5) * l0]);
                if x.norm() < 0.5 {
                    p.push(NewParticle {
                        position: x,
                        velocity: Vector::zero(),
                        kind: Kind::Fluid,
                        phase: 0,
                        density: 1.0,
                    });
                }
            }
        }
        let (a, b) = semi_axes(&p, Vector::zero());
        assert!(
            (a - 0.5).abs() < 0.2 * l0 && (b - 0.5).abs() < 0.2 * l0,
            "{a} {b}"
        );
        let r: Vec<f64> = p.position.iter().map(|x| x.norm()).collect();
        assert!((radius_99(r) - 0.5).abs() < l0);
    }
}
