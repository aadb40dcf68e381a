//! The recorder: one writer per output file of a run, and the series kept in memory for the
//! validations at the end.
//!
//! In a distributed run every process records alike (each measurement a sum, maximum or
//! gather over the processes' own particles), the first one writes the shared files, and
//! each process writes its own piece of every snapshot and checkpoint.

use crate::analysis::exact::{second_moments, semi_axes_from};
use crate::analysis::groups::{group_states, pressure_noise};
use crate::analysis::metrics::{front_position, Metrics};
use crate::analysis::rim_mode::RimMode;
use crate::error::{Error, Result};
use crate::input::case::ValidationSpec;
use crate::io::atomic::{is_temporary, remove_stale_temporaries};
use crate::io::checkpoint::{agree, write_checkpoint};
use crate::io::series::{read_records, Cell, Records, Series};
use crate::io::vtu::{pvd_bytes, pvtu_bytes, pvtu_pieces, vtu_bytes};
use crate::io::write_atomic;
use crate::particles::Vector;
use crate::simulation::{Simulation, StepReport};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// True for the name of a file or folder a run writes into its folder (and the figures and
/// report made from it): what `--force` may clear before a new run there.
pub fn is_run_file(name: &str) -> bool {
    const FILES: [&str; 18] = [
        "particles.pvd",
        "group_tracks.csv",
        "drop_axes.csv",
        "rim_mode.csv",
        "metrics.csv",
        "steps.csv",
        "probes.csv",
        "probes_smoothed.csv",
        "groups.csv",
        "front.csv",
        "dam_break_front.csv",
        "reference_comparison.csv",
        "summary.toml",
        "breakdown.toml",
        "breakdown_last_good_state.vtu",
        "checkpoint.bin",
        "case.toml",
        "report.html",
    ];
    let particles = name.ends_with(".vtu") || name.ends_with(".pvtu");
    FILES.contains(&name)
        || name == "figures"
        || (name.starts_with("particles_") && particles)
        || (name.starts_with("breakdown_last_good_state") && particles)
        || (name.starts_with("checkpoint_") && name.ends_with(".bin"))
        || is_temporary(name)
}

/// Prepares `dir` for a run: created if missing; a folder holding files refuses unless
/// `force`, which clears the files a run writes (others stay). Returns the files cleared.
pub fn prepare_folder(dir: &Path, force: bool) -> Result<usize> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
    let entries: Vec<std::fs::DirEntry> = std::fs::read_dir(dir)
        .map_err(|e| crate::error::Error::io(dir, e))?
        .flatten()
        .collect();
    if entries.is_empty() {
        return Ok(0);
    }
    if !force {
        return Err(crate::error::Error::Format {
            path: dir.to_path_buf(),
            message: "already holds files; use --force to replace the run there".into(),
        });
    }
    let mut cleared = 0;
    for e in entries {
        let name = e.file_name().to_string_lossy().to_string();
        if !is_run_file(&name) {
            continue;
        }
        let path = e.path();
        let done = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        done.map_err(|err| crate::error::Error::io(&path, err))?;
        cleared += 1;
    }
    Ok(cleared)
}

/// One row of `steps.csv`.
#[derive(Serialize)]
struct StepRow {
    step: u64,
    time: f64,
    dt: f64,
    unknowns: usize,
    ppe_iterations: usize,
    ppe_residual: f64,
    solver_fallback: u8,
    ds_active: u64,
    min_pair_distance_l0: f64,
    close_pairs: u64,
    max_speed: f64,
    collisions: u64,
    removed: u64,
}

