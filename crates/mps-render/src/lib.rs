//! Pictures of MPS runs: particle snapshots coloured by a field with a perceptually uniform
//! colour map, a colour bar with units, velocity vectors, walls in grey, true aspect ratio.

// Index loops over particles read like the drawing they do.
#![allow(clippy::needless_range_loop)]

pub mod canvas;
pub mod colormap;
pub mod plot;
pub mod report;
pub mod snapshot;

pub use canvas::Canvas;
pub use snapshot::{
    compose, read_pvd, render_frame, union_bounds, Field, Frame, Projection, RenderOptions,
};
pub mod movie;
