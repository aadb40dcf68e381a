//! Checkpoints: the complete particle state and clock of a run, serialised with serde in
//! postcard's binary format behind a magic tag, written atomically at every output step, so a
//! long run can be restarted, or extended to a later end time, from its last checkpoint.
//!
//! A distributed run writes one piece per process (`checkpoint_STEP_pRANK.bin`, the
//! process's own particles as packed rows) and the first process the index `checkpoint.bin`
//! naming them with the pieces' layout; reading it assembles the whole state, so it restarts
//! on any number of processes (bit for bit on as many, which cut the same pieces).

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use crate::input::Case;
use crate::particles::{Particles, NONE, NO_GROUP};
use crate::simulation::Simulation;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file's first bytes: format name and version.
const MAGIC: &[u8; 8] = b"MPSCKPT5";

/// The first bytes of a distributed run's piece.
const PIECE_MAGIC: &[u8; 8] = b"MPSPIEC1";

/// What a checkpoint holds.
#[derive(Serialize, Deserialize)]
struct State<const D: usize> {
    /// Space dimension.
    dimension: u32,
    /// [`crate::input::Case::fingerprint`] of the case that wrote it.
    case: u64,
    /// Simulated time (s).
    time: f64,
    /// Steps taken.
    step: u64,
    /// Fluid particles removed by outflow so far.
    removed: u64,
    /// Every particle field (none when the particles are in `pieces`).
    particles: Particles<D>,
    /// A distributed run's pieces, file names beside this one, in rank order.
    pieces: Vec<String>,
    /// A distributed run's layout of pieces (`Domain::layout`).
    layout: Vec<u64>,
}

/// One process's piece of a distributed run's checkpoint.
#[derive(Serialize, Deserialize)]
struct Piece {
    /// [`crate::input::Case::fingerprint`] of the case that wrote it.
    case: u64,
    /// Steps taken.
    step: u64,
    /// Numbers per particle (`Particles::packed_width`).
    width: u64,
    /// The process's own particles, packed.
    rows: Vec<f64>,
}

/// Serialises the state of `sim` (time, step, every particle field).
pub fn checkpoint_bytes<const D: usize>(sim: &Simulation<D>) -> Vec<u8> {
    let state = State {
        dimension: D as u32,
        case: sim.case.fingerprint(),
        time: sim.time,
        step: sim.step_count,
        removed: sim.outflow_removed,
        particles: sim.particles.clone(),
        pieces: Vec::new(),
        layout: Vec::new(),
    };
    let mut out = MAGIC.to_vec();
    out.extend(postcard::to_allocvec(&state).expect("particles serialise"));
    out
}

/// Writes the checkpoint of `sim` to `path` atomically; on several processes, each writes
/// its piece beside it, then the first the index at `path`, then each removes its older
/// pieces (collective: an error on any process is every process's).
pub fn write_checkpoint<const D: usize>(sim: &Simulation<D>, path: &Path) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    if !sim.is_distributed() {
        write_atomic(path, &checkpoint_bytes(sim))?;
        // A distributed checkpoint's pieces restarted from here are no longer named.
        remove_pieces(dir, "_p", None);
        return Ok(());
    }
    let (rank, size) = sim.process();
    let name = |r: usize| format!("checkpoint_{}_p{r}.bin", sim.step_count);
    let mine = name(rank);
    let mut rows = Vec::with_capacity(sim.owned() * Particles::<D>::packed_width());
    for i in 0..sim.owned() {
        sim.particles.pack(i, &mut rows);
    }
    let piece = Piece {
        case: sim.case.fingerprint(),
        step: sim.step_count,
        width: Particles::<D>::packed_width() as u64,
        rows,
    };
    let mut bytes = PIECE_MAGIC.to_vec();
    bytes.extend(postcard::to_allocvec(&piece).expect("numbers serialise"));
    agree(sim, write_atomic(&dir.join(&mine), &bytes))?;
    let index = if sim.is_first_process() {
        let state = State::<D> {
            dimension: D as u32,
            case: sim.case.fingerprint(),
            time: sim.time,
            step: sim.step_count,
            removed: sim.outflow_removed,
            particles: Particles::default(),
            pieces: (0..size).map(name).collect(),
            layout: sim.layout(),
        };
        let mut out = MAGIC.to_vec();
        out.extend(postcard::to_allocvec(&state).expect("a state serialises"));
        write_atomic(path, &out)
    } else {
        Ok(())
    };
    agree(sim, index)?;
    // The index names the new pieces now: this process's older ones go.
    remove_pieces(dir, &format!("_p{rank}."), Some(&mine));
    Ok(())
}

