//! `mps bench`: step time, particle-steps per second, the split of a step and the
//! 2-thread speed-up, measured in one run.

use crate::{load_case, CaseArgs};
use anyhow::{Context, Result};
use clap::Args;
use mps::simulation::Timers;
use mps::Simulation;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `mps bench`.
#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    case: CaseArgs,
    /// Thread counts to measure, comma-separated.
    #[arg(long, default_value = "1,2", value_delimiter = ',')]
    threads: Vec<usize>,
    /// Steps to time (default: the case's max_steps, else 200).
    #[arg(long)]
    steps: Option<u64>,
    /// Write the figures as CSV here.
    #[arg(long)]
    csv: Option<PathBuf>,
}

struct Row {
    threads: usize,
    particles: usize,
    steps: u64,
    seconds: f64,
    mean_iterations: f64,
    timers: Timers,
}

pub fn cmd_bench(a: BenchArgs) -> Result<ExitCode> {
    let mut args = a.case.clone();
    if args.case.is_none() && args.example.is_none() {
        args.example = Some("bench_dam_break".into());
    }
    let (case, label) = match load_case(&args) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(1));
        }
    };
    let steps = a.steps.or(case.time.max_steps).unwrap_or(200);
    let mut rows = Vec::new();
    for &t in &a.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .context("building the thread pool")?;
        let row = pool.install(|| -> Result<Row> {
            let mut sim = Simulation::<2>::new(case.clone(), &label)?;
            let start = Instant::now();
            let mut iters = 0u64;
            while sim.step_count < steps {
                let r = sim
                    .step(f64::INFINITY)
                    .map_err(|b| anyhow::anyhow!("{b}"))?;
                iters += r.solve.iterations as u64;
            }
            Ok(Row {
                threads: t,
                particles: sim.particles.len(),
                steps,
                seconds: start.elapsed().as_secs_f64(),
                mean_iterations: iters as f64 / steps as f64,
                timers: sim.timers,
            })
        })?;
        rows.push(row);
    }
    println!(
        "case {label}: {} particles, {steps} steps",
        rows[0].particles
    );
    println!(
        "{:>7} {:>10} {:>12} {:>9} {:>11} {:>11} {:>11} {:>11} {:>9}",
        "threads",
        "ms/step",
        "Mpart-st/s",
        "PPE it",
        "neighb ms",
        "assemb ms",
        "solve ms",
        "rest ms",
        "speed-up"
    );
    let mut csv = String::from("threads,particles,steps,ms_per_step,particle_steps_per_s,ppe_iterations,neighbors_ms,assembly_ms,solve_ms,rest_ms,speedup\n");
    let base = rows[0].seconds;
    for r in &rows {
        let per = |d: std::time::Duration| 1e3 * d.as_secs_f64() / r.steps as f64;
        let tm = &r.timers;
        let total = 1e3 * r.seconds / r.steps as f64;
        let (nb, asm, sol) = (per(tm.neighbors), per(tm.ppe_assembly), per(tm.ppe_solve));
        let rest = total - nb - asm - sol;
        let pss = r.particles as f64 * r.steps as f64 / r.seconds;
        let speedup = base / r.seconds;
        println!(
            "{:>7} {:>10.3} {:>12.3} {:>9.1} {:>11.3} {:>11.3} {:>11.3} {:>11.3} {:>9.2}",
            r.threads,
            total,
            pss / 1e6,
            r.mean_iterations,
            nb,
            asm,
            sol,
            rest,
            speedup
        );
        csv.push_str(&format!(
            "{},{},{},{total:.4},{pss:.0},{:.2},{nb:.4},{asm:.4},{sol:.4},{rest:.4},{speedup:.3}\n",
            r.threads, r.particles, r.steps, r.mean_iterations
        ));
    }
    if let Some(p) = &a.csv {
        mps::output::write_atomic(p, csv.as_bytes())
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
