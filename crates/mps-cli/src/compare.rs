//! `mps compare`: run one case once per scheme, each into its own folder, concurrently,
//! and write a comparison table.

use crate::failure::{bad, io_error, CmdResult, Failure};
use crate::render::read_frame;
use crate::{load_case, CaseArgs};
use clap::Args;
use mps::analysis::compare::{join_metrics, markdown_table, CompareRow, SchemeRun};
use mps::io::series::Series;
use mps::io::write_atomic;
use mps::run::{run, Silent};
use mps_render::Field;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mps compare`.
#[derive(Args)]
pub struct CompareArgs {
    #[command(flatten)]
    case: CaseArgs,
    /// Schemes to run, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "CMPS-HS,MPS-HS-GC,MPS-HS-GC-DS"
    )]
    schemes: Vec<String>,
    /// Output folder (default `runs/<case name>_compare`); one subfolder per scheme.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Times of the side-by-side figure's columns (s); default four up to the end time.
    #[arg(long, value_delimiter = ',')]
    figure_times: Vec<f64>,
    /// Colouring field of the figure: pressure, velocity, phase or density.
    #[arg(long, default_value = "pressure")]
    figure_field: Field,
    /// Draw velocity vectors in the figure.
    #[arg(long)]
    vectors: bool,
    /// Replace a comparison already in the output folder (the schemes' run files and the
    /// comparison files are cleared first).
    #[arg(long)]
    force: bool,
}

pub fn cmd_compare(a: CompareArgs) -> CmdResult {
    // Validate every scheme's case up front, so bad input fails before any run.
    let mut cases = Vec::new();
    for (k, scheme) in a.schemes.iter().enumerate() {
        if a.schemes[..k].contains(scheme) {
            return Err(bad(format!("--schemes: {scheme} is listed twice")));
        }
        let mut args = a.case.clone();
        args.set.push(format!("scheme.name={scheme}"));
        cases.push((scheme.clone(), load_case(&args)?));
    }
    if cases.is_empty() {
        return Err(bad("--schemes: name at least one scheme"));
    }
    let name = cases[0].1 .0.name.clone();
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("runs").join(format!("{name}_compare")));
    prepare_comparison(&out, &a.schemes, a.force)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Every run gets a full-size pool: when some schemes break down early the others keep
    // all cores (results do not depend on the thread count).
    let per_run = cores;
    say_err!(
        "comparing {} on {} ({} thread(s) per run) -> {}",
        a.schemes.join(", "),
        name,
        per_run,
        out.display()
    );
    let results: Vec<Result<SchemeRun, Failure>> = std::thread::scope(|scope| {
        let handles: Vec<_> = cases
            .iter()
            .map(|(scheme, (case, label))| {
                let dir = out.join(scheme);
                scope.spawn(move || -> Result<SchemeRun, Failure> {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(per_run)
                        .build()
                        .map_err(|e| bad(format!("thread pool: {e}")))?;
                    pool.install(|| {
                        let summary = run_in_dimension(case, label, &dir)?;
                        say_err!(
                            "  {scheme}: {}",
                            summary.breakdown.clone().unwrap_or_else(|| format!(
                                "reached t = {:.3} s without breakdown",
                                summary.time
                            ))
                        );
                        Ok(SchemeRun {
                            scheme: scheme.clone(),
                            summary,
                        })
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("comparison thread panicked"))
            .collect()
    });
    let runs: Vec<SchemeRun> = results.into_iter().collect::<Result<_, _>>()?;
    let md = markdown_table(&runs);
    write_atomic(&out.join("compare.md"), md.as_bytes())?;
    let mut csv = Series::create(&out.join("compare.csv"), None)?;
    for r in &runs {
        csv.push(&CompareRow::from(r))?;
    }
    csv.flush()?;
    let parts: Vec<(String, String)> = runs
        .iter()
        .map(|r| {
            let text = std::fs::read_to_string(out.join(&r.scheme).join("metrics.csv"))
                .unwrap_or_default();
            (r.scheme.clone(), text)
        })
        .collect();
    write_atomic(
        &out.join("compare_metrics.csv"),
        join_metrics(&parts).as_bytes(),
    )?;
    if let Some(f) = comparison_figure(&a, &out, &runs, cases[0].1 .0.time.end)? {
        say_err!("figure: {}", f.display());
    }
    say!("{md}");
    say_err!(
        "written: {0}/compare.md, compare.csv, compare_metrics.csv, one folder per scheme",
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Prepares the comparison folder: refused when it holds files, unless `force`, which
/// clears the comparison's own files and each scheme folder's run files.
fn prepare_comparison(
    out: &std::path::Path,
    schemes: &[String],
    force: bool,
) -> Result<(), Failure> {
    std::fs::create_dir_all(out).map_err(|e| io_error(out, e))?;
    let holds = std::fs::read_dir(out)
        .map_err(|e| io_error(out, e))?
        .next()
        .is_some();
    if holds && !force {
        return Err(bad(format!(
            "{}: already holds files; use --force to replace the comparison there",
            out.display()
        )));
    }
    for f in [
        "compare.md",
        "compare.csv",
        "compare_metrics.csv",
        "compare.png",
        "report.html",
    ] {
        let p = out.join(f);
        if p.exists() {
            std::fs::remove_file(&p).map_err(|e| io_error(&p, e))?;
        }
    }
    for scheme in schemes {
        mps::run::recorder::prepare_folder(&out.join(scheme), true)?;
    }
    Ok(())
}

/// The side-by-side figure: one row per scheme, one column per time, one colour scale; a
/// scheme that broke down before a column's time shows its last good state, marked.
fn comparison_figure(
    a: &CompareArgs,
    out: &std::path::Path,
    runs: &[SchemeRun],
    end: f64,
) -> Result<Option<PathBuf>, Failure> {
    use mps_render::{compose, read_pvd, render_frame, Frame, RenderOptions};
    let field = a.figure_field;
    let times: Vec<f64> = if a.figure_times.is_empty() {
        (1..=4).map(|k| end * k as f64 / 4.0).collect()
    } else {
        a.figure_times.clone()
    };
    // Load the frame of each (scheme, time).
    let mut grid: Vec<(String, f64, Frame, bool)> = Vec::new();
    for r in runs {
        let dir = out.join(&r.scheme);
        let Ok(text) = std::fs::read_to_string(dir.join("particles.pvd")) else {
            return Ok(None); // no VTU output (output.vtu = false)
        };
        let entries = read_pvd(&text);
        for &t in &times {
            let broken = r.summary.breakdown_time.is_some_and(|bt| bt < t);
            let entry = if broken {
                entries
                    .iter()
                    .find(|e| e.1.starts_with("breakdown"))
                    .or(entries.last())
            } else {
                entries
                    .iter()
                    .filter(|e| !e.1.starts_with("breakdown"))
                    .min_by(|x, y| (x.0 - t).abs().total_cmp(&(y.0 - t).abs()))
            };
            let Some((_, file)) = entry else { continue };
            let frame: Frame = read_frame(&dir.join(file))?;
            grid.push((r.scheme.clone(), t, frame, broken));
        }
    }
    // One colour scale for all panels (fluid range over every frame).
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (_, _, f, _) in &grid {
        let (a0, b0) = f.range(field);
        lo = lo.min(a0);
        hi = hi.max(b0);
    }
    // One frame for all panels: the union of each frame's fluid box (spray of a broken
    // scheme beyond the 0.5-99.5th percentile does not shrink the others).
    let bounds = mps_render::union_bounds(grid.iter().map(|(_, _, f, _)| f.bounds()));
    let panels: Vec<_> = grid
        .iter()
        .map(|(scheme, _, frame, broken)| {
            render_frame(
                frame,
                &RenderOptions {
                    width: 520,
                    field,
                    vectors: a.vectors,
                    range: Some((lo, hi)),
                    bounds,
                    label: scheme.clone(),
                    breakdown: *broken,
                    ..Default::default()
                },
            )
        })
        .collect();
    let fig = compose(&panels, times.len());
    let path = out.join("compare.png");
    fig.write_png(&path)?;
    Ok(Some(path))
}

/// Runs `case` (quietly, into `dir`) in its own dimension.
fn run_in_dimension(
    case: &mps::Case,
    label: &str,
    dir: &std::path::Path,
) -> Result<mps::analysis::RunSummary, Failure> {
    use mps::io::checkpoint::build_simulation;
    Ok(match case.dimension {
        3 => run(
            &mut build_simulation::<3>(case.clone(), label)?,
            dir,
            &mut Silent,
        )?,
        _ => run(
            &mut build_simulation::<2>(case.clone(), label)?,
            dir,
            &mut Silent,
        )?,
    })
}
