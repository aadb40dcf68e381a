//! Input and output files: atomic writes, VTU/PVD particle files (written from and read back
//! into the particle field registry), checkpoints, and CSV time series appended as a run goes.
//!
//! May read `particles` and `simulation`; never changes a simulation except to restore one
//! from a checkpoint.

pub mod atomic;
pub mod checkpoint;
pub mod series;
pub mod vtu;

pub use atomic::write_atomic;
