//! Numerical schemes as data: one plain struct of every choice the step reads, the paper's
//! four named presets (equations.md section 8) and two beyond the paper (the DS preset with
//! the interface repulsion of `numerics::interface_repulsion`, and the DS preset for strained
//! bodies). Overrides from a case file are applied by `input::scheme_spec`.

use super::collision::Collision;
use super::density::DensityAverage;
use super::gradient::{GcFallback, GradientDensity, GradientModel, PressureGradient};
use super::interface_repulsion::InterfaceRepulsion;
use super::shifting::ParticleShifting;
use super::source::{DriftControl, HsNormalization, PpeSource, SourceModel};
use super::stabilization::{DsVelocity, DsWeighting, DynamicStabilization};
use super::surface::distribution::Distribution;
use super::surface::number_density::NumberDensity;
use super::surface::SurfaceDetector;
use super::surface_pressure::SurfacePressure;
use super::walls::WallPressure;

/// A fully resolved scheme.
#[derive(Debug, Clone, PartialEq)]
pub struct Scheme {
    /// Preset name it started from.
    pub name: String,
    /// Pressure-gradient model and options.
    pub gradient: PressureGradient,
    /// PPE source and its drift control.
    pub source: PpeSource,
    /// Clamp negative pressure to zero.
    pub clamp_negative_pressure: bool,
    /// Free-surface detector.
    pub surface: SurfaceDetector,
    /// Where the free surface's `p = 0` is placed (particle centres, or the mean surface).
    pub surface_pressure: SurfacePressure,
    /// Wall particles take the free-surface test (walls open to the air are Dirichlet).
    pub wall_surface_test: bool,
    /// PPE rows count their missing neighbourhood as air at p = 0.
    pub air_ghosts: bool,
    /// Pair density average (PPE; the gradient keeps its own copy).
    pub density_average: DensityAverage,
    /// Smoothed density in the PPE coefficient and the gradient.
    pub density_smoothing: bool,
    /// Wall and dummy pressure model.
    pub wall_pressure: WallPressure,
    /// Artificial compressibility (1/Pa): a relaxation of the pressure toward zero.
    pub compressibility: f64,
    /// Slight compressibility by a sound speed `c` (m/s): `(p - p^n)/(rho c^2 dt^2)` on the
    /// PPE, a steady pressure unaffected; `None` for incompressible (the paper's presets).
    pub sound_speed: Option<f64>,
    /// Collision model, if on.
    pub collision: Option<Collision>,
    /// Dynamic Stabilization, if on.
    pub ds: Option<DynamicStabilization>,
    /// Particle shifting, if on (beyond the paper; off in every preset).
    pub shifting: Option<ParticleShifting>,
    /// Repulsion between unlike fluid particles, if on (beyond the paper).
    pub interface_repulsion: Option<InterfaceRepulsion>,
}

/// One of the paper's named schemes: the choices that distinguish it (equations.md s.8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    /// Name in case files.
    pub name: &'static str,
    /// Pressure-gradient model.
    pub gradient: GradientModel,
    /// Gradient correction.
    pub gradient_correction: bool,
    /// PPE source.
    pub source: SourceModel,
    /// Dynamic Stabilization.
    pub ds: bool,
    /// Collision model.
    pub collision: bool,
    /// Clamp negative pressure.
    pub clamp_negative_pressure: bool,
    /// Background pressure of the repulsion between unlike fluid particles (Pa; 0: none).
    pub interface_repulsion: f64,
    /// Where the free surface's pressure is set.
    pub surface_pressure: SurfacePressure,
    /// Weighting of the DS pair terms (used where `ds`).
    pub ds_weighting: DsWeighting,
    /// GC where the moment matrix is near-singular (used where `gradient_correction`).
    pub gc_fallback: GcFallback,
    /// What DS does to velocities (used where `ds`).
    pub ds_velocity: DsVelocity,
    /// Normalisation of the HS source (used where the source is HS).
    pub hs_normalization: HsNormalization,
    /// Drift control on the HS source (used where the source is HS).
    pub drift: DriftControl,
}

