//! Free-surface detection: which particles are on the free surface (Dirichlet `p = 0` in the
//! PPE). Detectors are models as data: each is one file here implementing [`Detector`], and
//! one line in the [`surface_detectors!`] registration below makes it selectable in case files
//! (`[scheme.surface] detector = "<name>"`, its parameters beside it).

use super::kernel::Kernels;
use crate::parallel;
use crate::particles::{Kind, NeighborList, Vector};
use std::fmt;

/// What a detector sees: positions, neighbours, number densities and kernels.
#[derive(Clone, Copy)]
pub struct SurfaceInput<'a, const D: usize> {
    /// Positions (m).
    pub pos: &'a [Vector<D>],
    /// Neighbour lists.
    pub neighbors: &'a NeighborList,
    /// Number density at re_grad (dimensionless).
    pub number_density: &'a [f64],
    /// Kernel constants and spacing.
    pub kernels: &'a Kernels,
}

/// The number-density threshold `beta` of `n* < beta n0` every detector starts from
/// (Koshizuka & Oka 1996), dimensionless.
pub fn default_beta() -> f64 {
    0.97
}

/// The kernel-weighted sum of the neighbours' offsets `sum_j w_ij r_ij` (m) within
/// re_grad, and `sum_j w_ij`: a one-sided neighbourhood has a large offset.
pub fn weighted_offset<const D: usize>(i: usize, s: &SurfaceInput<D>) -> (Vector<D>, f64) {
    let (mut sw, mut offset) = (0.0, Vector::<D>::zero());
    for q in super::pairs::pairs(s.pos, s.neighbors, i, s.kernels.grad.re) {
        sw += q.w;
        offset += q.xij * q.w;
    }
    (offset, sw)
}

/// A free-surface detector.
pub trait Detector: Sized + Clone + PartialEq + fmt::Debug {
    /// Its name in case files.
    const NAME: &'static str;
    /// Builds it from the parameters of `[scheme.surface]` (without `detector`); the error
    /// names the parameter.
    fn from_params(params: &toml::Table) -> Result<Self, ParamError>;
    /// True when particle `i` is on the free surface.
    fn is_surface<const D: usize>(&self, i: usize, s: &SurfaceInput<D>) -> bool;
}

/// A bad detector parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamError {
    /// The parameter's name.
    pub param: String,
    /// Its value as written.
    pub value: String,
    /// What is wrong.
    pub message: String,
}

/// `value` of parameter `param` must lie in the open interval `(lo, hi)`.
pub fn check_open(param: &str, value: f64, lo: f64, hi: f64) -> Result<(), ParamError> {
    if value > lo && value < hi {
        return Ok(());
    }
    Err(ParamError {
        param: param.into(),
        value: value.to_string(),
        message: format!("must lie in ({lo}, {hi})"),
    })
}

/// Reads a detector's parameter struct from its table (unknown keys are errors).
pub fn parse_params<P: serde::de::DeserializeOwned>(params: &toml::Table) -> Result<P, ParamError> {
    P::deserialize(toml::Value::Table(params.clone())).map_err(|e| {
        let msg = e.message().trim().replace('\n', " ");
        let param = msg
            .split('`')
            .nth(1)
            .map(str::to_string)
            .unwrap_or_default();
        ParamError {
            param,
            value: String::new(),
            message: msg,
        }
    })
}

/// Registers detectors: `module::Type` per line, one file each.
macro_rules! surface_detectors {
    ($($module:ident :: $ty:ident),* $(,)?) => {
        $(pub mod $module;)*

        /// A configured free-surface detector, one of the registered ones.
        #[derive(Clone, Debug, PartialEq)]
        pub enum SurfaceDetector {
            $(
                #[doc = concat!("See [`", stringify!($module), "`].")]
                $ty($module::$ty),
            )*
        }

        impl SurfaceDetector {
            /// Names of the registered detectors.
            pub const NAMES: &'static [&'static str] = &[$(<$module::$ty as Detector>::NAME),*];

            /// The detector called `name` with its parameters; `None` for an unknown name.
            pub fn from_params(name: &str, params: &toml::Table) -> Option<Result<Self, ParamError>> {
                $(
                    if name == <$module::$ty as Detector>::NAME {
                        return Some($module::$ty::from_params(params).map(SurfaceDetector::$ty));
                    }
                )*
                None
            }

            /// Its name in case files.
            pub fn name(&self) -> &'static str {
                match self {
                    $(SurfaceDetector::$ty(_) => <$module::$ty as Detector>::NAME,)*
                }
            }

            /// True when particle `i` is on the free surface.
            #[inline]
            pub fn is_surface<const D: usize>(&self, i: usize, s: &SurfaceInput<D>) -> bool {
                match self {
                    $(SurfaceDetector::$ty(d) => d.is_surface(i, s),)*
                }
            }
        }
    };
}

surface_detectors! {
    number_density::NumberDensity,
    distribution::Distribution,
    scan_region::ScanRegion,
}

/// Free-surface flags of every particle, into `out`: fluid particles, and wall particles
/// when `test_walls` (walls open to the air), take the detector's test; dummies never do.
pub fn detect<const D: usize>(
    detector: &SurfaceDetector,
    s: &SurfaceInput<D>,
    kind: &[Kind],
    test_walls: bool,
    out: &mut Vec<bool>,
) {
    parallel::map_into(out, s.pos.len(), |i| {
        let tested = match kind[i] {
            Kind::Fluid => true,
            Kind::Wall => test_walls,
            Kind::Dummy => false,
        };
        tested && detector.is_surface(i, s)
    })
}

/// The flags `detector` gives the points `pos` (2D, spacing `l0` m, re_grad 2.1, re_lap 3.1):
/// the unit tests' harness.
#[cfg(test)]
pub(crate) fn flags_of<T: Detector>(detector: &T, pos: &[Vector<2>], l0: f64) -> Vec<bool> {
    let k = Kernels::new::<2>(l0, 2.1, 3.1);
    let nl = crate::particles::neighbors::build_neighbor_list(pos, k.lap.re);
    let nd: Vec<f64> = (0..pos.len())
        .map(|i| super::operators::number_density(i, pos, &nl, k.grad.re))
        .collect();
    let s = SurfaceInput {
        pos,
        neighbors: &nl,
        number_density: &nd,
        kernels: &k,
    };
    (0..pos.len()).map(|i| detector.is_surface(i, &s)).collect()
}
