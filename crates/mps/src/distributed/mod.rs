//! The distributed run (issue 16): a run that spans MPI processes.
//!
//! - [`partition`]: cells ordered along a Morton curve and cut into pieces of equal particle
//!   count, the halo of each piece, the imbalance that calls for rebalancing; plain data,
//!   built and tested without MPI;
//! - `exchange` (feature `mpi`): migration of particles to the owner of their cell and the
//!   halo exchange, over MPI;
//! - `hypre` (feature `mpi`): the PPE solved by hypre's BoomerAMG-preconditioned PCG through
//!   its IJ interface, each process owning a contiguous block of rows;
//! - `step` (feature `mpi`): the [`crate::simulation::Domain`] over MPI that makes the
//!   serial step a distributed one (own particles, halo, refreshes, the solve);
//! - `run` (feature `mpi`): `mpirun -np N mps run CASE`, recorded by the serial run loop on
//!   the first process.
//!
//! On top: uses `particles`, `numerics`, `linalg`, `input`, `simulation`, `analysis` and
//! `run`; nothing else of the crate uses it (the step reaches it through the `Domain` trait
//! of `simulation`).

#[cfg(feature = "mpi")]
pub mod exchange;
#[cfg(feature = "mpi")]
pub mod hypre;
pub mod partition;
#[cfg(feature = "mpi")]
pub mod run;
#[cfg(feature = "mpi")]
pub mod step;

/// The system the distributed checks solve.
pub mod check {
    use crate::numerics::ppe::PressureSystem;

    /// The PPE of the dam break (MPS-HS-GC-DS) at its first step past t = 0.15 s: free
    /// surface, walls and a moving front; deterministic, so every process builds the same.
    pub fn dam_break_ppe() -> PressureSystem {
        let text = crate::input::examples::example("dam_break").expect("built in");
        let set = [("scheme.name".to_string(), "MPS-HS-GC-DS".to_string())];
        let case = crate::input::Case::from_str_named(text, "dam_break", &set).expect("valid");
        let mut s = crate::simulation::Simulation::<2>::new(case, "dam_break").expect("builds");
        while s.time < 0.15 {
            s.step(f64::INFINITY).expect("the dam break runs");
        }
        s.last_system.take().expect("the last system is kept")
    }
}
