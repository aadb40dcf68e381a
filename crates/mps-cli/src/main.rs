//! `mps`: command-line program over the MPS solver library.

/// Prints a line to standard output; a closed pipe (`mps ... | head -1`) is not an error.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// Prints a line to standard error; a closed pipe is not an error.
macro_rules! say_err {
    ($($arg:tt)*) => {{
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

use clap::{Args, Parser, Subcommand};
use failure::{bad, io_error, CmdResult, Failure};
use indicatif::{ProgressBar, ProgressStyle};
use mps::analysis::RunSummary;
use mps::examples::EXAMPLES;
use mps::run::{run_from, Observer, Progress};
use mps::{Case, Simulation};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

mod baseline;
mod bench;
mod compare;
mod failure;
mod heartbeat;
mod plot;
mod render;
mod report;

/// Most threads a run may ask for.
const MAX_THREADS: usize = 1024;

/// Parses a thread count: 1 to 1024.
fn parse_threads(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=MAX_THREADS).contains(&n) => Ok(n),
        _ => Err(format!("{s}: a thread count from 1 to {MAX_THREADS}")),
    }
}

/// Moving Particle Semi-implicit (MPS) solver for incompressible free-surface and multiphase flow.
#[derive(Parser)]
#[command(name = "mps", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a case file or a built-in example.
    Run(RunArgs),
    /// List the built-in examples.
    List,
    /// Benchmark a case: ms/step, particle-steps/s, split of the step, 2-thread speed-up.
    Bench(bench::BenchArgs),
    /// Run a case once per scheme and compare breakdown and stability metrics.
    Compare(compare::CompareArgs),
    /// Draw PNG snapshots of a run (particles coloured by a field, optional vectors).
    Render(render::RenderArgs),
    /// Plot a run's metrics over time and its validation curves (PNG).
    Plot(plot::PlotArgs),
    /// Write a self-contained HTML report of a run or a comparison.
    Report(report::ReportArgs),
}

