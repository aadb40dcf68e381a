//! The run loop: steps a simulation to its end time, hands every output to the
//! [`Recorder`] (VTU + PVD snapshots, metrics, step, probe, group and front series,
//! checkpoints), runs the validations at the end and writes the run summary; on breakdown it
//! writes the last good state and the breakdown record.
//!
//! A distributed run's processes all run this loop on their own particles: every measurement
//! is collective, the first process writes the shared files, and a failed write on any
//! process is every process's (`agree`), so that none waits alone for the others.

pub mod recorder;

use crate::analysis::added_mass::{first_accelerations, Disc};
use crate::analysis::groups::group_states;
use crate::analysis::metrics::Metrics;
use crate::analysis::probes::{noise, smooth, SMOOTHING_WINDOW};
use crate::analysis::validation::{
    against_curve, curve_results, dam_break, early_acceleration, early_acceleration_in_tank,
    elliptic_drop, hydrostatic, laplace_jump, rotating_disc, steady_flow, surface_mode, DiscSpec,
    ValidationResult,
};
use crate::analysis::{GroupSummary, RunSummary};
use crate::error::{IoContext, Result};
use crate::input::case::{Case, ShapeSpec, ValidationSpec};
use crate::input::reference::ReferenceFile;
use crate::input::setup::velocity_at;
use crate::io::checkpoint::agree;
use crate::io::series::Series;
use crate::io::write_atomic;
use crate::particles::Kind;
use crate::particles::Vector;
use crate::simulation::{Breakdown, BreakdownReason, Simulation, StepReport};
use recorder::Recorder;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Progress of a run, passed to the observer after every step.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Simulated time (s).
    pub time: f64,
    /// End time (s).
    pub end: f64,
    /// Steps taken.
    pub step: u64,
    /// Last step's report.
    pub report: StepReport,
    /// Wall-clock seconds since the run started.
    pub elapsed: f64,
}

/// Receives progress of a run (the CLI draws a progress bar or logs lines).
pub trait Observer {
    /// Called after every step.
    fn on_step(&mut self, _p: &Progress) {}
    /// Called with a one-line message (outputs written, breakdown).
    fn on_message(&mut self, _m: &str) {}
    /// Called after each VTU snapshot is written (its index and path).
    fn on_snapshot(&mut self, _index: usize, _path: &Path) {}
}

/// An observer that ignores everything.
pub struct Silent;
impl Observer for Silent {}

/// What the loop gathers for the summary.
struct Totals {
    breakdown: Option<Breakdown>,
    wall_seconds: f64,
}

/// One output, and the observer told of its snapshot (collective).
fn output<const D: usize>(
    rec: &mut Recorder<D>,
    sim: &Simulation<D>,
    observer: &mut dyn Observer,
) -> Result<()> {
    let index = rec.outputs;
    let written = rec.output(sim);
    let path = agree_on(sim, written)?;
    if let Some(path) = path {
        observer.on_snapshot(index, &path);
    }
    Ok(())
}

/// [`agree`] for a result with a value.
fn agree_on<const D: usize, T>(sim: &Simulation<D>, r: Result<T>) -> Result<T> {
    match r {
        Ok(v) => agree(sim, Ok(())).map(|_| v),
        Err(e) => agree(sim, Err(e)).map(|_| unreachable!("an error stays one")),
    }
}