/// The paper's DS scheme, MPS-HS-GC-DS (equations.md section 8).
const DS_PRESET: Preset = Preset {
    name: "MPS-HS-GC-DS",
    gradient: GradientModel::Taylor,
    gradient_correction: true,
    source: SourceModel::Hs,
    ds: true,
    collision: false,
    clamp_negative_pressure: false,
    interface_repulsion: 0.0,
    // Beyond the paper, which does not state its surface treatment: `p` set half a spacing
    // out at the particles' edge, DS applied whole to pairs with a free-surface particle
    // (docs/decisions.md, "DS whole at the free surface"), and GC kept, floored, where the
    // neighbours sample some directions only ("The GC fallback floored").
    surface_pressure: SurfacePressure::EdgeSurface,
    ds_weighting: DsWeighting::SurfaceFull,
    gc_fallback: GcFallback::Floored,
    ds_velocity: DsVelocity::Restoring,
    hs_normalization: HsNormalization::Consistent,
    drift: DriftControl::Gamma,
};

/// The paper's presets (equations.md section 8), then the two beyond the paper.
pub const PRESETS: [Preset; 6] = [
    Preset {
        name: "MPS",
        gradient: GradientModel::Original,
        gradient_correction: false,
        source: SourceModel::Pnd,
        ds: false,
        collision: true,
        clamp_negative_pressure: true,
        interface_repulsion: 0.0,
        surface_pressure: SurfacePressure::Zero,
        ds_weighting: DsWeighting::Kernel,
        gc_fallback: GcFallback::Identity,
        ds_velocity: DsVelocity::Restoring,
        hs_normalization: HsNormalization::Consistent,
        drift: DriftControl::Gamma,
    },
    Preset {
        name: "CMPS-HS",
        gradient: GradientModel::Cmps,
        gradient_correction: false,
        source: SourceModel::Hs,
        ds: false,
        collision: false,
        clamp_negative_pressure: false,
        interface_repulsion: 0.0,
        surface_pressure: SurfacePressure::Zero,
        ds_weighting: DsWeighting::Kernel,
        gc_fallback: GcFallback::Identity,
        ds_velocity: DsVelocity::Restoring,
        hs_normalization: HsNormalization::Consistent,
        drift: DriftControl::Gamma,
    },
    Preset {
        name: "MPS-HS-GC",
        gradient: GradientModel::Taylor,
        gradient_correction: true,
        source: SourceModel::Hs,
        ds: false,
        collision: false,
        clamp_negative_pressure: false,
        interface_repulsion: 0.0,
        surface_pressure: SurfacePressure::Zero,
        ds_weighting: DsWeighting::Kernel,
        gc_fallback: GcFallback::Identity,
        ds_velocity: DsVelocity::Restoring,
        hs_normalization: HsNormalization::Consistent,
        drift: DriftControl::Gamma,
    },
    DS_PRESET,
    // Beyond the paper: MPS-HS-GC-DS with a repulsion between unlike fluid particles, which
    // keeps two immiscible fluids from mixing particle by particle at the paper's Courant
    // 0.1 and alpha_DS 0.9 (docs/decisions.md, "Interface repulsion against two-phase
    // mixing").
    Preset {
        name: "MPS-HS-GC-DS-IR",
        interface_repulsion: defaults::INTERFACE_REPULSION,
        // The surface treatment the two-phase figures were measured with.
        surface_pressure: SurfacePressure::MeanSurface,
        ds_weighting: DsWeighting::Kernel,
        gc_fallback: GcFallback::Identity,
        ..DS_PRESET
    },
    // Beyond the paper: MPS-HS-GC-DS for free bodies under strain. Its source and drift
    // control measure the number density by a smooth kernel (no false compression where
    // the arrangement is strained at constant area), and DS cancels only each active pair's
    // approach (its losses no longer grow as the step falls): docs/decisions.md, "A DS
    // preset for strained bodies".
    Preset {
        name: "MPS-HS-GC-DS-S",
        ds_velocity: DsVelocity::Inelastic,
        hs_normalization: HsNormalization::Smooth,
        drift: DriftControl::SmoothGamma,
        ..DS_PRESET
    },
];