/// The writers of one run folder.
pub struct Recorder<const D: usize> {
    out: PathBuf,
    /// This process writes the run's shared files (the only process, or the first).
    first: bool,
    write_vtu: bool,
    /// (time, file) of every snapshot written (the `.pvd` index).
    snapshots: Vec<(f64, String)>,
    /// Outputs written (the index of the next snapshot).
    pub outputs: usize,
    metrics: Series,
    steps: Series,
    probes: Option<Series>,
    groups: Option<Series>,
    front: Option<Series>,
    probe_points: Vec<(String, Vector<D>)>,
    /// Each probe's pressure over time: `(t, p)` (s, Pa).
    pub probe_series: Vec<Vec<(f64, f64)>>,
    /// The dam-break front over time, `(t, x - wall_x)` (s, m), when the case measures it.
    pub front_series: Vec<(f64, f64)>,
    front_wall: Option<f64>,
    /// Names of the fluid groups.
    pub group_names: Vec<String>,
    /// Per step: time and each group's centroid (x, y).
    pub group_series: Vec<(f64, Vec<(f64, f64)>)>,
    /// Per output, for an elliptic-drop validation: time and the semi-axes (s, m, m).
    pub axes_series: Vec<(f64, f64, f64)>,
    axes_center: Option<Vector<D>>,
    tracks: Option<Series>,
    axes: Option<Series>,
    /// Per output, for a surface-mode validation: time and the mode's amplitude (s, m).
    pub rim_series: Vec<(f64, f64)>,
    /// The rim whose mode a surface-mode validation measures.
    pub rim: Option<RimMode<D>>,
    rim_csv: Option<Series>,
    /// The metrics of the first output (the start of the whole run).
    pub first_metrics: Option<Metrics>,
    /// PPE iterations summed over the steps so far (a resumed run's earlier ones included).
    pub iterations: u64,
    /// Closest pair over the steps so far (units of l0).
    pub min_pair_l0: f64,
}

/// The time column's name and whether rows are kept by step (`true`) or time.
const CARRIED: [(&str, bool); 8] = [
    ("metrics.csv", true),
    ("steps.csv", true),
    ("probes.csv", false),
    ("front.csv", false),
    ("groups.csv", false),
    ("group_tracks.csv", false),
    ("drop_axes.csv", false),
    ("rim_mode.csv", false),
];

/// What a resumed run carries over from the folder of its checkpoint: each series' kept rows
/// and the snapshots up to the checkpoint.
struct Earlier {
    series: Vec<(&'static str, Records)>,
    snapshots: Vec<(f64, String)>,
    from: PathBuf,
}

impl Earlier {
    /// Reads the series and the snapshot index of `from` up to `step` and `time` (s).
    fn read(from: &Path, step: u64, time: f64) -> Result<Earlier> {
        let mut series = Vec::new();
        for (file, by_step) in CARRIED {
            let Some(mut records) = read_records(&from.join(file))? else {
                continue;
            };
            let key = if by_step { "step" } else { "time" };
            let Some(k) = records.header.iter().position(|h| h == key) else {
                continue;
            };
            let width = records.header.len();
            records.rows.retain(|r| {
                if r.len() != width {
                    return false;
                }
                let v: f64 = r.get(k).and_then(|x| x.parse().ok()).unwrap_or(f64::NAN);
                if by_step {
                    v <= step as f64
                } else {
                    v <= time
                }
            });
            series.push((file, records));
        }
        let snapshots = std::fs::read_to_string(from.join("particles.pvd"))
            .map(|t| crate::io::vtu::read_pvd(&t))
            .unwrap_or_default()
            .into_iter()
            // The index holds times rounded to 1e-9 s.
            .filter(|s| s.0 <= time + 1e-9 && !s.1.starts_with("breakdown"))
            .collect();
        Ok(Earlier {
            series,
            snapshots,
            from: from.to_path_buf(),
        })
    }

    /// The kept header and rows of `file` (empty when it was not there).
    fn records(&self, file: &str) -> Option<&Records> {
        self.series.iter().find(|r| r.0 == file).map(|r| &r.1)
    }

    fn rows(&self, file: &str) -> &[Vec<String>] {
        self.records(file).map_or(&[], |r| r.rows.as_slice())
    }

    /// The values of column `name` of `file`'s kept rows.
    fn column(&self, file: &str, name: &str) -> Vec<f64> {
        let Some(r) = self.records(file) else {
            return Vec::new();
        };
        let Some(k) = r.header.iter().position(|h| h == name) else {
            return Vec::new();
        };
        r.rows
            .iter()
            .map(|r| r.get(k).and_then(|x| x.parse().ok()).unwrap_or(f64::NAN))
            .collect()
    }

