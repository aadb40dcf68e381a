//! The distributed step check (feature `mpi`): every process builds the same shipped
//! example, keeps its piece and halo, and runs STEPS steps of the distributed step; rank 0
//! also runs the serial step from the same start and compares every particle by id:
//! each exactly once over the processes, and the largest distance between a particle's
//! distributed and serial positions, in spacings, at most BOUND. Prints the figures on
//! rank 0; exits 1 when a check fails. Run as
//! `mpirun -np N mps-mpi-step EXAMPLE STEPS BOUND [KEY=VALUE ...]` (2D or 3D); BOUND `-`
//! skips the serial run and prints the distributed step's timing alone (a benchmark: the
//! first step, which sets up, is not timed).

use mpi::datatype::PartitionMut;
use mpi::traits::*;
use mps::distributed::step::{halo_depth, MpiDomain};
use mps::input::Case;
use mps::simulation::Simulation;
use std::time::Instant;

fn fail(rank: i32, what: &str) -> ! {
    eprintln!("mps-mpi-step (rank {rank}): {what}");
    std::process::exit(1);
}

/// The own particles of every process, summed (collective).
fn total_particles(world: &mpi::topology::SimpleCommunicator, own: usize) -> usize {
    let mut total = 0u64;
    world.all_reduce_into(
        &(own as u64),
        &mut total,
        mpi::collective::SystemOperation::sum(),
    );
    total as usize
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: mpirun -np N mps-mpi-step EXAMPLE STEPS BOUND [KEY=VALUE ...]");
        std::process::exit(1);
    }
    let (name, steps, bound) = (&args[1], &args[2], &args[3]);
    let steps: u64 = steps
        .parse()
        .unwrap_or_else(|_| fail(0, "STEPS is not a count"));
    let bound: Option<f64> = (bound != "-").then(|| {
        bound
            .parse()
            .unwrap_or_else(|_| fail(0, "BOUND is not a number"))
    });
    let set: Vec<(String, String)> = args[4..]
        .iter()
        .filter_map(|a| {
            a.split_once('=')
                .map(|(k, v)| (k.to_string(), v.to_string()))
        })
        .collect();
    let Some(universe) = mpi::initialize() else {
        fail(0, "MPI could not be initialised");
    };
    let world = universe.world();
    let (rank, size) = (world.rank(), world.size());
    let text = mps::input::examples::example(name).unwrap_or_else(|| fail(rank, "no such example"));
    let case =
        Case::from_str_named(text, name, &set).unwrap_or_else(|e| fail(rank, &e.to_string()));
    let run = Run {
        name,
        steps,
        bound,
        rank,
        size,
    };
    match case.dimension {
        3 => check::<3>(&universe, case, run),
        _ => check::<2>(&universe, case, run),
    }
}

/// What to run and check.
struct Run<'a> {
    name: &'a str,
    steps: u64,
    bound: Option<f64>,
    rank: i32,
    size: i32,
}

