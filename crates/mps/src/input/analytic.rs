//! Analytic fields used as initial conditions and validation references.

use std::f64::consts::PI;

/// Exact pressure (Pa) of a rotating square patch (cases.md): the solution of
/// `lap p = 2 rho omega^2` on a square of side `side` (m) with `p = 0` on its edges, at
/// `(xp, yp)` measured from a corner (m); `terms` odd modes per direction.
///
/// `p0 = - sum_{m,n odd} 32 rho omega^2 / (m n pi^2 ((m pi/L)^2 + (n pi/L)^2))
///        sin(m pi x'/L) sin(n pi y'/L)`.
pub fn square_patch_pressure(
    xp: f64,
    yp: f64,
    side: f64,
    rho: f64,
    omega: f64,
    terms: usize,
) -> f64 {
    let l = side;
    let sy: Vec<f64> = (0..terms)
        .map(|b| ((2 * b + 1) as f64 * PI * yp / l).sin())
        .collect();
    let mut p = 0.0;
    for a in 0..terms {
        let m = (2 * a + 1) as f64;
        let sx = (m * PI * xp / l).sin();
        for (b, sy) in sy.iter().enumerate() {
            let n = (2 * b + 1) as f64;
            let k2 = (m * PI / l).powi(2) + (n * PI / l).powi(2);
            p -= 32.0 * rho * omega * omega / (m * n * PI * PI * k2) * sx * sy;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values of cases.md, within 0.5 % (the acceptance tolerance).
    #[test]
    fn square_patch_reference_values() {
        let p = |x, y| square_patch_pressure(x, y, 1.0, 1000.0, 1.0, 200);
        for (x, y, want) in [
            (0.5, 0.5, -147.34),
            (0.25, 0.5, -114.67),
            (0.25, 0.25, -90.57),
        ] {
            let got = p(x, y);
            assert!(
                ((got - want) / want).abs() < 0.005,
                "p({x},{y}) = {got}, want {want}"
            );
        }
        assert!(p(0.0, 0.3).abs() < 1e-9);
    }
}
