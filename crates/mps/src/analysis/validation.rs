//! Comparisons of a run against reference data: the dam-break front against Martin & Moyce
//! (1952), and the hydrostatic bottom pressure against `rho g H`.

use serde::{Deserialize, Serialize};

/// Martin & Moyce (1952), column height/width 2, a = 2.25 in: `T = t sqrt(2g/a)`, `Z = z/a`.
pub const MARTIN_MOYCE: &str = include_str!("../../data/martin_moyce_1952_a2.25in.csv");

/// The (T, Z) points of [`MARTIN_MOYCE`].
pub fn martin_moyce() -> Vec<(f64, f64)> {
    MARTIN_MOYCE
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('T'))
        .filter_map(|l| {
            let mut it = l.split(',');
            Some((
                it.next()?.trim().parse().ok()?,
                it.next()?.trim().parse().ok()?,
            ))
        })
        .collect()
}

/// One validation figure of a run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ValidationResult {
    /// What was compared.
    pub name: String,
    /// The simulated value.
    pub value: f64,
    /// The reference value (0 where the figure is an error norm).
    pub reference: f64,
    /// Relative error, or the error norm itself.
    pub error: f64,
    /// A sentence on how it was measured.
    pub note: String,
    /// Largest accepted |error| (the acceptance tolerance of the check).
    pub tolerance: f64,
    /// Whether |error| is within the tolerance.
    pub passed: bool,
}

impl ValidationResult {
    /// A result whose pass/fail follows from `|error| <= tolerance`.
    pub fn new(
        name: &str,
        value: f64,
        reference: f64,
        error: f64,
        tolerance: f64,
        note: String,
    ) -> Self {
        ValidationResult {
            name: name.into(),
            value,
            reference,
            error,
            note,
            tolerance,
            passed: error.abs() <= tolerance,
        }
    }

    /// The same result judged against another `tolerance`.
    pub fn with_tolerance(self, tolerance: f64) -> Self {
        ValidationResult {
            passed: self.error.abs() <= tolerance,
            tolerance,
            ..self
        }
    }
}

/// Linear interpolation in a time series sorted by time; `None` outside it.
pub fn interpolate(series: &[(f64, f64)], t: f64) -> Option<f64> {
    if series.is_empty() || t < series[0].0 || t > series[series.len() - 1].0 {
        return None;
    }
    let k = series.partition_point(|s| s.0 < t);
    if k == 0 {
        return Some(series[0].1);
    }
    let (a, b) = (series[k - 1], series[k]);
    if b.0 == a.0 {
        return Some(b.1);
    }
    Some(a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0))
}

/// Dam-break comparison rows `(T, Z_exp, Z_sim)` at every experimental point the run
/// covered, and the RMS of `Z_sim - Z_exp`. `front` holds `(t, x_front - wall_x)` (s, m).
pub fn dam_break_front(
    front: &[(f64, f64)],
    column_width: f64,
    g: f64,
) -> (Vec<(f64, f64, f64)>, f64) {
    let scale = (2.0 * g / column_width).sqrt();
    let nd: Vec<(f64, f64)> = front
        .iter()
        .map(|&(t, x)| (t * scale, x / column_width))
        .collect();
    let rows: Vec<(f64, f64, f64)> = martin_moyce()
        .into_iter()
        .filter_map(|(tt, z)| interpolate(&nd, tt).map(|s| (tt, z, s)))
        .collect();
    let rms = if rows.is_empty() {
        f64::NAN
    } else {
        (rows.iter().map(|r| (r.2 - r.1).powi(2)).sum::<f64>() / rows.len() as f64).sqrt()
    };
    (rows, rms)
}

