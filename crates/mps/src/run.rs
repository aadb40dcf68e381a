//! The run loop: steps a simulation to its end time and writes everything a user needs:
//! VTU + PVD snapshots, the metrics and per-step CSVs, probe CSVs, validation comparisons,
//! a run summary, and on breakdown the last good state with a breakdown record.

use crate::case::ValidationSpec;
use crate::checkpoint::write_checkpoint;
use crate::diagnostics::{front_position, Metrics, METRICS_HEADER};
use crate::groups::{group_states, pressure_noise, GroupState};
use crate::output::{pvd_bytes, vtu_bytes, write_atomic};
use crate::particles::Kind;
use crate::simulation::{Breakdown, Simulation, StepReport};
use crate::validation::{dam_break_front, window_mean, ValidationResult};
use crate::vector::Vector;
use serde::Serialize;
use std::io;
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

/// Summary of a finished (or broken-down) run, written as `summary.toml`.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// Case name.
    pub case: String,
    /// Scheme preset.
    pub scheme: String,
    /// Fluid particles.
    pub fluid_particles: usize,
    /// Wall particles.
    pub wall_particles: usize,
    /// Dummy particles.
    pub dummy_particles: usize,
    /// Particle spacing (m).
    pub spacing: f64,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time reached (s).
    pub time: f64,
    /// End time asked for (s).
    pub end_time: f64,
    /// Wall-clock time (s).
    pub wall_seconds: f64,
    /// Particle-steps per second (all particles).
    pub particle_steps_per_second: f64,
    /// Mean PPE iterations per step.
    pub mean_ppe_iterations: f64,
    /// Breakdown description, if the run broke down.
    pub breakdown: Option<String>,
    /// Breakdown time (s), if any.
    pub breakdown_time: Option<f64>,
    /// Validation figures.
    pub validation: Vec<ValidationResult>,
    /// Seconds per stage of the step.
    pub stages: Vec<(String, f64)>,
    /// Rayon threads used.
    pub threads: usize,
    /// Kinetic energy at the start and at the end (J, per unit depth in 2D).
    pub kinetic_energy: (f64, f64),
    /// Angular momentum about the origin at the start and at the end (kg m^2/s).
    pub angular_momentum: (f64, f64),
    /// Closest fluid pair over the whole run, in units of l0.
    pub min_pair_distance_l0: f64,
    /// Spread (std) of n/n0 over interior fluid particles at the end.
    pub nd_spread_end: f64,
    /// RMS fluid speed at the end (m/s).
    pub rms_speed_end: f64,
    /// Each probe's pressure at the start and at the end (Pa).
    pub probes: Vec<(String, f64, f64)>,
    /// Fluid groups: arrival times, stray particles, final centroids.
    pub groups: Vec<GroupSummary>,
}

/// Summary of one fluid group over a run.
#[derive(Clone, Debug, Serialize)]
pub struct GroupSummary {
    /// Group label from the case file.
    pub name: String,
    /// Particles in the group.
    pub particles: usize,
    /// Time its centroid came within the validation distance of its target (bottom for a
    /// group heavier than the first phase, free surface for a lighter one), if it did (s).
    pub arrival_time: Option<f64>,
    /// Stray particles (no same-phase neighbour within re_grad) at the end.
    pub stray_end: usize,
    /// Centroid at the start and at the end (m).
    pub centroid: ((f64, f64), (f64, f64)),
}

struct Recorder {
    out: PathBuf,
    write_vtu: bool,
    snapshots: Vec<(f64, String)>,
    metrics: Vec<String>,
    steps: Vec<String>,
    probes: Vec<String>,
    probe_series: Vec<Vec<(f64, f64)>>,
    front: Vec<(f64, f64)>,
    group_names: Vec<String>,
    /// Per step: time and each group's centroid (x, y).
    group_series: Vec<(f64, Vec<(f64, f64)>)>,
    group_rows: Vec<String>,
}

impl Recorder {
    fn snapshot<const D: usize>(&mut self, sim: &Simulation<D>, name: &str) -> io::Result<()> {
        if self.write_vtu {
            write_atomic(
                &self.out.join(name),
                &vtu_bytes(&sim.particles, sim.time, sim.l0()),
            )?;
            self.snapshots.push((sim.time, name.to_string()));
            write_atomic(&self.out.join("particles.pvd"), &pvd_bytes(&self.snapshots))?;
        }
        Ok(())
    }