/// Steps to the end time, writing outputs at the first step past each output time
/// (shortening steps to land on them would kick PND-type sources, whose pressure scales as
/// `1/dt^2`); only the last step is shortened to end exactly at the end time.
fn step_loop<const D: usize>(
    sim: &mut Simulation<D>,
    rec: &mut Recorder<D>,
    observer: &mut dyn Observer,
    stepper: Stepper<D>,
) -> Result<Totals> {
    let start = Instant::now();
    let end = sim.case.time.end;
    let interval = sim.case.output.interval;
    // The next output time after the current one (a restarted run continues the sequence).
    let mut next_out = if interval > 0.0 {
        ((sim.time / interval + 1e-9).floor() + 1.0) * interval
    } else {
        end
    };
    let max_steps = sim.case.time.max_steps.unwrap_or(u64::MAX);
    let eps = 1e-9 * end;
    // The output tolerance never exceeds a millionth of the interval (a huge end time must
    // not make every step an output).
    let eps_out = if interval > 0.0 {
        eps.min(1e-6 * interval)
    } else {
        eps
    };
    let mut t = Totals {
        breakdown: None,
        wall_seconds: 0.0,
    };
    let mut last_output_step = sim.step_count;
    while sim.time < end - eps && sim.step_count < max_steps {
        let r = match stepper(sim, end) {
            Ok(r) => r,
            Err(b) => {
                observer.on_message(&b.to_string());
                t.breakdown = Some(b);
                break;
            }
        };
        rec.step(sim, &r)?;
        rec.sample(sim)?;
        if sim.time >= next_out - eps_out && sim.time < end - eps {
            output(rec, sim, observer)?;
            // The checkpoint holds no solver set-up: drop it here too, so a run restarted
            // from this checkpoint continues bit-identically.
            sim.reset_solver_cache();
            last_output_step = sim.step_count;
            next_out = following_output(next_out, sim.time + eps_out, interval);
        }
        observer.on_step(&Progress {
            time: sim.time,
            end,
            step: sim.step_count,
            report: r,
            elapsed: start.elapsed().as_secs_f64(),
        });
    }
    t.wall_seconds = start.elapsed().as_secs_f64();
    if let Some(b) = &t.breakdown {
        let last_good = rec.snapshot(sim, "breakdown_last_good_state.vtu")?;
        rec.metrics_row(sim)?;
        let b = the_breakdown(sim, b);
        let written = match sim.is_first_process() {
            true => write_breakdown(&b, rec.out_dir(), last_good),
            false => Ok(()),
        };
        agree(sim, written)?;
        t.breakdown = Some(b);
    } else if sim.step_count != last_output_step || rec.outputs <= 1 {
        output(rec, sim, observer)?;
    }
    let flushed = rec.flush();
    agree(sim, flushed)?;
    Ok(t)
}

/// The breakdown a distributed run reports (collective): the first process's own reason, or
/// that of the lowest process that found one (the others saw `Elsewhere`), with the
/// particles of every process. On one process, `b` itself.
fn the_breakdown<const D: usize>(sim: &Simulation<D>, b: &Breakdown) -> Breakdown {
    if !sim.is_distributed() {
        return b.clone();
    }
    let found = !matches!(b.reason, BreakdownReason::Elsewhere);
    let flags = sim.gather_over_processes(&[found as u8 as f64]);
    let rank = flags.iter().position(|&f| f > 0.0).unwrap_or(0);
    let me = sim.process().0;
    let text: Vec<f64> = match me == rank {
        true => b.reason.to_string().bytes().map(f64::from).collect(),
        false => Vec::new(),
    };
    let why: Vec<u8> = sim
        .gather_over_processes(&text)
        .into_iter()
        .map(|c| c as u8)
        .collect();
    let ids: Vec<f64> = b.particles.iter().map(|&i| i as f64).collect();
    let mut particles: Vec<u32> = sim
        .gather_over_processes(&ids)
        .into_iter()
        .map(|i| i as u32)
        .collect();
    particles.sort_unstable();
    particles.dedup();
    let reason = match me == rank {
        true => b.reason.clone(),
        false => BreakdownReason::OnProcess {
            rank,
            why: String::from_utf8_lossy(&why).into_owned(),
        },
    };
    Breakdown {
        reason,
        particles,
        ..b.clone()
    }
}

/// The record of a breakdown (`breakdown.toml`).
#[derive(Serialize)]
struct BreakdownRecord {
    /// Simulated time of the last good state (s).
    time: f64,
    /// The step that failed.
    step: u64,
    /// The reason, as data.
    reason: String,
    /// The reason, in words.
    message: String,
    /// Ids of the particles involved.
    particles: Vec<u32>,
}

