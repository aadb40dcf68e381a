//! The distributed PPE check (feature `mpi`): every process runs the same dam break
//! (MPS-HS-GC-DS, the PPE of its first step past t = 0.15 s, deterministic), owns a
//! contiguous block of its rows, and the system is solved by hypre's BoomerAMG-PCG across the
//! processes. Rank 0 writes the gathered solution as little-endian f64 to the file named on
//! the command line and prints the iterations; `tests/mpi.rs` compares it with faer's direct
//! solve. Run as `mpirun -np N mps-mpi-ppe OUT`.

use mpi::datatype::PartitionMut;
use mpi::traits::*;
use mps::distributed::hypre::{self, LocalRows};

fn main() {
    let Some(out) = std::env::args().nth(1) else {
        eprintln!("usage: mpirun -np N mps-mpi-ppe OUT_FILE");
        std::process::exit(1);
    };
    let Some(universe) = mpi::initialize() else {
        eprintln!("mps-mpi-ppe: MPI could not be initialised");
        std::process::exit(1);
    };
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    hypre::init().expect("hypre starts");

    let sys = mps::distributed::check::dam_break_ppe();
    let n = sys.matrix.n();
    let (first, last) = (rank * n / size, (rank + 1) * n / size);
    let mut row_ptr = vec![0usize];
    let (mut cols, mut vals) = (Vec::new(), Vec::new());
    for i in first..last {
        let (c, v) = sys.matrix.row(i);
        cols.extend(c.iter().map(|&j| j as usize));
        vals.extend_from_slice(v);
        row_ptr.push(cols.len());
    }
    let rows = LocalRows {
        first,
        row_ptr: &row_ptr,
        cols: &cols,
        vals: &vals,
    };
    let mut x = vec![0.0; last - first];
    let stats = hypre::pcg_boomeramg(&world, rows, &sys.rhs[first..last], &mut x, 1e-10, 500)
        .expect("hypre solves the PPE");

    let root = world.process_at_rank(0);
    if rank == 0 {
        let counts: Vec<i32> = (0..size)
            .map(|r| ((r + 1) * n / size - r * n / size) as i32)
            .collect();
        let displs: Vec<i32> = (0..size).map(|r| (r * n / size) as i32).collect();
        let mut all = vec![0.0f64; n];
        let mut part = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        root.gather_varcount_into_root(&x[..], &mut part);
        let bytes: Vec<u8> = all.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(&out, bytes).expect("writes the solution");
        println!(
            "{n} unknowns on {size} process(es): {} iterations, relative residual {:.2e}",
            stats.iterations, stats.relative_residual
        );
    } else {
        root.gather_varcount_into(&x[..]);
    }
    hypre::finalize().expect("hypre ends");
}
