//! Scheme comparison: the same case run once per scheme, summarised side by side (the
//! paper's question: which scheme breaks down, when, and how well it keeps the invariants).

use super::summary::RunSummary;
use serde::{Deserialize, Serialize};

/// One scheme's run in a comparison.
#[derive(Clone, Debug)]
pub struct SchemeRun {
    /// Scheme preset name.
    pub scheme: String,
    /// Its run summary.
    pub summary: RunSummary,
}

fn ratio(pair: (f64, f64)) -> f64 {
    if pair.0 != 0.0 {
        pair.1 / pair.0
    } else {
        f64::NAN
    }
}

/// The comparison as a Markdown table: per scheme, breakdown time and reason (or none), time
/// reached, kinetic energy and angular momentum at the end over their initial values, the
/// closest pair over the run, the n/n0 spread and RMS speed at the end, and every probe at
/// the start and at the end with its step-to-step noise (RMS about its 1 ms average).
pub fn markdown_table(runs: &[SchemeRun]) -> String {
    let probes: Vec<String> = runs
        .first()
        .map(|r| r.summary.probes.iter().map(|p| p.0.clone()).collect())
        .unwrap_or_default();
    let has_groups = runs.iter().any(|r| !r.summary.groups.is_empty());
    let mut s = String::from(
        "| scheme | breakdown | t reached (s) | KE end (J) | KE end/start | L end/start | min pair (l0) | n/n0 spread | RMS speed (m/s) |",
    );
    if has_groups {
        s.push_str(" group arrival (s) | stray at end |");
    }
    for p in &probes {
        s.push_str(&format!(
            " {p} start (Pa) | {p} end (Pa) | {p} noise (Pa) |"
        ));
    }
    s.push_str("\n|---|---|---|---|---|---|---|---|---|");
    if has_groups {
        s.push_str("---|---|");
    }
    for _ in &probes {
        s.push_str("---|---|---|");
    }
    s.push('\n');
    for r in runs {
        let m = &r.summary;
        let b = match (&m.breakdown_time, &m.breakdown) {
            (Some(t), Some(why)) => {
                let reason = why.split(": ").last().unwrap_or(why);
                format!("t = {t:.3} s: {reason}")
            }
            _ => "none".to_string(),
        };
        s.push_str(&format!(
            "| {} | {} | {:.3} | {:.4e} | {:.4} | {:.4} | {:.3} | {:.4} | {:.4} |",
            r.scheme,
            b,
            m.time,
            m.kinetic_energy.1,
            ratio(m.kinetic_energy),
            ratio(m.angular_momentum),
            m.min_pair_distance_l0,
            m.nd_spread_end,
            m.rms_speed_end
        ));
        if has_groups {
            let arrivals: Vec<String> = m
                .groups
                .iter()
                .map(|g| match g.arrival_time {
                    Some(t) => format!("{t:.2}"),
                    None => "-".into(),
                })
                .collect();
            let stray: usize = m.groups.iter().map(|g| g.stray_end).sum();
            let total: usize = m.groups.iter().map(|g| g.particles).sum();
            s.push_str(&format!(" {} | {stray} / {total} |", arrivals.join(", ")));
        }
        for p in &m.probes {
            let noise = m
                .probe_noise
                .iter()
                .find(|n| n.0 == p.0)
                .map_or(f64::NAN, |n| n.1);
            s.push_str(&format!(" {:.2} | {:.2} | {noise:.1} |", p.1, p.2));
        }
        s.push('\n');
    }
    s
}

/// One scheme's row of `compare.csv`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CompareRow {
    /// Scheme preset name.
    pub scheme: String,
    /// Breakdown time (s), if it broke down.
    pub breakdown_time: Option<f64>,
    /// Breakdown description (empty when none).
    pub breakdown: String,
    /// Simulated time reached (s).
    pub time_reached: f64,
    /// Kinetic energy at the start (J).
    pub ke_start: f64,
    /// Kinetic energy at the end (J).
    pub ke_end: f64,
    /// Angular momentum at the start (kg m^2/s).
    pub angular_momentum_start: f64,
    /// Angular momentum at the end (kg m^2/s).
    pub angular_momentum_end: f64,
    /// Closest fluid pair over the run (units of l0).
    pub min_pair_distance_l0: f64,
    /// Spread of n/n0 at the end.
    pub nd_spread_end: f64,
    /// RMS fluid speed at the end (m/s).
    pub rms_speed_end: f64,
}

impl From<&SchemeRun> for CompareRow {
    fn from(r: &SchemeRun) -> Self {
        let m = &r.summary;
        CompareRow {
            scheme: r.scheme.clone(),
            breakdown_time: m.breakdown_time,
            breakdown: m.breakdown.clone().unwrap_or_default(),
            time_reached: m.time,
            ke_start: m.kinetic_energy.0,
            ke_end: m.kinetic_energy.1,
            angular_momentum_start: m.angular_momentum.0,
            angular_momentum_end: m.angular_momentum.1,
            min_pair_distance_l0: m.min_pair_distance_l0,
            nd_spread_end: m.nd_spread_end,
            rms_speed_end: m.rms_speed_end,
        }
    }
}

/// Joins the per-scheme `metrics.csv` texts into one time series with a leading scheme column.
pub fn join_metrics(parts: &[(String, String)]) -> String {
    let mut out = String::new();
    for (k, (scheme, text)) in parts.iter().enumerate() {
        for (l, line) in text.lines().enumerate() {
            if l == 0 {
                if k == 0 {
                    out.push_str("scheme,");
                    out.push_str(line);
                    out.push('\n');
                }
                continue;
            }
            out.push_str(scheme);
            out.push(',');
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}