/// The first output time after `now` (s) on the grid of `interval` (s) from `next` (s): one
/// addition in the usual case, a multiple when steps are longer than the interval.
fn following_output(next: f64, now: f64, interval: f64) -> f64 {
    if next > now || !(interval > 0.0) {
        return next;
    }
    let next = next + interval;
    if next > now {
        return next;
    }
    next + ((now - next) / interval).floor().max(0.0) * interval + interval
}

/// `breakdown.toml`: time, step, reason and the particles involved (and where the last good
/// state is, when VTU output is on).
fn write_breakdown(b: &Breakdown, out: &Path, last_good: Option<PathBuf>) -> Result<()> {
    let record = BreakdownRecord {
        time: b.time,
        step: b.step,
        reason: format!("{:?}", b.reason),
        message: b.to_string(),
        particles: b.particles.clone(),
    };
    let state = match last_good.as_ref().and_then(|p| p.file_name()) {
        Some(f) => format!("the last good state is in {}", f.to_string_lossy()),
        None => "no particle file was written (output.vtu = false); checkpoint.bin holds the last output".into(),
    };
    let text = format!(
        "# The run broke down; {state}.\n{}",
        toml::to_string(&record).expect("a breakdown record serialises")
    );
    write_atomic(&out.join("breakdown.toml"), text.as_bytes())
}

/// One row of `dam_break_front.csv`.
#[derive(Serialize)]
struct FrontRow {
    #[serde(rename = "T")]
    t: f64,
    #[serde(rename = "Z_experiment")]
    experiment: f64,
    #[serde(rename = "Z_simulation")]
    simulation: f64,
    difference: f64,
}

/// Runs `sim` to its end time, writing into `out` (created if missing).
pub fn run<const D: usize>(
    sim: &mut Simulation<D>,
    out: &Path,
    observer: &mut dyn Observer,
) -> Result<RunSummary> {
    run_from(sim, out, None, observer)
}

/// Runs `sim` to its end time, writing into `out`; when `resumed` names the folder of the
/// checkpoint `sim` was restored from, the earlier run's series and snapshots up to the
/// checkpoint are carried into `out` and the summary covers the whole run, so every file
/// ends as if the run had not been interrupted.
pub fn run_from<const D: usize>(
    sim: &mut Simulation<D>,
    out: &Path,
    resumed: Option<&Path>,
    observer: &mut dyn Observer,
) -> Result<RunSummary> {
    run_stepped(sim, out, resumed, observer, &mut |s, until| s.step(until))
}

/// How the run loop advances its simulation one step towards a time (s): `Simulation::step`
/// on one process; in a distributed run, the step of every process, after which the first
/// one's copy of the whole (what is recorded) is gathered.
pub type Stepper<'a, const D: usize> =
    &'a mut dyn FnMut(&mut Simulation<D>, f64) -> std::result::Result<StepReport, Breakdown>;

/// [`run_from`], each step taken by `stepper`, whose simulation is recorded.
pub fn run_stepped<const D: usize>(
    sim: &mut Simulation<D>,
    out: &Path,
    resumed: Option<&Path>,
    observer: &mut dyn Observer,
    stepper: Stepper<D>,
) -> Result<RunSummary> {
    std::fs::create_dir_all(out).at(out)?;
    let front_wall = match &sim.case.validation {
        Some(ValidationSpec::DamBreak { wall_x, .. })
        | Some(ValidationSpec::FrontReference { wall_x, .. }) => Some(*wall_x),
        _ => None,
    };
    let mut rec = match resumed {
        Some(from) => {
            // The checkpoint's output is in the earlier rows; the solver set-up was dropped
            // there too.
            sim.reset_solver_cache();
            Recorder::resume(sim, out, front_wall, from)?
        }
        None => {
            let created = Recorder::create(sim, out, front_wall);
            let mut rec = agree_on(sim, created)?;
            rec.sample(sim)?;
            output(&mut rec, sim, observer)?;
            rec
        }
    };
    let totals = step_loop(sim, &mut rec, observer, stepper)?;
    let first = sim.is_first_process();
    let smoothed = match first {
        true => write_smoothed_probes(sim, &rec, out),
        false => Ok(()),
    };
    agree(sim, smoothed)?;
    let validation = validate(sim, &rec, out);
    let validation = agree_on(sim, validation)?;
    let summary = summarise(sim, &rec, &totals, validation);
    if first {
        write_atomic(&out.join("summary.toml"), summary.to_toml().as_bytes())?;
    }
    Ok(summary)
}

