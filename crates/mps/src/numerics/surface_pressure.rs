//! The Dirichlet value of free-surface particles in the PPE (a departure from the paper,
//! selectable; docs/decisions.md, "Surface pressure at the mean surface").
//!
//! The paper's schemes hold every free-surface particle at `p = 0`, wherever it sits: a
//! particle that sticks out of the surface by half a spacing, and its neighbours on the
//! surface that lie half a spacing in, all carry the pressure of the surface itself. Under
//! tension (a rotating body, a stretched filament) the protruding particle then feels less of
//! the pull that holds it and the recessed one more: the surface roughens and sheds
//! particles. With `mean-surface`, `p = 0` is placed on the mean surface through the
//! free-surface particles around `i`, and `i` takes the value a linear field has at its
//! signed distance `s_i` from it:
//!
//! - the outward normal `n_i = -sum_j w_ij r_ij / |sum_j w_ij r_ij|` over fluid neighbours
//!   (re_grad);
//! - `s_i = -(sum_{j surface} w_ij r_ij . n_i) / (w(l0) + sum_{j surface} w_ij)`, the offset
//!   of `i` beyond the kernel-weighted mean of the surface particles around it (itself
//!   counted with the weight of a neighbour at one spacing), at most `l0 / 2` either way;
//! - the normal gradient `G_i` fitted to the last step's pressures of the fluid neighbours
//!   that are not on the surface, along the normal, with `p = 0` on the mean surface:
//!   `G_i = sum w p_j d_j / sum w d_j^2`, `d_j = r_ij . n_i + s_i` (the height of `j` above
//!   the mean surface, negative inside); lagged one step, so the matrix stays symmetric, and
//!   without the particle's own last value, which would feed back;
//! - `p_i = G_i s_i`, bounded by the largest `|p_j|` of those neighbours; `0` when fewer than
//!   two such neighbours exist (spray, a filament one particle wide), when the neighbourhood
//!   is balanced (no normal), or beside a wall or dummy particle (a contact line, where the
//!   mean surface is not defined).
//!
//! On a flat surface `s_i = 0` and the value is the paper's `p = 0`.
//!
//! With `edge-surface` the zero lies half a spacing beyond that mean surface, where the
//! fluid's edge is (each particle stands for a cell of side l0): `p_i = G_i (s_i - l0/2)`,
//! the heights `d_j` measured from the edge; a flat still surface takes `rho g l0 / 2`, the
//! tank's bottom `rho g H`. Beside a wall it takes the kernel-weighted mean of its surface
//! neighbours' values (swept into corners), since `0` there beside `rho g l0 / 2` would drive
//! the water along the wall (docs/decisions.md, "The free surface at the particles' edge").

use super::kernel::{weight, Kernels};
use crate::parallel;
use crate::particles::{Kind, Vector, View};
use serde::{Deserialize, Serialize};

/// Where the free-surface Dirichlet condition `p = 0` is placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SurfacePressure {
    /// At every free-surface particle's centre (the paper's schemes).
    #[default]
    Zero,
    /// On the mean surface through the free-surface particles; each takes `G s` (Pa).
    MeanSurface,
    /// Half a spacing beyond that mean surface, at the edge of the surface particles'
    /// volumes; each takes `G (s - l0/2)` (Pa).
    EdgeSurface,
}

/// The largest offset from the mean surface, in spacings.
const MAX_OFFSET: f64 = 0.5;

impl SurfacePressure {
    /// Where `p = 0` lies beyond the mean surface of the surface particles' centres (m), at
    /// spacing `l0` (m): 0, or half a spacing with `edge-surface`.
    pub fn edge(self, l0: f64) -> f64 {
        match self {
            SurfacePressure::EdgeSurface => 0.5 * l0,
            _ => 0.0,
        }
    }
}

/// Dirichlet value (Pa) of every particle: `G_i (s_i - e)` for free-surface fluid particles
/// (module doc; `e` = `edge` (m), where `p = 0` lies beyond the mean surface), 0 for all
/// others. `previous` holds every particle's pressure of the last step (Pa).
pub fn dirichlet_values<const D: usize>(
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    edge: f64,
) -> Vec<f64> {
    let mut out = Vec::new();
    dirichlet_values_into(v, previous, k, (edge, &[]), &mut out);
    out
}