/// Where a case comes from, and how to change it.
#[derive(Args, Clone)]
pub struct CaseArgs {
    /// Case file (TOML).
    pub case: Option<PathBuf>,
    /// Run a built-in example instead (see `mps list`).
    #[arg(long, conflicts_with = "case")]
    pub example: Option<String>,
    /// Override a case field, e.g. `--set time.end=1.0 --set scheme.name=MPS-HS-GC-DS`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

#[derive(Args, Clone)]
struct RunArgs {
    #[command(flatten)]
    case: CaseArgs,
    /// Output folder (default `runs/<case name>`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// No progress output.
    #[arg(long, short)]
    quiet: bool,
    /// Number of threads, 1 to 1024 (default: all cores).
    #[arg(long, value_parser = parse_threads)]
    threads: Option<usize>,
    /// Continue from a checkpoint written by an earlier run of the same case (e.g. with a
    /// later `time.end`): in the checkpoint's own folder (or `--out`), every series and
    /// snapshot of the earlier run up to the checkpoint carried over, as if uninterrupted.
    #[arg(long, value_name = "CHECKPOINT")]
    restart: Option<PathBuf>,
    /// Replace a run already in the output folder (its files are cleared first; other files
    /// stay). Without it, a folder that holds files is refused.
    #[arg(long)]
    force: bool,
    /// Render every N-th snapshot to `OUT/figures/` (pressure, with vectors) as the run goes.
    #[arg(long, value_name = "N")]
    render_every: Option<usize>,
}

/// Loads the case named by the arguments, with overrides applied; returns it and its label.
pub fn load_case(a: &CaseArgs) -> Result<(Case, String), mps::CaseError> {
    let overrides: Vec<(String, String)> = a
        .set
        .iter()
        .map(|s| match s.split_once('=') {
            Some((k, v)) => Ok((k.trim().to_string(), v.trim().to_string())),
            None => Err(mps::CaseError::new(
                "--set",
                s.clone(),
                "",
                "expected KEY=VALUE",
            )),
        })
        .collect::<Result<_, _>>()?;
    match (&a.case, &a.example) {
        (Some(p), _) => Ok((Case::from_file(p, &overrides)?, p.display().to_string())),
        (None, Some(name)) => {
            let text = mps::examples::example(name).ok_or_else(|| {
                let names: Vec<&str> = EXAMPLES.iter().map(|e| e.0).collect();
                let msg = format!("no such example; one of {}", names.join(", "));
                mps::CaseError::new("--example", "", name.clone(), msg)
            })?;
            let label = format!("example:{name}");
            Ok((Case::from_str_named(text, &label, &overrides)?, label))
        }
        (None, None) => Err(mps::CaseError::new(
            "mps",
            "",
            "",
            "give a case file or --example NAME (see `mps list`)",
        )),
    }
}

/// Progress as a bar on a terminal, as log lines otherwise (through the heartbeat, so a long
/// step or set-up is never silent).
struct Reporter {
    bar: Option<ProgressBar>,
    beat: Option<heartbeat::Heartbeat>,
    quiet: bool,
    last_status: Instant,
    render_every: Option<usize>,
}

impl Reporter {
    /// A reporter to `end` (s); `beat` is the run's heartbeat (none when quiet).
    fn new(beat: Option<heartbeat::Heartbeat>, end: f64) -> Self {
        let bar = (beat.is_some() && std::io::stderr().is_terminal()).then(|| {
            let b = ProgressBar::new(1000);
            b.set_style(
                ProgressStyle::with_template(
                    "{bar:40.cyan/blue} t = {msg} [{elapsed_precise} < {eta_precise}]",
                )
                .expect("valid template"),
            );
            b.set_message(format!("0 / {end} s"));
            b.enable_steady_tick(std::time::Duration::from_millis(500));
            b
        });
        Reporter {
            // The bar shows that the run works; the heartbeat would write across it.
            quiet: beat.is_none(),
            beat: if bar.is_some() { None } else { beat },
            bar,
            last_status: Instant::now(),
            render_every: None,
        }
    }
}

impl Observer for Reporter {
    fn on_step(&mut self, p: &Progress) {
        let rate = p.step as f64 / p.elapsed.max(1e-9);
        if let Some(b) = &self.bar {
            b.set_position(((p.time / p.end) * 1000.0) as u64);
            b.set_message(format!(
                "{:.4} / {} s, step {}, {:.0} steps/s, PPE {} it",
                p.time, p.end, p.step, rate, p.report.solve.iterations
            ));
        } else if let Some(beat) = &self.beat {
            if self.last_status.elapsed().as_secs_f64() < 0.2 {
                return;
            }
            self.last_status = Instant::now();
            let eta = (p.end - p.time) / (p.time / p.elapsed.max(1e-9)).max(1e-12);
            beat.set(format!(
                "t = {:.4} / {} s  step {}  {:.0} steps/s  dt {:.2e} s  PPE {} it  ETA {:.0} s",
                p.time, p.end, p.step, rate, p.report.dt, p.report.solve.iterations, eta
            ));
        }
    }
    fn on_snapshot(&mut self, index: usize, path: &Path) {
        let Some(n) = self.render_every else { return };
        if n == 0 || !index.is_multiple_of(n) {
            return;
        }
        let done = std::fs::read(path)
            .map_err(|e| e.to_string())
            .and_then(|b| mps_render::Frame::from_vtu(&b, path).map_err(|e| e.to_string()))
            .and_then(|frame| {
                let dir = path.parent().unwrap_or(Path::new(".")).join("figures");
                std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
                let stem = path.file_stem().unwrap_or_default().to_string_lossy();
                let opts = mps_render::RenderOptions {
                    vectors: true,
                    ..Default::default()
                };
                mps_render::render_frame(&frame, &opts)
                    .write_png(&dir.join(format!("pressure_{stem}.png")))
                    .map_err(|e| e.to_string())
            });
        if let Err(e) = done {
            self.on_message(&format!("warning: rendering {}: {e}", path.display()));
        }
    }
    fn on_message(&mut self, m: &str) {
        if let Some(b) = &self.bar {
            b.println(m);
        } else if !self.quiet {
            say_err!("{m}");
        }
    }
}

fn print_timing(s: &RunSummary) {
    let total: f64 = s.stages.iter().map(|x| x.1).sum();
    let particles = s.fluid_particles + s.wall_particles + s.dummy_particles;
    say_err!(
        "timing: {:.2} s wall, {} particles, {} steps, {:.3} M particle-steps/s, {:.2} ms/step, {} threads",
        s.wall_seconds,
        particles,
        s.steps,
        s.particle_steps_per_second / 1e6,
        1e3 * s.wall_seconds / s.steps.max(1) as f64,
        s.threads
    );
    say_err!("  step loop {total:>9.3} s");
    let n = s.stages.len();
    for (k, (name, t)) in s.stages.iter().enumerate() {
        let branch = if k + 1 == n { "└─" } else { "├─" };
        say_err!(
            "  {branch} {name:<26} {t:>8.3} s {:>5.1} %",
            100.0 * t / total.max(1e-12)
        );
    }
}

/// Runs `f` on a thread pool of `threads` workers (default: all cores). The run's thread is
/// one of the workers, so each parallel loop of the step starts where it is called instead of
/// being handed to the pool and waited for (docs/decisions.md, "Thread pool").
fn in_pool<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> Result<T, Failure> + Send,
) -> Result<T, Failure> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        b = b.num_threads(t);
    }
    let pool = b
        .build()
        .map_err(|e| bad(format!("--threads {threads:?}: {e}")))?;
    pool.install(f)
}

