//! `mps plot RUN_DIR`: PNG charts of every recorded metric over time and of the validation
//! curves against their references.

use anyhow::{Context, Result};
use clap::Args;
use mps_render::plot::{line_chart, Series};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `mps plot`.
#[derive(Args)]
pub struct PlotArgs {
    /// A run's output folder.
    run_dir: PathBuf,
}

/// Columns of a CSV file with a header row: (names, rows of numbers).
pub fn read_csv(path: &Path) -> Option<(Vec<String>, Vec<Vec<f64>>)> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()?
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    Some((header, rows))
}

fn column(rows: &[Vec<f64>], x: usize, y: usize) -> Vec<(f64, f64)> {
    rows.iter()
        .filter(|r| r.len() > x.max(y))
        .map(|r| (r[x], r[y]))
        .collect()
}

/// Writes every chart of a run into `RUN_DIR/figures/`; returns the files written.
pub fn plot_run(dir: &Path) -> Result<Vec<PathBuf>> {
    let out = dir.join("figures");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let mut written = Vec::new();
    let mut save = |name: &str, c: mps_render::Canvas| -> Result<()> {
        let p = out.join(format!("{name}.png"));
        c.write_png(&p)
            .with_context(|| format!("writing {}", p.display()))?;
        written.push(p);
        Ok(())
    };
    if let Some((h, rows)) = read_csv(&dir.join("metrics.csv")) {
        for (k, name) in h.iter().enumerate().skip(2) {
            let pts = column(&rows, 0, k);
            let mut series = vec![Series {
                name: name.clone(),
                points: pts.clone(),
                markers: false,
            }];
            // Conserved quantities against their initial (exact) value.
            if name == "kinetic_energy" || name == "angular_momentum" {
                if let (Some(first), Some(last)) = (pts.first(), pts.last()) {
                    series.push(Series {
                        name: "initial (exact)".into(),
                        points: vec![(first.0, first.1), (last.0, first.1)],
                        markers: false,
                    });
                }
            }
            save(
                &format!("metric_{name}"),
                line_chart(name, "time (s)", name, &series, 800, 450),
            )?;
        }
    }
    if let Some((_, rows)) = read_csv(&dir.join("dam_break_front.csv")) {
        let series = [
            Series {
                name: "simulation".into(),
                points: column(&rows, 0, 2),
                markers: false,
            },
            Series {
                name: "Martin & Moyce 1952".into(),
                points: column(&rows, 0, 1),
                markers: true,
            },
        ];
        save(
            "validation_dam_break_front",
            line_chart(
                "dam-break front",
                "T = t sqrt(2g/L)",
                "Z = z/L",
                &series,
                800,
                450,
            ),
        )?;
    }
    if let Some((h, rows)) = read_csv(&dir.join("probes.csv")) {
        let summary: Option<toml::Table> = std::fs::read_to_string(dir.join("summary.toml"))
            .ok()
            .and_then(|t| t.parse().ok());
        let reference = summary.as_ref().and_then(|s| {
            s.get("validation")?
                .as_array()?
                .iter()
                .find(|v| {
                    v.get("name").and_then(|n| n.as_str()) == Some("hydrostatic_bottom_pressure")
                })?
                .get("reference")?
                .as_float()
        });
        for (k, name) in h.iter().enumerate().skip(1) {
            let pts = column(&rows, 0, k);
            let mut series = vec![Series {
                name: format!("probe {name}"),
                points: pts.clone(),
                markers: false,
            }];
            if let (Some(r), Some(a), Some(b)) = (reference, pts.first(), pts.last()) {
                series.push(Series {
                    name: "reference".into(),
                    points: vec![(a.0, r), (b.0, r)],
                    markers: false,
                });
            }
            save(
                &format!("probe_{name}"),
                line_chart(
                    &format!("pressure at {name}"),
                    "time (s)",
                    "Pa",
                    &series,
                    800,
                    450,
                ),
            )?;
        }
    }
    Ok(written)
}

pub fn cmd_plot(a: PlotArgs) -> Result<ExitCode> {
    if !a.run_dir.join("metrics.csv").exists() {
        eprintln!(
            "error: {}: no metrics.csv; is this a run folder?",
            a.run_dir.display()
        );
        return Ok(ExitCode::from(1));
    }
    for p in plot_run(&a.run_dir)? {
        println!("{}", p.display());
    }
    Ok(ExitCode::SUCCESS)
}
