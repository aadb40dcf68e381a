//! `mps render RUN_DIR`: PNG snapshots of a run's particles.

use crate::failure::{bad, io_error, CmdResult, Failure};
use clap::Args;
use mps_render::{read_pvd, render_frame, Field, Frame, Projection, RenderOptions};
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
    /// Fixed colour range `MIN,MAX` (default: each frame's 1st-99th percentile; with
    /// --movie, over all frames).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true)]
    range: Option<(f64, f64)>,
    /// Also write `figures/<field>.gif`: every chosen snapshot in one frame and one colour
    /// range, as an animation.
    #[arg(long)]
    movie: bool,
    /// 3D runs: draw the particles within l0/2 of a plane, `AXIS=POSITION` (m), e.g.
    /// `y=0.05` (default: the plane normal to y through the middle of the fluid).
    #[arg(long, value_parser = |s: &str| Projection::parse(s, true), conflicts_with = "view")]
    slice: Option<Projection>,
    /// 3D runs: an orthographic view of every fluid particle along an axis (`x`, `y` or `z`),
    /// nearer particles over farther ones, shaded by depth.
    #[arg(long, value_parser = |s: &str| Projection::parse(s, false))]
    view: Option<Projection>,
    /// Frames per second of the movie.
    #[arg(long, default_value = "10", value_parser = clap::value_parser!(u16).range(1..=50))]
    fps: u16,
}

/// Reads the frame of VTU file `path`; an unreadable file is bad input naming it.
pub fn read_frame(path: &Path) -> Result<Frame, Failure> {
    read_frame_projected(path, Projection::default())
}

/// Reads the frame of VTU file `path`, a 3D run drawn by `projection`.
pub fn read_frame_projected(path: &Path, projection: Projection) -> Result<Frame, Failure> {
    let bytes = std::fs::read(path).map_err(|e| bad(format!("{}: {e}", path.display())))?;
    Ok(Frame::from_vtu_projected(&bytes, path, projection)?)
}

impl RenderArgs {
    /// How a 3D run is drawn.
    fn projection(&self) -> Projection {
        self.view.or(self.slice).unwrap_or_default()
    }

    /// The name part that tells the projection (empty by default).
    fn projection_tag(&self) -> String {
        let axis = |a: usize| ["x", "y", "z"][a.min(2)];
        match (self.view, self.slice) {
            (Some(Projection::View { axis: a }), _) => format!("_view{}", axis(a)),
            (_, Some(Projection::Slice { axis: a, at })) => {
                format!(
                    "_slice{}{}",
                    axis(a),
                    at.map_or(String::new(), |v| format!("{v}"))
                )
            }
            _ => String::new(),
        }
    }
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

/// The animation of `chosen` snapshots: one frame (the union of the fluid boxes) and one
/// colour range (the widest 1st-99th percentile range, unless given) for all.
fn movie(a: &RenderArgs, chosen: &[(f64, String)], out: &Path) -> Result<PathBuf, Failure> {
    let frames: Vec<Frame> = chosen
        .par_iter()
        .map(|(_, file)| read_frame_projected(&a.run_dir.join(file), a.projection()))
        .collect::<Result<_, _>>()?;
    let bounds = mps_render::union_bounds(frames.iter().map(Frame::bounds));
    let range = a.range.or_else(|| {
        frames
            .iter()
            .map(|f| f.range(a.field))
            .reduce(|x, y| (x.0.min(y.0), x.1.max(y.1)))
    });
    let canvases: Vec<mps_render::Canvas> = frames
        .par_iter()
        .zip(chosen)
        .map(|(frame, (_, file))| {
            let opts = RenderOptions {
                width: a.width,
                field: a.field,
                vectors: a.vectors,
                range,
                bounds,
                breakdown: file.starts_with("breakdown"),
                ..Default::default()
            };
            render_frame(frame, &opts)
        })
        .collect();
    let gif = out.join(format!("{}{}.gif", a.field.name(), a.projection_tag()));
    let bytes =
        mps_render::movie::gif_bytes(&canvases, 100 / a.fps).map_err(|e| io_error(&gif, e))?;
    mps::io::write_atomic(&gif, &bytes)?;
    Ok(gif)
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
            let frame = read_frame_projected(&a.run_dir.join(file), a.projection())?;
            let opts = RenderOptions {
                width: a.width,
                field: a.field,
                vectors: a.vectors,
                range: a.range,
                breakdown: file.starts_with("breakdown"),
                ..Default::default()
            };
            let stem = file.trim_end_matches(".vtu").trim_end_matches(".pvtu");
            let tag = a.projection_tag();
            let png = out.join(format!("{}{tag}_{stem}.png", a.field.name()));
            render_frame(&frame, &opts).write_png(&png)?;
            Ok(png)
        })
        .collect();
    for w in written {
        say!("{}", w?.display());
    }
    if a.movie {
        say!("{}", movie(&a, &chosen, &out)?.display());
    }
    Ok(ExitCode::SUCCESS)
}