/// Restores `sim` from the checkpoint `ck`; returns the output folder of the restarted run
/// when none was given.
fn restart<const D: usize>(
    sim: &mut Simulation<D>,
    ck: &Path,
    quiet: bool,
) -> Result<PathBuf, Failure> {
    let bytes = std::fs::read(ck)
        .map_err(|e| bad(format!("{}: cannot read checkpoint: {e}", ck.display())))?;
    mps::io::checkpoint::restore(sim, &bytes, ck)?;
    if !quiet {
        say_err!(
            "restarting from {} at t = {:.6} s (step {})",
            ck.display(),
            sim.time,
            sim.step_count
        );
    }
    let dir = ck.parent().filter(|d| !d.as_os_str().is_empty());
    Ok(dir.unwrap_or(Path::new(".")).to_path_buf())
}

/// Keeps the case beside its output (the report shows it; a rerun starts from it).
fn save_case(a: &CaseArgs, out: &Path) -> Result<(), Failure> {
    let source = match (&a.case, &a.example) {
        (Some(p), _) => std::fs::read_to_string(p).unwrap_or_default(),
        (None, Some(n)) => mps::examples::example(n).unwrap_or_default().to_string(),
        _ => String::new(),
    };
    let sets: String = a.set.iter().map(|s| format!("# --set {s}\n")).collect();
    std::fs::create_dir_all(out).map_err(|e| io_error(out, e))?;
    mps::io::write_atomic(&out.join("case.toml"), format!("{sets}{source}").as_bytes())?;
    Ok(())
}

fn print_results(s: &RunSummary, out: &Path) {
    print_timing(s);
    for v in &s.validation {
        say_err!("validation: {} = {:.4} ({})", v.name, v.value, v.note);
        if v.reference != 0.0 {
            say_err!(
                "            reference {:.4}, relative error {:+.2} %",
                v.reference,
                100.0 * v.error
            );
        }
    }
    say_err!(
        "output: {} (open particles.pvd in ParaView; metrics.csv, steps.csv, summary.toml)",
        out.display()
    );
}

fn cmd_run(a: RunArgs) -> CmdResult {
    if let Some((var, n)) = mpi_processes() {
        #[cfg(feature = "mpi")]
        {
            let _ = (var, n);
            return distributed_run(a);
        }
        #[cfg(not(feature = "mpi"))]
        return Err(bad(format!(
            "mps run was started as one of {n} MPI processes ({var} = {n}), but this mps was built without the distributed run: build it with `cargo build --release --features mpi` (README, \"Distributed run\"); every process would write the same folder"
        )));
    }
    in_pool(a.threads, || run_in_pool(a))
}

/// `mps run` started by `mpirun` as one of several processes: the launcher's variable and
/// the number of processes. The launchers' environment: `OMPI_COMM_WORLD_SIZE` (Open MPI),
/// `PMI_SIZE` (MPICH, Intel MPI, Slurm).
fn mpi_processes() -> Option<(&'static str, u64)> {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"]
        .into_iter()
        .find_map(|var| {
            let n = std::env::var(var).ok()?.trim().parse::<u64>().ok()?;
            (n > 1).then_some((var, n))
        })
}