/// Defaults of the parts the presets share (sources in docs/decisions.md).
pub mod defaults {
    /// Drift coefficient `gamma` (Tanaka & Masunaga 2010 use 0.01-0.05).
    pub const GAMMA: f64 = 0.01;
    /// Relaxation of the PND source: 0.2 as in Koshizuka's reference MPS code
    /// (docs/decisions.md, "PND relaxation").
    pub const PND_RELAXATION: f64 = 0.2;
    /// GC fallback threshold (docs/decisions.md, "GC fallback").
    pub const GC_MIN_DETERMINANT: f64 = 0.2;
    /// Collision distance, fraction of l0 (Koshizuka's reference MPS code).
    pub const COLLISION_ALPHA: f64 = 0.5;
    /// Collision restitution coefficient (Koshizuka's reference MPS code).
    pub const COLLISION_RESTITUTION: f64 = 0.2;
    /// DS threshold `alpha_DS` with a fixed time step (paper Eq. 9 at Courant 0.1).
    pub const DS_ALPHA: f64 = 0.9;
    /// Interface repulsion of `MPS-HS-GC-DS-IR` (Pa) unless the case sets its own: about
    /// `rho U^2` of the flow along the interface (docs/decisions.md, "Interface repulsion
    /// against two-phase mixing": the settling tank takes 100, the surfacing tank 20).
    pub const INTERFACE_REPULSION: f64 = 50.0;
}

impl Preset {
    /// The preset called `name`.
    pub fn named(name: &str) -> Option<&'static Preset> {
        PRESETS.iter().find(|p| p.name == name)
    }

    /// The scheme of this preset with every shared part at its default.
    pub fn scheme(&self) -> Scheme {
        let hs = self.source == SourceModel::Hs;
        Scheme {
            name: self.name.to_string(),
            gradient: PressureGradient {
                model: self.gradient,
                correction: self.gradient_correction,
                gc_min_determinant: defaults::GC_MIN_DETERMINANT,
                gc_fallback: self.gc_fallback,
                density: GradientDensity::Pair,
                average: DensityAverage::Arithmetic,
            },
            source: PpeSource {
                model: self.source,
                hs_normalization: self.hs_normalization,
                pnd_relaxation: defaults::PND_RELAXATION,
                drift: if hs { self.drift } else { DriftControl::None },
                gamma: defaults::GAMMA,
            },
            clamp_negative_pressure: self.clamp_negative_pressure,
            // The DS presets: the distribution test (beyond the paper, which does not state
            // its surface treatment): docs/decisions.md, "The rotating disc is unstable". The
            // others keep the number density and p = 0 at the particles (MPS-HS-GC's still
            // tank breaks with the mean surface: "Surface pressure at the mean surface").
            surface: if self.ds {
                SurfaceDetector::Distribution(Distribution::default())
            } else {
                SurfaceDetector::NumberDensity(NumberDensity::default())
            },
            surface_pressure: self.surface_pressure,
            // Both on for the HS presets, off for plain MPS: docs/decisions.md, "Wall surface
            // test" and "Air ghosts" (departures from the paper).
            wall_surface_test: hs,
            air_ghosts: hs,
            density_average: DensityAverage::Arithmetic,
            density_smoothing: false,
            wall_pressure: WallPressure::Extrapolated,
            compressibility: 0.0,
            sound_speed: None,
            collision: self.collision.then_some(Collision {
                alpha: defaults::COLLISION_ALPHA,
                restitution: defaults::COLLISION_RESTITUTION,
            }),
            ds: self.ds.then_some(DynamicStabilization {
                alpha: defaults::DS_ALPHA,
                weighting: self.ds_weighting,
                walls: true,
                velocity: self.ds_velocity,
            }),
            shifting: None,
            interface_repulsion: (self.interface_repulsion > 0.0).then_some(InterfaceRepulsion {
                pressure: self.interface_repulsion,
            }),
        }
    }
}

