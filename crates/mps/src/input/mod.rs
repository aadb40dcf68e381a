//! Input: the case-file schema and its checks, command-line overrides, the scheme table
//! resolved into a [`crate::numerics::Scheme`], analytic initial fields, the built-in examples,
//! and the set-up that turns shapes into particles.
//!
//! May use `particles` and `numerics` (it builds particles and schemes); knows nothing of the
//! time loop, the solver or output.

pub mod analytic;
pub mod case;
pub mod examples;
pub mod expression;
pub mod overrides;
pub mod reference;
pub mod scheme_spec;
pub mod setup;
pub mod shapes;
pub mod stl;
mod validate;

pub use case::Case;