/// The case of `mps run`, its label and the output folder (`--out`, else `runs/NAME`).
fn case_and_folder(a: &RunArgs) -> Result<(mps::Case, String, PathBuf), Failure> {
    let (case, label) = load_case(&a.case)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(&case.name));
    Ok((case, label, out))
}

/// `mps run` on the run's thread pool.
fn run_in_pool(a: RunArgs) -> CmdResult {
    let (case, label, out) = case_and_folder(&a)?;
    match case.dimension {
        3 => run_case::<3>(a, case, label, out),
        _ => run_case::<2>(a, case, label, out),
    }
}

/// The simulation of `case`, restored from `--restart` if given; the output folder and the
/// folder of the checkpoint resumed from.
type Built<const D: usize> = (Simulation<D>, PathBuf, Option<PathBuf>);

/// Builds the simulation of `case` for `mps run` (restored from `--restart` if given).
fn build<const D: usize>(
    a: &RunArgs,
    case: mps::Case,
    label: &str,
    mut out: PathBuf,
    beat: Option<&heartbeat::Heartbeat>,
) -> Result<Built<D>, Failure> {
    // A restart takes every particle from its checkpoint: no settled start to make first.
    let mut sim = if a.restart.is_some() {
        Simulation::<D>::new(case, label)?
    } else {
        let mut end = 0.0;
        if let Some(r) = case.initial.as_ref().and_then(|i| i.relax.as_ref()) {
            end = r.time;
            if !a.quiet {
                say_err!(
                    "{label}: relaxing the tank at rest for up to {} s first ({})",
                    r.time,
                    mps::simulation::relax::RELAX_SCHEME
                );
            }
        }
        let mut progress = |t: f64| {
            if let Some(b) = beat {
                b.set(format!("relaxing {label}: t = {t:.4} / {end} s"));
            }
        };
        mps::io::checkpoint::build_simulation_with::<D>(case, label, &mut progress)?
    };
    let mut resumed = None;
    if let Some(ck) = &a.restart {
        let dir = restart(&mut sim, ck, a.quiet)?;
        if a.out.is_none() {
            out = dir.clone();
        }
        resumed = Some(dir);
    }
    Ok((sim, out, resumed))
}

/// Says what runs where, prepares the output folder and keeps the case in it.
fn open_output<const D: usize>(
    a: &RunArgs,
    sim: &Simulation<D>,
    label: &str,
    out: &Path,
    resumed: Option<&Path>,
) -> Result<(), Failure> {
    if !a.quiet {
        let p = &sim.particles;
        say_err!(
            "{}: {} fluid, {} wall, {} dummy particles, l0 = {} m, scheme {}, to t = {} s -> {}",
            label,
            p.count(mps::particles::Kind::Fluid),
            p.count(mps::particles::Kind::Wall),
            p.count(mps::particles::Kind::Dummy),
            sim.l0(),
            sim.scheme.name,
            sim.case.time.end,
            out.display()
        );
    }
    let in_place = resumed.is_some_and(|d| d.canonicalize().ok() == out.canonicalize().ok());
    if !in_place {
        mps::run::recorder::prepare_folder(out, a.force)?;
    }
    save_case(&a.case, out)
}

