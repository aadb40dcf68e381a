//! The `[scheme]` table of a case file: a named preset and overrides of its parts, resolved
//! into the plain [`Scheme`] the step reads. Every override is range-checked here.

use crate::error::CaseError;
use crate::numerics::collision::Collision;
use crate::numerics::density::DensityAverage;
use crate::numerics::gradient::{GcFallback, GradientDensity, GradientModel};
use crate::numerics::interface_repulsion::InterfaceRepulsion;
use crate::numerics::scheme::{Preset, Scheme, PRESETS};
use crate::numerics::shifting::ParticleShifting;
use crate::numerics::source::{DriftControl, HsNormalization, SourceModel};
use crate::numerics::stabilization::{DsVelocity, DsWeighting, DynamicStabilization};
use crate::numerics::surface::SurfaceDetector;
use crate::numerics::surface_pressure::SurfacePressure;
use crate::numerics::walls::WallPressure;
use serde::{Deserialize, Serialize};

/// Dynamic Stabilization options (equations.md section 6).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DsSpec {
    /// Switch DS on or off (default: from the preset).
    pub enabled: Option<bool>,
    /// Threshold fraction `alpha_DS` of the particle diameter (default `1 - time.courant`,
    /// paper Eq. 9: 0.9 at the default Courant number 0.1; 0.9 with a fixed time step).
    pub alpha: Option<f64>,
    /// Pair-term weighting (default: the preset's; `surface-full` for MPS-HS-GC-DS).
    pub weighting: Option<DsWeighting>,
    /// Whether DS acts on fluid-wall pairs (default true).
    pub walls: Option<bool>,
    /// What DS does to velocities: `restoring` (the paper's) or `inelastic` (default: the
    /// preset's).
    pub velocity: Option<DsVelocity>,
}

/// Particle shifting options (beyond the paper: `numerics::shifting`).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ShiftingSpec {
    /// Switch particle shifting on (default off in every preset).
    pub enabled: Option<bool>,
    /// Coefficient `C` of Xu et al. (2009) (default 0.3).
    pub coefficient: Option<f64>,
    /// Largest shift of one step as a fraction of l0 (default 0.2).
    pub max_shift: Option<f64>,
}

/// Interface repulsion options (beyond the paper: `numerics::interface_repulsion`).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InterfaceRepulsionSpec {
    /// Switch it on or off (default: from the preset, on only in `MPS-HS-GC-DS-IR`).
    pub enabled: Option<bool>,
    /// Background pressure `P` across unlike pairs (Pa; default 50), the same at every
    /// spacing.
    pub pressure: Option<f64>,
    /// Or the interface energy `P l0` (N/m): `P` is this over the case's spacing, so a
    /// refined run keeps the energy of unlike contact per length of interface (not both).
    pub energy: Option<f64>,
}

/// Collision model options (equations.md section 5, step 2).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Switch the collision model on or off (default: from the preset).
    pub enabled: Option<bool>,
    /// Pairs closer than `alpha l0` are treated (default 0.5).
    pub alpha: Option<f64>,
    /// Coefficient of restitution `e` (default 0.2).
    pub restitution: Option<f64>,
}

