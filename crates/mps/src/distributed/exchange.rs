//! Moving particles between processes (feature `mpi`): migration to the owner of their cell
//! under the Morton cuts, and the halo each process needs from the others. Both are one
//! all-to-all exchange of flat `f64` records (`Record::WIDTH` numbers per particle: id,
//! position, velocity, pressure, density, kind, phase), so that a field added to the record
//! travels with it.
//!
//! The cuts come from every particle's key gathered on every process ([`global_cuts`]):
//! simple and exact, `8 N` bytes per process; a sampled or histogram splitter is the
//! scalable replacement when N outgrows that.

use super::partition::{owner_of, splitters, MortonGrid};
use crate::particles::Vector;
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// What travels with a particle between processes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record<const D: usize> {
    /// Particle id (stable over the run).
    pub id: u32,
    /// Position (m).
    pub position: Vector<D>,
    /// Velocity (m/s).
    pub velocity: Vector<D>,
    /// Pressure (Pa).
    pub pressure: f64,
    /// Density (kg/m^3).
    pub density: f64,
    /// Kind code (0 fluid, 1 wall, 2 dummy).
    pub kind: u8,
    /// Phase index.
    pub phase: u16,
}

impl<const D: usize> Record<D> {
    /// Numbers per record.
    pub const WIDTH: usize = 5 + 2 * D;

    fn write(&self, out: &mut Vec<f64>) {
        out.push(self.id as f64);
        out.extend_from_slice(&self.position.0);
        out.extend_from_slice(&self.velocity.0);
        out.extend_from_slice(&[
            self.pressure,
            self.density,
            self.kind as f64,
            self.phase as f64,
        ]);
    }

    fn read(v: &[f64]) -> Self {
        let mut position = Vector::<D>::zero();
        let mut velocity = Vector::<D>::zero();
        for a in 0..D {
            position[a] = v[1 + a];
            velocity[a] = v[1 + D + a];
        }
        Record {
            id: v[0] as u32,
            position,
            velocity,
            pressure: v[1 + 2 * D],
            density: v[2 + 2 * D],
            kind: v[3 + 2 * D] as u8,
            phase: v[4 + 2 * D] as u16,
        }
    }
}

/// Sends `outgoing[q]` to process `q` and returns what every process sent here, in process
/// order (collective).
fn all_to_all<const D: usize>(
    world: &SimpleCommunicator,
    outgoing: &[Vec<Record<D>>],
) -> Vec<Record<D>> {
    let flat: Vec<Vec<f64>> = outgoing
        .iter()
        .map(|list| {
            let mut out = Vec::with_capacity(list.len() * Record::<D>::WIDTH);
            for r in list {
                r.write(&mut out);
            }
            out
        })
        .collect();
    let (received, _) = exchange_numbers(world, &flat);
    received
        .chunks_exact(Record::<D>::WIDTH)
        .map(Record::read)
        .collect()
}

/// Exclusive prefix sums of `c`.
fn displacements(c: &[i32]) -> Vec<i32> {
    c.iter()
        .scan(0, |acc, &x| {
            let d = *acc;
            *acc += x;
            Some(d)
        })
        .collect()
}

/// Sends the numbers `outgoing[q]` to process `q`; returns what every process sent here,
/// concatenated in process order, and how many numbers came from each (collective).
pub fn exchange_numbers(
    world: &SimpleCommunicator,
    outgoing: &[Vec<f64>],
) -> (Vec<f64>, Vec<usize>) {
    let size = world.size() as usize;
    let counts: Vec<i32> = (0..size)
        .map(|q| outgoing.get(q).map_or(0, |v| v.len()) as i32)
        .collect();
    let flat: Vec<f64> = outgoing.concat();
    let mut incoming = vec![0i32; size];
    world.all_to_all_into(&counts[..], &mut incoming[..]);
    let total: i32 = incoming.iter().sum();
    let mut received = vec![0.0f64; total as usize];
    {
        let send = Partition::new(&flat[..], &counts[..], displacements(&counts));
        let mut recv =
            PartitionMut::new(&mut received[..], &incoming[..], displacements(&incoming));
        world.all_to_all_varcount_into(&send, &mut recv);
    }
    (received, incoming.iter().map(|&c| c as usize).collect())
}