impl Scheme {
    /// The preset called `name` with its defaults, if there is one.
    pub fn preset(name: &str) -> Option<Scheme> {
        Preset::named(name).map(Preset::scheme)
    }

    /// Pair density `rho_ij` (kg/m^3) by the chosen average.
    #[inline]
    pub fn pair_density(&self, a: f64, b: f64) -> f64 {
        self.density_average.of(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_follow_the_design_table() {
        let m = Scheme::preset("MPS").unwrap();
        assert_eq!(
            (
                m.gradient.model,
                m.source.model,
                m.gradient.correction,
                m.ds.is_some()
            ),
            (GradientModel::Original, SourceModel::Pnd, false, false)
        );
        assert!(m.collision.is_some() && m.clamp_negative_pressure);
        let c = Scheme::preset("CMPS-HS").unwrap();
        assert_eq!(
            (c.gradient.model, c.source.model),
            (GradientModel::Cmps, SourceModel::Hs)
        );
        let g = Scheme::preset("MPS-HS-GC").unwrap();
        assert!(g.gradient.correction && g.ds.is_none());
        assert_eq!(g.gradient.model, GradientModel::Taylor);
        let d = Scheme::preset("MPS-HS-GC-DS").unwrap();
        assert!(d.gradient.correction && d.ds.is_some() && d.collision.is_none());
        assert_eq!(d.source.drift, DriftControl::Gamma);
        assert_eq!(d.ds.unwrap().alpha, 0.9);
        assert!(PRESETS[..4]
            .iter()
            .all(|p| p.scheme().interface_repulsion.is_none()));
        let ir = Scheme::preset("MPS-HS-GC-DS-IR").unwrap();
        assert_eq!(d.surface_pressure, SurfacePressure::EdgeSurface);
        assert_eq!(d.ds.unwrap().weighting, DsWeighting::SurfaceFull);
        // The repulsion preset keeps the surface treatment its figures were measured with.
        let plain = Scheme {
            name: d.name.clone(),
            interface_repulsion: None,
            surface_pressure: SurfacePressure::EdgeSurface,
            ds: d.ds,
            gradient: d.gradient,
            ..ir.clone()
        };
        assert_eq!(
            plain, d,
            "the DS preset, the repulsion and its surface treatment"
        );
        assert_eq!(ir.surface_pressure, SurfacePressure::MeanSurface);
        assert_eq!(ir.ds.unwrap().weighting, DsWeighting::Kernel);
        assert_eq!(d.gradient.gc_fallback, GcFallback::Floored);
        assert_eq!(ir.gradient.gc_fallback, GcFallback::Identity);
        assert!(PRESETS[..3]
            .iter()
            .all(|p| p.scheme().gradient.gc_fallback == GcFallback::Identity));
        assert!(ir.interface_repulsion.unwrap().pressure > 0.0);
        // The strained-body preset: the DS preset but for DS's velocities, the HS source and
        // the drift control; the others keep the paper's.
        let st = Scheme::preset("MPS-HS-GC-DS-S").unwrap();
        assert_eq!(st.ds.unwrap().velocity, DsVelocity::Inelastic);
        assert_eq!(st.source.hs_normalization, HsNormalization::Smooth);
        assert_eq!(st.source.drift, DriftControl::SmoothGamma);
        let mut back = st.clone();
        back.name = d.name.clone();
        back.ds = d.ds;
        back.source = d.source;
        assert_eq!(back, d);
        assert!(PRESETS[..5].iter().map(|p| p.scheme()).all(|s| s
            .ds
            .is_none_or(|d| d.velocity == DsVelocity::Restoring)
            && s.source.hs_normalization == HsNormalization::Consistent
            && s.source.drift != DriftControl::SmoothGamma));
        assert!(Scheme::preset("SPH").is_none());
    }
}
