//! Wall boundary (equations.md section 4, "the wall must push back"; s.7 for densities):
//! the pressures wall and dummy particles carry into the pressure gradient, and the density
//! they take from the fluid beside them. Why extrapolated pressures are the default, and what
//! was measured against the alternatives: docs/decisions.md, "Wall pressure".

use super::kernel::Kernels;
use super::pairs::is_within;
use crate::parallel;
use crate::particles::{Kind, Vector, View, NONE};
use serde::{Deserialize, Serialize};

/// Wall treatment in the PPE and the gradient (docs/decisions.md, "Wall pressure").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WallPressure {
    /// PPE with zero-gradient walls (dummies left out); for the gradient, wall and dummy
    /// pressures extrapolated from the fluid with the hydrostatic term (Adami, Hu & Adams
    /// 2012; default; a departure from the paper, which does not state its wall treatment).
    Extrapolated,
    /// Design candidate: hydrostatic Neumann rows in the PPE, dummy = backing wall pressure +
    /// hydrostatic difference. Double-counts gravity with velocity/PND sources (kept for study).
    Hydrostatic,
    /// Standard MPS: dummies carry no pressure; walls keep their PPE pressure.
    None,
}

/// Extrapolated pressure (Pa) of wall or dummy particle `i` from the fluid within `re` (m):
/// `p_w = sum_f w_wf (p_f + rho_f g . (r_w - r_f)) / sum_f w_wf`; `None` when no fluid
/// particle is in range.
pub fn extrapolated_pressure<const D: usize>(
    i: usize,
    v: &View<D>,
    p: &[f64],
    gravity: Vector<D>,
    re: f64,
) -> Option<f64> {
    let (mut sw, mut swp) = (0.0, 0.0);
    for q in v.pairs(i, re) {
        if v.kind[q.j] == Kind::Fluid {
            sw += q.w;
            swp += q.w * (p[q.j] + v.density[q.j] * gravity.dot(&-q.xij));
        }
    }
    (sw > 0.0).then(|| swp / sw)
}

/// Pressures of wall and dummy particles for the gradient, written into `pressure` (Pa), and
/// which particles carry pressure into the gradient stencil (`carries`).
///
/// With extrapolated pressures, a wall particle whose extrapolation is not positive (above
/// the waterline, where it runs into the air) leaves the stencil, as the missing air on the
/// fluid side does (docs/decisions.md, "Wall pressure"). In a `closed` domain (no free
/// surface, the level set by a reference) there is no air and the level is arbitrary: every
/// extrapolated wall pressure is kept as it is, negative ones included.
///
/// `values` and `carries` are filled (one entry a particle); `values` is scratch.
#[allow(clippy::too_many_arguments)]
pub fn boundary_pressures<const D: usize>(
    v: &View<D>,
    backing_wall: &[u32],
    (model, clamp, closed): (WallPressure, bool, bool),
    gravity: Vector<D>,
    k: &Kernels,
    pressure: &mut [f64],
    values: &mut Vec<f64>,
    carries: &mut Vec<bool>,
) {
    let n = v.pos.len();
    let solved: &[f64] = pressure;
    let boundary = |i: usize| match model {
        WallPressure::Extrapolated => v.kind[i] != Kind::Fluid,
        WallPressure::Hydrostatic => v.kind[i] == Kind::Dummy && backing_wall[i] != NONE,
        WallPressure::None => false,
    };
    parallel::unzip_into(values, carries, n, |i| {
        let carried = v.kind[i] != Kind::Dummy || model != WallPressure::None;
        if !boundary(i) {
            return (0.0, carried);
        }
        match model {
            WallPressure::Extrapolated => {
                let e = extrapolated_pressure(i, v, solved, gravity, k.lap.re);
                let (p, carried) = e.map_or((0.0, false), |p| (p, closed || p > 0.0));
                (if closed { p } else { p.max(0.0) }, carried)
            }
            _ => {
                let w = backing_wall[i] as usize;
                let p = solved[w] + v.density[i] * gravity.dot(&(v.pos[i] - v.pos[w]));
                (if clamp { p.max(0.0) } else { p }, carried)
            }
        }
    });
    for i in 0..n {
        if boundary(i) {
            pressure[i] = values[i];
        }
    }
}