    fn output<const D: usize>(&mut self, sim: &Simulation<D>) -> io::Result<()> {
        if sim.case.output.checkpoint {
            write_checkpoint(sim, &self.out.join("checkpoint.bin"))?;
        }
        let k = self.metrics.len();
        self.snapshot(sim, &format!("particles_{k:06}.vtu"))?;
        let m = Metrics::measure(sim);
        self.metrics.push(m.csv_row());
        if !self.group_names.is_empty() {
            let states = group_states(sim, self.group_names.len());
            let mut row = format!("{:.9}", sim.time);
            for g in &states {
                row.push_str(&format!(
                    ",{:.6e},{:.6e},{:.6e},{}",
                    g.centroid[0],
                    g.centroid[D - 1],
                    g.velocity.norm(),
                    g.stray
                ));
            }
            let total: usize = states.iter().map(|g| g.count).sum();
            let stray: usize = states.iter().map(|g| g.stray).sum();
            row.push_str(&format!(
                ",{:.6e},{:.6e},{:.6e},{:.6e}",
                stray as f64 / total.max(1) as f64,
                m.momentum_x,
                m.momentum_y,
                pressure_noise(sim)
            ));
            self.group_rows.push(row);
        }
        self.flush_series()
    }

    fn notify(&self, observer: &mut dyn Observer) {
        if let Some((_, f)) = self.snapshots.last() {
            observer.on_snapshot(self.snapshots.len() - 1, &self.out.join(f));
        }
    }

    fn record_groups<const D: usize>(&mut self, sim: &Simulation<D>) {
        if !self.group_names.is_empty() {
            let states = group_states(sim, self.group_names.len());
            self.group_series.push((
                sim.time,
                states
                    .iter()
                    .map(|g| (g.centroid[0], g.centroid[D - 1]))
                    .collect(),
            ));
        }
    }

    fn flush_series(&self) -> io::Result<()> {
        let join = |header: &str, rows: &[String]| {
            let mut s = String::with_capacity(rows.len() * 80 + header.len() + 1);
            s.push_str(header);
            s.push('\n');
            for r in rows {
                s.push_str(r);
                s.push('\n');
            }
            s
        };
        write_atomic(
            &self.out.join("metrics.csv"),
            join(METRICS_HEADER, &self.metrics).as_bytes(),
        )?;
        write_atomic(
            &self.out.join("steps.csv"),
            join(STEPS_HEADER, &self.steps).as_bytes(),
        )?;
        if !self.probe_series.is_empty() {
            write_atomic(
                &self.out.join("probes.csv"),
                self.probes.join("\n").as_bytes(),
            )?;
        }
        if !self.group_names.is_empty() {
            let mut header = String::from("time");
            for n in &self.group_names {
                header.push_str(&format!(",{n}_x,{n}_y,{n}_speed,{n}_stray"));
            }
            header.push_str(",stray_fraction,momentum_x,momentum_y,pressure_noise");
            write_atomic(
                &self.out.join("groups.csv"),
                join(&header, &self.group_rows).as_bytes(),
            )?;
        }
        Ok(())
    }
}

const STEPS_HEADER: &str =
    "step,time,dt,unknowns,ppe_iterations,ppe_residual,ds_active,min_pair_distance_l0,close_pairs,max_speed,collisions";