/// A simulated series against a reference curve: the rows `(t, reference, simulated)` at
/// every reference time the run covers (simulation interpolated linearly), and the RMS and
/// largest absolute difference (NaN when the run covers none of them).
pub fn against_curve(
    simulated: &[(f64, f64)],
    reference: &[(f64, f64)],
) -> (Vec<(f64, f64, f64)>, f64, f64) {
    let rows: Vec<(f64, f64, f64)> = reference
        .iter()
        .filter_map(|&(t, r)| interpolate(simulated, t).map(|s| (t, r, s)))
        .collect();
    if rows.is_empty() {
        return (rows, f64::NAN, f64::NAN);
    }
    let sq = rows.iter().map(|r| (r.2 - r.1).powi(2)).sum::<f64>();
    let rms = (sq / rows.len() as f64).sqrt();
    let peak = rows.iter().map(|r| (r.2 - r.1).abs()).fold(0.0, f64::max);
    (rows, rms, peak)
}

/// The two figures of a comparison against a reference curve, `what` naming the series
/// (`probe p1`, `front`): RMS and largest difference, each against its tolerance.
pub fn curve_results(
    what: &str,
    rows: &[(f64, f64, f64)],
    rms: f64,
    peak: f64,
    tolerances: (f64, f64),
    file: &str,
) -> Vec<ValidationResult> {
    let span = match (rows.first(), rows.last()) {
        (Some(a), Some(b)) => format!(
            "{} reference points from {} s to {} s",
            rows.len(),
            a.0,
            b.0
        ),
        _ => "no reference point inside the run's time span".to_string(),
    };
    let key = what.replace(' ', "_");
    vec![
        ValidationResult::new(
            &format!("{key}_rms_difference"),
            rms,
            0.0,
            rms,
            tolerances.0,
            format!("RMS of {what} minus `{file}` over {span}"),
        ),
        ValidationResult::new(
            &format!("{key}_peak_difference"),
            peak,
            0.0,
            peak,
            tolerances.1,
            format!("largest |{what} minus `{file}`| over {span}"),
        ),
    ]
}

/// Mean of a time series over `[t_end - window, t_end]`.
pub fn window_mean(series: &[(f64, f64)], window: f64) -> Option<f64> {
    let t_end = series.last()?.0;
    let sel: Vec<f64> = series
        .iter()
        .filter(|s| s.0 >= t_end - window)
        .map(|s| s.1)
        .collect();
    (!sel.is_empty()).then(|| sel.iter().sum::<f64>() / sel.len() as f64)
}

/// Hydrostatic check: the mean of a probe over the last `window` s against the reference
/// `exact` (Pa), within 5 %.
pub fn hydrostatic(
    probe: &str,
    series: &[(f64, f64)],
    window: f64,
    exact: f64,
    given: bool,
) -> Option<ValidationResult> {
    let mean = window_mean(series, window)?;
    Some(ValidationResult::new(
        "hydrostatic_bottom_pressure",
        mean,
        exact,
        (mean - exact) / exact,
        0.05,
        format!(
            "mean of probe `{probe}` over the last {window} s against {}",
            if given {
                "the given reference"
            } else {
                "rho g H"
            }
        ),
    ))
}

/// Laplace check: a measured pressure jump `jump` (Pa) across a drop of radius `radius`
/// (m) against `sigma (dimension - 1) / radius` (`sigma` in N/m), within `tolerance`.
pub fn laplace_jump(
    jump: f64,
    sigma: f64,
    radius: f64,
    dimension: usize,
    tolerance: f64,
) -> ValidationResult {
    let exact = sigma * (dimension as f64 - 1.0) / radius;
    ValidationResult::new(
        "laplace_pressure_jump",
        jump,
        exact,
        (jump - exact) / exact,
        tolerance,
        format!(
            "mean pressure inside minus outside against sigma (d - 1) / R = {sigma} * {} / {radius}",
            dimension - 1
        ),
    )
}

/// Dam-break check: RMS of `Z_sim - Z_exp` against Martin & Moyce at most 0.3, and the rows
/// of the comparison.
pub fn dam_break(
    front: &[(f64, f64)],
    column_width: f64,
    g: f64,
    l0: f64,
) -> (ValidationResult, Vec<(f64, f64, f64)>) {
    let (rows, rms) = dam_break_front(front, column_width, g);
    let result = ValidationResult::new(
        "dam_break_front_rms_Z",
        rms,
        0.0,
        rms,
        0.3,
        format!(
            "RMS of Z_sim - Z_exp over {} Martin & Moyce points, l0 = {l0} m (L/l0 = {:.1})",
            rows.len(),
            column_width / l0
        ),
    );
    (result, rows)
}