/// The check in `D` dimensions.
fn check<const D: usize>(universe: &mpi::environment::Universe, case: Case, run: Run) {
    let Run {
        name,
        steps,
        bound,
        rank,
        size,
    } = run;
    let world = universe.world();
    let mut sim =
        Simulation::<D>::new(case.clone(), name).unwrap_or_else(|e| fail(rank, &e.to_string()));
    let l0 = sim.l0();
    let domain =
        MpiDomain::<D>::new(universe.world(), halo_depth(&sim)).unwrap_or_else(|e| fail(rank, &e));
    sim.attach(Box::new(domain))
        .unwrap_or_else(|e| fail(rank, &e));
    let mut t = Instant::now();
    let (mut iterations, mut halo_ratio) = (0usize, 0.0f64);
    for k in 0..steps {
        if k == 1 && bound.is_none() {
            // The first step sets up: not timed in a benchmark.
            t = Instant::now();
            iterations = 0;
        }
        let r = sim
            .step(f64::INFINITY)
            .unwrap_or_else(|b| fail(rank, &b.to_string()));
        iterations += r.solve.iterations;
        let own = sim.owned();
        halo_ratio = halo_ratio.max((sim.particles.len() - own) as f64 / own.max(1) as f64);
    }
    let elapsed = t.elapsed().as_secs_f64();
    let rebalances = sim.rebalances();
    // Every own particle's id and position to rank 0.
    let own = sim.owned();
    let mut mine = Vec::with_capacity(own * (D + 1));
    for i in 0..own {
        mine.push(sim.particles.id[i] as f64);
        mine.extend_from_slice(&sim.particles.position[i].0);
    }
    let root = world.process_at_rank(0);
    let mut worst_halo = 0.0f64;
    world.all_reduce_into(
        &halo_ratio,
        &mut worst_halo,
        mpi::collective::SystemOperation::max(),
    );
    let total = total_particles(&world, own);
    let Some(bound) = bound else {
        if rank == 0 {
            let timed = steps.saturating_sub(1).max(1) as f64;
            println!(
                "{name}: {size} process(es), {total} particles: {:.2} ms/step, {:.1} PPE iterations/step, halo/own at most {worst_halo:.3} (rank 0: {own} own, {} halo)",
                1e3 * elapsed / timed,
                iterations as f64 / timed,
                sim.particles.len() - own
            );
        }
        return;
    };
    if rank != 0 {
        root.gather_into(&(mine.len() as i32));
        root.gather_varcount_into(&mine[..]);
        return;
    }
    let mut counts = vec![0i32; size as usize];
    root.gather_into_root(&(mine.len() as i32), &mut counts[..]);
    let displs: Vec<i32> = (0..size as usize)
        .map(|q| counts[..q].iter().sum())
        .collect();
    let mut all = vec![0.0f64; counts.iter().sum::<i32>() as usize];
    {
        let mut part = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        root.gather_varcount_into_root(&mine[..], &mut part);
    }
    let mut serial = Simulation::<D>::new(case, name).unwrap_or_else(|e| fail(0, &e.to_string()));
    let t = Instant::now();
    let mut serial_iterations = 0usize;
    for _ in 0..steps {
        let r = serial
            .step(f64::INFINITY)
            .unwrap_or_else(|b| fail(0, &format!("serial: {b}")));
        serial_iterations += r.solve.iterations;
    }
    let serial_elapsed = t.elapsed().as_secs_f64();
    let n = serial.particles.len();
    let mut at = vec![usize::MAX; n];
    for (i, &id) in serial.particles.id.iter().enumerate() {
        at[id as usize] = i;
    }
    let mut seen = vec![false; n];
    let mut worst = 0.0f64;
    for rec in all.chunks_exact(D + 1) {
        let id = rec[0] as usize;
        if id >= n || seen[id] {
            fail(0, &format!("particle {id} unknown or held twice"));
        }
        seen[id] = true;
        let x = serial.particles.position[at[id]];
        let d = (0..D)
            .map(|a| (rec[1 + a] - x[a]).powi(2))
            .sum::<f64>()
            .sqrt()
            / l0;
        worst = worst.max(d);
    }
    if let Some(id) = seen.iter().position(|s| !s) {
        fail(0, &format!("particle {id} lost"));
    }
    println!(
        "{name}: {steps} steps, {n} particles on {size} process(es): largest distance to the serial run {worst:.3e} l0 (bound {bound:.0e}); \
         PPE iterations {iterations} (serial {serial_iterations}); halo/own at most {worst_halo:.2}; pieces cut afresh {rebalances} times; {elapsed:.2} s (serial {serial_elapsed:.2} s)"
    );
    if worst.is_nan() || worst > bound {
        fail(
            0,
            &format!("largest distance {worst:.3e} l0 above {bound:.0e}"),
        );
    }
}
