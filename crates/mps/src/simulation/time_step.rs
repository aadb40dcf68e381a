//! The time step: fixed, or the Courant and viscous limits (equations.md s.5), landing on the
//! end time without a sliver of a last step.

use super::breakdown::BreakdownReason;
use super::Simulation;
use crate::error::CaseError;
use crate::input::Case;
use crate::parallel;
use crate::particles::{Kind, Particles};

/// The most steps a run's capillary limit may ask for.
const MAX_STEPS: f64 = 1e9;

/// The largest time step of a case (s): `time.dt_fixed`, `time.dt_max`, or
/// `C sqrt(l0/g)` with gravity, `C l0/u0` with only an initial velocity `u0`, else the
/// capillary limit of its surfaces under tension; unless fixed, at most that limit.
pub fn largest_time_step<const D: usize>(
    case: &Case,
    p: &Particles<D>,
    g: f64,
    label: &str,
) -> Result<f64, CaseError> {
    let l0 = case.particles.spacing;
    let c = case.time.courant;
    let u0 = initial_speed(p);
    let cap = capillary_time_step(case);
    // A run that cannot end: a tension so strong that its capillary limit asks more steps
    // than any run takes (a surface tension of 1e300 N/m ran at 1e-154 s a step).
    let steps = case.time.end / cap;
    if case.time.dt_fixed.is_none() && steps > MAX_STEPS {
        return Err(CaseError::new(
            label,
            "time.end",
            case.time.end.to_string(),
            format!("the capillary limit of the case's surface tension allows steps of {cap:.3e} s: {steps:.1e} steps, more than {MAX_STEPS:.0e}"),
        ));
    }
    match (case.time.dt_fixed, case.time.dt_max) {
        (Some(f), _) => Ok(f),
        (None, Some(m)) => Ok(m.min(cap)),
        (None, None) if g > 0.0 => Ok((c * (l0 / g).sqrt()).min(cap)),
        (None, None) if u0 > 0.0 => Ok((c * l0 / u0).min(cap)),
        (None, None) if cap.is_finite() => Ok(cap),
        _ => Err(CaseError::new(
            label,
            "time.dt_max",
            "",
            "needed: no gravity and no initial velocity give no time scale",
        )),
    }
}

/// Largest initial fluid speed (m/s).
pub fn initial_speed<const D: usize>(p: &Particles<D>) -> f64 {
    (0..p.len())
        .filter(|&i| p.kind[i] == Kind::Fluid)
        .map(|i| p.velocity[i].norm())
        .fold(0.0, f64::max)
}

/// The velocity scale of a case (m/s): the largest of the initial speed and the free-fall
/// speed over the fluid's height, `sqrt(2 g (h + l0))`.
pub fn velocity_scale<const D: usize>(p: &Particles<D>, g: f64, l0: f64) -> f64 {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for i in 0..p.len() {
        if p.kind[i] == Kind::Fluid {
            lo = lo.min(p.position[i][D - 1]);
            hi = hi.max(p.position[i][D - 1]);
        }
    }
    initial_speed(p).max((2.0 * g * (hi - lo + l0)).sqrt())
}

impl<const D: usize> Simulation<D> {
    /// The step to take (s) towards `until` (s): fixed, or
    /// `min(dt_max, C l0 / u_max, 0.1 l0^2 / nu)`; a step below `breakdown.min_dt_ratio`
    /// times `min(dt_max, 0.1 l0^2 / nu)` is a breakdown (a time-step collapse).
    pub(super) fn time_step(&mut self, until: f64) -> Result<f64, BreakdownReason> {
        let c = &self.case.time;
        let dt = if let Some(f) = c.dt_fixed {
            f
        } else {
            let p = &self.particles;
            let speed = |i: usize| match p.kind[i] {
                Kind::Fluid => p.velocity[i].norm(),
                _ => 0.0,
            };
            let umax = parallel::map_reduce(p.len(), 0.0, speed, f64::max);
            let umax = self.max(umax);
            let c = &self.case.time;
            let l0 = self.l0();
            let mut dt = self.dt_max;
            if umax > 0.0 {
                dt = dt.min(c.courant * l0 / umax);
            }
            dt.min(self.viscous_time_step())
        };
        // Against the largest step the case's fixed limits allow: a case whose largest step
        // is a weak tension's capillary limit (seconds) runs at its viscous limit throughout.
        let allowed = self.dt_max.min(self.viscous_time_step());
        if dt < self.case.breakdown.min_dt_ratio * allowed {
            return Err(BreakdownReason::TimeStepCollapse { dt });
        }
        Ok(land_on(until - self.time, dt))
    }

    /// The viscous limit of the step (s), `0.1 l0^2 / nu` with the largest kinematic
    /// viscosity of the phases; infinite where every phase is inviscid.
    fn viscous_time_step(&self) -> f64 {
        let nu = self.phase_viscosity.iter().cloned().fold(0.0, f64::max);
        if nu > 0.0 {
            0.1 * self.l0() * self.l0() / nu
        } else {
            f64::INFINITY
        }
    }
}

/// Every surface under tension of the case as `(sigma, rho_mean)` (N/m, kg/m^3): each
/// interface with its two phases' mean density, and each phase's free surface with half the
/// phase's density (the void's density is 0 in Brackbill's mean).
fn tensions(case: &Case) -> impl Iterator<Item = (f64, f64)> + '_ {
    let density = |name: &str| {
        let p = case.phases.iter().find(|p| p.name == name);
        p.map_or(f64::NAN, |p| p.density)
    };
    let interfaces = case.interfaces.iter().map(move |f| {
        let rho = 0.5 * (density(&f.phases[0]) + density(&f.phases[1]));
        (f.tension, rho)
    });
    let free = case.phases.iter().filter(|p| p.surface_tension > 0.0);
    interfaces.chain(free.map(|p| (p.surface_tension, 0.5 * p.density)))
}

/// The capillary limit of the step (s), `sqrt(rho_mean l0^3 / (2 pi sigma))` over the case's
/// interfaces and free surfaces under tension (Brackbill, Kothe & Zemach 1992); infinite
/// without either.
pub fn capillary_time_step(case: &Case) -> f64 {
    let l0 = case.particles.spacing;
    tensions(case)
        .map(|(sigma, rho)| (rho * l0.powi(3) / (2.0 * std::f64::consts::PI * sigma)).sqrt())
        .fold(f64::INFINITY, f64::min)
}

/// The capillary speed of the case's surfaces under tension at the particle scale (m/s),
/// `sqrt(sigma / (rho_mean l0))`, the largest; 0 without any. A velocity scale for the
/// breakdown speed bound where gravity gives none.
pub fn capillary_speed(case: &Case) -> f64 {
    let l0 = case.particles.spacing;
    tensions(case)
        .map(|(sigma, rho)| (sigma / (rho * l0)).sqrt())
        .fold(0.0, f64::max)
}

/// The step (s) for `remaining` (s) at step `dt` (s): the last two steps share what is left,
/// so no sliver of a step kicks the particles (the drift term scales as `1/dt^2`;
/// docs/decisions.md, "Last steps").
pub fn land_on(remaining: f64, dt: f64) -> f64 {
    if remaining < dt * 1.000_001 {
        remaining.max(dt * 1e-6)
    } else if remaining < 2.0 * dt {
        0.5 * remaining
    } else {
        dt
    }
}