/// `probes_smoothed.csv`: every probe's 1 ms moving average (a gauge's reading).
fn write_smoothed_probes<const D: usize>(
    sim: &Simulation<D>,
    rec: &Recorder<D>,
    out: &Path,
) -> Result<()> {
    let Some(first) = rec.probe_series.first() else {
        return Ok(());
    };
    let header: Vec<String> = std::iter::once("time".to_string())
        .chain(sim.case.probes.iter().map(|p| p.name.clone()))
        .collect();
    let smoothed: Vec<Vec<(f64, f64)>> = rec
        .probe_series
        .iter()
        .map(|s| smooth(s, SMOOTHING_WINDOW))
        .collect();
    let mut csv = Series::create(&out.join("probes_smoothed.csv"), Some(&header))?;
    for (k, &(t, _)) in first.iter().enumerate() {
        let row: Vec<f64> = std::iter::once(t)
            .chain(smoothed.iter().map(|s| s[k].1))
            .collect();
        csv.push(&row)?;
    }
    csv.flush()
}

/// The dam-break front against Martin & Moyce, and `dam_break_front.csv`.
fn dam_break_front<const D: usize>(
    rec: &Recorder<D>,
    column_width: f64,
    g: f64,
    l0: f64,
    out: &Path,
) -> Result<ValidationResult> {
    let (result, rows) = dam_break(&rec.front_series, column_width, g, l0);
    let header = ["T", "Z_experiment", "Z_simulation", "difference"].map(String::from);
    let path = out.join("dam_break_front.csv");
    let mut csv = Series::create_if(rec.writes_shared_files(), &path, Some(&header))?;
    for &(t, experiment, simulation) in &rows {
        let difference = simulation - experiment;
        csv.push(&FrontRow {
            t,
            experiment,
            simulation,
            difference,
        })?;
    }
    csv.flush()?;
    Ok(result)
}

/// The Laplace check `v` of `case` in `dimension`: the two probes' means from `from` on.
fn laplace<const D: usize>(
    case: &Case,
    rec: &Recorder<D>,
    v: &ValidationSpec,
    dimension: usize,
) -> Option<ValidationResult> {
    let ValidationSpec::Laplace {
        inside,
        outside,
        radius,
        from,
        tolerance,
    } = v
    else {
        return None;
    };
    let mean = |probe: &str| {
        let series = &rec.probe_series[probe_index(case, probe)];
        let sel: Vec<f64> = series
            .iter()
            .filter(|s| s.0 >= *from)
            .map(|s| s.1)
            .collect();
        (!sel.is_empty()).then(|| sel.iter().sum::<f64>() / sel.len() as f64)
    };
    let free = case
        .phases
        .iter()
        .map(|p| p.surface_tension)
        .fold(0.0, f64::max);
    let sigma = case.interfaces.first().map_or(free, |f| f.tension);
    let b = match outside {
        Some(o) => mean(o)?,
        None => 0.0,
    };
    let a = mean(inside)?;
    Some(laplace_jump(a - b, sigma, *radius, dimension, *tolerance))
}

