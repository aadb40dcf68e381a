//! `mps render RUN_DIR`: PNG snapshots of a run's particles.

use crate::failure::{bad, io_error, CmdResult, Failure};
use clap::Args;
use mps_render::{read_pvd, render_frame, Field, Frame, RenderOptions};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Widest image `render` draws (px).
const MAX_WIDTH: u32 = 8000;

/// Parses an image width: 100 to 8000 px.
fn parse_width(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(w) if (100..=MAX_WIDTH).contains(&w) => Ok(w),
        _ => Err(format!("{s}: a width from 100 to {MAX_WIDTH} px")),
    }
}

/// Parses a colour range `MIN,MAX` (finite, MIN < MAX; negative values allowed).
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let nums: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    match nums[..] {
        [lo, hi] if parts.len() == 2 && lo.is_finite() && hi.is_finite() && lo < hi => Ok((lo, hi)),
        _ => Err(format!("{s}: expected MIN,MAX with MIN < MAX")),
    }
}

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
    field: Field,
    /// Draw velocity vectors.
    #[arg(long)]
    vectors: bool,
    /// Image width (px, 100 to 8000).
    #[arg(long, default_value = "900", value_parser = parse_width)]
    width: u32,
    /// Fixed colour range `MIN,MAX` (default: each frame's range).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true)]
    range: Option<(f64, f64)>,
}

/// Reads the frame of VTU file `path`; an unreadable file is bad input naming it.
pub fn read_frame(path: &Path) -> Result<Frame, Failure> {
    let bytes = std::fs::read(path).map_err(|e| bad(format!("{}: {e}", path.display())))?;
    Ok(Frame::from_vtu(&bytes, path)?)
}

/// The `(time, file)` snapshots listed in a run folder's `particles.pvd`.
pub fn snapshots(run_dir: &Path) -> Result<Vec<(f64, String)>, Failure> {
    let pvd = run_dir.join("particles.pvd");
    let text = std::fs::read_to_string(&pvd).map_err(|e| {
        bad(format!(
            "{}: cannot read ({e}); is this a run folder with VTU output?",
            pvd.display()
        ))
    })?;
    let entries = read_pvd(&text);
    if entries.is_empty() {
        return Err(bad(format!("{}: no snapshots listed", pvd.display())));
    }
    Ok(entries)
}

pub fn cmd_render(a: RenderArgs) -> CmdResult {
    let entries = snapshots(&a.run_dir)?;
    let chosen: Vec<(f64, String)> = if a.time.is_empty() {
        entries.clone()
    } else {
        a.time
            .iter()
            .filter_map(|t| {
                entries
                    .iter()
                    .min_by(|x, y| (x.0 - t).abs().total_cmp(&(y.0 - t).abs()))
                    .cloned()
            })
            .collect()
    };
    let out = a.run_dir.join("figures");
    std::fs::create_dir_all(&out).map_err(|e| io_error(&out, e))?;
    let written: Vec<Result<PathBuf, Failure>> = chosen
        .par_iter()
        .map(|(_, file)| {
            let frame = read_frame(&a.run_dir.join(file))?;
            let opts = RenderOptions {
                width: a.width,
                field: a.field,
                vectors: a.vectors,
                range: a.range,
                breakdown: file.starts_with("breakdown"),
                ..Default::default()
            };
            let stem = file.trim_end_matches(".vtu");
            let png = out.join(format!("{}_{stem}.png", a.field.name()));
            render_frame(&frame, &opts).write_png(&png)?;
            Ok(png)
        })
        .collect();
    for w in written {
        println!("{}", w?.display());
    }
    Ok(ExitCode::SUCCESS)
}