/// Densities (kg/m^3) of every particle after the fluid moved to `v.pos`, into `out`: walls
/// take that of their nearest fluid particle within re_lap, dummies that of their backing
/// wall, fluid keeps its own (equations.md s.4, s.7). `walls` is scratch.
pub fn wall_densities<const D: usize>(
    v: &View<D>,
    backing_wall: &[u32],
    k: &Kernels,
    walls: &mut Vec<f64>,
    out: &mut Vec<f64>,
) {
    parallel::map_into(walls, v.pos.len(), |i| {
        if v.kind[i] != Kind::Wall {
            return v.density[i];
        }
        // The pairs of `v.pairs(i, re)` without their square roots and weights.
        let (re, xi) = (k.lap.re, v.pos[i]);
        let mut best = (re * re, v.density[i]);
        for &j in v.neighbors.for_radius(re).of(i) {
            let j = j as usize;
            let r2 = (v.pos[j] - xi).norm2();
            if v.kind[j] == Kind::Fluid && r2 < best.0 && is_within(r2, re) {
                best = (r2, v.density[j]);
            }
        }
        best.1
    });
    out.clear();
    out.extend((0..v.pos.len()).map(|i| match v.kind[i] {
        Kind::Dummy if backing_wall[i] != NONE => walls[backing_wall[i] as usize],
        _ => walls[i],
    }));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::neighbors::build_neighbor_list;

    /// A lid row of wall particles above two rows of still water whose pressure is -100 Pa
    /// at the top (a closed box whose level is set low): the extrapolated lid pressure is
    /// negative. Open (a free surface somewhere), it is clamped to 0 and leaves the stencil;
    /// closed, it is kept as extrapolated and carried, so shifting the level shifts every
    /// wall pressure by the same amount (the gradient cannot see the level).
    #[test]
    fn a_closed_domain_keeps_negative_wall_pressures() {
        let (l0, rho, g) = (0.01, 1000.0, 9.81);
        let gravity = Vector([0.0, -g]);
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let (mut pos, mut kind) = (Vec::new(), Vec::new());
        for row in 0..3 {
            for col in 0..7 {
                pos.push(Vector([col as f64 * l0, -(row as f64) * l0]));
                kind.push(if row == 0 { Kind::Wall } else { Kind::Fluid });
            }
        }
        let n = pos.len();
        let level =
            |top: f64| -> Vec<f64> { (0..n).map(|i| top + rho * g * (-pos[i][1] - l0)).collect() };
        let nl = build_neighbor_list(&pos, k.lap.re);
        let (density, zero, flags) = (vec![rho; n], vec![0.0; n], vec![false; n]);
        let vel = vec![Vector::zero(); n];
        let v = View {
            pos: &pos,
            vel: &vel,
            kind: &kind,
            density: &density,
            free_surface: &flags,
            number_density: &zero,
            neighbors: &nl,
        };
        let bw = vec![NONE; n];
        let lid = 3;
        let run = |top: f64, closed: bool| {
            let mut p = level(top);
            let (mut values, mut carries) = (Vec::new(), Vec::new());
            let model = (WallPressure::Extrapolated, false, closed);
            boundary_pressures(
                &v,
                &bw,
                model,
                gravity,
                &k,
                &mut p,
                &mut values,
                &mut carries,
            );
            (p[lid], carries[lid])
        };
        let (open_p, open_c) = run(-100.0, false);
        assert_eq!((open_p, open_c), (0.0, false));
        let (low, c) = run(-100.0, true);
        assert!(c && low < -100.0, "{low}");
        let (high, _) = run(900.0, true);
        assert!(((high - low) - 1000.0).abs() < 1e-9, "{low} {high}");
    }
}
