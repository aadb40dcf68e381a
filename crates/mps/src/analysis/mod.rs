//! Analysis: what is measured on a run: stability metrics, fluid groups, validation against
//! reference data, the run summary, and scheme comparisons.
//!
//! Reads `simulation` and `particles`; never changes a simulation.

pub mod added_mass;
pub mod compare;
pub mod exact;
pub mod groups;
pub mod metrics;
pub mod probes;
pub mod rim_mode;
pub mod summary;
pub mod surface;
pub mod validation;

pub use summary::{GroupSummary, RunSummary};
