//! The summary of a run (`summary.toml`): written by the run loop, read back through the
//! same struct by reports, plots and comparisons.

use super::validation::ValidationResult;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Summary of a finished (or broken-down) run, written as `summary.toml`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunSummary {
    /// Case name.
    pub case: String,
    /// Scheme preset.
    pub scheme: String,
    /// Fluid particles.
    pub fluid_particles: usize,
    /// Wall particles.
    pub wall_particles: usize,
    /// Dummy particles.
    pub dummy_particles: usize,
    /// Particle spacing (m).
    pub spacing: f64,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time reached (s).
    pub time: f64,
    /// End time asked for (s).
    pub end_time: f64,
    /// Wall-clock time (s).
    pub wall_seconds: f64,
    /// Particle-steps per second (all particles).
    pub particle_steps_per_second: f64,
    /// Mean PPE iterations per step.
    pub mean_ppe_iterations: f64,
    /// Steps whose PPE preconditioner could not be built and fell back to Jacobi.
    #[serde(default)]
    pub solver_fallbacks: u64,
    /// Fluid particles removed after leaving the domain (`domain.outflow = "remove"`).
    #[serde(default)]
    pub outflow_removed: u64,
    /// Breakdown description, if the run broke down.
    pub breakdown: Option<String>,
    /// Breakdown time (s), if any.
    pub breakdown_time: Option<f64>,
    /// Validation figures.
    pub validation: Vec<ValidationResult>,
    /// Seconds per stage of the step.
    pub stages: Vec<(String, f64)>,
    /// Rayon threads used.
    pub threads: usize,
    /// Kinetic energy at the start and at the end (J, per unit depth in 2D).
    pub kinetic_energy: (f64, f64),
    /// Angular momentum about the origin at the start and at the end (kg m^2/s).
    pub angular_momentum: (f64, f64),
    /// Closest fluid pair over the whole run, in units of l0.
    pub min_pair_distance_l0: f64,
    /// Spread (std) of n/n0 over interior fluid particles at the end.
    pub nd_spread_end: f64,
    /// RMS fluid speed at the end (m/s).
    pub rms_speed_end: f64,
    /// Each probe's pressure at the start and at the end (Pa).
    pub probes: Vec<(String, f64, f64)>,
    /// Each probe's step-to-step noise: RMS of the raw series minus its 1 ms moving average
    /// (Pa).
    #[serde(default)]
    pub probe_noise: Vec<(String, f64)>,
    /// Fluid groups: arrival times, stray particles, final centroids.
    pub groups: Vec<GroupSummary>,
}

/// Summary of one fluid group over a run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GroupSummary {
    /// Group label from the case file.
    pub name: String,
    /// Particles in the group.
    pub particles: usize,
    /// Time its centroid came within the validation distance of its target (bottom for a
    /// group heavier than the first phase, free surface for a lighter one), if it did (s).
    pub arrival_time: Option<f64>,
    /// Stray particles (no same-phase neighbour within re_grad) at the end.
    pub stray_end: usize,
    /// Centroid at the start and at the end (m).
    pub centroid: ((f64, f64), (f64, f64)),
}

impl RunSummary {
    /// Reads `summary.toml` from a run folder.
    pub fn read(dir: &Path) -> Result<RunSummary> {
        let path = dir.join("summary.toml");
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        toml::from_str(&text).map_err(|e| Error::Format {
            path,
            message: format!("not a run summary: {}", e.message().trim()),
        })
    }

    /// The summary as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a summary serialises")
    }

    /// Total particles (fluid, wall and dummy).
    pub fn particles(&self) -> usize {
        self.fluid_particles + self.wall_particles + self.dummy_particles
    }
}