/// Early acceleration of groups released from rest: the mean over groups of
/// `|2 dy / t^2|` of their centroids at the first recorded time `te >= early_time` (s),
/// against the mean of `g |rho_g - rho_w| / (rho_g + c_m rho_w)` (a body in unbounded
/// ideal fluid with added-mass coefficient `c_m`: 1 for a circle in 2D, 1/2 for a sphere in
/// `dimension` 3), within 30 %. `series` holds `(t, centroid (x, vertical) per group)`,
/// `densities` each group's density (kg/m^3).
pub fn early_acceleration(
    series: &[(f64, Vec<(f64, f64)>)],
    early_time: f64,
    densities: &[f64],
    (rho_w, g): (f64, f64),
    dimension: usize,
) -> Option<ValidationResult> {
    let (c_m, formula) = if dimension == 3 {
        (0.5, "g |rho_g - rho_w| / (rho_g + rho_w / 2) (sphere)")
    } else {
        (1.0, "g |rho_g - rho_w| / (rho_g + rho_w)")
    };
    let start = series.first()?;
    let at = series.iter().find(|s| s.0 >= early_time)?;
    let te = at.0;
    let (mut sum, mut est) = (0.0, 0.0);
    for (k, &rho_g) in densities.iter().enumerate() {
        sum += 2.0 * (at.1[k].1 - start.1[k].1).abs() / (te * te);
        est += g * (rho_g - rho_w).abs() / (rho_g + c_m * rho_w);
    }
    let n = densities.len().max(1) as f64;
    let (meas, estimate) = (sum / n, est / n);
    Some(ValidationResult::new(
        "group_early_acceleration",
        meas,
        estimate,
        (meas - estimate) / estimate,
        0.3,
        format!(
            "mean |2 dy / t^2| of the group centroids over the first {te:.3} s against {formula}"
        ),
    ))
}

/// The same early acceleration against the ideal fluid's first acceleration of the groups in
/// their tank (`analysis::added_mass`: walls, free surface and the other groups included),
/// `exact` each group's vertical first acceleration (m/s^2); `measured` the mean of
/// `|2 dy / t^2|` from [`early_acceleration`].
pub fn early_acceleration_in_tank(measured: &ValidationResult, exact: &[f64]) -> ValidationResult {
    let n = exact.len().max(1) as f64;
    let reference = exact.iter().map(|a| a.abs()).sum::<f64>() / n;
    ValidationResult::new(
        "group_early_acceleration_tank",
        measured.value,
        reference,
        (measured.value - reference) / reference,
        measured.tolerance,
        format!(
            "the same against the ideal fluid's first acceleration in this tank (added-mass \
             matrix by boundary elements; the unbounded estimate is {:.4})",
            measured.reference
        ),
    )
}

/// A rotating disc to check: centre (m), radius (m), angular velocity (rad/s), density
/// (kg/m^3).
pub struct DiscSpec<const D: usize> {
    /// Centre (m).
    pub center: crate::particles::Vector<D>,
    /// Radius (m).
    pub radius: f64,
    /// Angular velocity (rad/s).
    pub omega: f64,
    /// Density (kg/m^3).
    pub rho: f64,
}

