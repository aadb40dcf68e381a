//! Checkpoints: the complete particle state and clock of a run in a small binary file
//! (little-endian), written atomically at every output step, so a long run can be
//! restarted, or extended to a later end time, from its last checkpoint.

use crate::output::write_atomic;
use crate::particles::{Kind, Particles};
use crate::simulation::Simulation;
use crate::vector::Vector;
use std::io;
use std::path::Path;

const MAGIC: &[u8; 8] = b"MPSCKPT1";

fn put<T: Copy, const N: usize>(out: &mut Vec<u8>, v: &[T], f: impl Fn(T) -> [u8; N]) {
    out.extend_from_slice(&(v.len() as u64).to_le_bytes());
    for &x in v {
        out.extend_from_slice(&f(x));
    }
}

/// Serialises the state of `sim` (time, step, every particle array).
pub fn checkpoint_bytes<const D: usize>(sim: &Simulation<D>) -> Vec<u8> {
    let p = &sim.particles;
    let mut out = Vec::with_capacity(64 + p.len() * (24 + 16 * D));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(D as u32).to_le_bytes());
    out.extend_from_slice(&sim.time.to_le_bytes());
    out.extend_from_slice(&sim.step_count.to_le_bytes());
    let flat = |v: &[Vector<D>]| v.iter().flat_map(|x| x.0).collect::<Vec<f64>>();
    put(&mut out, &p.id, u32::to_le_bytes);
    put(&mut out, &flat(&p.position), f64::to_le_bytes);
    put(&mut out, &flat(&p.velocity), f64::to_le_bytes);
    put(&mut out, &p.pressure, f64::to_le_bytes);
    put(&mut out, &p.density, f64::to_le_bytes);
    put(&mut out, &p.phase, u16::to_le_bytes);
    put(
        &mut out,
        &p.kind.iter().map(|k| *k as u8).collect::<Vec<u8>>(),
        |b| [b],
    );
    put(&mut out, &p.number_density, f64::to_le_bytes);
    put(&mut out, &p.backing_wall, u32::to_le_bytes);
    put(&mut out, &p.group, u16::to_le_bytes);
    put(
        &mut out,
        &p.free_surface.iter().map(|&f| f as u8).collect::<Vec<u8>>(),
        |b| [b],
    );
    out
}

/// Writes the checkpoint of `sim` to `path` atomically.
pub fn write_checkpoint<const D: usize>(sim: &Simulation<D>, path: &Path) -> io::Result<()> {
    write_atomic(path, &checkpoint_bytes(sim))
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let s = self
            .b
            .get(self.at..self.at + n)
            .ok_or_else(|| "file is truncated".to_string())?;
        self.at += n;
        Ok(s)
    }
    fn array<T, const N: usize>(&mut self, f: impl Fn([u8; N]) -> T) -> Result<Vec<T>, String> {
        let len = u64::from_le_bytes(self.take(8)?.try_into().unwrap()) as usize;
        let bytes = self.take(len.checked_mul(N).ok_or("bad length")?)?;
        Ok(bytes
            .chunks_exact(N)
            .map(|c| f(c.try_into().unwrap()))
            .collect())
    }
}

/// Restores time, step and particles of `sim` from checkpoint bytes. The simulation must have
/// been built from the same case (same dimension and particle count).
pub fn restore<const D: usize>(sim: &mut Simulation<D>, bytes: &[u8]) -> Result<(), String> {
    let mut r = Reader { b: bytes, at: 0 };
    if r.take(8)? != MAGIC {
        return Err("not an MPS checkpoint".into());
    }
    let d = u32::from_le_bytes(r.take(4)?.try_into().unwrap()) as usize;
    if d != D {
        return Err(format!("checkpoint is {d}D, the case is {D}D"));
    }
    let time = f64::from_le_bytes(r.take(8)?.try_into().unwrap());
    let step = u64::from_le_bytes(r.take(8)?.try_into().unwrap());
    let id = r.array(u32::from_le_bytes)?;
    let n = id.len();
    if n != sim.particles.len() {
        return Err(format!(
            "checkpoint holds {n} particles, the case builds {}",
            sim.particles.len()
        ));
    }
    let vecs = |flat: Vec<f64>| -> Result<Vec<Vector<D>>, String> {
        if flat.len() != n * D {
            return Err("array length mismatch".into());
        }
        Ok(flat
            .chunks_exact(D)
            .map(|c| Vector::from_slice(c).unwrap())
            .collect())
    };
    let position = vecs(r.array(f64::from_le_bytes)?)?;
    let velocity = vecs(r.array(f64::from_le_bytes)?)?;
    let kind = |b: [u8; 1]| match b[0] {
        0 => Kind::Fluid,
        1 => Kind::Wall,
        _ => Kind::Dummy,
    };
    let p = Particles {
        id,
        position,
        velocity,
        pressure: r.array(f64::from_le_bytes)?,
        density: r.array(f64::from_le_bytes)?,
        phase: r.array(u16::from_le_bytes)?,
        kind: r.array(kind)?,
        number_density: r.array(f64::from_le_bytes)?,
        backing_wall: r.array(u32::from_le_bytes)?,
        group: r.array(u16::from_le_bytes)?,
        free_surface: Vec::new(),
    };
    let mut p = p;
    p.free_surface = r.array(|b: [u8; 1]| b[0] != 0)?;
    let lens = [
        p.free_surface.len(),
        p.pressure.len(),
        p.density.len(),
        p.phase.len(),
        p.kind.len(),
        p.number_density.len(),
        p.backing_wall.len(),
        p.group.len(),
    ];
    if lens.iter().any(|&l| l != n) {
        return Err("array length mismatch".into());
    }
    sim.particles = p;
    sim.time = time;
    sim.step_count = step;
    // Only the neighbour list is rebuilt: every stored array comes back as saved, so the
    // restarted run continues bit for bit.
    sim.rebuild_neighbors();
    Ok(())
}