/// The case's validation against reference data (and the dam break's comparison file).
fn validate<const D: usize>(
    sim: &Simulation<D>,
    rec: &Recorder<D>,
    out: &Path,
) -> Result<Vec<ValidationResult>> {
    let case = &sim.case;
    let g = sim.gravity.norm();
    let rho_w = case.phases[0].density;
    let result = match &case.validation {
        Some(ValidationSpec::DamBreak { column_width, .. }) => {
            Some(dam_break_front(rec, *column_width, g, sim.l0(), out)?)
        }
        Some(ValidationSpec::Hydrostatic {
            depth,
            reference,
            probe,
            window,
            tolerance,
        }) => {
            let series = &rec.probe_series[probe_index(case, probe)];
            let exact = reference.unwrap_or(rho_w * g * depth);
            let r = hydrostatic(probe, series, *window, exact, reference.is_some());
            r.map(|r| r.with_tolerance(*tolerance))
        }
        Some(ValidationSpec::Groups { early_time, .. }) => {
            return Ok(groups(sim, rec, *early_time));
        }
        Some(ValidationSpec::RotatingDisc {
            center,
            radius,
            omega,
            probe,
            from,
        }) => {
            let series = &rec.probe_series[probe_index(case, probe)];
            let series: Vec<(f64, f64)> = series.iter().copied().filter(|s| s.0 >= *from).collect();
            let disc = DiscSpec {
                center: Vector::from_slice(center).expect("validated"),
                radius: *radius,
                omega: *omega,
                rho: rho_w,
            };
            return Ok(rotating_disc(sim, &disc, &series));
        }
        Some(ValidationSpec::EllipticDrop {
            radius,
            strain_rate,
            ..
        }) => elliptic_drop(&rec.axes_series, *radius, *strain_rate),
        Some(ValidationSpec::SurfaceMode {
            omega,
            mode,
            until,
            tolerance,
            radius,
            ..
        }) => {
            let u = rec.rim.as_ref().map_or(0.0, |r| r.initial_velocity);
            // The disc's phase: its tension's share sigma / (rho R^3) of the growth.
            let p = &case.phases[0];
            let tension = p.surface_tension / (p.density * radius.powi(3));
            let spec = (*omega, tension, *mode);
            surface_mode(&rec.rim_series, u, spec, *until, *tolerance)
        }
        Some(v @ ValidationSpec::Laplace { .. }) => laplace(case, rec, v, D),
        Some(ValidationSpec::SteadyFlow { tolerance }) => {
            steady_flow(steady_flow_sums(sim), *tolerance)
        }
        Some(ValidationSpec::ProbeReference {
            probe,
            reference,
            rms_tolerance,
            peak_tolerance,
            smoothing,
        }) => {
            let series = &rec.probe_series[probe_index(case, probe)];
            let series = if *smoothing > 0.0 {
                smooth(series, *smoothing)
            } else {
                series.clone()
            };
            let what = format!("probe {probe}");
            let tolerances = (*rms_tolerance, *peak_tolerance);
            let out = rec.writes_shared_files().then_some(out);
            return compare_with_curve(&what, &series, reference, tolerances, out);
        }
        Some(ValidationSpec::FrontReference {
            reference,
            rms_tolerance,
            peak_tolerance,
            ..
        }) => {
            let tolerances = (*rms_tolerance, *peak_tolerance);
            let out = rec.writes_shared_files().then_some(out);
            return compare_with_curve("front", &rec.front_series, reference, tolerances, out);
        }
        None => None,
    };
    Ok(result.into_iter().collect())
}

/// The sums of a steady-flow check over every process's own fluid particles:
/// `|u_i - u(x_i)|^2`, `|u(x_i)|^2`, `|u_i|^2` (m^2/s^2) and their count, `u` the first fluid
/// region's initial velocity field.
fn steady_flow_sums<const D: usize>(sim: &Simulation<D>) -> [f64; 4] {
    let (p, f) = (&sim.particles, &sim.case.fluid[0]);
    let mut sums = [0.0; 4];
    for i in (0..sim.owned()).filter(|&i| p.kind[i] == Kind::Fluid) {
        let exact = velocity_at(f, &sim.case, p.position[i]);
        sums[0] += (p.velocity[i] - exact).norm2();
        sums[1] += exact.norm2();
        sums[2] += p.velocity[i].norm2();
        sums[3] += 1.0;
    }
    sim.sum_over_processes(&mut sums);
    sums
}

