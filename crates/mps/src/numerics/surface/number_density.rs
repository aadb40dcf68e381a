//! Number-density test (Koshizuka & Oka 1996): a particle is on the free surface when
//! `n*_i < beta n0`, optionally also when it has fewer than `count_ratio` times the lattice
//! number of neighbours within re_grad (a neighbour-count criterion as in PolyMPS).

use super::{check_open, parse_params, Detector, ParamError, SurfaceInput};
use crate::numerics::pairs::pairs;
use serde::Deserialize;

/// The number-density test.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NumberDensity {
    /// Threshold `beta` in `n* < beta n0` (dimensionless, default 0.97).
    #[serde(default = "super::default_beta")]
    pub beta: f64,
    /// Neighbour-count criterion: surface when the count within re_grad is below this
    /// fraction of the lattice count (dimensionless; off by default).
    #[serde(default)]
    pub count_ratio: Option<f64>,
}

impl Default for NumberDensity {
    fn default() -> Self {
        NumberDensity {
            beta: super::default_beta(),
            count_ratio: None,
        }
    }
}

impl Detector for NumberDensity {
    const NAME: &'static str = "number-density";

    fn from_params(params: &toml::Table) -> Result<Self, ParamError> {
        let d: NumberDensity = parse_params(params)?;
        check_open("beta", d.beta, 0.0, 1.0)?;
        if let Some(r) = d.count_ratio {
            check_open("count_ratio", r, 0.0, 1.0)?;
        }
        Ok(d)
    }

    fn is_surface<const D: usize>(&self, i: usize, s: &SurfaceInput<D>) -> bool {
        let k = &s.kernels.grad;
        if s.number_density[i] < self.beta * k.n0 {
            return true;
        }
        match self.count_ratio {
            Some(r) => {
                let count = pairs(s.pos, s.neighbors, i, k.re).count();
                (count as f64) < r * k.neighbours as f64
            }
            None => false,
        }
    }
}
