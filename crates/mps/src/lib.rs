//! A Moving Particle Semi-implicit (MPS) solver for incompressible free-surface and multiphase
//! flow, with the stabilization schemes of Tsuruta, Khayyer & Gotoh, "A Short Note on Dynamic
//! Stabilization of Moving Particle Semi-implicit Method".
//!
//! Folders, dependencies pointing one way (each folder's module comment says what it owns
//! and what it may not touch):
//! - [`parallel`]: the step's helper worker and its spin-ended parallel loops; a leaf, used
//!   by every folder;
//! - [`particles`]: the particle fields (declared once), vectors, neighbour lists; a leaf;
//! - [`linalg`]: sparse matrices, PCG, IC(0), AMG; a leaf;
//! - [`numerics`]: kernel, the one pair loop, operators and every model of a scheme;
//! - [`input`]: the case file, overrides, scheme resolution, set-up of the particles;
//! - [`simulation`]: the time step as named stages, the pressure solver, breakdown;
//! - [`analysis`]: metrics, groups, validation, the run summary, comparisons;
//! - [`io`]: atomic writes, VTU/PVD, checkpoints, CSV series;
//! - [`run`]: the run loop and its recorder, on top of all of them;
//! - [`distributed`]: the distributed run: the partition and (feature `mpi`) the step over
//!   MPI processes, its hypre solve and `mpirun -np N mps run`; on top, using `run`.

// `!(x > 0.0)` is used on purpose: it rejects NaN as well as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over components and particles read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod distributed;
pub mod error;
pub mod input;
pub mod io;
pub mod linalg;
pub mod numerics;
pub mod parallel;
pub mod particles;
pub mod run;
pub mod simulation;

pub use error::{CaseError, Error};
pub use input::examples;
pub use input::Case;
pub use simulation::{Breakdown, BreakdownReason, Simulation};
