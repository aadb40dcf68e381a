//! Wall boundary (equations.md section 4, "the wall must push back"; s.7 for densities):
//! the pressures wall and dummy particles carry into the pressure gradient, and the density
//! they take from the fluid beside them. Why extrapolated pressures are the default, and what
//! was measured against the alternatives: docs/decisions.md, "Wall pressure".

use super::kernel::Kernels;
use crate::particles::{Kind, Vector, View, NONE};
use rayon::prelude::*;
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
/// fluid side does (docs/decisions.md, "Wall pressure").
pub fn boundary_pressures<const D: usize>(
    v: &View<D>,
    backing_wall: &[u32],
    model: WallPressure,
    clamp: bool,
    gravity: Vector<D>,
    k: &Kernels,
    pressure: &mut [f64],
) -> Vec<bool> {
    let n = v.pos.len();
    let solved: &[f64] = pressure;
    let boundary: Vec<(usize, f64)> = match model {
        WallPressure::Extrapolated => (0..n)
            .into_par_iter()
            .filter(|&i| v.kind[i] != Kind::Fluid)
            .map(|i| {
                let e = extrapolated_pressure(i, v, solved, gravity, k.lap.re);
                (i, e.unwrap_or(0.0))
            })
            .collect(),
        WallPressure::Hydrostatic => (0..n)
            .into_par_iter()
            .filter(|&i| v.kind[i] == Kind::Dummy && backing_wall[i] != NONE)
            .map(|i| {
                let w = backing_wall[i] as usize;
                (
                    i,
                    solved[w] + v.density[i] * gravity.dot(&(v.pos[i] - v.pos[w])),
                )
            })
            .collect(),
        WallPressure::None => Vec::new(),
    };
    let mut carries: Vec<bool> = v
        .kind
        .iter()
        .map(|k| *k != Kind::Dummy || model != WallPressure::None)
        .collect();
    for (i, p) in boundary {
        if model == WallPressure::Extrapolated {
            carries[i] = p > 0.0;
            pressure[i] = p.max(0.0);
        } else {
            pressure[i] = if clamp { p.max(0.0) } else { p };
        }
    }
    carries
}

/// Densities (kg/m^3) of every particle after the fluid moved to `v.pos`: walls take that of
/// their nearest fluid particle within re_lap, dummies that of their backing wall, fluid keeps
/// its own (equations.md s.4, s.7).
pub fn wall_densities<const D: usize>(v: &View<D>, backing_wall: &[u32], k: &Kernels) -> Vec<f64> {
    let walls: Vec<f64> = (0..v.pos.len())
        .into_par_iter()
        .map(|i| {
            if v.kind[i] != Kind::Wall {
                return v.density[i];
            }
            let mut best = (k.lap.re * k.lap.re, v.density[i]);
            for q in v.pairs(i, k.lap.re) {
                if v.kind[q.j] == Kind::Fluid && q.r2 < best.0 {
                    best = (q.r2, v.density[q.j]);
                }
            }
            best.1
        })
        .collect();
    (0..v.pos.len())
        .map(|i| match v.kind[i] {
            Kind::Dummy if backing_wall[i] != NONE => walls[backing_wall[i] as usize],
            _ => walls[i],
        })
        .collect()
}