/// Scheme: a named preset and optional overrides of its parts.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SchemeSpec {
    /// Preset: `MPS`, `CMPS-HS`, `MPS-HS-GC`, `MPS-HS-GC-DS` or `MPS-HS-GC-DS-IR` (beyond the paper).
    #[serde(default = "default_scheme_name")]
    pub name: String,
    /// Pressure-gradient model override.
    pub gradient: Option<GradientModel>,
    /// Gradient correction override.
    pub gradient_correction: Option<bool>,
    /// GC falls back where the moment matrix's determinant is below this fraction of the
    /// interior lattice value (default 0.2).
    pub gc_min_determinant: Option<f64>,
    /// What GC falls back to: `identity` (`d I`) or `floored` (the inverse with its
    /// eigenvalues raised to at least `gc_min_determinant / d`); default the preset's.
    pub gc_fallback: Option<GcFallback>,
    /// PPE source override.
    pub source: Option<SourceModel>,
    /// HS normalisation.
    pub hs_normalization: Option<HsNormalization>,
    /// Relaxation coefficient on the PND source (1 = restore the density error in one step).
    pub pnd_relaxation: Option<f64>,
    /// Drift control override.
    pub drift: Option<DriftControl>,
    /// Drift-control coefficient `gamma`.
    pub gamma: Option<f64>,
    /// Clamp negative pressure to zero.
    pub clamp_negative_pressure: Option<bool>,
    /// Free-surface detector and its parameters: `detector = "<name>"` (one of
    /// `numerics::surface::SurfaceDetector::NAMES`; default the preset's), the rest the
    /// detector's own parameters.
    pub surface: Option<toml::Table>,
    /// Shorthand for `surface.beta` of the number-density detector.
    pub surface_beta: Option<f64>,
    /// Shorthand for `surface.count_ratio` of the number-density detector.
    pub surface_count_ratio: Option<f64>,
    /// Where the free surface's `p = 0` is placed: `zero` (every surface particle, the
    /// paper's) or `mean-surface` (docs/decisions.md, "Surface pressure at the mean surface").
    pub surface_pressure: Option<SurfacePressure>,
    /// Wall particles take the free-surface test (a side open to the air: Dirichlet `p = 0`).
    pub wall_surface_test: Option<bool>,
    /// Count the missing part of a PPE row's neighbourhood as air at `p = 0` (Dirichlet)
    /// rather than leaving it out (zero gradient).
    pub air_ghosts: Option<bool>,
    /// Pair density average.
    pub density_average: Option<DensityAverage>,
    /// Density used in the pressure gradient.
    pub gradient_density: Option<GradientDensity>,
    /// Smooth the density near interfaces for the PPE coefficient and the gradient:
    /// `rho~_i = (n0 rho_i + sum_j w_ij rho_j) / (n0 + sum_j w_ij)` over re_grad.
    pub density_smoothing: Option<bool>,
    /// Dummy-particle pressure model.
    pub wall_pressure: Option<WallPressure>,
    /// Artificial compressibility `kappa` (1/Pa, rho-scaled) on the PPE diagonal.
    pub compressibility: Option<f64>,
    /// Sound speed (m/s) of a slight compressibility on the PPE (default: none).
    pub sound_speed: Option<f64>,
    /// Collision model.
    #[serde(default)]
    pub collision: CollisionSpec,
    /// Dynamic Stabilization.
    #[serde(default)]
    pub ds: DsSpec,
    /// Particle shifting (beyond the paper).
    #[serde(default)]
    pub shifting: ShiftingSpec,
    /// Repulsion between unlike fluid particles (beyond the paper:
    /// `numerics::interface_repulsion`).
    #[serde(default)]
    pub interface_repulsion: InterfaceRepulsionSpec,
}

impl Default for SchemeSpec {
    fn default() -> Self {
        toml::from_str("").expect("empty scheme table is valid")
    }
}

fn default_scheme_name() -> String {
    "MPS".into()
}

/// Checks `value` against `ok`; the error names `scheme.<field>`.
fn check(label: &str, field: &str, value: f64, ok: bool, range: &str) -> Result<f64, CaseError> {
    if ok {
        Ok(value)
    } else {
        let msg = format!("must lie in {range}");
        Err(CaseError::new(
            label,
            format!("scheme.{field}"),
            value.to_string(),
            msg,
        ))
    }
}

impl SchemeSpec {
    /// The free-surface detector: `[scheme.surface]`, or the number-density shorthands;
    /// `preset` names the preset's detector, taken when the case names none.
    fn surface(&self, label: &str, preset: &str) -> Result<SurfaceDetector, CaseError> {
        let mut params = self.surface.clone().unwrap_or_default();
        let name = match params.remove("detector") {
            None => preset.to_string(),
            Some(toml::Value::String(s)) => s,
            Some(other) => {
                let msg = "must be a string (a detector name)";
                return Err(CaseError::new(
                    label,
                    "scheme.surface.detector",
                    other.to_string(),
                    msg,
                ));
            }
        };
        for (key, v) in [
            ("beta", self.surface_beta),
            ("count_ratio", self.surface_count_ratio),
        ] {
            if let Some(v) = v {
                params.insert(key.into(), toml::Value::Float(v));
            }
        }
        match SurfaceDetector::from_params(&name, &params) {
            Some(Ok(d)) => Ok(d),
            Some(Err(e)) => Err(CaseError::new(
                label,
                format!("scheme.surface.{}", e.param),
                e.value,
                e.message,
            )),
            None => {
                let msg = format!(
                    "unknown detector; one of {}",
                    SurfaceDetector::NAMES.join(", ")
                );
                Err(CaseError::new(
                    label,
                    "scheme.surface.detector",
                    format!("{name:?}"),
                    msg,
                ))
            }
        }
    }

