//! `mps report DIR`: a self-contained HTML page of a run (parameters, timing, validation with
//! pass/fail, charts, snapshots) or of a comparison folder (table, figure, metric curves).

use crate::plot::{plot_run, read_csv};
use anyhow::{Context, Result};
use clap::Args;
use mps_render::plot::{line_chart, Series};
use mps_render::report::{html, Block};
use mps_render::{read_pvd, render_frame, Field, Frame, RenderOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mps report`.
#[derive(Args)]
pub struct ReportArgs {
    /// A run's output folder, or a comparison folder from `mps compare`.
    dir: PathBuf,
}

fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(f) => format!("{f:.6}"),
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn png(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("reading {}", path.display()))
}

/// The report blocks of one run folder.
pub fn run_blocks(dir: &Path) -> Result<(String, Vec<Block>)> {
    let text = std::fs::read_to_string(dir.join("summary.toml"))
        .with_context(|| format!("{}: no summary.toml; is this a run folder?", dir.display()))?;
    let s: toml::Table = text.parse().context("parsing summary.toml")?;
    let mut blocks = vec![Block::Heading("Run".into())];
    let keys = [
        "case",
        "scheme",
        "fluid_particles",
        "wall_particles",
        "dummy_particles",
        "spacing",
        "steps",
        "time",
        "end_time",
        "wall_seconds",
        "particle_steps_per_second",
        "mean_ppe_iterations",
        "threads",
        "breakdown",
    ];
    let rows = keys
        .iter()
        .map(|k| {
            vec![
                k.to_string(),
                s.get(*k).map(value_text).unwrap_or_else(|| "none".into()),
            ]
        })
        .collect();
    blocks.push(Block::Table(vec!["quantity".into(), "value".into()], rows));
    if let Some(stages) = s.get("stages").and_then(|v| v.as_array()) {
        let total: f64 = stages.iter().filter_map(|p| p.get(1)?.as_float()).sum();
        let rows = stages
            .iter()
            .filter_map(|p| {
                let (n, t) = (p.get(0)?.as_str()?, p.get(1)?.as_float()?);
                Some(vec![
                    n.to_string(),
                    format!("{t:.3}"),
                    format!("{:.1}", 100.0 * t / total.max(1e-12)),
                ])
            })
            .collect();
        blocks.push(Block::Heading("Time per stage of the step".into()));
        blocks.push(Block::Table(
            vec!["stage".into(), "seconds".into(), "%".into()],
            rows,
        ));
    }
    if let Some(v) = s.get("validation").and_then(|v| v.as_array()) {
        let rows = v
            .iter()
            .map(|r| {
                let f = |k: &str| r.get(k).map(value_text).unwrap_or_default();
                let pass = r.get("passed").and_then(|p| p.as_bool()).unwrap_or(false);
                vec![
                    f("name"),
                    f("value"),
                    f("reference"),
                    f("error"),
                    f("tolerance"),
                    if pass { "PASS" } else { "FAIL" }.into(),
                    f("note"),
                ]
            })
            .collect();
        blocks.push(Block::Heading("Validation".into()));
        blocks.push(Block::Table(
            [
                "check",
                "value",
                "reference",
                "error",
                "tolerance",
                "result",
                "how",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        ));
    }
    if let Some(g) = s
        .get("groups")
        .and_then(|v| v.as_array())
        .filter(|g| !g.is_empty())
    {
        let rows = g
            .iter()
            .map(|r| {
                let f = |k: &str| r.get(k).map(value_text).unwrap_or_else(|| "-".into());
                vec![
                    f("name"),
                    f("particles"),
                    f("arrival_time"),
                    f("stray_end"),
                    f("centroid"),
                ]
            })
            .collect();
        blocks.push(Block::Heading("Fluid groups".into()));
        blocks.push(Block::Table(
            [
                "group",
                "particles",
                "arrival (s)",
                "stray at end",
                "centroid start, end (m)",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        ));
    }
    blocks.push(Block::Heading("Charts".into()));
    for p in plot_run(dir)? {
        let name = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        blocks.push(Block::Image(name, png(&p)?));
    }
    if let Ok(pvd) = std::fs::read_to_string(dir.join("particles.pvd")) {
        let e = read_pvd(&pvd);
        if !e.is_empty() {
            blocks.push(Block::Heading("Snapshots".into()));
            let picks = [0, e.len() / 2, e.len() - 1];
            let mut last = usize::MAX;
            for k in picks {
                if k == last {
                    continue;
                }
                last = k;
                let bytes = std::fs::read(dir.join(&e[k].1))?;
                let frame =
                    Frame::from_vtu(&bytes).map_err(|x| anyhow::anyhow!("{}: {x}", e[k].1))?;
                let c = render_frame(
                    &frame,
                    &RenderOptions {
                        field: Field::Pressure,
                        vectors: true,
                        breakdown: e[k].1.starts_with("breakdown"),
                        ..Default::default()
                    },
                );
                blocks.push(Block::Image(
                    format!("pressure at t = {:.3} s", frame.time),
                    c.png_bytes(),
                ));
            }
        }
    }
    if let Ok(case) = std::fs::read_to_string(dir.join("case.toml")) {
        blocks.push(Block::Heading("Case file".into()));
        blocks.push(Block::Pre(case));
    }
    let title = format!(
        "MPS run: {}",
        s.get("case").map(value_text).unwrap_or_default()
    );
    Ok((title, blocks))
}

/// The report blocks of a comparison folder.
fn compare_blocks(dir: &Path) -> Result<(String, Vec<Block>)> {
    let md = std::fs::read_to_string(dir.join("compare.md")).context("reading compare.md")?;
    let cells = |l: &str| {
        l.trim()
            .trim_matches('|')
            .split('|')
            .map(|c| c.trim().to_string())
            .collect::<Vec<_>>()
    };
    let mut lines = md.lines().filter(|l| l.starts_with('|'));
    let head = lines.next().map(cells).unwrap_or_default();
    let rows: Vec<Vec<String>> = lines.skip(1).map(cells).collect();
    let mut blocks = vec![
        Block::Heading("Schemes side by side".into()),
        Block::Table(head, rows),
    ];
    if let Ok(p) = png(&dir.join("compare.png")) {
        blocks.push(Block::Image(
            "one row per scheme, one column per time, one colour scale".into(),
            p,
        ));
    }
    if let Some((h, rows)) = read_csv(&dir.join("compare_metrics.csv")) {
        // The scheme column is text: re-read it to group the rows.
        let text = std::fs::read_to_string(dir.join("compare_metrics.csv"))?;
        let schemes: Vec<String> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap_or("").to_string())
            .collect();
        let mut names: Vec<String> = Vec::new();
        for s in &schemes {
            if !names.contains(s) {
                names.push(s.clone());
            }
        }
        for metric in [
            "kinetic_energy",
            "angular_momentum",
            "min_pair_distance_l0",
            "rms_speed",
            "nd_spread",
        ] {
            let Some(col) = h.iter().position(|x| x == metric) else {
                continue;
            };
            let series: Vec<Series> = names
                .iter()
                .map(|n| Series {
                    name: n.clone(),
                    points: rows
                        .iter()
                        .zip(&schemes)
                        .filter(|(_, s)| *s == n)
                        .map(|(r, _)| (r[1], r[col]))
                        .collect(),
                    markers: false,
                })
                .collect();
            let c = line_chart(metric, "time (s)", metric, &series, 800, 450);
            blocks.push(Block::Image(format!("{metric} per scheme"), c.png_bytes()));
        }
    }
    for n in std::fs::read_dir(dir)?.flatten() {
        if n.path().join("summary.toml").exists() {
            blocks.push(Block::Heading(format!(
                "Scheme {}",
                n.file_name().to_string_lossy()
            )));
            let (_, b) = run_blocks(&n.path())?;
            blocks.extend(b.into_iter().filter(|x| matches!(x, Block::Table(..))));
        }
    }
    Ok((format!("MPS scheme comparison: {}", dir.display()), blocks))
}

/// Writes `DIR/report.html`; returns its path.
pub fn write_report(dir: &Path) -> Result<PathBuf> {
    let (title, blocks) = if dir.join("compare.md").exists() {
        compare_blocks(dir)?
    } else {
        run_blocks(dir)?
    };
    let path = dir.join("report.html");
    mps::output::write_atomic(&path, html(&title, &blocks).as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

pub fn cmd_report(a: ReportArgs) -> Result<ExitCode> {
    if !a.dir.join("summary.toml").exists() && !a.dir.join("compare.md").exists() {
        eprintln!(
            "error: {}: neither a run folder (summary.toml) nor a comparison (compare.md)",
            a.dir.display()
        );
        return Ok(ExitCode::from(1));
    }
    println!("{}", write_report(&a.dir)?.display());
    Ok(ExitCode::SUCCESS)
}