    /// The first kept metrics row, read back as [`Metrics`].
    fn first_metrics(&self) -> Option<Metrics> {
        let r = self.records("metrics.csv")?;
        let mut w = csv::WriterBuilder::new().from_writer(Vec::new());
        w.write_record(&r.header).ok()?;
        w.write_record(r.rows.first()?).ok()?;
        let bytes = w.into_inner().ok()?;
        csv::Reader::from_reader(bytes.as_slice())
            .deserialize()
            .next()?
            .ok()
    }
}

/// The rim a surface-mode validation measures, taken from the case's particles at `t = 0`
/// (built anew from the case, so that a resumed run measures the same particles).
fn rim_of<const D: usize>(sim: &Simulation<D>) -> Result<Option<RimMode<D>>> {
    let Some(ValidationSpec::SurfaceMode {
        center,
        radius,
        mode,
        ..
    }) = &sim.case.validation
    else {
        return Ok(None);
    };
    let initial = crate::input::setup::build_particles::<D>(&sim.case, "")
        .map_err(crate::error::Error::from)?;
    let center = Vector::from_slice(center).expect("validated");
    Ok(Some(RimMode::new(
        &initial,
        center,
        *radius,
        sim.l0(),
        *mode,
    )))
}

/// A series `file` in `out` with a time column and `columns`, if there are any (written
/// when `write`).
fn series_if(
    write: bool,
    out: &Path,
    file: &str,
    columns: Option<Vec<String>>,
) -> Result<Option<Series>> {
    match columns {
        Some(cols) => {
            let header: Vec<String> = std::iter::once("time".to_string()).chain(cols).collect();
            Ok(Some(Series::create_if(
                write,
                &out.join(file),
                Some(&header),
            )?))
        }
        None => Ok(None),
    }
}

/// True when run-folder file `name` belongs to snapshot entry `kept` (the file itself, or a
/// piece of it when it is a `.pvtu` index).
fn belongs_to(name: &str, kept: &str) -> bool {
    name == kept
        || kept
            .strip_suffix(".pvtu")
            .is_some_and(|stem| name.starts_with(&format!("{stem}_p")) && name.ends_with(".vtu"))
}

/// The numbers of a row of text fields (NaN where not a number).
fn numbers(r: &[String]) -> Vec<f64> {
    r.iter().map(|x| x.parse().unwrap_or(f64::NAN)).collect()
}

/// The earlier run's snapshots up to its checkpoint in `out`: the ones it wrote after the
/// checkpoint go when `out` is its folder, the kept ones are copied when it is another.
fn carry_snapshots(earlier: &Earlier, out: &Path) -> Result<()> {
    let same = out.canonicalize().ok() == earlier.from.canonicalize().ok();
    let io = |p: &Path, e| crate::error::Error::io(p, e);
    if same {
        for e in std::fs::read_dir(out).map_err(|e| io(out, e))?.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            let kept = earlier.snapshots.iter().any(|s| belongs_to(&name, &s.1));
            let snapshot = name.ends_with(".vtu") || name.ends_with(".pvtu");
            if snapshot && is_run_file(&name) && !kept {
                std::fs::remove_file(e.path()).map_err(|x| io(&e.path(), x))?;
            }
        }
        return Ok(());
    }
    for (_, file) in &earlier.snapshots {
        let src = earlier.from.join(file);
        let index = std::fs::read(&src).map_err(|e| io(&src, e))?;
        let pieces = pvtu_pieces(&index).unwrap_or_default();
        for f in pieces.iter().chain(std::iter::once(file)) {
            if f.contains(['/', '\\']) {
                continue;
            }
            let (src, dst) = (earlier.from.join(f), out.join(f));
            std::fs::copy(&src, &dst).map_err(|e| io(&src, e))?;
        }
    }
    Ok(())
}

