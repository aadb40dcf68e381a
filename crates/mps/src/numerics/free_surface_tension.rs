//! Tension of a free surface (beyond the paper, whose cases have none): the continuum surface
//! force of Brackbill, Kothe & Zemach (1992) with the void beyond the surface as the second
//! phase. For a phase whose free surface has tension `sigma`:
//! - the colour `c` is 1 on every particle (walls and other phases read as more of the body,
//!   so a contact line meets a wall at a right angle) and 0 in the void. With the void's
//!   missing neighbours read as particles of colour 0, the gradient by the smooth kernel,
//!   consistent for linear fields, is `grad c_i = (d / s0) sum_j (-W'(r_ij)) r_ij / r_ij`
//!   over the particles present (on a full lattice the sum over all is zero);
//! - the unit normal `m_i = grad c_i / |grad c_i|` on the surface band: particles with a
//!   free-surface particle of the last step within `re` (themselves included) and
//!   `|grad c_i| l0 > 0.05` (inside the body the gradient reads the disorder of a
//!   neighbourhood, up to 0.12 / l0 on a lattice shaken by 0.1 l0);
//! - the curvature `kappa_i = -div_s m`, the surface divergence of the normals over the
//!   neighbours in the band, by least squares in the plane tangent to `m_i` (so one or two
//!   layers of normals give it);
//! - the acceleration `a_i = (2 sigma / rho) kappa_i grad c_i`: Brackbill's density-weighted
//!   form with the void's density 0, which puts the whole jump on the fluid side (across a
//!   flat surface `grad c` integrates to 1/2 over the particles present).
//!
//! All pair sums run at the Laplacian's radius. Checked against the Laplace jump of a free
//! drop (`sigma / R` in 2D).

use super::interfacial_tension::TensionInput;
use super::kernel::smooth_slope;
use super::pairs::pairs;
use crate::particles::{Matrix, Vector};
use rayon::prelude::*;

/// Colour gradients below this size times `1/l0` give no normal.
const NORMAL_THRESHOLD: f64 = 0.05;

/// The colour gradient (1/m) of particle `i` against the void.
fn void_gradient<const D: usize>(inp: &TensionInput<D>, i: usize) -> Vector<D> {
    let mut g = Vector::zero();
    for p in pairs(inp.pos, inp.nl, i, inp.re) {
        g += p.xij * (smooth_slope(p.r, inp.re) / p.r);
    }
    g * (D as f64 / inp.s0)
}

/// The surface divergence (1/m) of the unit normals at particle `i` (normal `mi`) over the
/// neighbours that have one: `sum_j w_ij (m_j - m_i) . (T^-1 t_ij) / r^2` with `t_ij` the
/// tangential part of `r_ij` and `T = sum_j w_ij t_ij (x) t_ij / r^2 + s m_i (x) m_i` (the
/// last term, `s` the tangential moment per direction, only makes `T` invertible). Zero
/// where the neighbours give no tangential spread.
fn surface_divergence<const D: usize>(
    inp: &TensionInput<D>,
    i: usize,
    mi: Vector<D>,
    normal: &impl Fn(usize) -> Option<Vector<D>>,
) -> f64 {
    let tangential = |v: Vector<D>| v - mi * mi.dot(&v);
    let mut t = Matrix::<D>::zero();
    let mut spread = 0.0;
    for p in pairs(inp.pos, inp.nl, i, inp.re) {
        if normal(p.j).is_some() {
            let tij = tangential(p.xij);
            t.add_scaled(&tij.outer(&tij), p.w / p.r2);
            spread += tij.norm2() * p.w / p.r2;
        }
    }
    if D < 2 || spread <= 0.0 {
        return 0.0;
    }
    let s = spread / (D - 1) as f64;
    t.add_scaled(&mi.outer(&mi), s);
    match t.determinant_and_inverse() {
        Some((det, inv)) if det > 0.01 * s.powi(D as i32) => pairs(inp.pos, inp.nl, i, inp.re)
            .filter_map(|p| normal(p.j).map(|mj| (p, mj)))
            .map(|(p, mj)| (mj - mi).dot(&inv.mul_vec(&tangential(p.xij))) * p.w / p.r2)
            .sum(),
        _ => 0.0,
    }
}