/// Removes the checkpoint pieces `checkpoint_STEP_pRANK.bin` in `dir` whose name holds
/// `mark`, but `keep` (best effort: a piece left behind is named by no index).
fn remove_pieces(dir: &Path, mark: &str, keep: Option<&str>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let f = e.file_name().to_string_lossy().to_string();
        let piece = f.starts_with("checkpoint_") && f.ends_with(".bin") && f.contains(mark);
        if piece && Some(f.as_str()) != keep {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// `r` on this process, and an error on every process when any process's failed (so that
/// none goes on alone into the next collective step).
pub fn agree<const D: usize>(sim: &Simulation<D>, r: Result<()>) -> Result<()> {
    let mut failed = [r.is_err() as u8 as f64];
    sim.sum_over_processes(&mut failed);
    match r {
        Err(e) => Err(e),
        Ok(()) if failed[0] > 0.0 => Err(Error::Format {
            path: std::path::PathBuf::from("."),
            message: "another process of the run could not write its files".into(),
        }),
        Ok(()) => Ok(()),
    }
}

/// The particles of a distributed run's checkpoint: its pieces (beside `path`) read and
/// joined, in id order.
fn join_pieces<const D: usize>(state: &State<D>, path: &Path) -> Result<Particles<D>> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut p = Particles::<D>::default();
    for name in &state.pieces {
        let at = dir.join(name);
        let bad = |message: String| Error::Checkpoint {
            path: at.clone(),
            message,
        };
        if name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(bad("not a piece name beside the checkpoint".into()));
        }
        let bytes = std::fs::read(&at).map_err(|e| Error::io(&at, e))?;
        let piece: Piece = bytes
            .strip_prefix(PIECE_MAGIC.as_slice())
            .and_then(|b| postcard::from_bytes(b).ok())
            .ok_or_else(|| bad("not a piece of an MPS checkpoint".into()))?;
        if piece.case != state.case || piece.step != state.step {
            return Err(bad(format!(
                "a piece of step {} of another run, the checkpoint is of step {}",
                piece.step, state.step
            )));
        }
        let width = Particles::<D>::packed_width();
        if piece.width != width as u64 || !piece.rows.len().is_multiple_of(width) {
            return Err(bad("its rows are not this version's particles".into()));
        }
        for row in piece.rows.chunks_exact(width) {
            p.push_packed(row)
                .ok_or_else(|| bad("a particle row out of range".into()))?;
        }
    }
    p.ids_to_indices();
    let mut order: Vec<u32> = (0..p.len() as u32).collect();
    order.sort_unstable_by_key(|&k| p.id[k as usize]);
    p.permute(&order);
    Ok(p)
}

/// Checks that every index in `p` points where it may: phases into the case's phase table,
/// backing walls to particles, groups to the case's groups.
fn check_indices<const D: usize>(
    p: &Particles<D>,
    phases: usize,
    groups: usize,
) -> Result<(), String> {
    if let Some(f) = p.inconsistent_field() {
        return Err(format!("field `{f}` has the wrong length"));
    }
    let n = p.len();
    for i in 0..n {
        if p.phase[i] as usize >= phases {
            return Err(format!("phase {} of particle {i} out of range", p.phase[i]));
        }
        if p.backing_wall[i] != NONE && p.backing_wall[i] as usize >= n {
            return Err(format!("backing wall of particle {i} out of range"));
        }
        if p.group[i] != NO_GROUP && p.group[i] as usize >= groups {
            return Err(format!("group {} of particle {i} out of range", p.group[i]));
        }
    }
    Ok(())
}

