//! `mps compare`: run one case once per scheme, each into its own folder, concurrently,
//! and write a comparison table.

use crate::{load_case, CaseArgs};
use anyhow::{Context, Result};
use clap::Args;
use mps::compare::{csv_table, join_metrics, markdown_table, SchemeRun};
use mps::output::write_atomic;
use mps::run::{run, Silent};
use mps::Simulation;
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
}

pub fn cmd_compare(a: CompareArgs) -> Result<ExitCode> {
    // Validate every scheme's case up front, so bad input fails before any run.
    let mut cases = Vec::new();
    for scheme in &a.schemes {
        let mut args = a.case.clone();
        args.set.push(format!("scheme.name={scheme}"));
        match load_case(&args) {
            Ok(c) => cases.push((scheme.clone(), c)),
            Err(e) => {
                eprintln!("error: {e}");
                return Ok(ExitCode::from(1));
            }
        }
    }
    let name = cases[0].1 .0.name.clone();
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("runs").join(format!("{name}_compare")));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Every run gets a full-size pool: when some schemes break down early the others keep
    // all cores (results do not depend on the thread count).
    let per_run = cores;
    eprintln!(
        "comparing {} on {} ({} thread(s) per run) -> {}",
        a.schemes.join(", "),
        name,
        per_run,
        out.display()
    );
    let results: Vec<Result<SchemeRun>> = std::thread::scope(|scope| {
        let handles: Vec<_> = cases
            .iter()
            .map(|(scheme, (case, label))| {
                let dir = out.join(scheme);
                scope.spawn(move || -> Result<SchemeRun> {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(per_run)
                        .build()?;
                    pool.install(|| {
                        let mut sim = Simulation::<2>::new(case.clone(), label)?;
                        let summary = run(&mut sim, &dir, &mut Silent)
                            .with_context(|| format!("writing {}", dir.display()))?;
                        eprintln!(
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
    let runs: Vec<SchemeRun> = results.into_iter().collect::<Result<_>>()?;
    let md = markdown_table(&runs);
    write_atomic(&out.join("compare.md"), md.as_bytes())?;
    write_atomic(&out.join("compare.csv"), csv_table(&runs).as_bytes())?;
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
    println!("{md}");
    eprintln!(
        "written: {0}/compare.md, compare.csv, compare_metrics.csv, one folder per scheme",
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}