    /// Collision model: the preset's unless switched, with checked parameters.
    fn collision(&self, preset: &Preset, label: &str) -> Result<Option<Collision>, CaseError> {
        let c = &self.collision;
        if !c.enabled.unwrap_or(preset.collision) {
            return Ok(None);
        }
        let d = preset.scheme().collision.unwrap_or(Collision {
            alpha: crate::numerics::scheme::defaults::COLLISION_ALPHA,
            restitution: crate::numerics::scheme::defaults::COLLISION_RESTITUTION,
        });
        let alpha = c.alpha.unwrap_or(d.alpha);
        let e = c.restitution.unwrap_or(d.restitution);
        Ok(Some(Collision {
            alpha: check(
                label,
                "collision.alpha",
                alpha,
                alpha > 0.0 && alpha < 1.0,
                "(0, 1)",
            )?,
            restitution: check(
                label,
                "collision.restitution",
                e,
                (0.0..=1.0).contains(&e),
                "[0, 1]",
            )?,
        }))
    }

    /// Dynamic Stabilization: the preset's unless switched. Without a given threshold and
    /// with Courant time steps, paper Eq. 9: `alpha_DS + alpha_dt = 1`, `alpha_dt` the Courant
    /// number, so a pair is treated once it closes by more than one step's travel.
    fn ds(
        &self,
        preset: &Preset,
        courant: Option<f64>,
        label: &str,
    ) -> Result<Option<DynamicStabilization>, CaseError> {
        let s = &self.ds;
        if !s.enabled.unwrap_or(preset.ds) {
            return Ok(None);
        }
        let alpha = match (s.alpha, courant) {
            (Some(a), _) => check(label, "ds.alpha", a, a > 0.0 && a < 1.0, "(0, 1)")?,
            (None, Some(c)) => (1.0 - c).clamp(0.5, 0.99),
            (None, None) => crate::numerics::scheme::defaults::DS_ALPHA,
        };
        Ok(Some(DynamicStabilization {
            alpha,
            weighting: s.weighting.unwrap_or(preset.ds_weighting),
            walls: s.walls.unwrap_or(true),
            velocity: s.velocity.unwrap_or(preset.ds_velocity),
        }))
    }

    /// Interface repulsion: as the preset has it unless switched, with a checked pressure,
    /// given as such or as an energy over the spacing `l0` (m).
    fn interface_repulsion(
        &self,
        preset: &Preset,
        l0: f64,
        label: &str,
    ) -> Result<Option<InterfaceRepulsion>, CaseError> {
        let s = &self.interface_repulsion;
        if !s.enabled.unwrap_or(preset.interface_repulsion > 0.0) {
            return Ok(None);
        }
        let pressure = match (s.pressure, s.energy) {
            (Some(_), Some(e)) => {
                let field = "scheme.interface_repulsion.energy";
                let msg = "give energy or pressure, not both";
                return Err(CaseError::new(label, field, e.to_string(), msg));
            }
            (None, Some(e)) => {
                let ok = e > 0.0 && e.is_finite();
                check(label, "interface_repulsion.energy", e, ok, "(0, inf)")? / l0
            }
            (p, None) => {
                let p = p.unwrap_or(crate::numerics::scheme::defaults::INTERFACE_REPULSION);
                let ok = p > 0.0 && p.is_finite();
                check(label, "interface_repulsion.pressure", p, ok, "(0, inf)")?
            }
        };
        Ok(Some(InterfaceRepulsion { pressure }))
    }

    /// Particle shifting: off unless switched on, with checked parameters.
    fn shifting(&self, label: &str) -> Result<Option<ParticleShifting>, CaseError> {
        let s = &self.shifting;
        if !s.enabled.unwrap_or(false) {
            return Ok(None);
        }
        let d = ParticleShifting::default();
        let c = s.coefficient.unwrap_or(d.coefficient);
        let m = s.max_shift.unwrap_or(d.max_shift);
        Ok(Some(ParticleShifting {
            coefficient: check(
                label,
                "shifting.coefficient",
                c,
                c > 0.0 && c <= 10.0,
                "(0, 10]",
            )?,
            max_shift: check(
                label,
                "shifting.max_shift",
                m,
                m > 0.0 && m <= 0.5,
                "(0, 0.5]",
            )?,
        }))
    }

