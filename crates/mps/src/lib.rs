//! A Moving Particle Semi-implicit (MPS) solver for incompressible free-surface and multiphase
//! flow, with the stabilization schemes of Tsuruta, Khayyer & Gotoh, "A Short Note on Dynamic
//! Stabilization of Moving Particle Semi-implicit Method".
//!
//! Data flow, one module per stage:
//! case file ([`case`]) -> set-up ([`setup`]) -> step loop ([`simulation`]: [`neighbors`] ->
//! explicit forces ([`operators`]) -> number density and surface -> pressure solve
//! ([`ppe`], [`linsolve`]) -> pressure gradient ([`gradient`]) and stabilization
//! ([`stabilization`]) -> correction) -> output ([`output`], [`run`]) -> diagnostics and
//! validation ([`diagnostics`], [`validation`]).

// `!(x > 0.0)` is used on purpose: it rejects NaN as well as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over components and particles read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod amg;
pub mod analytic;
pub mod case;
pub mod checkpoint;
pub mod compare;
pub mod diagnostics;
pub mod examples;
pub mod fields;
pub mod gradient;
pub mod groups;
pub mod kernel;
pub mod linsolve;
pub mod neighbors;
pub mod operators;
pub mod output;
pub mod parallel;
pub mod particles;
pub mod ppe;
pub mod run;
pub mod scheme;
pub mod setup;
pub mod simulation;
pub mod stabilization;
pub mod validation;
pub mod vector;
pub mod walls;

pub use case::{Case, CaseError};
pub use simulation::{Breakdown, BreakdownReason, Simulation};
