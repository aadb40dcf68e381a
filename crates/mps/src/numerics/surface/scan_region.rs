//! Scan-region ("umbrella") test after Marrone, Colagrossi, Le Touzé & Graziani (2010), "Fast
//! free-surface detection and level-set function definition in SPH solvers", JCP 229,
//! s.2.2. A particle with `n*_i < beta n0` is on the free surface only if a region on its
//! open side holds no particle (fluid or wall):
//!
//! - the normal `n_i` points away from the kernel-weighted centroid of its neighbours
//!   (`-sum_j w_ij r_ij`, normalised); `T = x_i + h n_i`;
//! - the region is the disc `|x_j - T| < h` for neighbours with `|r_ij| >= sqrt(2) h`, and the
//!   square `|n_perp . r_ij| + |n_i . (x_j - T)| < h` (a diamond about `T`) for closer ones.
//!
//! A particle in a balanced neighbourhood has no open side and is never flagged; one under a
//! wall or a closed lid has the wall particles in its region. Unlike the number-density and
//! distribution tests, a gap must be at least about `h` wide to count as a surface. `h` is
//! in units of l0; the paper's tests use `h / dx = 4/3`, the default here.

use super::{check_open, parse_params, weighted_offset, Detector, ParamError, SurfaceInput};
use crate::numerics::pairs::pairs;
use crate::particles::Vector;
use serde::Deserialize;

/// The scan-region test.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanRegion {
    /// Number-density threshold `beta` of the candidates (dimensionless, default 0.97).
    #[serde(default = "super::default_beta")]
    pub beta: f64,
    /// Size `h` of the scan region (units of l0, default 4/3); the region reaches `2h`
    /// from the particle (within the Laplacian radius, where the neighbour list ends).
    #[serde(default = "default_h")]
    pub h: f64,
    /// Below `certain n0` a particle is on the surface without the scan (its neighbourhood
    /// is cut too deeply for a Laplacian; Marrone's `lambda <= 0.2` rule), default 0.8.
    #[serde(default = "default_certain")]
    pub certain: f64,
}

fn default_certain() -> f64 {
    0.8
}

fn default_h() -> f64 {
    4.0 / 3.0
}

impl Detector for ScanRegion {
    const NAME: &'static str = "scan_region";

    fn from_params(params: &toml::Table) -> Result<Self, ParamError> {
        let d: ScanRegion = parse_params(params)?;
        check_open("beta", d.beta, 0.0, 1.0)?;
        check_open("h", d.h, 0.5, 1.55)?;
        check_open("certain", d.certain, 0.0, 1.0)?;
        Ok(d)
    }

    fn is_surface<const D: usize>(&self, i: usize, s: &SurfaceInput<D>) -> bool {
        let k = &s.kernels.grad;
        let nd = s.number_density[i];
        if nd >= self.beta * k.n0 {
            return false;
        }
        if nd < self.certain * k.n0 {
            return true;
        }
        let (centroid, sw) = weighted_offset(i, s);
        let l0 = s.kernels.l0;
        let offset = centroid.norm();
        if sw == 0.0 {
            return true;
        }
        if offset <= 1e-9 * l0 * sw {
            return false;
        }
        let n = centroid * (-1.0 / offset);
        let h = self.h * l0;
        let reach = (2.0 * h).min(s.kernels.lap.re.max(k.re));
        !pairs(s.pos, s.neighbors, i, reach).any(|q| in_region(q.xij, n, h))
    }
}

