//! Dynamic Stabilization (DS), Tsuruta, Khayyer & Gotoh, paper Eq. 7-19 (equations.md s.6).
//!
//! For every neighbour pair, predict the relative displacement the gradient alone would cause
//! in one step (Eq. 11), and if the predicted distance falls below `d_ji = alpha_DS l0`
//! (Eq. 8, 9), add the repulsive acceleration that restores `d_ji` along the pair line
//! (Eq. 14-19), split between the two particles in the inverse ratio of their densities
//! (Newton's third law, Eq. 12, 17), and averaged with the kernel weight (Eq. 7); or, for a
//! pair with a free-surface particle, applied whole (`surface-full`, beyond the paper:
//! docs/decisions.md, "DS whole at the free surface").

use super::kernel::Kernels;
use super::pairs::pair_with;
use crate::particles::{Kind, Vector, View};
use serde::{Deserialize, Serialize};

/// Weighting of the DS pair terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DsWeighting {
    /// Kernel-weighted average `(1/n0) sum F w` (paper Eq. 7).
    Kernel,
    /// Full restoration per pair, for study.
    None,
    /// Kernel-weighted between two interior particles, full restoration for a pair with a
    /// free-surface particle (the DS preset's default; beyond the paper).
    SurfaceFull,
}

/// What DS does to the velocities of an active pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DsVelocity {
    /// The restoring acceleration acts on the velocity too (`dt Pi`, paper Eq. 7): the pair
    /// leaves the step separating at `delta / dt`.
    Restoring,
    /// The positions are restored as in the paper, but the velocities only lose the pair's
    /// approach along its line (an inelastic contact, beyond the paper), and the sliding
    /// across it falls as the pair moves apart so that the pair keeps its angular momentum:
    /// each step's velocity change is bounded by the pair's own motion, not `delta / dt`.
    Inelastic,
}

/// Dynamic Stabilization parameters (equations.md section 6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicStabilization {
    /// Threshold `alpha_DS` (fraction of the mean particle diameter, dimensionless).
    pub alpha: f64,
    /// Pair-term weighting.
    pub weighting: DsWeighting,
    /// Act on fluid-wall pairs (wall immovable).
    pub walls: bool,
    /// What the pair term does to the velocities.
    pub velocity: DsVelocity,
}

/// DS's effect on one fluid particle over one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DsCorrection<const D: usize> {
    /// Acceleration (m/s^2) whose `dt^2` multiple is the position correction (paper Eq. 7).
    pub acc: Vector<D>,
    /// Velocity change (m/s) with [`DsVelocity::Inelastic`]; zero with `Restoring`, whose
    /// velocity change is `dt acc`.
    pub dvel: Vector<D>,
    /// Active pairs counted at this particle (fluid pairs at the lower index, wall pairs).
    pub active: u32,
}

