//! Numerics: the MPS kernel, the one pair loop, the operators, and every model a scheme is
//! made of (gradient models, PPE source and assembly, free-surface detectors and
//! the surface's Dirichlet value, walls, density
//! averages, collisions, Dynamic Stabilization, particle shifting), with the paper's presets as data.
//!
//! Each file implements one model and cites its equation. May use `particles` and `linalg`
//! (the PPE is assembled into its sparse matrix); knows nothing of the time loop, case files
//! or output.

pub mod collision;
pub mod density;
pub mod free_surface_tension;
pub mod gradient;
pub mod interface_repulsion;
pub mod interfacial_tension;
pub mod kernel;
pub mod operators;
pub mod pairs;
pub mod ppe;
pub mod scheme;
pub mod shifting;
pub mod source;
pub mod stabilization;
pub mod surface;
pub mod surface_pressure;
pub mod walls;

pub use kernel::{weight, KernelConstants, Kernels};
pub use pairs::Pair;
pub use scheme::Scheme;
