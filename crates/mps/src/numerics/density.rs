//! Densities of pairs and of interfaces in multiphase flow (equations.md section 7).

use super::kernel::Kernels;
use crate::parallel;
use crate::particles::{Kind, View};
use serde::{Deserialize, Serialize};

/// How the pair density `rho_ij` is formed from two particle densities.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DensityAverage {
    /// `(rho_i + rho_j) / 2` (harmonic mean of `1/rho`).
    Arithmetic,
    /// `2 rho_i rho_j / (rho_i + rho_j)`.
    Harmonic,
}

impl DensityAverage {
    /// Pair density `rho_ij` (kg/m^3) of densities `a`, `b` (kg/m^3).
    #[inline]
    pub fn of(self, a: f64, b: f64) -> f64 {
        match self {
            DensityAverage::Arithmetic => 0.5 * (a + b),
            DensityAverage::Harmonic => 2.0 * a * b / (a + b),
        }
    }
}

/// Smoothed densities (kg/m^3) for the PPE coefficient and the gradient near interfaces:
/// `rho~_i = (n0 rho_i + sum_j w_ij rho_j) / (n0 + sum_j w_ij)` over re_grad, dummies left out.
pub fn smoothed_density<const D: usize>(v: &View<D>, k: &Kernels) -> Vec<f64> {
    let n0 = k.grad.n0;
    parallel::map(v.pos.len(), |i| {
        let (mut sw, mut swr) = (n0, n0 * v.density[i]);
        for q in v.pairs(i, k.grad.re) {
            if v.kind[q.j] != Kind::Dummy {
                sw += q.w;
                swr += q.w * v.density[q.j];
            }
        }
        swr / sw
    })
}
