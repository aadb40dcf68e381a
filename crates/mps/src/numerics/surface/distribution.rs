//! Number-density test refined by the particle distribution (after Khayyer, Gotoh & Shao
//! 2009): a particle with `n*_i < beta n0` is on the free surface only if its neighbourhood is
//! one-sided, i.e. the kernel-weighted centroid of its neighbours within re_grad lies more than
//! `threshold l0` from it:
//!
//! `|sum_j w_ij r_ij| / sum_j w_ij > threshold l0`.
//!
//! Inside a fluid under tension the number density falls below `beta n0` with the
//! neighbourhood still balanced around the particle (centroid deviation near zero), so the
//! number-density test alone flags interior particles there; this one does not.

use super::{check_open, parse_params, weighted_offset, Detector, ParamError, SurfaceInput};
use serde::Deserialize;

/// The distribution test.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Distribution {
    /// Number-density threshold `beta` (dimensionless, default 0.97).
    #[serde(default = "super::default_beta")]
    pub beta: f64,
    /// Centroid deviation beyond which the neighbourhood counts as one-sided (units of l0,
    /// default 0.2).
    #[serde(default = "default_threshold")]
    pub threshold: f64,
}

fn default_threshold() -> f64 {
    0.2
}

impl Default for Distribution {
    fn default() -> Self {
        Distribution {
            beta: super::default_beta(),
            threshold: default_threshold(),
        }
    }
}

impl Detector for Distribution {
    const NAME: &'static str = "distribution";

    fn from_params(params: &toml::Table) -> Result<Self, ParamError> {
        let d: Distribution = parse_params(params)?;
        check_open("beta", d.beta, 0.0, 1.0)?;
        check_open("threshold", d.threshold, 0.0, 2.0)?;
        Ok(d)
    }

    fn is_surface<const D: usize>(&self, i: usize, s: &SurfaceInput<D>) -> bool {
        let k = &s.kernels.grad;
        if s.number_density[i] >= self.beta * k.n0 {
            return false;
        }
        let (centroid, sw) = weighted_offset(i, s);
        sw == 0.0 || centroid.norm() > self.threshold * s.kernels.l0 * sw
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::surface::flags_of;
    use crate::particles::Vector;
    use crate::numerics::surface::number_density::NumberDensity;

    /// A lattice of `n x n` points at spacing `a` (m).
    fn lattice(n: usize, a: f64) -> Vec<Vector<2>> {
        let mut p = Vec::new();
        for y in 0..n {
            for x in 0..n {
                p.push(Vector([x as f64 * a, y as f64 * a]));
            }
        }
        p
    }

    fn flags(pos: &[Vector<2>], l0: f64) -> (Vec<bool>, Vec<bool>) {
        let dist = Distribution {
            beta: 0.97,
            threshold: 0.2,
        };
        let nd = NumberDensity::default();
        (flags_of(&dist, pos, l0), flags_of(&nd, pos, l0))
    }

    /// On a block at rest both tests flag exactly the outermost rows and nothing inside.
    #[test]
    fn a_block_at_rest_is_flagged_on_its_edges_only() {
        let l0 = 0.01;
        let pos = lattice(15, l0);
        let (dist, nd) = flags(&pos, l0);
        for (i, x) in pos.iter().enumerate() {
            let edge = (0..2).any(|k| x[k] < 0.5 * l0 || x[k] > 13.5 * l0);
            assert_eq!(dist[i], edge, "distribution at {x:?}");
            assert_eq!(nd[i], edge, "number density at {x:?}");
        }
    }

    /// A block stretched uniformly by 3 % (a fluid under tension): every interior particle's
    /// number density falls below 0.97 n0, so the number-density test flags the whole block;
    /// the distribution test still flags only the edges.
    #[test]
    fn a_stretched_block_is_not_flagged_inside() {
        let l0 = 0.01;
        let pos = lattice(15, 1.03 * l0);
        let (dist, nd) = flags(&pos, l0);
        let centre = 7 * 15 + 7;
        assert!(nd[centre], "the number-density test misfires inside (the defect)");
        assert!(!dist[centre]);
        let inside = (0..pos.len())
            .filter(|&i| (0..2).all(|k| pos[i][k] > 2.5 * l0 && pos[i][k] < 11.5 * l0))
            .filter(|&i| dist[i])
            .count();
        assert_eq!(inside, 0);
        assert!(dist[7], "bottom edge particle");
    }
}
