//! Wall boundary pressures for the pressure gradient (equations.md section 4, "the wall must
//! push back").
//!
//! Measured on a still tank (one step from the exact hydrostatic state, l0 = 5 mm): with the
//! fluid falling onto a fixed wall, the PPE source (HS or PND) already carries the signal
//! that stops it, so a zero-gradient wall in the PPE gives the right interior slope `rho g`;
//! adding the hydrostatic Neumann rows on top (design candidate) counts gravity twice and
//! gave 1.9x (MPS-HS-GC) to 2.3x (MPS) the hydrostatic slope after one step. The PPE's wall
//! values sit half a hydrostatic increment short, though, so for the gradient the walls and
//! dummies take pressures extrapolated from the fluid beside them (Adami, Hu & Adams 2012):
//! `p_w = sum_f w_wf (p_f + rho_f g . (r_w - r_f)) / sum_f w_wf` over fluid within re_lap,
//! clipped at zero by the step. A wall or dummy particle whose extrapolation is not positive
//! (above the waterline, where it runs into the air) is treated as air: it leaves the
//! gradient stencil and the GC moment matrix, as the missing air on the fluid side does.
//! Measured: with those particles kept at p = 0 in the stencil, GC turned the vertical
//! gradient into a sideways push on the waterline corner particle (0.7 m/s^2 in the first
//! step) and MPS-HS-GC broke the still tank at 0.13 s; without them it holds 2 s.
//!
//! Tried and rejected (measured): clipping the fluid-wall pair pressure difference at zero
//! in the gradient ("walls never pull") did not keep MPS-HS-GC's waterline corners in the
//! still tank (breakdown 0.11 s instead of 0.13 s), so it is not used.

use crate::fields::Fields;
use crate::kernel::weight;
use crate::particles::Kind;
use crate::vector::Vector;

/// Extrapolated pressure (Pa) of wall or dummy particle `i` from the fluid within `re` (m);
/// `None` when no fluid particle is in range.
pub fn extrapolated_pressure<const D: usize>(
    i: usize,
    f: &Fields<D>,
    p: &[f64],
    gravity: Vector<D>,
    re: f64,
) -> Option<f64> {
    let xi = f.pos[i];
    let (mut sw, mut swp) = (0.0, 0.0);
    for &j in f.neighbors.of(i) {
        let j = j as usize;
        if f.kind[j] != Kind::Fluid {
            continue;
        }
        let r = xi - f.pos[j];
        let w = weight(r.norm(), re);
        if w > 0.0 {
            sw += w;
            swp += w * (p[j] + f.density[j] * gravity.dot(&r));
        }
    }
    (sw > 0.0).then(|| swp / sw)
}