/// Rotating-disc checks: the mean centre pressure over `series` (s, Pa) against the exact
/// steady value within 5 %; the radius holding 99 % of the fluid at the end (m) within one
/// spacing of `R`; particles with at most one neighbour below 1 % at the end.
pub fn rotating_disc<const D: usize>(
    sim: &crate::simulation::Simulation<D>,
    disc: &DiscSpec<D>,
    series: &[(f64, f64)],
) -> Vec<ValidationResult> {
    use super::exact::{radius_99, rotating_disc_centre_pressure};
    let l0 = sim.l0();
    let exact = rotating_disc_centre_pressure(disc.rho, disc.omega, disc.radius, l0);
    let mut out = Vec::new();
    if !series.is_empty() {
        let mean = series.iter().map(|s| s.1).sum::<f64>() / series.len() as f64;
        out.push(ValidationResult::new(
            "rotating_disc_centre_pressure",
            mean,
            exact,
            (mean - exact) / exact,
            0.05,
            format!(
                "mean centre pressure over {:.3}-{:.3} s against -rho omega^2 (R - l0/2)^2 / 2",
                series[0].0,
                series[series.len() - 1].0
            ),
        ));
    }
    // The radii of every process's own fluid particles (a distributed run's, gathered).
    let own = &sim.particles;
    let radii: Vec<f64> = (0..sim.owned())
        .filter(|&i| own.kind[i] == crate::particles::Kind::Fluid)
        .map(|i| (own.position[i] - disc.center).norm())
        .collect();
    let r99 = radius_99(sim.gather_over_processes(&radii));
    out.push(ValidationResult::new(
        "rotating_disc_radius",
        r99,
        disc.radius,
        (r99 - disc.radius) / disc.radius,
        l0 / disc.radius,
        "radius holding 99 % of the fluid at the end (m), within one spacing".into(),
    ));
    let counts = super::surface::surface_counts_of(sim);
    let fluid = sim
        .count_over_processes(crate::particles::Kind::Fluid)
        .max(1);
    let iso = counts.isolated as f64 / fluid as f64;
    out.push(ValidationResult::new(
        "rotating_disc_isolated_fraction",
        iso,
        0.0,
        iso,
        0.01,
        "fraction of fluid particles with at most one neighbour within re_grad at the end".into(),
    ));
    out
}

/// Elliptic-drop check: the largest relative error of either semi-axis over the recorded
/// `(t, a, b)` series against the exact solution, within 2 %. The measured axes are scaled
/// by their initial value (the lattice disc's second-moment radius) to the exact `R`.
pub fn elliptic_drop(
    series: &[(f64, f64, f64)],
    radius: f64,
    strain_rate: f64,
) -> Option<ValidationResult> {
    let first = *series.first()?;
    let times: Vec<f64> = series.iter().map(|s| s.0).collect();
    let exact = super::exact::elliptic_drop(radius, strain_rate, &times);
    let (mut worst, mut at) = (0.0f64, 0.0);
    for (s, e) in series.iter().zip(&exact) {
        let a = s.1 / first.1 * radius;
        let b = s.2 / first.2 * radius;
        let err = ((a - e.0) / e.0).abs().max(((b - e.1) / e.1).abs());
        if err > worst {
            (worst, at) = (err, s.0);
        }
    }
    let last = series.last()?;
    Some(ValidationResult::new(
        "elliptic_drop_axes",
        last.1 / first.1 * radius,
        exact.last()?.0,
        worst,
        0.02,
        format!(
            "largest relative error of the semi-axes against the exact solution over {} outputs (at t = {at:.5} s); value and reference: semi-major axis at the end (m)",
            series.len()
        ),
    ))
}

/// Steady-flow check: the relative L2 error `sqrt(err2 / exact2)` of the fluid velocities
/// against an exact steady field, from the sums of `|u_i - u(x_i)|^2` and `|u(x_i)|^2`
/// (m^2/s^2) over the fluid particles, within `tolerance`. Value: the fluid's RMS speed
/// (m/s) from `speed2` (the sum of `|u_i|^2`) over `count` particles; reference: the exact
/// field's there.
pub fn steady_flow(
    [err2, exact2, speed2, count]: [f64; 4],
    tolerance: f64,
) -> Option<ValidationResult> {
    if exact2 <= 0.0 || count < 1.0 {
        return None;
    }
    Some(ValidationResult::new(
        "steady_flow_velocity",
        (speed2 / count).sqrt(),
        (exact2 / count).sqrt(),
        (err2 / exact2).sqrt(),
        tolerance,
        "relative L2 error of the fluid velocities against the exact steady field (the initial one) at their positions at the end; value and reference: RMS speeds (m/s)".into(),
    ))
}