impl<const D: usize> Recorder<D> {
    /// Opens the writers of a run of `sim` into folder `out`; `front_wall` is the wall x (m)
    /// the dam-break front is measured from, when the case measures it.
    pub fn create(sim: &Simulation<D>, out: &Path, front_wall: Option<f64>) -> Result<Self> {
        let case = &sim.case;
        let first = sim.is_first_process();
        let probe_points: Vec<(String, Vector<D>)> = case
            .probes
            .iter()
            .map(|p| {
                (
                    p.name.clone(),
                    Vector::from_slice(&p.position).expect("validated"),
                )
            })
            .collect();
        let probes = series_if(
            first,
            out,
            "probes.csv",
            (!probe_points.is_empty()).then(|| probe_points.iter().map(|p| p.0.clone()).collect()),
        )?;
        let group_names = crate::input::setup::group_names(case);
        let group_columns = |fields: &[&str]| -> Option<Vec<String>> {
            (!group_names.is_empty()).then(|| {
                group_names
                    .iter()
                    .flat_map(|n| fields.iter().map(move |c| format!("{n}_{c}")))
                    .collect()
            })
        };
        let groups = group_columns(&["x", "y", "speed", "stray"]).map(|mut cols| {
            let totals = [
                "stray_fraction",
                "momentum_x",
                "momentum_y",
                "pressure_noise",
            ];
            cols.extend(totals.map(String::from));
            cols
        });
        let groups = series_if(first, out, "groups.csv", groups)?;
        let tracks = series_if(first, out, "group_tracks.csv", group_columns(&["x", "y"]))?;
        let drop = matches!(case.validation, Some(ValidationSpec::EllipticDrop { .. }));
        let axes = series_if(
            first,
            out,
            "drop_axes.csv",
            drop.then(|| vec!["a".into(), "b".into()]),
        )?;
        let rim = rim_of(sim)?;
        let rim_csv = series_if(
            first,
            out,
            "rim_mode.csv",
            rim.as_ref().map(|_| vec!["amplitude".into()]),
        )?;
        let front = series_if(
            first,
            out,
            "front.csv",
            front_wall.map(|_| vec!["front".into()]),
        )?;
        Ok(Recorder {
            out: out.to_path_buf(),
            first,
            write_vtu: case.output.vtu,
            snapshots: Vec::new(),
            outputs: 0,
            metrics: Series::create_if(first, &out.join("metrics.csv"), None)?,
            steps: Series::create_if(first, &out.join("steps.csv"), None)?,
            probes,
            groups,
            front,
            probe_series: vec![Vec::new(); probe_points.len()],
            probe_points,
            front_series: Vec::new(),
            front_wall,
            group_names,
            group_series: Vec::new(),
            axes_series: Vec::new(),
            axes_center: match &case.validation {
                Some(ValidationSpec::EllipticDrop { center, .. }) => Vector::from_slice(center),
                _ => None,
            },
            tracks,
            axes,
            rim_series: Vec::new(),
            rim,
            rim_csv,
            first_metrics: None,
            iterations: 0,
            min_pair_l0: f64::INFINITY,
        })
    }

    /// Opens the writers of a run resumed from a checkpoint in folder `from` at the state of
    /// `sim`: every series and snapshot of the earlier run up to the checkpoint is carried
    /// into `out` (which may be `from` itself), so the folder ends as if the run had not been
    /// interrupted.
    pub fn resume(
        sim: &Simulation<D>,
        out: &Path,
        front_wall: Option<f64>,
        from: &Path,
    ) -> Result<Self> {
        let earlier = Earlier::read(from, sim.step_count, sim.time);
        // Every process has read the earlier files before the first rewrites them.
        let read = earlier.as_ref().map(|_| ()).map_err(|e| Error::Format {
            path: from.to_path_buf(),
            message: e.to_string(),
        });
        let status = agree(sim, read);
        let earlier = earlier?;
        status?;
        let carried = if sim.is_first_process() {
            // A run killed while writing left its temporary (every process waits here).
            remove_stale_temporaries(out);
            carry_snapshots(&earlier, out)
        } else {
            Ok(())
        };
        agree(sim, carried)?;
        let mut rec = Recorder::create(sim, out, front_wall)?;
        rec.carry(&earlier)?;
        if !earlier.snapshots.is_empty() {
            rec.snapshots = earlier.snapshots;
            if rec.first {
                write_atomic(&out.join("particles.pvd"), &pvd_bytes(&rec.snapshots))?;
            }
        }
        rec.flush()?;
        Ok(rec)
    }

