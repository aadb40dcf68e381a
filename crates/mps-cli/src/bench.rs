//! `mps bench`: step time, particle-steps per second, the split of a step and the
//! thread speed-up, measured in one run; with `--ladder`, the same over a ladder of
//! resolutions with PPE iterations, peak memory and the SpMV and step costs stated against
//! the machine's measured memory bandwidth (a triad loop).

use crate::baseline::{ratios, Table};
use crate::failure::{bad, io_error, CmdResult, Failure};
use crate::{load_case, CaseArgs};
use clap::Args;
use mps::particles::Kind;
use mps::simulation::{Stage, Timers};
use mps::{Case, Simulation};
use mps_render::plot::{line_chart_svg, Chart, Series};
use rayon::prelude::*;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Arguments of `mps bench`.
#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    case: CaseArgs,
    /// Thread counts to measure, comma-separated.
    #[arg(long, default_value = "1,2", value_delimiter = ',')]
    threads: Vec<usize>,
    /// Steps to time (default: the case's max_steps, else 200; with --ladder, between 5
    /// and 200 so that each rung does about 4 million particle-steps).
    #[arg(long)]
    steps: Option<u64>,
    /// Write the figures as CSV here.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Resolution ladder: fluid particle counts, e.g. `1e4,4e4,1.6e5,6.4e5,1e6`; the case's
    /// spacing (and fixed time step, in proportion) is scaled to reach each.
    #[arg(long, value_delimiter = ',')]
    ladder: Vec<f64>,
    /// With --ladder: write charts of the ladder here (SVG, logarithmic particle axis).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// A stored `--csv` of the same command: print every figure against it as new / old.
    #[arg(long)]
    baseline: Option<PathBuf>,
    /// With --ladder: write the ladder here as a Markdown table, in the README's columns.
    #[arg(long, requires = "ladder")]
    markdown: Option<PathBuf>,
}

struct Row {
    threads: usize,
    particles: usize,
    fluid: usize,
    steps: u64,
    seconds: f64,
    mean_iterations: f64,
    timers: Timers,
    /// Peak resident memory during the rung (bytes), if the OS reports it.
    peak_bytes: Option<u64>,
    /// Best time of one SpMV with the last PPE matrix, its rows and stored entries.
    spmv: Option<(Duration, usize, usize)>,
    /// The process's system CPU time over its user CPU time during the timed steps (%).
    system_percent: f64,
}

/// Per-step figures of a measurement (ms), and particle-steps per second.
struct Split {
    total: f64,
    nb: f64,
    asm: f64,
    setup: f64,
    sol: f64,
    rest: f64,
    pss: f64,
}

impl Row {
    fn split(&self) -> Split {
        let tm = &self.timers;
        let total = self.ms_per_step();
        let (nb, asm, setup, sol) = (
            self.per_step(tm.get(Stage::Neighbors)),
            self.per_step(tm.get(Stage::PpeAssembly)),
            self.per_step(tm.get(Stage::PpeSetup)),
            self.per_step(tm.get(Stage::PpeSolve)),
        );
        Split {
            total,
            nb,
            asm,
            setup,
            sol,
            rest: total - nb - asm - setup - sol,
            pss: self.particles as f64 * self.steps as f64 / self.seconds,
        }
    }
    /// The rest of the step by stage (ms/step): explicit forces, number density and free
    /// surface, gradient (with DS and the pair diagnostics), correction; as CSV columns.
    fn rest_by_stage(&self) -> String {
        let t = &self.timers;
        [
            Stage::Explicit,
            Stage::DensitySurface,
            Stage::Gradient,
            Stage::Correction,
        ]
        .map(|st| format!(",{:.4}", self.per_step(t.get(st))))
        .concat()
    }
    fn per_step(&self, d: Duration) -> f64 {
        1e3 * d.as_secs_f64() / self.steps as f64
    }
    fn ms_per_step(&self) -> f64 {
        1e3 * self.seconds / self.steps as f64
    }
}

