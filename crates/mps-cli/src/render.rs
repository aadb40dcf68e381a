//! `mps render RUN_DIR`: PNG snapshots of a run's particles.

use anyhow::{bail, Context, Result};
use clap::Args;
use mps_render::{read_pvd, render_frame, Field, Frame, RenderOptions};
use rayon::prelude::*;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mps render`.
#[derive(Args)]
pub struct RenderArgs {
    /// A run's output folder (holding particles.pvd).
    run_dir: PathBuf,
    /// Times to draw (s); the nearest output is used. Default: every output.
    #[arg(long, num_args = 1.., value_delimiter = ',')]
    time: Vec<f64>,
    /// Colouring field: pressure, velocity, phase or density.
    #[arg(long, default_value = "pressure")]
    field: String,
    /// Draw velocity vectors.
    #[arg(long)]
    vectors: bool,
    /// Image width (px).
    #[arg(long, default_value_t = 900)]
    width: u32,
    /// Fixed colour range `MIN,MAX` (default: each frame's range).
    #[arg(long, value_delimiter = ',', num_args = 2)]
    range: Vec<f64>,
}

pub fn cmd_render(a: RenderArgs) -> Result<ExitCode> {
    let Some(field) = Field::parse(&a.field) else {
        eprintln!(
            "error: --field {}: one of pressure, velocity, phase, density",
            a.field
        );
        return Ok(ExitCode::from(1));
    };
    let pvd = a.run_dir.join("particles.pvd");
    let text = match std::fs::read_to_string(&pvd) {
        Ok(t) => t,
        Err(e) => {
            eprintln!(
                "error: {}: cannot read ({e}); is this a run folder with VTU output?",
                pvd.display()
            );
            return Ok(ExitCode::from(1));
        }
    };
    let entries = read_pvd(&text);
    if entries.is_empty() {
        bail!("{}: no snapshots listed", pvd.display());
    }
    let chosen: Vec<(f64, String)> = if a.time.is_empty() {
        entries.clone()
    } else {
        a.time
            .iter()
            .map(|t| {
                entries
                    .iter()
                    .min_by(|x, y| (x.0 - t).abs().total_cmp(&(y.0 - t).abs()))
                    .cloned()
                    .expect("non-empty")
            })
            .collect()
    };
    let out = a.run_dir.join("figures");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let range = (a.range.len() == 2).then(|| (a.range[0], a.range[1]));
    let written: Vec<Result<PathBuf>> = chosen
        .par_iter()
        .map(|(_, file)| -> Result<PathBuf> {
            let path = a.run_dir.join(file);
            let bytes =
                std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
            let frame =
                Frame::from_vtu(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let opts = RenderOptions {
                width: a.width,
                field,
                vectors: a.vectors,
                range,
                breakdown: file.starts_with("breakdown"),
                ..Default::default()
            };
            let stem = file.trim_end_matches(".vtu");
            let png = out.join(format!("{}_{stem}.png", a.field));
            render_frame(&frame, &opts)
                .write_png(&png)
                .with_context(|| format!("writing {}", png.display()))?;
            Ok(png)
        })
        .collect();
    for w in written {
        println!("{}", w?.display());
    }
    Ok(ExitCode::SUCCESS)
}
