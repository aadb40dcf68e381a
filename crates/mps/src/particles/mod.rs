//! Particles: the state of every particle (its fields declared once), vectors, neighbour
//! lists and the read-only view the stages share.
//!
//! Owns the data layout. May use nothing else in the crate; it knows
//! no kernel, scheme or file format.

pub mod fields;
pub mod neighbors;
pub mod vector;
pub mod view;

pub use fields::{Column, Kind, NewParticle, Particles, SpareArrays, Spared, NONE, NO_GROUP};
pub use neighbors::NeighborList;
pub use vector::{Matrix, Vector};
pub use view::View;