/// True when `x` (relative to the particle) lies in the scan region of normal `n` and size
/// `h` (m): the disc of radius `h` about `T = h n` beyond `sqrt(2) h`, the square about `T`
/// with diagonals along `n` nearer.
fn in_region<const D: usize>(x: Vector<D>, n: Vector<D>, h: f64) -> bool {
    let d = x - n * h;
    if x.norm() >= std::f64::consts::SQRT_2 * h {
        return d.norm() < h;
    }
    let along = d.dot(&n);
    let across = (d - n * along).norm();
    across + along.abs() < h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::surface::flags_of;

    fn flags(pos: &[Vector<2>], l0: f64) -> Vec<bool> {
        let d = ScanRegion {
            beta: 0.97,
            h: 4.0 / 3.0,
            certain: 0.8,
        };
        flags_of(&d, pos, l0)
    }

    fn lattice(n: usize, a: f64, keep: impl Fn(f64, f64) -> bool) -> Vec<Vector<2>> {
        let mut p = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let (x, y) = (x as f64 * a, y as f64 * a);
                if keep(x, y) {
                    p.push(Vector([x, y]));
                }
            }
        }
        p
    }

    #[test]
    fn the_region_is_a_disc_far_and_a_diamond_near() {
        let n = Vector([0.0, 1.0]);
        assert!(in_region(Vector([0.0, 1.0]), n, 1.0)); // at T
        assert!(in_region(Vector([0.0, 1.9]), n, 1.0)); // far, inside the disc
        assert!(!in_region(Vector([1.0, 0.0]), n, 1.0)); // beside, on the surface
        assert!(!in_region(Vector([0.0, -1.0]), n, 1.0)); // behind
        assert!(in_region(Vector([0.3, 0.5]), n, 1.0)); // near, inside the diamond
        assert!(!in_region(Vector([0.7, 0.2]), n, 1.0)); // near, outside it
    }

    /// A block at rest: the outermost rows and nothing inside.
    #[test]
    fn a_block_is_flagged_on_its_edges_only() {
        let l0 = 0.01;
        let pos = lattice(15, l0, |_, _| true);
        let f = flags(&pos, l0);
        for (i, x) in pos.iter().enumerate() {
            let edge = (0..2).any(|k| x[k] < 0.5 * l0 || x[k] > 13.5 * l0);
            assert_eq!(f[i], edge, "at {x:?}");
        }
    }

    /// A block stretched by 3 % (tension): the number density falls below beta n0
    /// everywhere, yet only the edges are flagged.
    #[test]
    fn a_stretched_block_is_not_flagged_inside() {
        let l0 = 0.01;
        let pos = lattice(15, 1.03 * l0, |_, _| true);
        let f = flags(&pos, l0);
        for (i, x) in pos.iter().enumerate() {
            let inside = (0..2).all(|k| x[k] > 1.5 * l0 && x[k] < 13.0 * l0);
            if inside {
                assert!(!f[i], "interior particle at {x:?}");
            }
        }
    }

    /// A block with one particle missing (a vacancy, as disorder makes them): its
    /// neighbours lose number density, but the gap is narrower than the region, so nothing
    /// is flagged there. A hole of radius 2.5 l0 is a true inner surface: its rim is flagged.
    #[test]
    fn a_vacancy_is_not_a_surface_and_a_hole_is() {
        let l0 = 0.01;
        let c = 10.0 * l0;
        let vacancy = lattice(21, l0, |x, y| (x - c).abs() + (y - c).abs() > 0.1 * l0);
        let f = flags(&vacancy, l0);
        let near = |x: &Vector<2>, r: f64| ((x[0] - c).powi(2) + (x[1] - c).powi(2)).sqrt() < r;
        assert!(vacancy.iter().zip(&f).all(|(x, &s)| !(s && near(x, 5.0 * l0))));
        let r = 2.5 * l0;
        let hole = lattice(21, l0, |x, y| ((x - c).powi(2) + (y - c).powi(2)).sqrt() > r);
        let f = flags(&hole, l0);
        let rim = hole.iter().filter(|x| near(x, r + l0)).count();
        let flagged = hole.iter().zip(&f).filter(|(x, &s)| s && near(x, r + l0)).count();
        assert_eq!(flagged, rim, "every rim particle of the hole");
        assert!(hole.iter().zip(&f).all(|(x, &s)| !(s && near(x, 6.0 * l0) && !near(x, r + l0))));
    }
}