/// Runs `steps` steps of `case` on `threads` threads after `warmup` untimed ones.
fn measure(
    case: &Case,
    label: &str,
    threads: usize,
    steps: u64,
    warmup: u64,
) -> Result<Row, Failure> {
    match case.dimension {
        3 => measure_in::<3>(case, label, threads, steps, warmup),
        _ => measure_in::<2>(case, label, threads, steps, warmup),
    }
}

/// [`measure`] in `D` dimensions.
fn measure_in<const D: usize>(
    case: &Case,
    label: &str,
    threads: usize,
    steps: u64,
    warmup: u64,
) -> Result<Row, Failure> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| bad(format!("--threads {threads}: {e}")))?;
    let broke = |b: mps::Breakdown| bad(format!("{label}: the benchmark run broke down: {b}"));
    pool.install(|| -> Result<Row, Failure> {
        // An earlier measurement's freed memory, which glibc was told to keep, would count.
        mps::simulation::memory::release_freed_memory();
        reset_peak_memory();
        let mut sim = Simulation::<D>::new(case.clone(), label)?;
        for _ in 0..warmup {
            sim.step(f64::INFINITY).map_err(broke)?;
        }
        sim.timers = Timers::default();
        let cpu0 = cpu_times();
        let start = Instant::now();
        let mut iters = 0u64;
        for _ in 0..steps {
            let r = sim.step(f64::INFINITY).map_err(broke)?;
            iters += r.solve.iterations as u64;
        }
        let seconds = start.elapsed().as_secs_f64();
        let system_percent = match (cpu0, cpu_times()) {
            (Some((u0, s0)), Some((u1, s1))) if u1 > u0 => 100.0 * (s1 - s0) / (u1 - u0),
            _ => f64::NAN,
        };
        let spmv = sim.last_system.as_ref().map(|s| {
            let a = &s.matrix;
            let x = vec![1.0; a.n()];
            let mut y = vec![0.0; a.n()];
            let best = (0..20)
                .map(|_| {
                    let t = Instant::now();
                    a.spmv(&x, &mut y);
                    t.elapsed()
                })
                .min()
                .unwrap_or_default();
            (best, a.n(), a.nnz())
        });
        let fluid = sim
            .particles
            .kind
            .iter()
            .filter(|k| **k == Kind::Fluid)
            .count();
        Ok(Row {
            threads,
            particles: sim.particles.len(),
            fluid,
            steps,
            seconds,
            mean_iterations: iters as f64 / steps.max(1) as f64,
            timers: sim.timers,
            peak_bytes: peak_memory(),
            spmv,
            system_percent,
        })
    })
}

/// CPU time of this process so far, all threads, (user, system) in seconds (`getrusage`,
/// microsecond resolution); `None` where it fails or on other systems than Unix.
fn cpu_times() -> Option<(f64, f64)> {
    #[cfg(unix)]
    {
        // SAFETY: getrusage writes one rusage struct, which is plain data.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
            return None;
        }
        let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
        Some((secs(u.ru_utime), secs(u.ru_stime)))
    }
    #[cfg(not(unix))]
    None
}

/// Resets the kernel's peak-RSS mark of this process (Linux; ignored elsewhere).
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident memory of this process since the last reset (bytes; Linux only).
fn peak_memory() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Memory bandwidth by a STREAM-style triad `a = b + s c` over arrays far larger than the
/// caches, on `threads` threads: best of five, counting 24 bytes per element (GB/s).
pub fn triad_bandwidth(threads: usize) -> Result<f64, Failure> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| bad(format!("--threads {threads}: {e}")))?;
    Ok(pool.install(|| {
        let n = 1 << 23;
        let b = vec![1.0f64; n];
        let c = vec![2.0f64; n];
        let mut a = vec![0.0f64; n];
        let mut best = f64::INFINITY;
        for k in 0..6 {
            let s = 0.5 + k as f64;
            let t = Instant::now();
            a.par_chunks_mut(1 << 14)
                .zip(b.par_chunks(1 << 14).zip(c.par_chunks(1 << 14)))
                .for_each(|(a, (b, c))| {
                    for i in 0..a.len() {
                        a[i] = b[i] + s * c[i];
                    }
                });
            if k > 0 {
                best = best.min(t.elapsed().as_secs_f64());
            }
        }
        std::hint::black_box(&a);
        24.0 * n as f64 / best / 1e9
    }))
}