/// A series against the case's reference curve: `reference_comparison.csv` (time, reference,
/// simulation, difference) in `out` when given, and the RMS and peak figures.
fn compare_with_curve(
    what: &str,
    series: &[(f64, f64)],
    reference: &ReferenceFile,
    tolerances: (f64, f64),
    out: Option<&Path>,
) -> Result<Vec<ValidationResult>> {
    let (rows, rms, peak) = against_curve(series, &reference.curve);
    let header = ["time", "reference", "simulation", "difference"].map(String::from);
    let path = out
        .unwrap_or(Path::new("."))
        .join("reference_comparison.csv");
    let mut csv = Series::create_if(out.is_some(), &path, Some(&header))?;
    for &(t, r, s) in &rows {
        csv.push(&[t, r, s, s - r])?;
    }
    csv.flush()?;
    Ok(curve_results(
        what,
        &rows,
        rms,
        peak,
        tolerances,
        &reference.file,
    ))
}

/// The run summary.
fn summarise<const D: usize>(
    sim: &Simulation<D>,
    rec: &Recorder<D>,
    t: &Totals,
    validation: Vec<ValidationResult>,
) -> RunSummary {
    let m1 = Metrics::measure(sim);
    let m0 = rec.first_metrics.clone().unwrap_or_else(|| m1.clone());
    let [fluid, wall, dummy] =
        [Kind::Fluid, Kind::Wall, Kind::Dummy].map(|k| sim.count_over_processes(k));
    let total = fluid + wall + dummy;
    RunSummary {
        case: sim.case.name.clone(),
        scheme: sim.scheme.name.clone(),
        fluid_particles: fluid,
        wall_particles: wall,
        dummy_particles: dummy,
        spacing: sim.l0(),
        steps: sim.step_count,
        time: sim.time,
        end_time: sim.case.time.end,
        wall_seconds: t.wall_seconds,
        particle_steps_per_second: total as f64 * sim.step_count as f64 / t.wall_seconds.max(1e-9),
        mean_ppe_iterations: rec.iterations as f64 / sim.step_count.max(1) as f64,
        solver_fallbacks: sim.solver.fallbacks,
        outflow_removed: sim.outflow_removed,
        breakdown: t.breakdown.as_ref().map(|b| b.to_string()),
        breakdown_time: t.breakdown.as_ref().map(|b| b.time),
        validation,
        stages: sim
            .timers
            .stages()
            .iter()
            .map(|(n, d)| (n.to_string(), d.as_secs_f64()))
            .collect(),
        threads: rayon::current_num_threads(),
        kinetic_energy: (m0.kinetic_energy, m1.kinetic_energy),
        angular_momentum: (m0.angular_momentum, m1.angular_momentum),
        min_pair_distance_l0: rec.min_pair_l0,
        nd_spread_end: m1.nd_spread,
        rms_speed_end: m1.rms_speed,
        probes: rec
            .probe_series
            .iter()
            .zip(&sim.case.probes)
            .map(|(s, p)| (p.name.clone(), s[0].1, s[s.len() - 1].1))
            .collect(),
        probe_noise: rec
            .probe_series
            .iter()
            .zip(&sim.case.probes)
            .map(|(s, p)| (p.name.clone(), noise(s, SMOOTHING_WINDOW)))
            .collect(),
        groups: group_summaries(sim, rec),
    }
}

/// Density of group `k` (kg/m^3): that of its first fluid particle (on the first process
/// that holds one; collective).
fn group_density<const D: usize>(sim: &Simulation<D>, k: usize) -> Option<f64> {
    let p = &sim.particles;
    let own = (0..sim.owned())
        .find(|&i| p.group[i] as usize == k && p.kind[i] == Kind::Fluid)
        .map(|i| p.density[i]);
    if !sim.is_distributed() {
        return own;
    }
    let all = sim.gather_over_processes(&[own.unwrap_or(f64::NAN)]);
    all.into_iter().find(|d| !d.is_nan())
}

