//! Wall-clock time per stage of the step, by one mechanism: a [`Stage`] name and
//! [`Timers::add`], called by `Simulation::timed` around each stage.

use std::time::Duration;

/// The timed stages of a step, in step order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Neighbour search and reordering.
    Neighbors,
    /// Viscosity, gravity and the collision model.
    Explicit,
    /// Number density, free surface, wall densities.
    DensitySurface,
    /// PPE assembly.
    PpeAssembly,
    /// Preconditioner set-up (IC(0) factorisation, AMG hierarchy).
    PpeSetup,
    /// CG iterations.
    PpeSolve,
    /// Boundary pressures, pressure gradient, DS and pair diagnostics.
    Gradient,
    /// Velocity/position correction and breakdown checks.
    Correction,
}

impl Stage {
    /// Every stage, in step order.
    pub const ALL: [Stage; 8] = [
        Stage::Neighbors,
        Stage::Explicit,
        Stage::DensitySurface,
        Stage::PpeAssembly,
        Stage::PpeSetup,
        Stage::PpeSolve,
        Stage::Gradient,
        Stage::Correction,
    ];

    /// Its name in timing trees and summaries.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Neighbors => "neighbour search",
            Stage::Explicit => "explicit forces",
            Stage::DensitySurface => "number density + surface",
            Stage::PpeAssembly => "PPE assembly",
            Stage::PpeSetup => "PPE solver set-up",
            Stage::PpeSolve => "PPE solve",
            Stage::Gradient => "pressure gradient + DS",
            Stage::Correction => "correction + checks",
        }
    }
}

/// Time spent in each stage.
#[derive(Clone, Copy, Debug, Default)]
pub struct Timers {
    spent: [Duration; 8],
}

impl Timers {
    /// Adds `d` to `stage`.
    pub fn add(&mut self, stage: Stage, d: Duration) {
        self.spent[stage as usize] += d;
    }
    /// Time spent in `stage`.
    pub fn get(&self, stage: Stage) -> Duration {
        self.spent[stage as usize]
    }
    /// Sum of all stages.
    pub fn total(&self) -> Duration {
        self.spent.iter().sum()
    }
    /// (name, duration) of each stage, in step order.
    pub fn stages(&self) -> [(&'static str, Duration); 8] {
        Stage::ALL.map(|s| (s.name(), self.get(s)))
    }
}