/// Rim-mode check (`analysis::rim_mode`): the largest relative error of the recorded mode
/// amplitude `(t, |eta_n|)` against linear theory, `(U / gamma) sinh(gamma t)`, over the
/// outputs with `0 < t <= until`, within `tolerance`. Value and reference: the amplitude at
/// the last compared output (m).
pub fn surface_mode(
    series: &[(f64, f64)],
    u: f64,
    (omega, tension, mode): (f64, f64, u32),
    until: f64,
    tolerance: f64,
) -> Option<ValidationResult> {
    use super::rim_mode::linear_amplitude;
    let compared: Vec<(f64, f64, f64)> = series
        .iter()
        .filter(|s| s.0 > 0.0 && s.0 <= until)
        .map(|&(t, a)| (t, a, linear_amplitude(u, (omega, tension), mode, t)))
        .collect();
    let &(_, last, last_exact) = compared.last()?;
    let (mut worst, mut at) = (0.0f64, 0.0);
    for &(t, a, e) in &compared {
        let err = if e > 0.0 { (a - e) / e } else { f64::INFINITY };
        if !(err.abs() <= worst.abs()) {
            (worst, at) = (err, t);
        }
    }
    Some(ValidationResult::new(
        "surface_mode_growth",
        last,
        last_exact,
        worst,
        tolerance,
        format!(
            "mode {mode} of the rim's displacement against linear theory (U = {u:.4e} m/s, growth rate squared {:.3} /s^2) over {} outputs to t = {until} s: largest relative error at t = {at:.4} s; value and reference: amplitude at the last output compared (m)",
            (mode as f64 - 1.0) * (omega * omega - tension * f64::from(mode * (mode + 1))),
            compared.len()
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The steady-flow check: the exact field passes with error 0, a field slowed by 10 %
    /// reads 0.1 (and fails a 5 % tolerance), a field with no motion gives no result.
    #[test]
    fn steady_flow_check() {
        let exact: Vec<[f64; 2]> = (0..50)
            .map(|k| [(k as f64).sin(), (k as f64).cos()])
            .collect();
        let sums = |scale: f64| {
            let mut s = [0.0; 4];
            for u in &exact {
                let v = [scale * u[0], scale * u[1]];
                s[0] += (v[0] - u[0]).powi(2) + (v[1] - u[1]).powi(2);
                s[1] += u[0] * u[0] + u[1] * u[1];
                s[2] += v[0] * v[0] + v[1] * v[1];
                s[3] += 1.0;
            }
            s
        };
        let same = steady_flow(sums(1.0), 0.05).unwrap();
        assert!(same.passed && same.error == 0.0);
        assert!((same.value - same.reference).abs() < 1e-15);
        let slow = steady_flow(sums(0.9), 0.05).unwrap();
        assert!((slow.error - 0.1).abs() < 1e-12 && !slow.passed, "{slow:?}");
        assert!((slow.value / slow.reference - 0.9).abs() < 1e-12);
        assert!(steady_flow([0.0; 4], 0.05).is_none());
    }

    /// The rim-mode check passes the theory itself, fails a rim that drifts ballistically
    /// (no pressure force: amplitude `U t`), and fails an empty window.
    #[test]
    fn surface_mode_check() {
        use crate::analysis::rim_mode::linear_amplitude;
        let (u, omega, n) = (0.01, 1.0, 6);
        let exact: Vec<(f64, f64)> = (0..=20)
            .map(|k| {
                let t = k as f64 * 0.05;
                (t, linear_amplitude(u, (omega, 0.0), n, t))
            })
            .collect();
        let r = surface_mode(&exact, u, (omega, 0.0, n), 1.0, 0.15).unwrap();
        assert!(r.passed && r.error.abs() < 1e-12, "{r:?}");
        let ballistic: Vec<(f64, f64)> = exact.iter().map(|&(t, _)| (t, u * t)).collect();
        let r = surface_mode(&ballistic, u, (omega, 0.0, n), 1.0, 0.15).unwrap();
        assert!(!r.passed && r.error < -0.3, "{r:?}");
        assert!(surface_mode(&exact[..1], u, (omega, 0.0, n), 1.0, 0.15).is_none());
        // Against the tension-free theory a mode held back by tension fails.
        let r = surface_mode(&exact, u, (omega, 0.5 / 42.0, n), 1.0, 0.15).unwrap();
        assert!(!r.passed && r.error > 0.3, "{r:?}");
    }

    /// A group falling at exactly the sphere's ideal-fluid acceleration passes in 3D with
    /// no error, and reads (rho_g + rho_w) / (rho_g + rho_w / 2) - 1 = +15.9 % against the
    /// 2D circle.
    #[test]
    fn early_acceleration_uses_the_added_mass_of_the_dimension() {
        let (rho_g, rho_w, g) = (2650.0, 1000.0, 9.81);
        let a = g * (rho_g - rho_w) / (rho_g + 0.5 * rho_w);
        let series: Vec<(f64, Vec<(f64, f64)>)> = (0..=10)
            .map(|k| {
                let t = k as f64 * 0.01;
                (t, vec![(0.1, 0.14 - 0.5 * a * t * t)])
            })
            .collect();
        let r3 = early_acceleration(&series, 0.05, &[rho_g], (rho_w, g), 3).unwrap();
        assert!(r3.error.abs() < 1e-9 && r3.passed, "{r3:?}");
        let r2 = early_acceleration(&series, 0.05, &[rho_g], (rho_w, g), 2).unwrap();
        let want = (rho_g + rho_w) / (rho_g + 0.5 * rho_w) - 1.0;
        assert!((r2.error - want).abs() < 1e-9, "{} vs {want}", r2.error);
    }

    #[test]
    fn reference_data_is_complete() {
        let d = martin_moyce();
        assert_eq!(d.len(), 14);
        assert_eq!(d[0], (0.41, 1.11));
    }

    #[test]
    fn a_curve_comparison_measures_rms_and_peak() {
        // Simulation sin(t) sampled finely; reference sin(t) + 0.1 at its own times, one
        // point outside the run.
        let sim: Vec<(f64, f64)> = (0..=1000)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (t, t.sin())
            })
            .collect();
        let mut reference: Vec<(f64, f64)> = (0..10)
            .map(|k| (k as f64 * 0.1, (k as f64 * 0.1).sin() + 0.1))
            .collect();
        reference.push((2.0, 0.0));
        let (rows, rms, peak) = against_curve(&sim, &reference);
        assert_eq!(rows.len(), 10);
        assert!(
            (rms - 0.1).abs() < 1e-6 && (peak - 0.1).abs() < 1e-6,
            "{rms} {peak}"
        );
        let r = curve_results("probe p", &rows, rms, peak, (0.05, 0.2), "r.csv");
        assert!(!r[0].passed && r[1].passed);
        assert_eq!(r[0].name, "probe_p_rms_difference");
        let (rows, rms, _) = against_curve(&sim, &[(5.0, 1.0), (6.0, 1.0)]);
        assert!(rows.is_empty() && rms.is_nan());
        assert!(!curve_results("front", &rows, rms, rms, (1.0, 1.0), "f.csv")[0].passed);
    }

    #[test]
    fn a_perfect_front_has_zero_rms() {
        let g: f64 = 9.81;
        let l = 0.146;
        let scale = (2.0 * g / l).sqrt();
        let front: Vec<(f64, f64)> = martin_moyce()
            .iter()
            .map(|&(t, z)| (t / scale, z * l))
            .collect();
        let (rows, rms) = dam_break_front(&front, l, g);
        assert_eq!(rows.len(), 14);
        assert!(rms < 1e-12);
        let shifted: Vec<(f64, f64)> = front.iter().map(|&(t, x)| (t, x + 0.1 * l)).collect();
        assert!((dam_break_front(&shifted, l, g).1 - 0.1).abs() < 1e-9);
    }
}
