//! `mps report DIR`: a self-contained HTML page of a run (parameters, timing, validation with
//! pass/fail, charts, snapshots) or of a comparison folder (table, figure, metric curves).

use crate::failure::{bad, io_error, CmdResult, Failure};
use crate::plot::{line, run_charts, time_chart};
use crate::render::{read_frame, snapshots};
use clap::Args;
use mps::analysis::compare::CompareRow;
use mps::analysis::RunSummary;
use mps::io::series::{read_rows, read_table, Table};
use mps_render::plot::line_chart_svg;
use mps_render::report::{html, Block};
use mps_render::{render_frame, Field, RenderOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mps report`.
#[derive(Args)]
pub struct ReportArgs {
    /// A run's output folder, or a comparison folder from `mps compare`.
    dir: PathBuf,
}

fn png(path: &Path) -> Result<Vec<u8>, Failure> {
    std::fs::read(path).map_err(|e| io_error(path, e))
}

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |x| format!("{x:.6}"))
}

/// The parameters table of a run.
fn run_table(s: &RunSummary) -> Block {
    let rows: Vec<[String; 2]> = vec![
        ["case".into(), s.case.clone()],
        ["scheme".into(), s.scheme.clone()],
        ["fluid particles".into(), s.fluid_particles.to_string()],
        ["wall particles".into(), s.wall_particles.to_string()],
        ["dummy particles".into(), s.dummy_particles.to_string()],
        ["spacing (m)".into(), s.spacing.to_string()],
        ["steps".into(), s.steps.to_string()],
        ["time reached (s)".into(), format!("{:.6}", s.time)],
        ["end time (s)".into(), format!("{:.6}", s.end_time)],
        ["wall time (s)".into(), format!("{:.3}", s.wall_seconds)],
        [
            "particle-steps/s".into(),
            format!("{:.0}", s.particle_steps_per_second),
        ],
        [
            "mean PPE iterations".into(),
            format!("{:.2}", s.mean_ppe_iterations),
        ],
        ["solver fall-backs".into(), s.solver_fallbacks.to_string()],
        [
            "particles removed by outflow".into(),
            s.outflow_removed.to_string(),
        ],
        ["threads".into(), s.threads.to_string()],
        [
            "breakdown".into(),
            s.breakdown.clone().unwrap_or_else(|| "none".into()),
        ],
    ];
    Block::Table(
        vec!["quantity".into(), "value".into()],
        rows.into_iter().map(Vec::from).collect(),
    )
}

/// Timing, validation and group tables of a run.
fn result_tables(s: &RunSummary) -> Vec<Block> {
    let mut blocks = Vec::new();
    let total: f64 = s.stages.iter().map(|x| x.1).sum();
    let rows = s
        .stages
        .iter()
        .map(|(n, t)| {
            let share = format!("{:.1}", 100.0 * t / total.max(1e-12));
            vec![n.clone(), format!("{t:.3}"), share]
        })
        .collect();
    blocks.push(Block::Heading("Time per stage of the step".into()));
    let head = ["stage", "seconds", "%"].map(String::from).to_vec();
    blocks.push(Block::Table(head, rows));
    if !s.validation.is_empty() {
        let rows = s
            .validation
            .iter()
            .map(|v| {
                let pass = if v.passed { "PASS" } else { "FAIL" };
                vec![
                    v.name.clone(),
                    format!("{:.6}", v.value),
                    format!("{:.6}", v.reference),
                    format!("{:.6}", v.error),
                    format!("{:.6}", v.tolerance),
                    pass.into(),
                    v.note.clone(),
                ]
            })
            .collect();
        blocks.push(Block::Heading("Validation".into()));
        let head = [
            "check",
            "value",
            "reference",
            "error",
            "tolerance",
            "result",
            "how",
        ];
        blocks.push(Block::Table(head.map(String::from).to_vec(), rows));
    }
    if !s.groups.is_empty() {
        let rows = s
            .groups
            .iter()
            .map(|g| {
                vec![
                    g.name.clone(),
                    g.particles.to_string(),
                    opt(g.arrival_time),
                    g.stray_end.to_string(),
                    format!("{:?}", g.centroid),
                ]
            })
            .collect();
        blocks.push(Block::Heading("Fluid groups".into()));
        let head = [
            "group",
            "particles",
            "arrival (s)",
            "stray at end",
            "centroid start, end (m)",
        ];
        blocks.push(Block::Table(head.map(String::from).to_vec(), rows));
    }
    blocks
}

/// Snapshots of the first, middle and last output of a run.
fn snapshot_blocks(dir: &Path) -> Result<Vec<Block>, Failure> {
    let Ok(e) = snapshots(dir) else {
        return Ok(Vec::new());
    };
    let mut blocks = vec![Block::Heading("Snapshots".into())];
    let mut picks = vec![0, e.len() / 2, e.len() - 1];
    picks.dedup();
    for k in picks {
        let frame = read_frame(&dir.join(&e[k].1))?;
        let c = render_frame(
            &frame,
            &RenderOptions {
                field: Field::Pressure,
                vectors: true,
                breakdown: e[k].1.starts_with("breakdown"),
                ..Default::default()
            },
        );
        let caption = format!("pressure at t = {} s", frame.time);
        blocks.push(Block::Image(caption, c.png_bytes()));
    }
    Ok(blocks)
}

/// The charts of a run, inlined as SVG.
fn chart_blocks(dir: &Path) -> Result<Vec<Block>, Failure> {
    let mut blocks = vec![Block::Heading("Charts".into())];
    for (name, chart) in run_charts(dir)? {
        let svg = line_chart_svg(&chart).map_err(bad)?;
        blocks.push(Block::Svg(name, svg));
    }
    Ok(blocks)
}

/// The report blocks of one run folder.
pub fn run_blocks(dir: &Path) -> Result<(String, Vec<Block>), Failure> {
    let s = RunSummary::read(dir)?;
    let mut blocks = vec![Block::Heading("Run".into()), run_table(&s)];
    blocks.extend(result_tables(&s));
    blocks.extend(chart_blocks(dir)?);
    blocks.extend(snapshot_blocks(dir)?);
    if let Ok(case) = std::fs::read_to_string(dir.join("case.toml")) {
        blocks.push(Block::Heading("Case file".into()));
        blocks.push(Block::Pre(case));
    }
    Ok((format!("MPS run: {}", s.case), blocks))
}

/// The comparison table from `compare.csv`, read back through its row type.
fn compare_table(rows: &[CompareRow]) -> Block {
    let ratio = |a: f64, b: f64| {
        if a != 0.0 {
            format!("{:.4}", b / a)
        } else {
            "-".into()
        }
    };
    let body = rows
        .iter()
        .map(|r| {
            let breakdown = match r.breakdown_time {
                Some(t) => format!(
                    "t = {t:.3} s: {}",
                    r.breakdown.rsplit(": ").next().unwrap_or("")
                ),
                None => "none".into(),
            };
            vec![
                r.scheme.clone(),
                breakdown,
                format!("{:.3}", r.time_reached),
                ratio(r.ke_start, r.ke_end),
                ratio(r.angular_momentum_start, r.angular_momentum_end),
                format!("{:.3}", r.min_pair_distance_l0),
                format!("{:.4}", r.nd_spread_end),
                format!("{:.4}", r.rms_speed_end),
            ]
        })
        .collect();
    let head = [
        "scheme",
        "breakdown",
        "t reached (s)",
        "KE end/start",
        "L end/start",
        "min pair (l0)",
        "n/n0 spread",
        "RMS speed (m/s)",
    ];
    Block::Table(head.map(String::from).to_vec(), body)
}

/// Each compared metric over time, one curve per scheme.
fn compare_charts(dir: &Path, schemes: &[String]) -> Result<Vec<Block>, Failure> {
    let mut blocks = Vec::new();
    let per_scheme: Vec<(String, Table)> = schemes
        .iter()
        .filter_map(|s| {
            Some((
                s.clone(),
                read_table(&dir.join(s).join("metrics.csv")).ok()?,
            ))
        })
        .collect();
    for metric in [
        "kinetic_energy",
        "angular_momentum",
        "min_pair_distance_l0",
        "rms_speed",
        "nd_spread",
    ] {
        let series = per_scheme
            .iter()
            .filter_map(|(s, t)| {
                let k = t.header.iter().position(|x| x == metric)?;
                Some(line(s, crate::plot::points(&t.columns, 0, k)))
            })
            .collect();
        let chart = time_chart(metric, &crate::plot::metric_label(metric), series);
        let svg = line_chart_svg(&chart).map_err(bad)?;
        blocks.push(Block::Svg(format!("{metric} per scheme"), svg));
    }
    Ok(blocks)
}

/// The report blocks of a comparison folder.
fn compare_blocks(dir: &Path) -> Result<(String, Vec<Block>), Failure> {
    let rows: Vec<CompareRow> = read_rows(&dir.join("compare.csv"))?;
    let schemes: Vec<String> = rows.iter().map(|r| r.scheme.clone()).collect();
    let mut blocks = vec![
        Block::Heading("Schemes side by side".into()),
        compare_table(&rows),
    ];
    if let Ok(p) = png(&dir.join("compare.png")) {
        let caption = "one row per scheme, one column per time, one colour scale";
        blocks.push(Block::Image(caption.into(), p));
    }
    blocks.extend(compare_charts(dir, &schemes)?);
    for s in &schemes {
        let sub = dir.join(s);
        if sub.join("summary.toml").exists() {
            blocks.push(Block::Heading(format!("Scheme {s}")));
            let summary = RunSummary::read(&sub)?;
            blocks.push(run_table(&summary));
            blocks.extend(
                result_tables(&summary)
                    .into_iter()
                    .filter(|b| matches!(b, Block::Table(..))),
            );
        }
    }
    Ok((format!("MPS scheme comparison: {}", dir.display()), blocks))
}

/// Writes `DIR/report.html`; returns its path.
pub fn write_report(dir: &Path) -> Result<PathBuf, Failure> {
    let (title, blocks) = if dir.join("compare.csv").exists() {
        compare_blocks(dir)?
    } else {
        run_blocks(dir)?
    };
    let path = dir.join("report.html");
    mps::io::write_atomic(&path, html(&title, &blocks).as_bytes())?;
    Ok(path)
}

pub fn cmd_report(a: ReportArgs) -> CmdResult {
    if !a.dir.join("summary.toml").exists() && !a.dir.join("compare.csv").exists() {
        return Err(bad(format!(
            "{}: neither a run folder (summary.toml) nor a comparison (compare.csv)",
            a.dir.display()
        )));
    }
    say!("{}", write_report(&a.dir)?.display());
    Ok(ExitCode::SUCCESS)
}