/// DS correction of fluid particle `i`: its acceleration, its velocity change (inelastic
/// mode) and the number of active pairs it counts.
///
/// `acc` holds every particle's pressure acceleration from the gradient model (`-G/rho`,
/// zero for walls), so the predicted displacement of Eq. 11 is `(acc_j - acc_i) dt^2`, and
/// the velocities after the pressure step are `u*_j + dt acc_j`.
pub fn ds_acceleration<const D: usize>(
    i: usize,
    v: &View<D>,
    acc: &[Vector<D>],
    ds: &DynamicStabilization,
    k: &Kernels,
    dt: f64,
) -> DsCorrection<D> {
    let d_ji = ds.alpha * k.l0; // Eq. 8 with d_i = d_j = l0
    let rho_i = v.density[i];
    let mut out = DsCorrection::default();
    let inelastic = ds.velocity == DsVelocity::Inelastic;
    let (xi, d2) = (v.pos[i], d_ji * d_ji);
    for &j in v.neighbors.for_radius(k.grad.re).of(i) {
        let j = j as usize;
        let solid = v.kind[j] != Kind::Fluid;
        if solid && !ds.walls {
            continue;
        }
        // Most pairs end beyond d_ji after the gradient's displacement, |r_ij + dr| >= d_ji
        // (the test below, which decides, in other terms): they are passed over without
        // their geometry, by a margin far above the two forms' rounding.
        let dr = (acc[j] - acc[i]) * (dt * dt);
        let y = v.pos[j] - xi + dr;
        let scale = d2 + (v.pos[j] - xi).norm2() + dr.norm2();
        if y.norm2() >= d2 + 1e-9 * scale {
            continue;
        }
        let Some(q) = pair_with(v.pos, xi, j, k.grad.re) else {
            continue;
        };
        let e = q.xij / q.r;
        // Eq. 11: displacement of j relative to i caused by the gradient term (`dr` above).
        let along = dr.dot(&e);
        let s_par = q.r + along;
        let s_perp = (dr - e * along).norm();
        if s_par * s_par + s_perp * s_perp >= d_ji * d_ji {
            continue;
        }
        // Eq. 14-18: displacement along e restoring the distance d_ji.
        let delta = (d_ji * d_ji - s_perp * s_perp).max(0.0).sqrt() - s_par;
        if delta <= 0.0 {
            continue;
        }
        // Eq. 19: Pi_ij = rho_j delta / (dt^2 (rho_i + rho_j)); an immovable wall takes none.
        let (pi, share) = if solid {
            (delta / (dt * dt), 1.0)
        } else {
            let rho_j = v.density[j];
            let pi = rho_j * delta / (dt * dt * (rho_i + rho_j));
            (pi, rho_j / (rho_i + rho_j))
        };
        let whole = match ds.weighting {
            DsWeighting::Kernel => false,
            DsWeighting::None => true,
            DsWeighting::SurfaceFull => v.free_surface[i] || v.free_surface[j],
        };
        let w = if whole { 1.0 } else { q.w / k.grad.n0 };
        // Repulsion: i is pushed from j, along -e_ji.
        out.acc -= e * (pi * w);
        if inelastic {
            // The pair's approach speed after the pressure step, cancelled in i's share.
            let u_i = v.vel[i] + acc[i] * dt;
            let u_j = v.vel[j] + acc[j] * dt;
            let u_ij = u_j - u_i;
            let approach = -u_ij.dot(&e);
            if approach > 0.0 {
                out.dvel -= e * (share * approach * w);
            }
            if !solid {
                // Moved apart from s to s + w delta, the pair keeps its angular momentum: its
                // relative sliding falls by the factor s / (s + w delta).
                let s = (s_par * s_par + s_perp * s_perp).sqrt();
                let sliding = u_ij + e * approach;
                out.dvel += sliding * (share * w * delta / (s + w * delta));
            }
        }
        if solid || i < j {
            out.active += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::kernel::weight;
    use crate::particles::view::Cloud;

    fn pair(dist: f64, rho: [f64; 2], weighting: DsWeighting) -> [Vector<2>; 2] {
        let l0 = 0.01;
        let pos = vec![Vector([0.0, 0.0]), Vector([dist * l0, 0.0])];
        let cloud = Cloud::new(pos, vec![Vector::zero(); 2], rho.to_vec(), 0.0, 3.1 * l0);
        let f = cloud.view();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let ds = DynamicStabilization {
            alpha: 0.9,
            weighting,
            walls: true,
            velocity: DsVelocity::Restoring,
        };
        let acc = vec![Vector::zero(); 2];
        let dt = 1e-3;
        let a0 = ds_acceleration(0, &f, &acc, &ds, &k, dt).acc;
        let a1 = ds_acceleration(1, &f, &acc, &ds, &k, dt).acc;
        // Displacements over one step: dt^2 a.
        [a0 * (dt * dt), a1 * (dt * dt)]
    }

    #[test]
    fn close_pair_separates_to_the_threshold_and_conserves_momentum() {
        let [d0, d1] = pair(0.8, [1000.0, 1000.0], DsWeighting::None);
        // Full restoration: the gap grows from 0.8 l0 to 0.9 l0.
        let gap = 0.8 * 0.01 + d1[0] - d0[0];
        assert!((gap - 0.9 * 0.01).abs() < 1e-12, "gap {gap}");
        assert!(d0[0] < 0.0 && d1[0] > 0.0);
        assert!((d0 * 1000.0 + d1 * 1000.0).norm() < 1e-15);
        // Kernel weighting removes w/n0 of the overlap (0.25 at 0.8 l0).
        let [k0, k1] = pair(0.8, [1000.0, 1000.0], DsWeighting::Kernel);
        let frac = (k1[0] - k0[0]) / (0.1 * 0.01);
        let want = weight(0.8, 2.1)
            / crate::numerics::kernel::KernelConstants::on_lattice::<2>(2.1, 1.0).n0;
        assert!((frac - want).abs() < 1e-9, "{frac} vs {want}");
    }

    /// Pairs whose displaced distance `|r_ij + dr|` lies just inside or outside `d_ji`
    /// (relative offsets from 1e-13 to 1e-3 either way): the pair is active exactly when
    /// Eq. 11-13's own test says so, `s_par^2 + s_perp^2 < d_ji^2`, so the pass-over of far
    /// pairs drops none that the test keeps.
    #[test]
    fn pairs_at_the_threshold_are_active_as_eq_13_says() {
        let (l0, dt) = (0.01, 1e-3);
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let ds = DynamicStabilization {
            alpha: 0.9,
            weighting: DsWeighting::Kernel,
            walls: true,
            velocity: DsVelocity::Restoring,
        };
        let d = ds.alpha * l0;
        let (mut seed, mut active) = (7u64, [0, 0]);
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for m in 0..2000 {
            let delta = 10f64.powf(-13.0 + 10.0 * next()) * if m % 2 == 0 { 1.0 } else { -1.0 };
            let tau = std::f64::consts::TAU;
            let (t, u) = (tau * next(), tau * next());
            let acc1 = Vector([u.cos(), u.sin()]) * (3000.0 * next());
            let dr = acc1 * (dt * dt);
            // r_ij chosen so that r_ij + dr lies at d (1 + delta) along direction t.
            let x1 = Vector([t.cos(), t.sin()]) * (d * (1.0 + delta)) - dr;
            let cloud = Cloud::new(
                vec![Vector::zero(), x1],
                vec![Vector::zero(); 2],
                vec![1000.0; 2],
                0.0,
                3.4 * l0,
            );
            let acc = vec![Vector::zero(), acc1];
            let got = ds_acceleration(0, &cloud.view(), &acc, &ds, &k, dt).active;
            let r = x1.norm();
            let e = x1 / r;
            let along = dr.dot(&e);
            let (s_par, s_perp) = (r + along, (dr - e * along).norm());
            let inside = s_par * s_par + s_perp * s_perp < d * d;
            let restores = (d * d - s_perp * s_perp).max(0.0).sqrt() - s_par > 0.0;
            let want = (r < k.grad.re && inside && restores) as usize;
            assert_eq!(got as usize, want, "pair {m}: delta {delta:e}");
            active[want] += 1;
        }
        // Both outcomes occur, about half each.
        assert!(active[0] > 800 && active[1] > 800, "{active:?}");
    }

    #[test]
    fn heavy_light_pair_splits_in_inverse_mass_ratio() {
        let [d0, d1] = pair(0.8, [2650.0, 1000.0], DsWeighting::None);
        assert!((d1[0] / -d0[0] - 2.65).abs() < 1e-9);
        assert!((d0 * 2650.0 + d1 * 1000.0).norm() < 1e-15);
    }

    /// In 3D, with the gradient driving the pair together off its line: the repulsion acts
    /// along the pair line, restores the predicted distance to alpha l0 (Eq. 14-19 with the
    /// perpendicular part), and conserves momentum with unequal densities.
    #[test]
    fn in_3d_the_pair_is_restored_along_its_line_with_momentum_conserved() {
        let l0 = 0.01;
        let x1 = Vector([0.5, 0.4, 0.6]) * l0;
        let pos = vec![Vector::zero(), x1];
        let rho = [2650.0, 1000.0];
        let cloud = Cloud::new(pos, vec![Vector::zero(); 2], rho.to_vec(), 0.0, 3.1 * l0);
        let f = cloud.view();
        let k = Kernels::new::<3>(l0, 2.1, 3.1);
        let ds = DynamicStabilization {
            alpha: 0.9,
            weighting: DsWeighting::None,
            walls: true,
            velocity: DsVelocity::Restoring,
        };
        let dt = 1e-3;
        // Gradient accelerations that bring j towards i and shear it sideways.
        let acc = vec![Vector([0.0, 0.0, 0.0]), Vector([-1.0, 0.5, -0.8])];
        let a0 = ds_acceleration(0, &f, &acc, &ds, &k, dt).acc;
        let a1 = ds_acceleration(1, &f, &acc, &ds, &k, dt).acc;
        let e = x1 / x1.norm();
        for a in [a0, a1] {
            assert!(
                (a - e * a.dot(&e)).norm() < 1e-9 * a.norm(),
                "{a:?} not along e"
            );
        }
        assert!((a0 * rho[0] + a1 * rho[1]).norm() < 1e-9 * a1.norm() * rho[1]);
        let predicted = x1 + (acc[1] + a1 - acc[0] - a0) * (dt * dt);
        assert!(
            (predicted.norm() - 0.9 * l0).abs() < 1e-12,
            "{}",
            predicted.norm() / l0
        );
    }

    /// `surface-full`: a pair with a free-surface particle is restored whole (to 0.9 l0 in
    /// one step), a pair of two interior particles by the kernel-weighted share of Eq. 7.
    #[test]
    fn surface_pairs_are_restored_whole_and_interior_pairs_by_the_kernel_share() {
        let l0 = 0.01;
        let pos = vec![Vector([0.0, 0.0]), Vector([0.8 * l0, 0.0])];
        let mut cloud = Cloud::new(pos, vec![Vector::zero(); 2], vec![1000.0; 2], 0.0, 3.1 * l0);
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let ds = DynamicStabilization {
            alpha: 0.9,
            weighting: DsWeighting::SurfaceFull,
            walls: true,
            velocity: DsVelocity::Restoring,
        };
        let (acc, dt) = (vec![Vector::zero(); 2], 1e-3);
        let gap = |c: &Cloud<2>| {
            let f = c.view();
            let a0 = ds_acceleration(0, &f, &acc, &ds, &k, dt).acc;
            let a1 = ds_acceleration(1, &f, &acc, &ds, &k, dt).acc;
            assert!((a0 + a1).norm() < 1e-12 * a1.norm(), "momentum");
            0.8 * l0 + (a1[0] - a0[0]) * dt * dt
        };
        let interior = (gap(&cloud) - 0.8 * l0) / (0.1 * l0);
        let share = weight(0.8, 2.1)
            / crate::numerics::kernel::KernelConstants::on_lattice::<2>(2.1, 1.0).n0;
        assert!((interior - share).abs() < 1e-9, "{interior} vs {share}");
        // One surface particle in the pair is enough.
        cloud.set_surface(|x| x[0] > 0.5 * l0);
        assert!((gap(&cloud) - 0.9 * l0).abs() < 1e-12);
    }

    /// `inelastic`: the positions are restored as the paper's DS restores them, but the
    /// velocities only lose the pair's approach along its line, whatever the step (the
    /// paper's velocity change, `dt Pi`, grows as `1/dt`), and the sliding that keeps the
    /// pair's angular momentum as it moves apart; momentum is conserved, and a pair already
    /// separating keeps its velocities along its line.
    #[test]
    fn inelastic_ds_cancels_the_approach_whatever_the_step() {
        let l0 = 0.01;
        let pos = vec![Vector([0.0, 0.0]), Vector([0.8 * l0, 0.0])];
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let rho = [2650.0, 1000.0];
        let ds = |velocity| DynamicStabilization {
            alpha: 0.9,
            weighting: DsWeighting::None,
            walls: true,
            velocity,
        };
        let acc = vec![Vector::zero(); 2];
        let run = |vel: Vec<Vector<2>>, velocity, dt| {
            let cloud = Cloud::new(pos.clone(), vel, rho.to_vec(), 0.0, 3.1 * l0);
            let f = cloud.view();
            let c0 = ds_acceleration(0, &f, &acc, &ds(velocity), &k, dt);
            let c1 = ds_acceleration(1, &f, &acc, &ds(velocity), &k, dt);
            (c0, c1)
        };
        // Closing at 0.3 m/s along the pair line, sliding 0.2 m/s across it.
        let closing = vec![Vector([0.1, 0.0]), Vector([-0.2, 0.2])];
        for dt in [1e-3, 1e-4] {
            let (r0, r1) = run(closing.clone(), DsVelocity::Restoring, dt);
            let (c0, c1) = run(closing.clone(), DsVelocity::Inelastic, dt);
            assert_eq!(
                (c0.acc, c1.acc),
                (r0.acc, r1.acc),
                "positions as the paper's"
            );
            assert_eq!((r0.dvel, r1.dvel), (Vector::zero(), Vector::zero()));
            let u0 = closing[0] + c0.dvel;
            let u1 = closing[1] + c1.dvel;
            assert!(
                (u1[0] - u0[0]).abs() < 1e-15,
                "approach left {}",
                u1[0] - u0[0]
            );
            // Moved from 0.8 to 0.9 l0, the pair keeps its angular momentum about its
            // centre of mass: the relative sliding falls to 0.8 / 0.9 of 0.2 m/s.
            let sliding = u1[1] - u0[1];
            assert!(
                (0.9 * sliding - 0.8 * 0.2).abs() < 1e-15,
                "sliding {sliding}"
            );
            assert!((c0.dvel * rho[0] + c1.dvel * rho[1]).norm() < 1e-12);
            // The light particle takes the larger share of the 0.3 m/s.
            assert!((c1.dvel[0] - 0.3 * 2650.0 / 3650.0).abs() < 1e-12);
        }
        let separating = vec![Vector([-0.1, 0.0]), Vector([0.2, 0.0])];
        let (c0, c1) = run(separating, DsVelocity::Inelastic, 1e-3);
        assert_eq!((c0.dvel, c1.dvel), (Vector::zero(), Vector::zero()));
        assert!(
            c0.acc[0] < 0.0 && c1.acc[0] > 0.0,
            "positions still restored"
        );
    }

    #[test]
    fn pair_beyond_threshold_is_untouched() {
        let [d0, d1] = pair(0.95, [1000.0, 1000.0], DsWeighting::Kernel);
        assert_eq!(d0, Vector::zero());
        assert_eq!(d1, Vector::zero());
    }
}