    /// Resolves the preset and overrides; `courant` is the Courant number when the time step
    /// follows it (for the DS threshold of Eq. 9), `spacing` the particle spacing l0 (m),
    /// `label` names the case in errors.
    pub fn resolve(
        &self,
        courant: Option<f64>,
        spacing: f64,
        label: &str,
    ) -> Result<Scheme, CaseError> {
        let Some(preset) = Preset::named(&self.name) else {
            let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
            let msg = format!("unknown scheme; one of {}", names.join(", "));
            return Err(CaseError::new(
                label,
                "scheme.name",
                format!("{:?}", self.name),
                msg,
            ));
        };
        let mut s = preset.scheme();
        if let Some(source) = self.source {
            s.source.model = source;
            s.source.drift = if source == SourceModel::Hs {
                DriftControl::Gamma
            } else {
                DriftControl::None
            };
        }
        let gamma = self.gamma.unwrap_or(s.source.gamma);
        s.source.gamma = check(
            label,
            "gamma",
            gamma,
            (0.0..=1.0).contains(&gamma),
            "[0, 1]",
        )?;
        let relax = self.pnd_relaxation.unwrap_or(s.source.pnd_relaxation);
        s.source.pnd_relaxation = check(
            label,
            "pnd_relaxation",
            relax,
            relax > 0.0 && relax <= 1.0,
            "(0, 1]",
        )?;
        let gc = self
            .gc_min_determinant
            .unwrap_or(s.gradient.gc_min_determinant);
        s.gradient.gc_min_determinant = check(
            label,
            "gc_min_determinant",
            gc,
            (0.0..=1.0).contains(&gc),
            "[0, 1]",
        )?;
        s.gradient.gc_fallback = self.gc_fallback.unwrap_or(s.gradient.gc_fallback);
        let kappa = self.compressibility.unwrap_or(0.0);
        s.compressibility = check(
            label,
            "compressibility",
            kappa,
            kappa >= 0.0 && kappa.is_finite(),
            "[0, inf)",
        )?;
        if let Some(c) = self.sound_speed {
            let ok = c > 0.0 && c.is_finite();
            s.sound_speed = Some(check(label, "sound_speed", c, ok, "(0, inf)")?);
        }
        s.surface = self.surface(label, s.surface.name())?;
        s.surface_pressure = self.surface_pressure.unwrap_or(s.surface_pressure);
        s.collision = self.collision(preset, label)?;
        s.ds = self.ds(preset, courant, label)?;
        s.shifting = self.shifting(label)?;
        s.interface_repulsion = self.interface_repulsion(preset, spacing, label)?;
        let g = &mut s.gradient;
        g.model = self.gradient.unwrap_or(g.model);
        g.correction = self.gradient_correction.unwrap_or(g.correction);
        g.density = self.gradient_density.unwrap_or(g.density);
        let src = &mut s.source;
        src.hs_normalization = self.hs_normalization.unwrap_or(src.hs_normalization);
        src.drift = self.drift.unwrap_or(src.drift);
        s.clamp_negative_pressure = self
            .clamp_negative_pressure
            .unwrap_or(s.clamp_negative_pressure);
        // The wall surface test and air ghosts follow the source (on for HS, off for PND).
        let hs = s.source.model != SourceModel::Pnd;
        s.wall_surface_test = self.wall_surface_test.unwrap_or(hs);
        s.air_ghosts = self.air_ghosts.unwrap_or(hs);
        s.density_average = self.density_average.unwrap_or(s.density_average);
        s.gradient.average = s.density_average;
        s.density_smoothing = self.density_smoothing.unwrap_or(s.density_smoothing);
        s.wall_pressure = self.wall_pressure.unwrap_or(s.wall_pressure);
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(name: &str) -> SchemeSpec {
        SchemeSpec {
            name: name.into(),
            ..Default::default()
        }
    }

    #[test]
    fn the_bare_preset_is_the_numerics_preset() {
        for p in PRESETS {
            assert_eq!(spec(p.name).resolve(None, 0.01, "t").unwrap(), p.scheme());
        }
    }

    #[test]
    fn overrides_replace_preset_parts() {
        let mut s = spec("MPS-HS-GC-DS");
        s.ds.enabled = Some(false);
        s.gradient_correction = Some(false);
        let r = s.resolve(None, 0.01, "t").unwrap();
        assert!(r.ds.is_none() && !r.gradient.correction);
    }

    #[test]
    fn ds_threshold_follows_the_courant_number_unless_given() {
        let s = spec("MPS-HS-GC-DS");
        assert_eq!(
            s.resolve(Some(0.03), 0.01, "t").unwrap().ds.unwrap().alpha,
            0.97
        );
        let mut given = spec("MPS-HS-GC-DS");
        given.ds.alpha = Some(0.95);
        assert_eq!(
            given
                .resolve(Some(0.03), 0.01, "t")
                .unwrap()
                .ds
                .unwrap()
                .alpha,
            0.95
        );
    }

    #[test]
    fn bad_values_and_names_are_named() {
        let e = spec("SPH").resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.name");
        let mut s = spec("MPS");
        s.gamma = Some(2.0);
        assert_eq!(
            s.resolve(None, 0.01, "t").unwrap_err().field,
            "scheme.gamma"
        );
        let mut s = spec("MPS");
        s.surface = Some(toml::from_str("detector = \"nope\"").unwrap());
        assert_eq!(
            s.resolve(None, 0.01, "t").unwrap_err().field,
            "scheme.surface.detector"
        );
        let mut s = spec("MPS");
        s.surface = Some(toml::from_str("detector = \"distribution\"\nthreshold = 5.0").unwrap());
        assert_eq!(
            s.resolve(None, 0.01, "t").unwrap_err().field,
            "scheme.surface.threshold"
        );
        let mut s = spec("MPS");
        s.surface_beta = Some(1.5);
        assert_eq!(
            s.resolve(None, 0.01, "t").unwrap_err().field,
            "scheme.surface.beta"
        );
    }

    #[test]
    fn the_distribution_detector_is_selectable() {
        let mut s = spec("MPS-HS-GC-DS");
        assert_eq!(s.resolve(None, 0.01, "t").unwrap().shifting, None);
        s.shifting.enabled = Some(true);
        let on = s.resolve(None, 0.01, "t").unwrap().shifting.unwrap();
        assert_eq!(on, ParticleShifting::default());
        s.shifting.coefficient = Some(0.0);
        let e = s.resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.shifting.coefficient");
        s.shifting.coefficient = None;
        s.shifting.max_shift = Some(0.7);
        let e = s.resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.shifting.max_shift");
        let mut s = spec("MPS-HS-GC-DS");
        s.surface = Some(toml::from_str("detector = \"distribution\"").unwrap());
        assert_eq!(
            s.resolve(None, 0.01, "t").unwrap().surface.name(),
            "distribution"
        );
    }

    /// The repulsion's pressure applies where the preset has it (so `mps compare` runs the
    /// paper's presets without it from the same case) or where it is switched on.
    #[test]
    fn the_interface_repulsion_follows_the_preset_unless_switched() {
        let pressure = |s: &SchemeSpec| {
            s.resolve(Some(0.1), 0.01, "t")
                .unwrap()
                .interface_repulsion
                .map(|r| r.pressure)
        };
        let mut s = spec("MPS-HS-GC-DS-IR");
        assert_eq!(pressure(&s), Some(50.0));
        s.interface_repulsion.pressure = Some(100.0);
        assert_eq!(pressure(&s), Some(100.0));
        s.name = "MPS-HS-GC-DS".into();
        assert_eq!(pressure(&s), None);
        s.interface_repulsion.enabled = Some(true);
        assert_eq!(pressure(&s), Some(100.0));
        s.interface_repulsion.pressure = Some(-1.0);
        let e = s.resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.interface_repulsion.pressure");
        // As an energy (N/m): the pressure is it over the spacing, at any spacing.
        s.interface_repulsion.pressure = None;
        s.interface_repulsion.energy = Some(0.05);
        for l0 in [0.0025, 0.00125] {
            let r = s
                .resolve(None, l0, "t")
                .unwrap()
                .interface_repulsion
                .unwrap();
            assert_eq!(r.pressure, 0.05 / l0);
        }
        s.interface_repulsion.pressure = Some(20.0);
        let e = s.resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.interface_repulsion.energy");
        s.interface_repulsion.pressure = None;
        s.interface_repulsion.energy = Some(f64::NAN);
        let e = s.resolve(None, 0.01, "t").unwrap_err();
        assert_eq!(e.field, "scheme.interface_repulsion.energy");
    }
}
