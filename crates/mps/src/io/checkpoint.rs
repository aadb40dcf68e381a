//! Checkpoints: the complete particle state and clock of a run, serialised with serde in
//! postcard's binary format behind a magic tag, written atomically at every output step, so a
//! long run can be restarted, or extended to a later end time, from its last checkpoint.

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use crate::input::Case;
use crate::particles::{Particles, NONE, NO_GROUP};
use crate::simulation::Simulation;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file's first bytes: format name and version.
const MAGIC: &[u8; 8] = b"MPSCKPT4";

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
    /// Every particle field.
    particles: Particles<D>,
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
    };
    let mut out = MAGIC.to_vec();
    out.extend(postcard::to_allocvec(&state).expect("particles serialise"));
    out
}

/// Writes the checkpoint of `sim` to `path` atomically.
pub fn write_checkpoint<const D: usize>(sim: &Simulation<D>, path: &Path) -> Result<()> {
    write_atomic(path, &checkpoint_bytes(sim))
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
    if let Some(f) = state.particles.inconsistent_field() {
        return Err(bad(format!("field `{f}` has the wrong length")));
    }
    Ok(state)
}

/// Builds the simulation of `case`; with a settled start (`[initial] state`), its particles
/// then take positions, velocities and pressures from that checkpoint (matched by id; see
/// [`crate::input::case::InitialSpec`]).
pub fn build_simulation<const D: usize>(case: Case, label: &str) -> Result<Simulation<D>> {
    let initial = case.initial.clone();
    let mut sim = Simulation::<D>::new(case, label)?;
    if let Some(init) = initial {
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
    // Only the neighbour list is rebuilt: every stored array comes back as saved, so the
    // restarted run continues bit for bit.
    sim.rebuild_neighbors();
    Ok(())
}