pub fn cmd_bench(a: BenchArgs) -> CmdResult {
    let mut args = a.case.clone();
    if args.case.is_none() && args.example.is_none() {
        args.example = Some("bench_dam_break".into());
    }
    let (case, label) = load_case(&args)?;
    if a.threads.iter().any(|&t| t == 0 || t > 1024) {
        return Err(bad("--threads: thread counts from 1 to 1024"));
    }
    if a.ladder.iter().any(|&n| !(100.0..=1e9).contains(&n)) {
        return Err(bad("--ladder: fluid particle counts from 100 to 1e9"));
    }
    let baseline = a.baseline.as_deref().map(Table::read).transpose()?;
    if !a.ladder.is_empty() {
        return ladder(&a, &case, &label, baseline.as_ref());
    }
    let steps = a.steps.or(case.time.max_steps).unwrap_or(200);
    let mut rows = Vec::new();
    for &t in &a.threads {
        rows.push(measure(&case, &label, t, steps, 0)?);
    }
    say!(
        "case {label}: {} particles, {steps} steps",
        rows[0].particles
    );
    say!(
        "{:>7} {:>10} {:>12} {:>9} {:>11} {:>11} {:>11} {:>11} {:>11} {:>9} {:>12} {:>6}",
        "threads",
        "ms/step",
        "Mpart-st/s",
        "PPE it",
        "neighb ms",
        "assemb ms",
        "setup ms",
        "solve ms",
        "rest ms",
        "speed-up",
        "nb+expl s-up",
        "sys %"
    );
    let mut csv = String::from("threads,particles,steps,ms_per_step,particle_steps_per_s,ppe_iterations,neighbors_ms,assembly_ms,setup_ms,solve_ms,rest_ms,speedup,neighbors_explicit_speedup,system_percent_of_user,explicit_ms,density_surface_ms,gradient_ms,correction_ms\n");
    let base = &rows[0];
    let explicit = |r: &Row| {
        let t = &r.timers;
        r.per_step(t.get(Stage::Neighbors) + t.get(Stage::Explicit) + t.get(Stage::DensitySurface))
    };
    for r in &rows {
        let Split {
            total,
            nb,
            asm,
            setup,
            sol,
            rest,
            pss,
        } = r.split();
        let speedup = base.seconds / r.seconds;
        let nb_speedup = explicit(base) / explicit(r);
        say!(
            "{:>7} {:>10.3} {:>12.3} {:>9.1} {:>11.3} {:>11.3} {:>11.3} {:>11.3} {:>11.3} {:>9.2} {:>12.2} {:>6.1}",
            r.threads, total, pss / 1e6, r.mean_iterations, nb, asm, setup, sol, rest, speedup, nb_speedup,
            r.system_percent
        );
        csv.push_str(&format!(
            "{},{},{},{total:.4},{pss:.0},{:.2},{nb:.4},{asm:.4},{setup:.4},{sol:.4},{rest:.4},{speedup:.3},{nb_speedup:.3},{:.2}{}\n",
            r.threads, r.particles, r.steps, r.mean_iterations, r.system_percent, r.rest_by_stage()
        ));
    }
    finish(&a, &csv, baseline.as_ref())?;
    Ok(ExitCode::SUCCESS)
}

/// Writes the table where `--csv` says, and prints it against the baseline if one was given.
fn finish(a: &BenchArgs, csv: &str, baseline: Option<&Table>) -> Result<(), Failure> {
    if let Some(p) = &a.csv {
        mps::io::write_atomic(p, csv.as_bytes())?;
        say!("wrote {}", p.display());
    }
    if let (Some(old), Some(path)) = (baseline, &a.baseline) {
        say!("against {} (new / old):", path.display());
        for line in ratios(&Table::parse(csv, "this run")?, old) {
            say!("  {line}");
        }
    }
    Ok(())
}