    /// Writes the earlier run's rows and reloads the in-memory series from them.
    fn carry(&mut self, e: &Earlier) -> Result<()> {
        let targets: [(&str, Option<&mut Series>); 8] = [
            ("metrics.csv", Some(&mut self.metrics)),
            ("steps.csv", Some(&mut self.steps)),
            ("probes.csv", self.probes.as_mut()),
            ("front.csv", self.front.as_mut()),
            ("groups.csv", self.groups.as_mut()),
            ("group_tracks.csv", self.tracks.as_mut()),
            ("drop_axes.csv", self.axes.as_mut()),
            ("rim_mode.csv", self.rim_csv.as_mut()),
        ];
        for (file, series) in targets {
            if let Some(series) = series {
                if let Some(r) = e.records(file).filter(|r| !r.rows.is_empty()) {
                    series.carry(&r.header, &r.rows)?;
                }
            }
        }
        self.outputs = e.rows("metrics.csv").len();
        self.first_metrics = e.first_metrics();
        for it in e.column("steps.csv", "ppe_iterations") {
            self.iterations += it as u64;
        }
        for m in e.column("steps.csv", "min_pair_distance_l0") {
            self.min_pair_l0 = self.min_pair_l0.min(m);
        }
        for r in e.rows("probes.csv").iter().map(|r| numbers(r)) {
            for (k, s) in self.probe_series.iter_mut().enumerate() {
                s.push((r[0], r.get(k + 1).copied().unwrap_or(f64::NAN)));
            }
        }
        for r in e.rows("front.csv").iter().map(|r| numbers(r)) {
            self.front_series.push((r[0], r[1]));
        }
        for r in e.rows("group_tracks.csv").iter().map(|r| numbers(r)) {
            let c = r[1..].chunks_exact(2).map(|c| (c[0], c[1])).collect();
            self.group_series.push((r[0], c));
        }
        for r in e.rows("drop_axes.csv").iter().map(|r| numbers(r)) {
            self.axes_series.push((r[0], r[1], r[2]));
        }
        for r in e.rows("rim_mode.csv").iter().map(|r| numbers(r)) {
            self.rim_series.push((r[0], r[1]));
        }
        Ok(())
    }

    /// Writes a VTU snapshot of the current state as `name` and adds it to the `.pvd` index;
    /// returns its path when one was written. On several processes each writes its own
    /// particles as `STEM_pRANK.vtu` and the first the index `STEM.pvtu` naming them.
    pub fn snapshot(&mut self, sim: &Simulation<D>, name: &str) -> Result<Option<PathBuf>> {
        if !self.write_vtu {
            return Ok(None);
        }
        let entry = if sim.is_distributed() {
            let stem = name.strip_suffix(".vtu").unwrap_or(name);
            let (rank, size) = sim.process();
            let piece = |r: usize| format!("{stem}_p{r}.vtu");
            let own = sim.particles.first(sim.owned());
            let bytes = vtu_bytes(&own, sim.time, sim.l0());
            agree(sim, write_atomic(&self.out.join(piece(rank)), &bytes))?;
            let index = format!("{stem}.pvtu");
            let pieces: Vec<String> = (0..size).map(piece).collect();
            let written = match self.first {
                true => write_atomic(&self.out.join(&index), &pvtu_bytes::<D>(&pieces)),
                false => Ok(()),
            };
            agree(sim, written)?;
            index
        } else {
            write_atomic(
                &self.out.join(name),
                &vtu_bytes(&sim.particles, sim.time, sim.l0()),
            )?;
            name.to_string()
        };
        self.snapshots.push((sim.time, entry.clone()));
        let indexed = match self.first {
            true => write_atomic(&self.out.join("particles.pvd"), &pvd_bytes(&self.snapshots)),
            false => Ok(()),
        };
        agree(sim, indexed)?;
        Ok(Some(self.out.join(entry)))
    }