/// [`dirichlet_values`] into `out`, reusing its memory, with the zero level `edge` (m)
/// beyond the mean surface (0 or `l0 / 2`).
pub fn dirichlet_values_into<const D: usize>(
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    (edge, levels): (f64, &[f64]),
    out: &mut Vec<f64>,
) {
    parallel::map_into(out, v.pos.len(), |i| {
        // Only free-surface fluid particles have a value (and pay for its three
        // neighbour passes).
        if v.kind[i] != Kind::Fluid || !v.free_surface[i] {
            return 0.0;
        }
        let level = levels.get(i).copied().unwrap_or(0.0);
        match mean_surface_value(i, v, previous, k, (edge, level)) {
            Some(p) => p,
            None if edge > 0.0 => f64::NAN,
            None => 0.0,
        }
    });
    if edge > 0.0 {
        fill_contact_lines(v, k, out);
    }
}

/// Where the free surface meets a wall (`edge-surface`; marked NaN in `out`): the
/// kernel-weighted mean of the values of the free-surface fluid neighbours that have one,
/// swept in particle order until no marked particle gains a value (a corner takes its
/// value from the contact line beside it), the rest 0. With `p = 0` at the contact line
/// and `rho g l0 / 2` beside it, still water would be driven along the wall.
fn fill_contact_lines<const D: usize>(v: &View<D>, k: &Kernels, out: &mut [f64]) {
    loop {
        let mut filled = false;
        for i in 0..out.len() {
            if !out[i].is_nan() {
                continue;
            }
            let (mut sum, mut sw) = (0.0, 0.0);
            for q in v.pairs(i, k.grad.re) {
                if v.kind[q.j] == Kind::Fluid && v.free_surface[q.j] && !out[q.j].is_nan() {
                    sum += q.w * out[q.j];
                    sw += q.w;
                }
            }
            if sw > 0.0 {
                out[i] = sum / sw;
                filled = true;
            }
        }
        if !filled {
            break;
        }
    }
    for p in out.iter_mut().filter(|p| p.is_nan()) {
        *p = 0.0;
    }
}

