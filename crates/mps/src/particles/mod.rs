//! Particles: the state of every particle (its fields declared once), vectors, neighbour
//! lists and the read-only view the stages share.
//!
//! Owns the data layout. May use nothing else in the crate but the leaf `parallel`; it knows
//! no kernel, scheme or file format.

pub mod fields;
pub mod neighbors;
pub mod vector;
pub mod view;

pub use fields::{Column, Kind, NewParticle, Particles, NONE, NO_GROUP};
pub use neighbors::NeighborList;
pub use vector::{Matrix, Vector};
pub use view::View;
