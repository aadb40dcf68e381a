//! The particle exchange check (feature `mpi`): every process builds the dam break's
//! particles, keeps every `size`-th one (a scattered start), and then
//! 1. migrates them to the owners of their cells under the Morton cuts: every particle ends
//!    on exactly one process, the one its cell belongs to, and the pieces agree with the
//!    serial partition of the same particles;
//! 2. exchanges halos: each process's halo equals the serial halo of its piece;
//! 3. moves every particle by 0.37 cells along x and 0.21 along y (crossing cuts) and
//!    migrates again under the same cuts: still none lost or duplicated.
//!
//! Prints `OK` on rank 0 when all hold, else exits 1 naming the failed check. Run as
//! `mpirun -np N mps-mpi-exchange [SPACING]` (the dam break's spacing by default).

use mpi::traits::*;
use mps::distributed::exchange::{global_cuts, global_grid, halo, migrate, Record};
use mps::distributed::partition::{owner_of, Partition};
use mps::particles::{Kind, Vector};

fn fail(rank: i32, what: &str) -> ! {
    eprintln!("mps-mpi-exchange (rank {rank}): {what}");
    std::process::exit(1);
}

/// Ids on every process gathered to all, sorted: each exactly once, `0..n`.
fn all_ids(world: &mpi::topology::SimpleCommunicator, mine: &[Record<2>]) -> Vec<u32> {
    let ids: Vec<u32> = mine.iter().map(|r| r.id).collect();
    let size = world.size() as usize;
    let mut counts = vec![0i32; size];
    world.all_gather_into(&(ids.len() as i32), &mut counts[..]);
    let displs: Vec<i32> = (0..size).map(|q| counts[..q].iter().sum()).collect();
    let mut all = vec![0u32; counts.iter().sum::<i32>() as usize];
    let mut part = mpi::datatype::PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
    world.all_gather_varcount_into(&ids[..], &mut part);
    all.sort_unstable();
    all
}

fn main() {
    let Some(universe) = mpi::initialize() else {
        eprintln!("mps-mpi-exchange: MPI could not be initialised");
        std::process::exit(1);
    };
    let world = universe.world();
    let (rank, size) = (world.rank(), world.size() as usize);
    let text = mps::examples::example("dam_break").expect("built in");
    // An optional spacing (m) scales the check up (the halo figures of the README).
    let set: Vec<(String, String)> = std::env::args()
        .nth(1)
        .map(|s| vec![("particles.spacing".to_string(), s)])
        .unwrap_or_default();
    let case = mps::Case::from_str_named(text, "dam_break", &set).expect("valid");
    let sim = mps::Simulation::<2>::new(case, "dam_break").expect("builds");
    let p = &sim.particles;
    let n = p.len();
    let record = |i: usize| Record::<2> {
        id: p.id[i],
        position: p.position[i],
        velocity: p.velocity[i],
        pressure: p.pressure[i],
        density: p.density[i],
        kind: match p.kind[i] {
            Kind::Fluid => 0,
            Kind::Wall => 1,
            Kind::Dummy => 2,
        },
        phase: p.phase[i],
    };
    let start: Vec<Record<2>> = (0..n)
        .filter(|i| i % size == rank as usize)
        .map(record)
        .collect();
    let cell = sim.kernels.lap.re;
    let grid = global_grid(&world, &start, cell);
    let cuts = global_cuts(&world, &grid, &start);
    let mine = migrate(&world, &grid, &cuts, start);
    let everyone: Vec<u32> = (0..n as u32).collect();
    if all_ids(&world, &mine) != everyone {
        fail(
            rank,
            "after the first migration a particle is lost or duplicated",
        );
    }
    let serial = Partition::along_morton(&p.position, cell, size).expect("partition");
    let mut expected: Vec<u32> = (0..n)
        .filter(|&i| serial.owner[i] == rank as u32)
        .map(|i| p.id[i])
        .collect();
    expected.sort_unstable();
    if mine.iter().map(|r| r.id).collect::<Vec<_>>() != expected {
        fail(rank, "the migrated piece differs from the serial partition");
    }
    let h = halo(&world, &grid, &cuts, &mine, cell);
    let nl = &mps::particles::neighbors::build_neighbor_list(&p.position, cell);
    let mut want: Vec<u32> = serial
        .halo(rank as u32, &p.position, nl, cell)
        .iter()
        .map(|&j| p.id[j])
        .collect();
    want.sort_unstable();
    if h.iter().map(|r| r.id).collect::<Vec<_>>() != want {
        fail(rank, "the halo differs from the serial halo");
    }
    let index_of: std::collections::HashMap<u32, usize> = (0..n).map(|i| (p.id[i], i)).collect();
    if h.iter().any(|r| {
        let i = index_of[&r.id];
        r.position != p.position[i] || r.velocity != p.velocity[i] || r.pressure != p.pressure[i]
    }) {
        fail(rank, "a halo particle's fields changed on the way");
    }
    let moved: Vec<Record<2>> = mine
        .into_iter()
        .map(|mut r| {
            r.position += Vector([0.37 * cell, 0.21 * cell]);
            r
        })
        .collect();
    let again = migrate(&world, &grid, &cuts, moved);
    if all_ids(&world, &again) != everyone {
        fail(
            rank,
            "after the second migration a particle is lost or duplicated",
        );
    }
    if again
        .iter()
        .any(|r| owner_of(&cuts, grid.key(&r.position)) != rank as u32)
    {
        fail(
            rank,
            "a particle sits on a process that does not own its cell",
        );
    }
    let gather = |v: usize| {
        let mut all = vec![0u64; size];
        world.all_gather_into(&(v as u64), &mut all[..]);
        all
    };
    let (owned, halos, moved) = (gather(expected.len()), gather(h.len()), gather(again.len()));
    if rank == 0 {
        println!(
            "OK {n} particles on {size} process(es): owned {owned:?}, halo {halos:?}, after the move {moved:?}"
        );
    }
}