/// The curvature (1/m) of the free surface at every particle of the band (0 elsewhere):
/// `-div_s m` averaged with weights `w_ij` over the particle and its neighbours in the
/// band; `free[phase]` each phase's tension (N/m, 0 for none).
fn curvature<const D: usize>(inp: &TensionInput<D>, free: &[f64]) -> Vec<f64> {
    let n = inp.pos.len();
    let tension = |i: usize| inp.fluid[i] && free.get(inp.phase[i] as usize).is_some_and(|&s| s > 0.0);
    let near_surface = |i: usize| {
        inp.surface[i] || pairs(inp.pos, inp.nl, i, inp.re).any(|p| inp.surface[p.j])
    };
    let thr: f64 = std::env::var("MPS_THR").ok().and_then(|s| s.parse().ok()).unwrap_or(NORMAL_THRESHOLD);
    let threshold = thr / inp.l0;
    let normals: Vec<Option<Vector<D>>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let g = (tension(i) && near_surface(i)).then(|| void_gradient(inp, i))?;
            let m = g.norm();
            (m > threshold).then(|| g * (1.0 / m))
        })
        .collect();
    let normal = |i: usize| normals[i];
    let kappa: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| normal(i).map_or(0.0, |m| -surface_divergence(inp, i, m, &normal)))
        .collect();
    let passes: usize = std::env::var("MPS_PASSES").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let mut kappa = kappa;
    for _ in 0..passes {
    kappa = (0..n)
        .into_par_iter()
        .map(|i| {
            if normals[i].is_none() {
                return 0.0;
            }
            let (mut sum, mut weight) = (kappa[i], 1.0);
            for p in pairs(inp.pos, inp.nl, i, inp.re) {
                if normals[p.j].is_some() {
                    sum += kappa[p.j] * p.w;
                    weight += p.w;
                }
            }
            sum / weight
        })
        .collect();
    }
    kappa
}

/// CSF accelerations (m/s^2): `(2 sigma / rho) kappa_i grad c_i` on the band.
pub fn csf_force<const D: usize>(inp: &TensionInput<D>, free: &[f64], density: &[f64]) -> Vec<Vector<D>> {
    let kappa = curvature(inp, free);
    (0..inp.pos.len())
        .into_par_iter()
        .map(|i| {
            let sigma = free.get(inp.phase[i] as usize).copied().unwrap_or(0.0);
            if kappa[i] == 0.0 || sigma == 0.0 || !inp.fluid[i] {
                return Vector::zero();
            }
            void_gradient(inp, i) * (2.0 * sigma * kappa[i] / density[i])
        })
        .collect()
}

/// The Young-Laplace jump `sigma kappa_i` (Pa) at every free-surface particle whose phase's
/// free surface has tension `free[phase]` (N/m, 0 for none), 0 elsewhere: the value its
/// Dirichlet condition takes over the void's 0 Pa. `None` where no phase has a tension.
pub fn laplace_jump<const D: usize>(inp: &TensionInput<D>, free: &[f64]) -> Option<Vec<f64>> {
    if free.iter().all(|&sigma| sigma == 0.0) {
        return None;
    }
    let kappa = curvature(inp, free);
    Some(
        (0..inp.pos.len())
            .map(|i| {
                let sigma = free.get(inp.phase[i] as usize).copied().unwrap_or(0.0);
                if inp.surface[i] && inp.fluid[i] {
                    sigma * kappa[i]
                } else {
                    0.0
                }
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::kernel::KernelConstants;
    use crate::particles::neighbors::build_neighbor_list;

    /// A disc of radius `r` of rings `l0` apart with particles about `l0` apart along each
    /// (a square lattice's staircase edge reads corners of curvature `1 / l0`: on the lattice
    /// disc of R = 25 l0 the force's integral is 1.48 times the jump), flagged free surface
    /// within `l0` of its edge.
    fn disc(l0: f64, r: f64) -> (Vec<Vector<2>>, Vec<bool>) {
        let tau = 2.0 * std::f64::consts::PI;
        let mut pos = Vec::new();
        for k in 0..(r / l0).round() as usize {
            let rk = (k as f64 + 0.5) * l0;
            let m = (tau * rk / l0).round().max(1.0) as usize;
            for q in 0..m {
                let t = tau * (q as f64 + 0.5 * (k % 2) as f64) / m as f64;
                pos.push(Vector([rk * t.cos(), rk * t.sin()]));
            }
        }
        let surface = pos.iter().map(|p| p.norm() > r - l0).collect();
        (pos, surface)
    }

    fn jumps(pos: &[Vector<2>], surface: &[bool], l0: f64, sigma: f64) -> Vec<f64> {
        let re = 3.1 * l0;
        let nl = build_neighbor_list(pos, re);
        let fluid = vec![true; pos.len()];
        let phase = vec![0u16; pos.len()];
        let inp = TensionInput {
            pos,
            nl: &nl,
            re,
            l0,
            phase: &phase,
            fluid: &fluid,
            s0: KernelConstants::on_lattice::<2>(re, l0).s0_smooth,
            surface,
        };
        laplace_jump(&inp, &[sigma]).unwrap()
    }

    /// Every surface particle of a disc on rings takes the Laplace jump `sigma / R`.
    #[test]
    fn a_free_disc_takes_the_laplace_jump_at_its_surface() {
        for (l0, r) in [(1e-3, 0.00625), (1e-3, 0.0125), (1e-3, 0.025), (5e-4, 0.025)] {
            let (pos, surface) = disc(l0, r);
            let sigma = 0.1;
            let jump = jumps(&pos, &surface, l0, sigma);
            let on: Vec<f64> = (0..pos.len()).filter(|&i| surface[i]).map(|i| jump[i] * r / sigma).collect();
            let mean = on.iter().sum::<f64>() / on.len() as f64;
            let (lo, hi) = on.iter().fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            eprintln!("R/l0 {}: mean {mean} range {lo} {hi}", r / l0);
            assert!(jump.iter().zip(&surface).all(|(j, s)| *s || *j == 0.0));
        }
    }
}