/// The grid every process shares: cells of side `cell` (m) from the lowest position over all
/// processes (collective).
pub fn global_grid<const D: usize>(
    world: &SimpleCommunicator,
    local: &[Record<D>],
    cell: f64,
) -> MortonGrid<D> {
    let mut lo = [f64::INFINITY; D];
    for r in local {
        for a in 0..D {
            lo[a] = lo[a].min(r.position[a]);
        }
    }
    let mut global = [0.0f64; D];
    world.all_reduce_into(&lo[..], &mut global[..], SystemOperation::min());
    MortonGrid { lo: global, cell }
}

/// The Morton cuts into one piece per process from every particle's key (collective).
pub fn global_cuts<const D: usize>(
    world: &SimpleCommunicator,
    grid: &MortonGrid<D>,
    local: &[Record<D>],
) -> Vec<u64> {
    let keys: Vec<u64> = local.iter().map(|r| grid.key(&r.position)).collect();
    cuts_of_keys(world, &keys)
}

/// The Morton cuts into one piece per process from the cell keys of every process's
/// particles, `keys` this process's (collective).
pub fn cuts_of_keys(world: &SimpleCommunicator, keys: &[u64]) -> Vec<u64> {
    let size = world.size() as usize;
    let mut counts = vec![0i32; size];
    world.all_gather_into(&(keys.len() as i32), &mut counts[..]);
    let displs = displacements(&counts);
    let mut all = vec![0u64; counts.iter().sum::<i32>() as usize];
    {
        let mut part = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        world.all_gather_varcount_into(keys, &mut part);
    }
    all.sort_unstable();
    splitters(&all, size)
}

/// Sends every particle to the process owning its cell under `cuts` and returns the
/// particles this process owns afterwards, in increasing id order (collective).
pub fn migrate<const D: usize>(
    world: &SimpleCommunicator,
    grid: &MortonGrid<D>,
    cuts: &[u64],
    local: Vec<Record<D>>,
) -> Vec<Record<D>> {
    let mut outgoing = vec![Vec::new(); world.size() as usize];
    for r in local {
        outgoing[owner_of(cuts, grid.key(&r.position)) as usize].push(r);
    }
    let mut mine = all_to_all(world, &outgoing);
    mine.sort_unstable_by_key(|r| r.id);
    mine
}

/// The halo of this process: the particles of the others that lie within `radius` (m, at
/// most the cell side) of one of its own, in increasing id order (collective). Each process
/// sends a particle to every other owner of a cell next to the particle's, and the receiver
/// keeps those within `radius` of one of its own.
pub fn halo<const D: usize>(
    world: &SimpleCommunicator,
    grid: &MortonGrid<D>,
    cuts: &[u64],
    local: &[Record<D>],
    radius: f64,
) -> Vec<Record<D>> {
    let me = world.rank() as u32;
    let mut outgoing = vec![Vec::new(); world.size() as usize];
    for r in local {
        let mut owners: Vec<u32> = grid
            .neighbour_keys(&r.position)
            .into_iter()
            .map(|k| owner_of(cuts, k))
            .filter(|&q| q != me)
            .collect();
        owners.sort_unstable();
        owners.dedup();
        for q in owners {
            outgoing[q as usize].push(*r);
        }
    }
    let candidates = all_to_all(world, &outgoing);
    // Keep the candidates within the radius of an own particle (cell lists of the own ones).
    let mut cells: std::collections::HashMap<u64, Vec<usize>> = Default::default();
    for (i, r) in local.iter().enumerate() {
        cells.entry(grid.key(&r.position)).or_default().push(i);
    }
    let r2 = radius * radius;
    let mut kept: Vec<Record<D>> = candidates
        .into_iter()
        .filter(|c| {
            grid.neighbour_keys(&c.position).iter().any(|k| {
                cells.get(k).is_some_and(|own| {
                    own.iter()
                        .any(|&i| (local[i].position - c.position).norm2() < r2)
                })
            })
        })
        .collect();
    kept.sort_unstable_by_key(|r| r.id);
    kept
}