/// After a run: the results, and exit code 2 on a breakdown.
fn finish(a: &RunArgs, summary: &RunSummary, out: &Path, vtu: bool) -> CmdResult {
    if !a.quiet {
        print_results(summary, out);
    }
    if let Some(b) = &summary.breakdown {
        let files = if vtu {
            "last good state and breakdown.toml"
        } else {
            "breakdown.toml (no last good state: output.vtu = false)"
        };
        say_err!("error: {b}; {files} in {}", out.display());
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs a loaded `case` in `D` dimensions into `out` (the rest of `mps run`).
fn run_case<const D: usize>(a: RunArgs, case: mps::Case, label: String, out: PathBuf) -> CmdResult {
    let (end, vtu) = (case.time.end, case.output.vtu);
    let beat = (!a.quiet).then(|| heartbeat::Heartbeat::start(&format!("setting up {label}")));
    let (mut sim, out, resumed) = build::<D>(&a, case, &label, out, beat.as_ref())?;
    open_output(&a, &sim, &label, &out, resumed.as_deref())?;
    if let Some(b) = &beat {
        b.set(format!("{label}: first step"));
    }
    let mut rep = Reporter::new(beat, end);
    rep.render_every = a.render_every;
    let summary = run_from(&mut sim, &out, resumed.as_deref(), &mut rep)?;
    if let Some(b) = &rep.bar {
        b.finish_and_clear();
    }
    finish(&a, &summary, &out, vtu)
}

/// `mpirun -np N mps run CASE` (feature `mpi`): every process builds the case and steps its
/// piece; the first one records the whole run as a serial run would (README, "Distributed
/// run"). One thread per process unless `--threads` says otherwise.
#[cfg(feature = "mpi")]
fn distributed_run(a: RunArgs) -> CmdResult {
    let threads = a.threads.or(Some(1));
    in_pool(threads, || {
        let procs = mps::distributed::run::Processes::start()
            .ok_or_else(|| bad("mps run: MPI could not be initialised".to_string()))?;
        let first = procs.rank() == 0;
        let run = || {
            let (case, label, out) = case_and_folder(&a)?;
            match case.dimension {
                3 => distributed_case::<3>(&procs, a, case, label, out),
                _ => distributed_case::<2>(&procs, a, case, label, out),
            }
        };
        let r = run();
        // Every process reads the same input and meets the same error: the first says it,
        // and the others wait until it has (mpirun ends the whole job as soon as one
        // process exits with an error, which could cut the first short of its message).
        let r = match r {
            Err(e) if first => {
                say_err!("error: {e}");
                Ok(e.exit_code())
            }
            Err(e) => Ok(e.exit_code()),
            ok => ok,
        };
        procs.all(true);
        r
    })
}

/// The distributed run of a loaded case in `D` dimensions.
#[cfg(feature = "mpi")]
fn distributed_case<const D: usize>(
    procs: &mps::distributed::run::Processes,
    mut a: RunArgs,
    case: mps::Case,
    label: String,
    out: PathBuf,
) -> CmdResult {
    let first = procs.rank() == 0;
    a.quiet |= !first;
    let (end, vtu) = (case.time.end, case.output.vtu);
    let beat = (!a.quiet).then(|| heartbeat::Heartbeat::start(&format!("setting up {label}")));
    let (sim, out, resumed) = build::<D>(&a, case, &label, out, beat.as_ref())?;
    procs.check_size(&sim, &label)?;
    let opened = match first {
        true => open_output(&a, &sim, &label, &out, resumed.as_deref()),
        false => Ok(()),
    };
    // Every process learns whether the first could open the folder.
    if !procs.all(opened.is_ok()) {
        opened?;
        return Ok(ExitCode::from(1));
    }
    if !a.quiet {
        say_err!("on {} MPI processes", procs.size());
    }
    if let Some(b) = &beat {
        b.set(format!("{label}: first step"));
    }
    // The first process shows the progress, as a serial run does.
    let mut rep = Reporter::new(beat, end);
    rep.render_every = a.render_every;
    let summary = procs.run(sim, &out, resumed.as_deref(), &mut rep)?;
    if let Some(b) = &rep.bar {
        b.finish_and_clear();
    }
    match first {
        true => finish(&a, &summary, &out, vtu),
        false => Ok(ExitCode::SUCCESS),
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // Help and version go to stdout with exit 0; a bad argument is bad input (1).
            if !e.use_stderr() {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            // One line, as every bad input gets: clap's first paragraph (a missing argument
            // is named on the line after the message), without the usage hint below it.
            let text = e.render().to_string();
            let first: Vec<&str> = text
                .lines()
                .skip_while(|l| l.trim().is_empty())
                .take_while(|l| !l.trim().is_empty())
                .map(str::trim)
                .collect();
            say_err!("{} (mps --help)", first.join(" "));
            return ExitCode::from(1);
        }
    };
    let r = match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::List => {
            for (name, desc, _) in EXAMPLES {
                say!("{name:<20} {desc}");
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Bench(a) => bench::cmd_bench(a),
        Command::Compare(a) => compare::cmd_compare(a),
        Command::Render(a) => render::cmd_render(a),
        Command::Plot(a) => plot::cmd_plot(a),
        Command::Report(a) => report::cmd_report(a),
    };
    match r {
        Ok(c) => c,
        Err(e) => {
            say_err!("error: {e}");
            e.exit_code()
        }
    }
}