/// The state in checkpoint bytes read from `path`: tag, format and dimension checked.
fn decode<const D: usize>(bytes: &[u8], path: &Path) -> Result<State<D>> {
    let bad = |message: String| Error::Checkpoint {
        path: path.to_path_buf(),
        message,
    };
    let payload = bytes
        .strip_prefix(MAGIC.as_slice())
        .ok_or_else(|| bad("not an MPS checkpoint (or one from an older version)".into()))?;
    let state: State<D> = postcard::from_bytes(payload)
        .map_err(|e| bad(format!("cannot read the checkpoint: {e}")))?;
    if state.dimension as usize != D {
        return Err(bad(format!(
            "checkpoint is {}D, the case is {D}D",
            state.dimension
        )));
    }
    let mut state = state;
    if !state.pieces.is_empty() {
        state.particles = join_pieces(&state, path)?;
    }
    if let Some(f) = state.particles.inconsistent_field() {
        return Err(bad(format!("field `{f}` has the wrong length")));
    }
    Ok(state)
}

/// Builds the simulation of `case`; with a settled start (`[initial] state`), its particles
/// then take positions, velocities and pressures from that checkpoint (matched by id; see
/// [`crate::input::case::InitialSpec`]), or from the relaxation it runs first
/// (`[initial.relax]`).
pub fn build_simulation<const D: usize>(case: Case, label: &str) -> Result<Simulation<D>> {
    build_simulation_with(case, label, &mut |_| {})
}

/// [`build_simulation`], telling `progress` the time (s) a relaxation first has reached.
pub fn build_simulation_with<const D: usize>(
    case: Case,
    label: &str,
    progress: &mut dyn FnMut(f64),
) -> Result<Simulation<D>> {
    let initial = case.initial.clone();
    let settled = match initial.as_ref().and_then(|i| i.relax.as_ref()) {
        Some(spec) => Some(crate::simulation::relax::relax_with::<D>(
            &case, spec, label, progress,
        )?),
        None => None,
    };
    let mut sim = Simulation::<D>::new(case, label)?;
    if let Some(p) = settled {
        // The relaxation ran this geometry: its particles match by construction.
        sim.start_from(&p).map_err(|m| Error::Format {
            path: label.into(),
            message: format!("initial.relax: cannot start from it: {m}"),
        })?;
    } else if let Some(init) = initial {
        let bytes = std::fs::read(&init.path).map_err(|e| Error::io(&init.path, e))?;
        let state = decode::<D>(&bytes, &init.path)?;
        sim.start_from(&state.particles)
            .map_err(|m| Error::Checkpoint {
                path: init.path.clone(),
                message: format!("initial.state: cannot start from it: {m}"),
            })?;
    }
    Ok(sim)
}

/// Restores time, step and particles of `sim` from checkpoint bytes read from `path`. The
/// simulation must have been built from the same case (same dimension and particles).
pub fn restore<const D: usize>(sim: &mut Simulation<D>, bytes: &[u8], path: &Path) -> Result<()> {
    let bad = |message: String| Error::Checkpoint {
        path: path.to_path_buf(),
        message,
    };
    let state = decode::<D>(bytes, path)?;
    if state.case != sim.case.fingerprint() {
        return Err(bad(
            "written by another case: only time.end, max_steps, output, probes, validation and breakdown limits may change for a restart".into(),
        ));
    }
    if !state.time.is_finite() || state.time < 0.0 {
        return Err(bad(format!("time {} is not a valid time", state.time)));
    }
    let n = state.particles.len();
    if n as u64 + state.removed != sim.particles.len() as u64 {
        return Err(bad(format!(
            "checkpoint holds {n} particles and {} removed by outflow, the case builds {}",
            state.removed,
            sim.particles.len()
        )));
    }
    let groups = crate::input::setup::group_names(&sim.case).len();
    check_indices(&state.particles, sim.case.phases.len(), groups).map_err(bad)?;
    sim.particles = state.particles;
    sim.time = state.time;
    sim.step_count = state.step;
    sim.outflow_removed = state.removed;
    sim.layout = state.layout;
    // Only the neighbour list is rebuilt: every stored array comes back as saved, so the
    // restarted run continues bit for bit.
    sim.rebuild_neighbors();
    Ok(())
}
