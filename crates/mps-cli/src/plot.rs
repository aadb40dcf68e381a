//! `mps plot RUN_DIR`: SVG charts of every recorded metric over time and of the validation
//! curves against their references.

use crate::failure::{bad, io_error, CmdResult, Failure};
use clap::Args;
use mps::analysis::RunSummary;
use mps::io::series::{read_table, Table};
use mps_render::plot::{line_chart_svg, Chart, Series};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mps plot`.
#[derive(Args)]
pub struct PlotArgs {
    /// A run's output folder.
    run_dir: PathBuf,
}

/// `(x, y)` points of columns `x`, `y` of a table.
pub fn points(cols: &[Vec<f64>], x: usize, y: usize) -> Vec<(f64, f64)> {
    cols[x]
        .iter()
        .copied()
        .zip(cols[y].iter().copied())
        .collect()
}

/// The y-axis label of a `metrics.csv` column, with its unit.
pub fn metric_label(name: &str) -> String {
    let unit = match name {
        "dt" => "s",
        "kinetic_energy" | "potential_energy" => "J (per m depth)",
        "momentum_x" | "momentum_y" => "kg m/s (per m depth)",
        "angular_momentum" => "kg m^2/s (per m depth)",
        "min_pair_distance_l0" => "l0",
        "max_speed" | "rms_speed" => "m/s",
        "nd_mean" | "nd_spread" => "n/n0",
        _ => "",
    };
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} ({unit})")
    }
}

/// A chart on a linear time axis.
pub fn time_chart(title: &str, y_label: &str, series: Vec<Series>) -> Chart {
    Chart {
        title: title.to_string(),
        x_label: "time (s)".into(),
        y_label: y_label.to_string(),
        series,
        ..Default::default()
    }
}

/// A line series.
pub fn line(name: &str, points: Vec<(f64, f64)>) -> Series {
    Series {
        name: name.to_string(),
        points,
        markers: false,
    }
}

/// The charts of a run folder: every metric (conserved quantities against their initial
/// value), the dam-break front against Martin & Moyce, a probe or front against the case's
/// reference curve, each probe (against the hydrostatic reference when the run has one). A file that is there but unreadable is bad input.
pub fn run_charts(dir: &Path) -> Result<Vec<(String, Chart)>, Failure> {
    let mut charts = Vec::new();
    let table = |name: &str| -> Result<Option<Table>, Failure> {
        let p = dir.join(name);
        if !p.exists() {
            return Ok(None);
        }
        read_table(&p).map(Some).map_err(Failure::from)
    };
    if let Some(Table { header, columns }) = table("metrics.csv")? {
        for (k, name) in header.iter().enumerate().skip(2) {
            let pts = points(&columns, 0, k);
            let mut series = vec![line(name, pts.clone())];
            if name == "kinetic_energy" || name == "angular_momentum" {
                if let (Some(first), Some(last)) = (pts.first(), pts.last()) {
                    series.push(line("initial (exact)", vec![*first, (last.0, first.1)]));
                }
            }
            let chart = time_chart(name, &metric_label(name), series);
            charts.push((format!("metric_{name}"), chart));
        }
    }
    if let Some(Table { columns: cols, .. }) = table("dam_break_front.csv")? {
        let series = vec![
            line("simulation", points(&cols, 0, 2)),
            Series {
                name: "Martin & Moyce 1952".into(),
                points: points(&cols, 0, 1),
                markers: true,
            },
        ];
        let chart = Chart {
            title: "dam-break front".into(),
            x_label: "T = t sqrt(2g/L)".into(),
            y_label: "Z = z/L".into(),
            series,
            ..Default::default()
        };
        charts.push(("validation_dam_break_front".into(), chart));
    }
    if let Some(Table { columns: cols, .. }) = table("reference_comparison.csv")? {
        let what = RunSummary::read(dir)
            .ok()
            .and_then(|s| s.validation.first().map(|v| v.name.clone()))
            .map(|n| n.trim_end_matches("_rms_difference").replace('_', " "))
            .unwrap_or_else(|| "simulation".into());
        let unit = if what.starts_with("probe") { "Pa" } else { "m" };
        let series = vec![
            line(
                &format!("{what} at the reference times"),
                points(&cols, 0, 2),
            ),
            Series {
                name: "reference (the case's CSV)".into(),
                points: points(&cols, 0, 1),
                markers: true,
            },
        ];
        let title = format!("{what} against the reference curve");
        charts.push((
            "validation_reference".into(),
            time_chart(&title, unit, series),
        ));
    }
    if let Some(Table {
        header: h,
        columns: cols,
    }) = table("probes.csv")?
    {
        let reference = RunSummary::read(dir).ok().and_then(|s| {
            s.validation
                .iter()
                .find(|v| v.name == "hydrostatic_bottom_pressure")
                .map(|v| v.reference)
        });
        for (k, name) in h.iter().enumerate().skip(1) {
            let pts = points(&cols, 0, k);
            let mut series = vec![line(&format!("probe {name}"), pts.clone())];
            if let (Some(r), Some(a), Some(b)) = (reference, pts.first(), pts.last()) {
                series.push(line("reference", vec![(a.0, r), (b.0, r)]));
            }
            let title = format!("pressure at {name}");
            charts.push((format!("probe_{name}"), time_chart(&title, "Pa", series)));
        }
    }
    Ok(charts)
}

/// Writes every chart of a run into `RUN_DIR/figures/` as SVG; returns the files written.
pub fn plot_run(dir: &Path) -> Result<Vec<PathBuf>, Failure> {
    let out = dir.join("figures");
    std::fs::create_dir_all(&out).map_err(|e| io_error(&out, e))?;
    let mut written = Vec::new();
    for (name, chart) in run_charts(dir)? {
        let p = out.join(format!("{name}.svg"));
        let svg = line_chart_svg(&chart).map_err(|e| io_error(&p, e))?;
        mps::io::write_atomic(&p, svg.as_bytes())?;
        written.push(p);
    }
    Ok(written)
}

pub fn cmd_plot(a: PlotArgs) -> CmdResult {
    if !a.run_dir.join("metrics.csv").exists() {
        return Err(bad(format!(
            "{}: no metrics.csv; is this a run folder?",
            a.run_dir.display()
        )));
    }
    for p in plot_run(&a.run_dir)? {
        say!("{}", p.display());
    }
    Ok(ExitCode::SUCCESS)
}
