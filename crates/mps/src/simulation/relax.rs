//! A relaxation phase before a run (`[initial.relax]`, issue 12's settled start): a particle
//! lattice under gravity is not at rest (the wall rows' number-density deficit, the free
//! surface's first step), so a case whose measurement starts at t = 0 (the early
//! acceleration of a settling group) first lets its tank settle. The tank is the case's own
//! geometry with every fluid region of the first region's phase, at rest, stepped under the
//! MPS-HS-GC-DS preset (which holds a still tank: docs/decisions.md) with the surface
//! treatment the settled starts were measured with (the paper's DS weighting, `p = 0` on the
//! mean surface, GC falling back to `d I`), the same state whatever scheme the run itself
//! then uses (so `mps compare` starts every scheme alike).

use super::Simulation;
use crate::error::{Error, Result};
use crate::input::case::{Case, RelaxSpec};
use crate::input::scheme_spec::{DsSpec, SchemeSpec};
use crate::numerics::gradient::GcFallback;
use crate::numerics::stabilization::DsWeighting;
use crate::numerics::surface_pressure::SurfacePressure;
use crate::particles::{Kind, Particles};

/// The preset the relaxation runs under.
pub const RELAX_SCHEME: &str = "MPS-HS-GC-DS";

/// The case a relaxation of `case` runs: every fluid region of the first region's phase and
/// without initial velocity, the relaxation's scheme, no settled start, probes, validation
/// or outputs, to the relaxation's longest time.
pub fn relaxation_case(case: &Case, spec: &RelaxSpec) -> Case {
    let mut rest = case.clone();
    if let Some(first) = case.fluid.first() {
        for f in &mut rest.fluid {
            f.phase = first.phase.clone();
            f.velocity = None;
        }
    }
    rest.scheme = SchemeSpec {
        name: RELAX_SCHEME.into(),
        surface_pressure: Some(SurfacePressure::MeanSurface),
        gc_fallback: Some(GcFallback::Identity),
        ds: DsSpec {
            weighting: Some(DsWeighting::Kernel),
            ..DsSpec::default()
        },
        ..SchemeSpec::default()
    };
    rest.initial = None;
    rest.probes = Vec::new();
    rest.validation = None;
    rest.time.end = spec.time;
    rest.time.max_steps = None;
    rest
}

/// Runs the relaxation of `case` (file `label` in messages) and returns its particles.
/// A breakdown of the relaxation is an error naming `initial.relax`.
pub fn relax<const D: usize>(case: &Case, spec: &RelaxSpec, label: &str) -> Result<Particles<D>> {
    relax_with(case, spec, label, &mut |_| {})
}

/// [`relax`], telling `progress` the relaxation's time (s) after every step.
pub fn relax_with<const D: usize>(
    case: &Case,
    spec: &RelaxSpec,
    label: &str,
    progress: &mut dyn FnMut(f64),
) -> Result<Particles<D>> {
    let rest = relaxation_case(case, spec);
    let mut sim = Simulation::<D>::new(rest, label)?;
    let end = spec.time;
    let mut peak = 0.0f64;
    while sim.time < end * (1.0 - 1e-9) {
        sim.step(end).map_err(|b| Error::Format {
            path: label.into(),
            message: format!("initial.relax: the relaxation broke down ({b})"),
        })?;
        progress(sim.time);
        let e = kinetic_energy(&sim.particles);
        peak = peak.max(e);
        if spec
            .kinetic_fraction
            .is_some_and(|f| peak > 0.0 && e < f * peak)
        {
            break;
        }
    }
    Ok(sim.particles)
}

/// `sum m |u|^2 / 2` over the fluid particles, per unit spacing volume (J / m^D).
fn kinetic_energy<const D: usize>(p: &Particles<D>) -> f64 {
    (0..p.len())
        .filter(|&i| p.kind[i] == Kind::Fluid)
        .map(|i| 0.5 * p.density[i] * p.velocity[i].norm2())
        .sum()
}