/// The case at a spacing giving about `target` fluid particles (the count scales as
/// `l0^-d`); a fixed time step scales with the spacing (constant Courant number).
fn scaled_case(case: &Case, fluid0: usize, target: f64) -> Case {
    let mut c = case.clone();
    let f = (fluid0 as f64 / target).powf(1.0 / case.dimension as f64);
    c.particles.spacing *= f;
    if let Some(dt) = c.time.dt_fixed.as_mut() {
        *dt *= f;
    }
    c.time.max_steps = None;
    c.time.end = f64::INFINITY;
    c
}

fn ladder(a: &BenchArgs, case: &Case, label: &str, baseline: Option<&Table>) -> CmdResult {
    let fluid0 = match case.dimension {
        3 => Simulation::<3>::new(case.clone(), label)?
            .particles
            .count(Kind::Fluid),
        _ => Simulation::<2>::new(case.clone(), label)?
            .particles
            .count(Kind::Fluid),
    };
    let max_threads = a.threads.iter().copied().max().unwrap_or(1);
    let triad = triad_bandwidth(max_threads)?;
    let triad1 = triad_bandwidth(1)?;
    say!(
        "case {label}, solver {:?}; triad bandwidth {triad:.2} GB/s on {max_threads} threads, {triad1:.2} GB/s on 1",
        case.solver.kind
    );
    say!(
        "{:>9} {:>3} {:>6} {:>9} {:>8} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8} {:>7} {:>7} {:>8} {:>8} {:>6}",
        "particles", "thr", "steps", "ms/step", "Mp-st/s", "PPE it", "neighb", "assemb", "setup",
        "solve", "rest", "ns/p/core", "B/part", "SpMV/bw", "PPE/SpMV", "Mp-s/s/c", "sys %"
    );
    let mut csv = String::from(
        "particles,fluid,threads,steps,ms_per_step,particle_steps_per_s,ppe_iterations,neighbors_ms,assembly_ms,setup_ms,solve_ms,rest_ms,non_ppe_ns_per_particle_core,peak_bytes_per_particle,spmv_ms,spmv_gb_per_s,spmv_bandwidth_ratio,ppe_spmv_equivalents,triad_gb_per_s,system_percent_of_user,explicit_ms,density_surface_ms,gradient_ms,correction_ms\n",
    );
    let mut md = String::from(
        "| particles | threads | ms/step | M particle-steps/s | CG it | neighb | assembly | set-up | solve | rest (ms) | non-PPE ns/particle/core | bytes/particle | SpMV / triad | PPE in SpMVs |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut rows = Vec::new();
    for &target in &a.ladder {
        let c = scaled_case(case, fluid0, target);
        let steps = a.steps.unwrap_or(((4e6 / target) as u64).clamp(5, 200));
        for &t in &a.threads {
            let r = measure(&c, label, t, steps, 2)?;
            let Split {
                total,
                nb,
                asm,
                setup,
                sol,
                rest,
                pss,
            } = r.split();
            // Everything but the PPE (assembly, set-up, solve), per particle and core.
            let non_ppe_ns = (total - asm - setup - sol) * 1e6 / r.particles as f64 * t as f64;
            let bytes = r
                .peak_bytes
                .map_or(f64::NAN, |b| b as f64 / r.particles as f64);
            let bw = if t == max_threads { triad } else { triad1 };
            let (spmv_ms, spmv_gbs, ratio, equiv) = match r.spmv {
                Some((d, n, nnz)) => {
                    let s = d.as_secs_f64();
                    let gbs = (12.0 * nnz as f64 + 20.0 * n as f64) / s / 1e9;
                    (1e3 * s, gbs, gbs / bw, (setup + sol) / (1e3 * s))
                }
                None => (f64::NAN, f64::NAN, f64::NAN, f64::NAN),
            };
            say!(
                "{:>9} {:>3} {:>6} {:>9.2} {:>8.3} {:>7.1} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>8.0} {:>7.0} {:>7.2} {:>8.1} {:>8.3} {:>6.1}",
                r.particles, t, r.steps, total, pss / 1e6, r.mean_iterations, nb, asm, setup, sol,
                rest, non_ppe_ns, bytes, ratio, equiv, pss / 1e6 / t as f64, r.system_percent
            );
            csv.push_str(&format!(
                "{},{},{t},{},{total:.4},{pss:.0},{:.2},{nb:.4},{asm:.4},{setup:.4},{sol:.4},{rest:.4},{non_ppe_ns:.1},{bytes:.0},{spmv_ms:.4},{spmv_gbs:.3},{ratio:.3},{equiv:.2},{bw:.3},{:.2}{}\n",
                r.particles, r.fluid, r.steps, r.mean_iterations, r.system_percent, r.rest_by_stage()
            ));
            md.push_str(&format!(
                "| {} | {t} | {} | {:.3} | {:.1} | {} | {} | {} | {} | {} | {non_ppe_ns:.0} | {bytes:.0} | {ratio:.2} | {equiv:.0} |\n",
                count_label(r.particles),
                figure(total),
                pss / 1e6,
                r.mean_iterations,
                figure(nb),
                figure(asm),
                figure(setup),
                figure(sol),
                figure(rest),
            ));
            rows.push(r);
        }
    }
    finish(a, &csv, baseline)?;
    if let Some(p) = &a.markdown {
        mps::io::write_atomic(p, md.as_bytes())?;
        say!("wrote {}", p.display());
    }
    if let Some(dir) = &a.plot {
        ladder_charts(a, &rows, dir)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// A particle count as the README's tables give it: `12.5k`, `170k`, `1.02M`.
fn count_label(n: usize) -> String {
    let x = n as f64;
    match x {
        x if x >= 1e6 => format!("{:.2}M", x / 1e6),
        x if x >= 1e5 => format!("{:.0}k", x / 1e3),
        x if x >= 1e3 => format!("{:.1}k", x / 1e3),
        _ => n.to_string(),
    }
}

/// A time (ms) to three significant figures, as the README's tables give it.
fn figure(ms: f64) -> String {
    match ms.abs() {
        m if m >= 100.0 => format!("{ms:.0}"),
        m if m >= 10.0 => format!("{ms:.1}"),
        _ => format!("{ms:.2}"),
    }
}

/// Charts of a ladder over the particle count (logarithmic axis): iterations, and time per
/// particle-step of the whole step and of the PPE.
fn ladder_charts(a: &BenchArgs, rows: &[Row], dir: &std::path::Path) -> Result<(), Failure> {
    std::fs::create_dir_all(dir).map_err(|e| io_error(dir, e))?;
    let by_threads = |f: &dyn Fn(&Row) -> f64, what: &str| -> Vec<Series> {
        a.threads
            .iter()
            .map(|&t| Series {
                name: format!("{what}, {t} thread(s)"),
                points: rows
                    .iter()
                    .filter(|r| r.threads == t)
                    .map(|r| (r.particles as f64, f(r)))
                    .collect(),
                markers: false,
            })
            .collect()
    };
    let per_particle_step = |r: &Row, d: std::time::Duration| {
        d.as_secs_f64() / r.steps as f64 / r.particles as f64 * 1e9
    };
    let ppe = |r: &Row| {
        let t = &r.timers;
        per_particle_step(
            r,
            t.get(Stage::PpeAssembly) + t.get(Stage::PpeSetup) + t.get(Stage::PpeSolve),
        )
    };
    let charts = [
        (
            "bench_iterations",
            Chart {
                title: "PPE iterations per step".into(),
                x_label: "particles".into(),
                y_label: "CG iterations".into(),
                series: by_threads(&|r| r.mean_iterations, "iterations"),
                log_x: true,
                log_y: false,
            },
        ),
        (
            "bench_time_per_particle",
            Chart {
                title: "time per particle-step".into(),
                x_label: "particles".into(),
                y_label: "ns per particle-step".into(),
                series: [
                    by_threads(
                        &|r| per_particle_step(r, std::time::Duration::from_secs_f64(r.seconds)),
                        "whole step",
                    ),
                    by_threads(&ppe, "PPE"),
                ]
                .concat(),
                log_x: true,
                log_y: true,
            },
        ),
    ];
    for (name, c) in charts {
        let p = dir.join(format!("{name}.svg"));
        let svg = line_chart_svg(&c).map_err(|e| io_error(&p, e))?;
        mps::io::write_atomic(&p, svg.as_bytes())?;
        say!("wrote {}", p.display());
    }
    Ok(())
}