    /// An output: snapshot, metrics and group rows, every series flushed, then the
    /// checkpoint (last, so that a run killed at any moment leaves a checkpoint whose rows
    /// are all on disk: a resumed run keeps the rows up to its checkpoint and drops the
    /// rest). Returns the snapshot's path when one was written.
    pub fn output(&mut self, sim: &Simulation<D>) -> Result<Option<PathBuf>> {
        let path = self.snapshot(sim, &format!("particles_{:06}.vtu", self.outputs))?;
        self.outputs += 1;
        let m = Metrics::measure(sim);
        self.metrics.push(&m)?;
        if self.first_metrics.is_none() {
            self.first_metrics = Some(m.clone());
        }
        if let Some(c) = self.axes_center {
            let mut moments = second_moments(&sim.particles, sim.owned(), c);
            sim.sum_over_processes(&mut moments);
            let (a, b) = semi_axes_from(moments);
            self.axes_series.push((sim.time, a, b));
            if let Some(series) = &mut self.axes {
                series.push(&[sim.time, a, b])?;
            }
        }
        if let Some(rim) = &self.rim {
            let a = rim.amplitude_in(sim);
            self.rim_series.push((sim.time, a));
            if let Some(series) = &mut self.rim_csv {
                series.push(&[sim.time, a])?;
            }
        }
        if let Some(series) = &mut self.groups {
            let states = group_states(sim, self.group_names.len());
            let mut row = vec![Cell::Real(sim.time)];
            for g in &states {
                row.extend([
                    Cell::Real(g.centroid[0]),
                    Cell::Real(g.centroid[D - 1]),
                    Cell::Real(g.velocity.norm()),
                    Cell::Count(g.stray as u64),
                ]);
            }
            let total: usize = states.iter().map(|g| g.count).sum();
            let stray: usize = states.iter().map(|g| g.stray).sum();
            row.extend([
                Cell::Real(stray as f64 / total.max(1) as f64),
                Cell::Real(m.momentum_x),
                Cell::Real(m.momentum_y),
                Cell::Real(pressure_noise(sim)),
            ]);
            series.push(&row)?;
        }
        self.flush()?;
        if sim.case.output.checkpoint {
            write_checkpoint(sim, &self.out.join("checkpoint.bin"))?;
        }
        Ok(path)
    }

    /// The metrics row of a state that is not an output (the last good state of a
    /// breakdown).
    pub fn metrics_row(&mut self, sim: &Simulation<D>) -> Result<()> {
        self.metrics.push(&Metrics::measure(sim))
    }

    /// What is sampled at every step (and at the start): probes, the front, group centroids.
    pub fn sample(&mut self, sim: &Simulation<D>) -> Result<()> {
        if let Some(series) = &mut self.probes {
            let mut row = vec![sim.time];
            for (k, (_, x)) in self.probe_points.iter().enumerate() {
                let v = sim.sample_pressure(x).unwrap_or(f64::NAN);
                row.push(v);
                self.probe_series[k].push((sim.time, v));
            }
            series.push(&row)?;
        }
        if !self.group_names.is_empty() {
            let states = group_states(sim, self.group_names.len());
            let centroids: Vec<(f64, f64)> = states
                .iter()
                .map(|g| (g.centroid[0], g.centroid[D - 1]))
                .collect();
            if let Some(series) = &mut self.tracks {
                let row: Vec<f64> = std::iter::once(sim.time)
                    .chain(centroids.iter().flat_map(|c| [c.0, c.1]))
                    .collect();
                series.push(&row)?;
            }
            self.group_series.push((sim.time, centroids));
        }
        if let (Some(series), Some(wx)) = (&mut self.front, self.front_wall) {
            let x = front_position(sim) - wx;
            self.front_series.push((sim.time, x));
            series.push(&[sim.time, x])?;
        }
        Ok(())
    }

    /// The row of one step in `steps.csv` (and the run's totals).
    pub fn step(&mut self, sim: &Simulation<D>, r: &StepReport) -> Result<()> {
        self.iterations += r.solve.iterations as u64;
        self.min_pair_l0 = self.min_pair_l0.min(r.min_pair_distance / sim.l0());
        self.steps.push(&StepRow {
            step: sim.step_count,
            time: sim.time,
            dt: r.dt,
            unknowns: r.unknowns,
            ppe_iterations: r.solve.iterations,
            ppe_residual: r.solve.residual,
            solver_fallback: r.solver_fallback as u8,
            ds_active: r.ds_active,
            min_pair_distance_l0: r.min_pair_distance / sim.l0(),
            close_pairs: r.close_pairs,
            max_speed: r.max_speed,
            collisions: r.collisions,
            removed: r.removed,
        })
    }

    /// True when this process writes the run's shared files (the only process, or the first
    /// of a distributed run).
    pub fn writes_shared_files(&self) -> bool {
        self.first
    }

    /// The run folder.
    pub fn out_dir(&self) -> &Path {
        &self.out
    }

    /// Writes everything appended so far.
    pub fn flush(&mut self) -> Result<()> {
        self.metrics.flush()?;
        self.steps.flush()?;
        for s in [
            &mut self.probes,
            &mut self.groups,
            &mut self.front,
            &mut self.tracks,
            &mut self.axes,
            &mut self.rim_csv,
        ]
        .into_iter()
        .flatten()
        {
            s.flush()?;
        }
        Ok(())
    }
}