/// Runs `sim` to its end time, writing into `out` (created if missing).
pub fn run<const D: usize>(
    sim: &mut Simulation<D>,
    out: &Path,
    observer: &mut dyn Observer,
) -> io::Result<RunSummary> {
    std::fs::create_dir_all(out)?;
    let case = sim.case.clone();
    let probes: Vec<(String, Vector<D>)> = case
        .probes
        .iter()
        .map(|p| {
            (
                p.name.clone(),
                Vector::from_slice(&p.position).expect("validated"),
            )
        })
        .collect();
    let mut rec = Recorder {
        out: out.to_path_buf(),
        write_vtu: case.output.vtu,
        snapshots: Vec::new(),
        metrics: Vec::new(),
        steps: Vec::new(),
        probes: vec![std::iter::once("time".to_string())
            .chain(probes.iter().map(|p| p.0.clone()))
            .collect::<Vec<_>>()
            .join(",")],
        probe_series: vec![Vec::new(); probes.len()],
        front: Vec::new(),
        group_names: crate::setup::group_names(&case),
        group_series: Vec::new(),
        group_rows: Vec::new(),
    };
    let sample_probes = |sim: &Simulation<D>, rec: &mut Recorder| {
        let mut row = format!("{:.9}", sim.time);
        for (k, (_, x)) in probes.iter().enumerate() {
            let v = sim.sample_pressure(x).unwrap_or(f64::NAN);
            row.push_str(&format!(",{v:.6e}"));
            rec.probe_series[k].push((sim.time, v));
        }
        rec.probes.push(row);
    };
    let wall_x = match &case.validation {
        Some(ValidationSpec::DamBreak { wall_x, .. }) => Some(*wall_x),
        _ => None,
    };
    if let Some(wx) = wall_x {
        rec.front.push((sim.time, front_position(sim) - wx));
    }
    sample_probes(sim, &mut rec);
    rec.record_groups(sim);
    rec.output(sim)?;
    rec.notify(observer);
    let m0 = Metrics::measure(sim);
    let groups0 = group_states(sim, rec.group_names.len());
    let mut min_pair = f64::INFINITY;

    let start = Instant::now();
    let end = case.time.end;
    let interval = case.output.interval;
    // The next output time after the current one (a restarted run continues the sequence).
    let mut next_out = if interval > 0.0 {
        ((sim.time / interval + 1e-9).floor() + 1.0) * interval
    } else {
        end
    };
    let max_steps = case.time.max_steps.unwrap_or(u64::MAX);
    let mut breakdown: Option<Breakdown> = None;
    let mut iterations_total = 0u64;
    let mut last_output_step = sim.step_count;
    let eps = 1e-9 * end;
    while sim.time < end - eps && sim.step_count < max_steps {
        // Outputs are written at the first step past each output time: shortening steps to
        // land on them would kick PND-type sources (pressure ~ 1/dt^2). Only the last step
        // is shortened to end exactly at the end time.
        match sim.step(end) {
            Ok(r) => {
                iterations_total += r.solve.iterations as u64;
                min_pair = min_pair.min(r.min_pair_distance / sim.l0());
                rec.steps.push(format!(
                    "{},{:.9},{:.6e},{},{},{:.3e},{},{:.6},{},{:.6e},{}",
                    sim.step_count,
                    sim.time,
                    r.dt,
                    r.unknowns,
                    r.solve.iterations,
                    r.solve.residual,
                    r.ds_active,
                    r.min_pair_distance / sim.l0(),
                    r.close_pairs,
                    r.max_speed,
                    r.collisions
                ));
                sample_probes(sim, &mut rec);
                rec.record_groups(sim);
                if let Some(wx) = wall_x {
                    rec.front.push((sim.time, front_position(sim) - wx));
                }
                if sim.time >= next_out - eps && sim.time < end - eps {
                    rec.output(sim)?;
                    // The checkpoint holds no solver set-up: drop it here too, so a run
                    // restarted from this checkpoint continues bit-identically.
                    sim.reset_solver_cache();
                    rec.notify(observer);
                    last_output_step = sim.step_count;
                    while next_out <= sim.time + eps {
                        next_out += interval;
                    }
                }
                observer.on_step(&Progress {
                    time: sim.time,
                    end,
                    step: sim.step_count,
                    report: r,
                    elapsed: start.elapsed().as_secs_f64(),
                });
            }
            Err(b) => {
                observer.on_message(&b.to_string());
                breakdown = Some(b);
                break;
            }
        }
    }
    let wall = start.elapsed().as_secs_f64();
    if let Some(b) = &breakdown {
        rec.snapshot(sim, "breakdown_last_good_state.vtu")?;
        rec.metrics.push(Metrics::measure(sim).csv_row());
        let ids: Vec<String> = b.particles.iter().map(|i| i.to_string()).collect();
        let record = format!(
            "# The run broke down; the last good state is in breakdown_last_good_state.vtu.\n\
             time = {:.9}\nstep = {}\nreason = {:?}\nmessage = {:?}\nparticles = [{}]\n",
            b.time,
            b.step,
            format!("{:?}", b.reason),
            b.to_string(),
            ids.join(", ")
        );
        write_atomic(&out.join("breakdown.toml"), record.as_bytes())?;
    } else if sim.step_count != last_output_step || rec.metrics.len() == 1 {
        rec.output(sim)?;
        rec.notify(observer);
    }
    rec.flush_series()?;

    // Validation against reference data.
    let mut validation = Vec::new();
    match &case.validation {
        Some(ValidationSpec::DamBreak { column_width, .. }) => {
            let (rows, rms) = dam_break_front(&rec.front, *column_width, sim.gravity.norm());
            let mut csv = String::from("T,Z_experiment,Z_simulation,difference\n");
            for (t, ze, zs) in &rows {
                csv.push_str(&format!("{t:.3},{ze:.3},{zs:.4},{:.4}\n", zs - ze));
            }
            write_atomic(&out.join("dam_break_front.csv"), csv.as_bytes())?;
            let mut fcsv = String::from("time,front\n");
            for (t, x) in &rec.front {
                fcsv.push_str(&format!("{t:.9},{x:.6e}\n"));
            }
            write_atomic(&out.join("front.csv"), fcsv.as_bytes())?;
            validation.push(ValidationResult::new(
                "dam_break_front_rms_Z",
                rms,
                0.0,
                rms,
                0.3,
                format!(
                    "RMS of Z_sim - Z_exp over {} Martin & Moyce points, l0 = {} m (L/l0 = {:.1})",
                    rows.len(),
                    sim.l0(),
                    column_width / sim.l0()
                ),
            ));
        }
        Some(ValidationSpec::Hydrostatic {
            depth,
            reference,
            probe,
            window,
        }) => {
            let k = case
                .probes
                .iter()
                .position(|p| &p.name == probe)
                .expect("validated");
            let rho = case.phases[0].density;
            let exact = reference.unwrap_or(rho * sim.gravity.norm() * depth);
            if let Some(mean) = window_mean(&rec.probe_series[k], *window) {
                validation.push(ValidationResult::new(
                    "hydrostatic_bottom_pressure",
                    mean,
                    exact,
                    (mean - exact) / exact,
                    0.05,
                    format!(
                        "mean of probe `{probe}` over the last {window} s against {}",
                        if reference.is_some() {
                            "the given reference"
                        } else {
                            "rho g H"
                        }
                    ),
                ));
            }
        }
        Some(ValidationSpec::Groups { early_time, .. }) => {
            let g = sim.gravity.norm();
            let rho_w = case.phases[0].density;
            let mut sum = 0.0;
            let mut est = 0.0;
            let t_early = rec
                .group_series
                .iter()
                .find(|s| s.0 >= *early_time)
                .map(|s| s.0);
            if let Some(te) = t_early {
                let at = rec.group_series.iter().find(|s| s.0 == te).expect("found");
                let start = &rec.group_series[0];
                for (k, name) in rec.group_names.iter().enumerate() {
                    let rho_g = group_density(sim, k).unwrap_or(rho_w);
                    let _ = name;
                    sum += 2.0 * (at.1[k].1 - start.1[k].1).abs() / (te * te);
                    est += g * (rho_g - rho_w).abs() / (rho_g + rho_w);
                }
                let n = rec.group_names.len().max(1) as f64;
                let (meas, estimate) = (sum / n, est / n);
                validation.push(ValidationResult::new(
                    "group_early_acceleration",
                    meas,
                    estimate,
                    (meas - estimate) / estimate,
                    0.3,
                    format!(
                        "mean |2 dy / t^2| of the group centroids over the first {te:.3} s against g |rho_g - rho_w| / (rho_g + rho_w)"
                    ),
                ));
            }
        }
        None => {}
    }
    let groups = group_summaries(sim, &rec, &groups0);
    let total = sim.particles.len();
    let m1 = Metrics::measure(sim);
    let summary = RunSummary {
        case: case.name.clone(),
        scheme: sim.scheme.name.clone(),
        fluid_particles: sim.particles.count(Kind::Fluid),
        wall_particles: sim.particles.count(Kind::Wall),
        dummy_particles: sim.particles.count(Kind::Dummy),
        spacing: sim.l0(),
        steps: sim.step_count,
        time: sim.time,
        end_time: end,
        wall_seconds: wall,
        particle_steps_per_second: total as f64 * sim.step_count as f64 / wall.max(1e-9),
        mean_ppe_iterations: iterations_total as f64 / sim.step_count.max(1) as f64,
        breakdown: breakdown.as_ref().map(|b| b.to_string()),
        breakdown_time: breakdown.as_ref().map(|b| b.time),
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
        min_pair_distance_l0: min_pair,
        nd_spread_end: m1.nd_spread,
        rms_speed_end: m1.rms_speed,
        probes: probes
            .iter()
            .enumerate()
            .map(|(k, (name, _))| {
                let s = &rec.probe_series[k];
                (name.clone(), s[0].1, s[s.len() - 1].1)
            })
            .collect(),
        groups,
    };
    let text = toml::to_string(&summary).map_err(|e| io::Error::other(e.to_string()))?;
    write_atomic(&out.join("summary.toml"), text.as_bytes())?;
    Ok(summary)
}

/// Density of group `k` (kg/m^3): that of its first fluid particle.
fn group_density<const D: usize>(sim: &Simulation<D>, k: usize) -> Option<f64> {
    let p = &sim.particles;
    (0..p.len())
        .find(|&i| p.group[i] as usize == k && p.kind[i] == Kind::Fluid)
        .map(|i| p.density[i])
}

fn group_summaries<const D: usize>(
    sim: &Simulation<D>,
    rec: &Recorder,
    start: &[GroupState<D>],
) -> Vec<GroupSummary> {
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
                    (start[k].centroid[0], start[k].centroid[D - 1]),
                    (end[k].centroid[0], end[k].centroid[D - 1]),
                ),
            }
        })
        .collect()
}