/// `G_i (s_i - edge)` (Pa) of free-surface particle `i`; `None` beside a wall or dummy
/// particle, where the mean surface is not defined (a contact line).
fn mean_surface_value<const D: usize>(
    i: usize,
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    (edge, level): (f64, f64),
) -> Option<f64> {
    let (re, l0) = (k.grad.re, k.l0);
    let mut centroid = Vector::<D>::zero();
    for q in v.pairs(i, re) {
        if v.kind[q.j] != Kind::Fluid {
            return None;
        }
        centroid += q.xij * q.w;
    }
    let len = centroid.norm();
    if len <= 1e-12 * l0 {
        return Some(0.0);
    }
    let n = centroid * (-1.0 / len);
    let (mut sw, mut so) = (weight(l0, re), 0.0);
    // Every neighbour is fluid from here on (a wall or dummy returned above).
    for q in v.pairs(i, re).filter(|q| v.free_surface[q.j]) {
        sw += q.w;
        so += q.w * q.xij.dot(&n);
    }
    let s = (-so / sw).clamp(-MAX_OFFSET * l0, MAX_OFFSET * l0);
    let (mut num, mut den, mut count, mut bound) = (0.0, 0.0, 0, 0.0f64);
    for q in v.pairs(i, re).filter(|q| !v.free_surface[q.j]) {
        let d = q.xij.dot(&n) + s - edge;
        num += q.w * (previous[q.j] - level) * d;
        den += q.w * d * d;
        count += 1;
        bound = bound.max((previous[q.j] - level).abs());
    }
    if count < 2 || den <= 0.0 {
        return Some(0.0);
    }
    Some((num / den * (s - edge)).clamp(-bound, bound))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::view::Cloud;

    /// A block of 15 x 10 particles, its top row (y = 9 l0) flagged, the particle at
    /// x = 7 l0 of that row raised by `lift` l0; the last pressures `g (y - y0)` (Pa).
    fn block(lift: f64, g: f64, y0: f64) -> (Cloud<2>, Kernels, Vec<f64>, usize) {
        let l0 = 0.01;
        let mut pos = Vec::new();
        let mut raised = 0;
        for a in 0..15 {
            for b in 0..10 {
                let mut x = Vector([a as f64 * l0, b as f64 * l0]);
                if a == 7 && b == 9 {
                    x[1] += lift * l0;
                    raised = pos.len();
                }
                pos.push(x);
            }
        }
        let n = pos.len();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let p = pos.iter().map(|x| g * (x[1] - y0)).collect();
        let mut cloud = Cloud::new(pos, vec![Vector::zero(); n], vec![1000.0; n], 0.0, 3.4 * l0);
        cloud.set_surface(|x| x[1] > 8.5 * l0);
        (cloud, k, p, raised)
    }

    /// A flat surface keeps the paper's `p = 0` on every surface particle (away from the
    /// block's side edges, where the neighbourhood is cut sideways too).
    #[test]
    fn a_flat_surface_stays_at_zero() {
        let l0 = 0.01;
        let (cloud, k, p, _) = block(0.0, 500.0, 9.0 * l0);
        let v = cloud.view();
        let pd = dirichlet_values(&v, &p, &k, 0.0);
        for i in 0..v.pos.len() {
            let x = v.pos[i][0] / l0;
            if !v.free_surface[i] {
                assert_eq!(pd[i], 0.0);
            } else if (3.0..=11.0).contains(&x) {
                assert!(pd[i].abs() < 1e-9, "particle at {:?}: {}", v.pos[i], pd[i]);
            }
        }
    }

    /// A surface particle raised by 0.3 l0 lies `s` beyond the mean surface (the weighted
    /// mean of the row around it and itself); a field linear in y with zero on that mean
    /// surface gives it exactly `g s`, under tension (`g > 0`, pressure rising outward) and
    /// under gravity (`g < 0`). With the interior at zero, or beside a wall, it gets zero.
    #[test]
    fn a_raised_particle_takes_the_field_at_its_offset() {
        let (l0, lift) = (0.01, 0.3);
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        // Its surface neighbours: the row at x = 5..9 l0 (dx = 2 at 0.3 l0 height is inside).
        let (mut sw, mut so) = (weight(l0, k.grad.re), 0.0);
        for dx in [-2.0, -1.0, 1.0, 2.0] {
            let d = Vector([dx * l0, -lift * l0]);
            let w = weight(d.norm(), k.grad.re);
            sw += w;
            so += w * d[1];
        }
        let s = -so / sw;
        assert!(s > 0.1 * l0 && s < lift * l0, "offset {}", s / l0);
        for g in [500.0, -9810.0] {
            let y_mean = (9.0 + lift) * l0 - s;
            let (cloud, k, p, top) = block(lift, g, y_mean);
            let pd = dirichlet_values(&cloud.view(), &p, &k, 0.0)[top];
            let want = g * s;
            assert!(
                (pd - want).abs() < 1e-9 * want.abs(),
                "g {g}: {pd} vs {want}"
            );
        }
        let (cloud, k, _, top) = block(lift, 500.0, 0.0);
        let zero = vec![0.0; cloud.view().pos.len()];
        assert_eq!(dirichlet_values(&cloud.view(), &zero, &k, 0.0)[top], 0.0);
        // Beside a wall (the columns left of it made wall particles): a contact line, 0.
        let (mut cloud, k, p, top) = block(lift, 500.0, (9.0 + lift) * l0 - s);
        cloud.set_walls(|x| x[0] < 6.5 * l0);
        assert_eq!(dirichlet_values(&cloud.view(), &p, &k, 0.0)[top], 0.0);
    }

    /// With `edge-surface` the zero lies half a spacing beyond the mean surface: a flat
    /// surface under gravity takes `rho g l0 / 2` (the hydrostatic pressure half a spacing
    /// down), under tension the field's negative value there; a raised particle takes
    /// `G (s - l0 / 2)` of a linear field that is zero at that edge.
    #[test]
    fn the_edge_surface_lies_half_a_spacing_out() {
        let l0 = 0.01;
        let edge = SurfacePressure::EdgeSurface.edge(l0);
        assert_eq!(edge, 0.5 * l0);
        assert_eq!(SurfacePressure::MeanSurface.edge(l0), 0.0);
        for g in [500.0, -9810.0] {
            // The field is zero half a spacing above the top row at y = 9 l0.
            let (cloud, k, p, _) = block(0.0, g, 9.5 * l0);
            let v = cloud.view();
            let pd = dirichlet_values(&v, &p, &k, edge);
            for i in 0..v.pos.len() {
                let x = v.pos[i][0] / l0;
                if v.free_surface[i] && (3.0..=11.0).contains(&x) {
                    let want = -g * 0.5 * l0;
                    assert!(
                        (pd[i] - want).abs() < 1e-9 * want.abs(),
                        "{} vs {want}",
                        pd[i]
                    );
                }
            }
        }
        let lift = 0.3;
        let (cloud, k, _, top) = block(lift, 0.0, 0.0);
        let v = cloud.view();
        let (mut sw, mut so) = (weight(l0, k.grad.re), 0.0);
        for q in v.pairs(top, k.grad.re).filter(|q| v.free_surface[q.j]) {
            sw += q.w;
            so += q.w * q.xij[1];
        }
        let s = -so / sw;
        let g = 500.0;
        let y_edge = v.pos[top][1] - s + 0.5 * l0;
        let (cloud, k, p, top) = block(lift, g, y_edge);
        let pd = dirichlet_values(&cloud.view(), &p, &k, edge)[top];
        let want = g * (s - 0.5 * l0);
        assert!((pd - want).abs() < 1e-9 * want.abs(), "{pd} vs {want}");
    }
}