/// The groups' early acceleration over the first `early_time` (s) against the unbounded
/// estimate and, where the case is a tank of circles, the tank's ideal-fluid value.
fn groups<const D: usize>(
    sim: &Simulation<D>,
    rec: &Recorder<D>,
    early_time: f64,
) -> Vec<ValidationResult> {
    let (case, g) = (&sim.case, sim.gravity.norm());
    let rho_w = case.phases[0].density;
    let densities: Vec<f64> = (0..rec.group_names.len())
        .map(|k| group_density(sim, k).unwrap_or(rho_w))
        .collect();
    let series = &rec.group_series;
    let Some(r) = early_acceleration(series, early_time, &densities, (rho_w, g), D) else {
        return Vec::new();
    };
    let tank = tank_accelerations(case, &densities, rho_w, g);
    let in_tank = tank.map(|a| early_acceleration_in_tank(&r, &a));
    std::iter::once(r).chain(in_tank).collect()
}

/// The groups' first vertical accelerations (m/s^2) in the ideal fluid of their tank
/// (`analysis::added_mass`), where the case is one: 2D, the first fluid region a rectangle
/// (the tank's water, walls below and beside it, its top the free surface) and every group
/// one circle inside it; `densities` each group's (kg/m^3), `rho_w` the water's.
fn tank_accelerations(case: &Case, densities: &[f64], rho_w: f64, g: f64) -> Option<Vec<f64>> {
    let ShapeSpec::Rectangle { min, max } = &case.fluid.first()?.shape else {
        return None;
    };
    let corner = |v: &[f64]| (v.len() == 2).then(|| [v[0], v[1]]);
    let tank = (corner(min)?, corner(max)?);
    let names = crate::input::setup::group_names(case);
    let mut discs = Vec::with_capacity(names.len());
    for (name, &density) in names.iter().zip(densities) {
        let mut regions = case.fluid.iter().filter(|f| f.group.as_ref() == Some(name));
        let (Some(f), None) = (regions.next(), regions.next()) else {
            return None;
        };
        let ShapeSpec::Circle { center, radius } = &f.shape else {
            return None;
        };
        discs.push(Disc {
            center: corner(center)?,
            radius: *radius,
            density,
        });
    }
    let a = first_accelerations(tank, &discs, rho_w, g)?;
    Some(a.iter().map(|a| a[1]).collect())
}

/// Each group's arrival time (heavier groups at the bottom, lighter ones at the free
/// surface, within the validation distance), strays and centroids.
fn group_summaries<const D: usize>(sim: &Simulation<D>, rec: &Recorder<D>) -> Vec<GroupSummary> {
    let end = group_states(sim, rec.group_names.len());
    let (bottom, surface, distance) = match &sim.case.validation {
        Some(ValidationSpec::Groups {
            bottom,
            surface,
            distance,
            ..
        }) => (Some(*bottom), Some(*surface), *distance),
        _ => (None, None, 0.0),
    };
    let rho_w = sim.case.phases[0].density;
    rec.group_names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let heavy = group_density(sim, k).unwrap_or(rho_w) > rho_w;
            let arrived = |y: f64| match (heavy, bottom, surface) {
                (true, Some(b), _) => y - b <= distance,
                (false, _, Some(s)) => s - y <= distance,
                _ => false,
            };
            GroupSummary {
                name: name.clone(),
                particles: end[k].count,
                arrival_time: rec
                    .group_series
                    .iter()
                    .find(|s| arrived(s.1[k].1))
                    .map(|s| s.0),
                stray_end: end[k].stray,
                centroid: (
                    rec.group_series
                        .first()
                        .map_or((f64::NAN, f64::NAN), |s| s.1[k]),
                    (end[k].centroid[0], end[k].centroid[D - 1]),
                ),
            }
        })
        .collect()
}

/// The index of the probe named `name` (the case was validated to have it).
fn probe_index(case: &Case, name: &str) -> usize {
    case.probes
        .iter()
        .position(|p| p.name == name)
        .expect("validated")
}
