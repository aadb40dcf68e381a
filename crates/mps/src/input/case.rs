//! The case file: a TOML description of one simulation, its validation and overrides.
//!
//! Every field is documented in the README's case-file reference. Unknown fields are errors;
//! every error names the file, the field and the offending value.

use super::overrides::apply_override;
use super::scheme_spec::SchemeSpec;
use crate::error::CaseError;
use crate::input::reference::ReferenceFile;
use crate::linalg::SolverKind;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A complete simulation case.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// Short name, used for the default output folder.
    pub name: String,
    /// Free text describing the case.
    #[serde(default)]
    pub description: String,
    /// Number of space dimensions (2; 3 is reserved for the 3D instantiation).
    #[serde(default = "default_dimension")]
    pub dimension: usize,
    /// The box particles must stay in (a particle leaving it is a breakdown).
    pub domain: DomainSpec,
    /// Particle spacing and kernel radii.
    pub particles: ParticleSpec,
    /// Body forces.
    #[serde(default)]
    pub physics: PhysicsSpec,
    /// Time stepping.
    pub time: TimeSpec,
    /// Numerical scheme (a named preset plus overrides).
    #[serde(default)]
    pub scheme: SchemeSpec,
    /// Pressure solver.
    #[serde(default)]
    pub solver: SolverSpec,
    /// Output settings.
    #[serde(default)]
    pub output: OutputSpec,
    /// Materials.
    pub phases: Vec<PhaseSpec>,
    /// Interfacial tensions between pairs of phases (beyond the paper; none by default).
    #[serde(default)]
    pub interfaces: Vec<InterfaceSpec>,
    /// Fluid regions, filled on the particle lattice in order.
    #[serde(default)]
    pub fluid: Vec<FluidSpec>,
    /// Solid walls; wall and dummy layers are generated from them.
    #[serde(default)]
    pub walls: Vec<WallSpec>,
    /// Points where pressure is sampled every step.
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
    /// When a run counts as broken down.
    #[serde(default)]
    pub breakdown: BreakdownSpec,
    /// Optional comparison against reference data written by the run.
    #[serde(default)]
    pub validation: Option<ValidationSpec>,
    /// Named constants for the expressions of initial fields (e.g. `omega = 1.0`).
    #[serde(default)]
    pub constants: std::collections::BTreeMap<String, f64>,
    /// A settled start: the particle state of another run's checkpoint.
    #[serde(default)]
    pub initial: Option<InitialSpec>,
}

/// A settled start (`[initial]`): the run begins at t = 0 from the positions, velocities
/// and pressures of a settled state, matched particle by particle (by id) to this case's
/// particles, whose phases, groups and densities come from this case's regions. The state
/// is another run's checkpoint of the same geometry (`state`: domain, spacing, walls, fluid
/// shapes; for example the same tank run at rest with every region water), or a relaxation
/// this run makes first (`relax`: `simulation::relax`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Checkpoint file, relative to the case file's folder (or absolute).
    #[serde(default)]
    pub state: Option<String>,
    /// A relaxation phase run first instead of a checkpoint.
    #[serde(default)]
    pub relax: Option<RelaxSpec>,
    /// The checkpoint's path as resolved when the case loaded.
    #[serde(skip)]
    pub path: std::path::PathBuf,
}

/// A relaxation phase (`[initial.relax]`): the case's tank at rest under gravity, every fluid
/// region of the first region's phase and without its initial velocity, stepped under the
/// MPS-HS-GC-DS preset for `time`, or until the kinetic energy has fallen below
/// `kinetic_fraction` of its largest value; the run then starts from that state.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RelaxSpec {
    /// Longest relaxation (s).
    pub time: f64,
    /// Ends the relaxation once the fluid's kinetic energy is below this fraction of its
    /// largest value so far (dimensionless, between 0 and 1); none: the whole `time`.
    #[serde(default)]
    pub kinetic_fraction: Option<f64>,
}

fn default_dimension() -> usize {
    2
}

/// The simulation box.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DomainSpec {
    /// Lower corner (m).
    pub min: Vec<f64>,
    /// Upper corner (m).
    pub max: Vec<f64>,
    /// Pressure level of a closed domain (no free surface): the fluid particle nearest to
    /// `position` takes `value`; default the highest fluid particle at 0 Pa.
    #[serde(default)]
    pub pressure_reference: Option<PressureReferenceSpec>,
    /// What happens to a fluid particle that leaves the domain box (by more than l0).
    #[serde(default)]
    pub outflow: Outflow,
}

/// What happens to a fluid particle that leaves the domain box.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Outflow {
    /// The run stops with a breakdown record (exit 2): nothing should leave a closed tank.
    #[default]
    Breakdown,
    /// The particle is removed from the run (an open boundary, a splash leaving the region
    /// of interest); removals are counted in `metrics.csv`, `steps.csv` and the summary.
    Remove,
}

/// Where a closed domain's pressure level is set.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PressureReferenceSpec {
    /// Reference point (m); default the highest fluid particle.
    #[serde(default)]
    pub position: Option<Vec<f64>>,
    /// Pressure there (Pa).
    #[serde(default)]
    pub value: f64,
}

/// Particle spacing and kernel radii.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSpec {
    /// Initial particle spacing `l0` (m).
    pub spacing: f64,
    /// Radius of number density, gradient and free-surface test, in units of `l0`.
    #[serde(default = "default_re_grad")]
    pub re_grad: f64,
    /// Radius of the Laplacian and the PPE, in units of `l0`.
    #[serde(default = "default_re_lap")]
    pub re_lap: f64,
    /// Number of dummy layers behind the wall layer (default: enough for a full neighbourhood).
    #[serde(default)]
    pub dummy_layers: Option<usize>,
}

fn default_re_grad() -> f64 {
    2.1
}
fn default_re_lap() -> f64 {
    3.1
}

/// Body forces.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsSpec {
    /// Gravitational acceleration (m/s^2).
    #[serde(default = "default_gravity")]
    pub gravity: Vec<f64>,
}

impl Default for PhysicsSpec {
    fn default() -> Self {
        PhysicsSpec {
            gravity: default_gravity(),
        }
    }
}

fn default_gravity() -> Vec<f64> {
    vec![0.0, -9.81]
}

/// Gravity (m/s^2) when the case gives none: along -y in 2D, -z in 3D.
fn default_gravity_of(dimension: usize) -> Vec<f64> {
    let mut g = vec![0.0; dimension];
    if let Some(last) = g.last_mut() {
        *last = -9.81;
    }
    g
}

/// Time stepping.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// End time (s).
    pub end: f64,
    /// Courant number `C` in `dt <= C l0 / u_max`.
    #[serde(default = "default_courant")]
    pub courant: f64,
    /// Largest time step (s); default `C sqrt(l0/g)` with gravity.
    #[serde(default)]
    pub dt_max: Option<f64>,
    /// A fixed time step (s), overriding the Courant limit.
    #[serde(default)]
    pub dt_fixed: Option<f64>,
    /// Stop after this many steps (optional).
    #[serde(default)]
    pub max_steps: Option<u64>,
}

fn default_courant() -> f64 {
    0.1
}

/// Pressure solver settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Which solver.
    #[serde(default = "default_solver")]
    pub kind: SolverKind,
    /// Relative residual tolerance (`|b - A p| / |b|`, dimensionless).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Volume tolerance (dimensionless): the solve also stops once the residual's volume
    /// error over the step, `dt^2 RMS(b - A p)`, is below it; 0 turns it off. Unset, it is
    /// 1e-8 with the default `tolerance` and off with a tolerance of the case's own (a
    /// solve asked for 1e-12 gets 1e-12; [`SolverSpec::volume_rule`], docs/decisions.md,
    /// "PPE stopping rule", "The volume rule by default").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_tolerance: Option<f64>,
    /// Iteration limit; not converging within it is a breakdown.
    #[serde(default = "default_max_iter")]
    pub max_iterations: usize,
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec {
            kind: default_solver(),
            tolerance: default_tolerance(),
            volume_tolerance: None,
            max_iterations: default_max_iter(),
        }
    }
}

fn default_solver() -> SolverKind {
    SolverKind::Auto
}
fn default_tolerance() -> f64 {
    1e-8
}
/// The volume rule of a solver section that does not set it and keeps the default tolerance.
const DEFAULT_VOLUME_TOLERANCE: f64 = 1e-8;

impl SolverSpec {
    /// The volume tolerance in force (dimensionless; 0 off): as set, else 1e-8 with the
    /// default relative tolerance and 0 with one of the case's own.
    pub fn volume_rule(&self) -> f64 {
        match self.volume_tolerance {
            Some(v) => v,
            None if self.tolerance == default_tolerance() => DEFAULT_VOLUME_TOLERANCE,
            None => 0.0,
        }
    }
}
fn default_max_iter() -> usize {
    5000
}

/// Output settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Interval between output steps (s); 0 writes only the first and last state.
    #[serde(default = "default_interval")]
    pub interval: f64,
    /// Write VTU particle files (and the `.pvd` index).
    #[serde(default = "default_true")]
    pub vtu: bool,
    /// Write `checkpoint.bin` (the full state, for restart) at every output step.
    #[serde(default = "default_true")]
    pub checkpoint: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            interval: default_interval(),
            vtu: true,
            checkpoint: true,
        }
    }
}

fn default_interval() -> f64 {
    0.05
}
fn default_true() -> bool {
    true
}

/// A material.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseSpec {
    /// Name used by regions.
    pub name: String,
    /// Density (kg/m^3).
    pub density: f64,
    /// Kinematic viscosity (m^2/s).
    #[serde(default)]
    pub viscosity: f64,
    /// Tension of the phase's free surface (N/m; beyond the paper, whose cases have none):
    /// a continuum surface force against the void (`numerics::interfacial_tension`).
    #[serde(default)]
    pub surface_tension: f64,
}

/// An interface between two immiscible phases with its tension (`[[interfaces]]`; beyond
/// the paper): particles of the two phases repel so that the contact between them stores
/// `tension` joules per square metre (`numerics::interfacial_tension`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InterfaceSpec {
    /// The two phases' names.
    pub phases: Vec<String>,
    /// Interfacial tension (N/m).
    pub tension: f64,
}

/// A geometric shape.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Axis-aligned box between two corners (m); `type = "box"` reads the same.
    #[serde(alias = "box")]
    Rectangle {
        /// Lower corner (m).
        min: Vec<f64>,
        /// Upper corner (m).
        max: Vec<f64>,
    },
    /// Disc (2D) or ball (3D) of a centre and radius (m); `type = "sphere"` reads the same.
    #[serde(alias = "sphere")]
    Circle {
        /// Centre (m).
        center: Vec<f64>,
        /// Radius (m).
        radius: f64,
    },
    /// Closed polygon through points (m), 2D.
    Polygon {
        /// Vertices (m).
        points: Vec<Vec<f64>>,
    },
    /// Band of half-width `thickness` around a polyline (m), 2D; walls only.
    Polyline {
        /// Vertices (m).
        points: Vec<Vec<f64>>,
        /// Distance from the line within which lattice points are solid (m).
        thickness: f64,
    },
    /// Solid cylinder (3D): the disc of `radius` (m) about `base` (m) swept along `axis` (m,
    /// its length the cylinder's).
    Cylinder {
        /// Centre of one end face (m).
        base: Vec<f64>,
        /// From that centre to the centre of the other end face (m).
        axis: Vec<f64>,
        /// Radius (m).
        radius: f64,
    },
    /// The inside of a closed STL surface (3D; ASCII or binary, coordinates in m), `file`
    /// relative to the case file.
    Stl {
        /// The STL file.
        file: String,
        /// The mesh, read when the case loads.
        #[serde(skip)]
        mesh: Option<std::sync::Arc<crate::input::stl::Mesh>>,
    },
    /// The walls of a box whose inside is `min..max` (m), layers generated outward; walls only.
    Tank {
        /// Inner lower corner (m).
        min: Vec<f64>,
        /// Inner upper corner (m).
        max: Vec<f64>,
        /// Leave the top open (default true).
        #[serde(default = "default_true")]
        open_top: bool,
    },
}

/// Initial velocity of a fluid region.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocitySpec {
    /// The same velocity everywhere (m/s).
    Uniform {
        /// Velocity (m/s).
        value: Vec<f64>,
    },
    /// Solid-body rotation about `center` (m) at `omega` (rad/s, counter-clockwise positive);
    /// in 3D about the line through `center` along `axis` (default z).
    Rotation {
        /// Centre of rotation (m), a point of the axis in 3D.
        center: Vec<f64>,
        /// Angular velocity (rad/s), counter-clockwise positive (right-handed about `axis`).
        omega: f64,
        /// Direction of the rotation axis (3D only, any length but zero; default `[0, 0, 1]`).
        #[serde(default)]
        axis: Option<Vec<f64>>,
    },
    /// Affine field `u = u0 + A (x - x0)`.
    Affine {
        /// Velocity at `x0` (m/s).
        u0: Vec<f64>,
        /// Reference point (m).
        x0: Vec<f64>,
        /// Velocity gradient rows (1/s).
        a: Vec<Vec<f64>>,
    },
    /// Components as expressions in `x`, `y` (and `z`), `t = 0` and the case's constants
    /// (m/s).
    Expression {
        /// x component (m/s).
        u: String,
        /// y component (m/s).
        v: String,
        /// z component (m/s), 3D only.
        #[serde(default)]
        w: Option<String>,
    },
}

/// Initial pressure of a fluid region: a built-in analytic field.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PressureSpec {
    /// Constant pressure (Pa).
    Uniform {
        /// Pressure (Pa).
        value: f64,
    },
    /// `p = offset + rho |g| (surface - y)`: hydrostatic below height `surface` (m), plus
    /// `offset` (Pa), the weight of any layers above (e.g. a lighter layer on a heavy one).
    Hydrostatic {
        /// Height of this layer's top, the free surface for a single layer (m).
        surface: f64,
        /// Pressure at `surface` (Pa), default 0.
        #[serde(default)]
        offset: f64,
        /// Density of the column above (kg/m^3); default the region's own phase density
        /// (set it to the surrounding fluid's for a group immersed in another phase).
        #[serde(default)]
        density: Option<f64>,
    },
    /// An expression in `x`, `y` (and `z`), `t = 0` and the case's constants (Pa). In a
    /// projection method the initial pressure is the t = 0 record and the solver's first
    /// guess, not a constraint: the first pressure solve replaces it.
    Expression {
        /// The pressure (Pa).
        p: String,
    },
    /// Exact pressure of a rotating square patch (cases.md): `lap p = 2 rho omega^2`, 0 on edges.
    SquarePatch {
        /// Centre of the square (m).
        center: Vec<f64>,
        /// Side length (m).
        side: f64,
        /// Angular velocity (rad/s).
        omega: f64,
    },
}

/// A fluid region.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FluidSpec {
    /// Name of its phase.
    pub phase: String,
    /// Its shape.
    pub shape: ShapeSpec,
    /// Initial velocity (default at rest).
    #[serde(default)]
    pub velocity: Option<VelocitySpec>,
    /// Initial pressure (default zero).
    #[serde(default)]
    pub pressure: Option<PressureSpec>,
    /// Replace particles of earlier regions where they overlap (otherwise overlap is an error).
    #[serde(default)]
    pub overrides: bool,
    /// Group label for diagnostics (e.g. settling groups).
    #[serde(default)]
    pub group: Option<String>,
    /// How the region's particles are placed: on the case's lattice (default) or, for a
    /// circle in 2D, on concentric rings.
    #[serde(default)]
    pub arrangement: Arrangement,
}

/// How a fluid region's particles are placed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Arrangement {
    /// On the lattice of spacing l0 shared by every region and wall.
    #[default]
    Lattice,
    /// A circle in 2D on concentric rings of spacing `h = R / round(R / l0)`: ring `k` at
    /// radius `(k + 1/2) h` holds `round(2 pi (k + 1/2))` particles, every other ring turned
    /// by half a step, so each particle keeps an area of about `h^2` and the edge is a
    /// smooth circle, not the lattice's staircase (whose corners seed the surface modes
    /// 4, 8, 12, ... of a disc under tension: docs/decisions.md, "The rotating disc is
    /// unstable").
    Rings,
}

/// A solid wall region.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WallSpec {
    /// Its shape.
    pub shape: ShapeSpec,
}

/// A pressure probe.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// Name (CSV column).
    pub name: String,
    /// Location (m).
    pub position: Vec<f64>,
}

/// Breakdown criteria (cases.md, "Breakdown").
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BreakdownSpec {
    /// Interpenetration: a pair closer than this fraction of `l0`.
    #[serde(default = "default_min_pair")]
    pub min_pair_distance: f64,
    /// Largest allowed speed (m/s); default 50 x the case velocity scale.
    #[serde(default)]
    pub max_speed: Option<f64>,
    /// Smallest allowed time step as a fraction of the largest (`dt_max` or the viscous limit,
    /// whichever is smaller).
    #[serde(default = "default_min_dt_ratio")]
    pub min_dt_ratio: f64,
}

impl Default for BreakdownSpec {
    fn default() -> Self {
        BreakdownSpec {
            min_pair_distance: default_min_pair(),
            max_speed: None,
            min_dt_ratio: default_min_dt_ratio(),
        }
    }
}

fn default_min_pair() -> f64 {
    0.3
}
fn default_laplace_tolerance() -> f64 {
    0.1
}

fn default_min_dt_ratio() -> f64 {
    1e-3
}

/// A comparison against reference data, written by the run.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ValidationSpec {
    /// Dam-break front against Martin & Moyce (1952): `Z = front/L` against `T = t sqrt(2g/L)`.
    DamBreak {
        /// Initial column width `L` (m); the front is measured from the left wall at `x = wall_x`.
        column_width: f64,
        /// x of the wall the column stands against (m).
        #[serde(default)]
        wall_x: f64,
    },
    /// Bottom pressure of still water against `rho g H` (or a given reference).
    Hydrostatic {
        /// Water depth `H` (m).
        depth: f64,
        /// Reference bottom pressure (Pa); default `rho g H` with the first phase's density.
        #[serde(default)]
        reference: Option<f64>,
        /// Probe name that samples the bottom pressure.
        probe: String,
        /// Averaging window at the end of the run (s).
        #[serde(default = "default_window")]
        window: f64,
        /// Largest relative difference from the reference that passes (default 0.05).
        #[serde(default = "default_hydrostatic_tolerance")]
        tolerance: f64,
    },
    /// Settling or surfacing groups: heavier groups must reach the bottom, lighter ones the
    /// free surface; their early acceleration is compared with `g |rho_g - rho_w| /
    /// (rho_g + rho_w)` (a circle in unbounded fluid, cases.md), rho_w the first phase's.
    Groups {
        /// Height of the tank bottom (m).
        bottom: f64,
        /// Height of the initial free surface (m).
        surface: f64,
        /// A group has arrived when its centroid is this close to its target (m).
        #[serde(default = "default_group_distance")]
        distance: f64,
        /// Window for the early acceleration, from rest (s).
        #[serde(default = "default_early_time")]
        early_time: f64,
    },
    /// A disc in solid rotation, an exact steady state under tension: pressure
    /// `rho omega^2 (r^2 - R_s^2)/2` with `R_s = R - l0/2` (the surface particles' centres).
    /// Checks the centre pressure (probe `probe`, mean from `from` s to the end) within 5 %,
    /// the disc's radius at the end within one spacing, and particles with at most one
    /// neighbour below 1 % at the end.
    RotatingDisc {
        /// Centre (m).
        center: Vec<f64>,
        /// Radius `R` (m).
        radius: f64,
        /// Angular velocity (rad/s).
        omega: f64,
        /// Probe at the centre.
        probe: String,
        /// Start of the averaging window (s), after the pressure has built up.
        #[serde(default)]
        from: f64,
    },
    /// A disc in solid rotation with a small perturbation of azimuthal mode `n`: the
    /// centrifugal Rayleigh-Taylor instability of its free surface (`analysis::rim_mode`).
    /// The amplitude of mode `n` of the initially outermost row's radial displacement must
    /// follow linear theory, `(U / gamma) sinh(gamma t)` with `gamma = omega sqrt(n - 1)` and
    /// `U` the mode's initial radial velocity at the rim, within `tolerance` (relative) at
    /// every output up to `until` (s), while the amplitude stays small (linear theory).
    SurfaceMode {
        /// Centre (m).
        center: Vec<f64>,
        /// Radius `R` (m).
        radius: f64,
        /// Angular velocity (rad/s).
        omega: f64,
        /// Azimuthal mode number `n` (at least 2).
        mode: u32,
        /// End of the compared window (s).
        until: f64,
        /// Largest accepted relative error (dimensionless).
        #[serde(default = "default_mode_tolerance")]
        tolerance: f64,
    },
    /// An initially circular drop of radius `R` in the strain `u = A0 x`, `v = -A0 y` about its
    /// centre (Monaghan 1994): it stays an ellipse whose semi-axes follow
    /// `a' = A a`, `b = R^2 / a`, `A' = A^2 (b^2 - a^2)/(a^2 + b^2)`. Checks the semi-axes
    /// (from the second moments of the particle positions) against that solution at every
    /// output, largest relative error within 2 %.
    EllipticDrop {
        /// Centre (m).
        center: Vec<f64>,
        /// Initial radius `R` (m).
        radius: f64,
        /// Initial strain rate `A0` (1/s).
        strain_rate: f64,
    },
    /// A drop at rest under interfacial tension (the case's one `[[interfaces]]` entry) or,
    /// with no interface and no `outside` probe, a free drop under its phase's
    /// `surface_tension`: the pressure jump between a probe inside and one outside (the
    /// void's 0 Pa for a free drop), each averaged from `from` (s) to the end, against the
    /// Laplace law `sigma (d - 1) / R` (`sigma / R` for a circle, `2 sigma / R` for a
    /// sphere), within `tolerance` (relative).
    Laplace {
        /// Probe inside the drop.
        inside: String,
        /// Probe outside the drop (none for a free drop).
        #[serde(default)]
        outside: Option<String>,
        /// Drop radius `R` (m).
        radius: f64,
        /// Start of the averaging window (s).
        #[serde(default)]
        from: f64,
        /// Largest accepted relative error (default 0.1).
        #[serde(default = "default_laplace_tolerance")]
        tolerance: f64,
    },
    /// An exact steady flow (a Taylor-Green cell in a slip box, solid rotation): the first
    /// fluid region's initial velocity field, evaluated at the fluid particles' positions at
    /// the end of the run, against their velocities. Checks the relative L2 error,
    /// `sqrt(sum |u_i - u(x_i)|^2 / sum |u(x_i)|^2)`, within `tolerance`.
    SteadyFlow {
        /// Largest accepted relative L2 error (dimensionless).
        tolerance: f64,
    },
    /// A probe against a reference curve the case names (a wall-pressure gauge of an
    /// experiment, another code's result): the probe's moving average against the curve at
    /// every reference time the run covers; RMS and largest difference within tolerances
    /// (the probe's unit, Pa).
    ProbeReference {
        /// Probe compared.
        probe: String,
        /// The reference curve (time, value).
        reference: ReferenceFile,
        /// Largest accepted RMS difference (Pa).
        rms_tolerance: f64,
        /// Largest accepted single difference (Pa).
        peak_tolerance: f64,
        /// Moving-average window applied to the probe before comparing (s); 0 compares the
        /// raw samples.
        #[serde(default = "default_smoothing")]
        smoothing: f64,
    },
    /// The front (the largest x of the fluid, measured from `wall_x`) against a reference
    /// curve the case names: RMS and largest difference within tolerances (m).
    FrontReference {
        /// The reference curve (time, front distance from the wall).
        reference: ReferenceFile,
        /// x of the wall the front is measured from (m).
        #[serde(default)]
        wall_x: f64,
        /// Largest accepted RMS difference (m).
        rms_tolerance: f64,
        /// Largest accepted single difference (m).
        peak_tolerance: f64,
    },
}

/// The probes' 1 ms moving average, as `probes_smoothed.csv` (decisions.md "Probe noise").
fn default_smoothing() -> f64 {
    1e-3
}

fn default_window() -> f64 {
    1.0
}

fn default_group_distance() -> f64 {
    0.03
}

/// 15 %: at l0 = R/25 the mode-6 growth of `rotating_disc_mode` lies within 7.4 % of linear
/// theory up to t = 1.05 s (docs/decisions.md, "The rotating disc is unstable").
fn default_mode_tolerance() -> f64 {
    0.15
}

fn default_hydrostatic_tolerance() -> f64 {
    0.05
}

fn default_early_time() -> f64 {
    0.05
}

impl Case {
    /// Reads and validates a case file, applying `key=value` overrides first.
    pub fn from_file(path: &Path, overrides: &[(String, String)]) -> Result<Case, CaseError> {
        let label = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| CaseError::new(&label, "", "", format!("cannot read case file: {e}")))?;
        let mut case = Case::parse(&text, &label, overrides)?;
        let base = path.parent().unwrap_or(Path::new("."));
        case.load_references(base, &label)?;
        Ok(case)
    }

    /// Parses and validates case text; `label` names its source in errors, and files the
    /// case names are read relative to the working folder.
    pub fn from_str_named(
        text: &str,
        label: &str,
        overrides: &[(String, String)],
    ) -> Result<Case, CaseError> {
        let mut case = Case::parse(text, label, overrides)?;
        case.load_references(Path::new("."), label)?;
        Ok(case)
    }

    /// Reads the reference curves the validation names and resolves the settled start's
    /// checkpoint, relative to `base`.
    fn load_references(&mut self, base: &Path, label: &str) -> Result<(), CaseError> {
        self.load_meshes(base, label)?;
        if let Some(init) = &mut self.initial {
            check_initial(init, label)?;
            if let Some(state) = &init.state {
                init.path = base.join(state);
                if !init.path.is_file() {
                    let value = format!("{state:?}");
                    let msg = format!("no checkpoint file at {}", init.path.display());
                    return Err(CaseError::new(label, "initial.state", &value, msg));
                }
            }
        }
        let reference = match &mut self.validation {
            Some(ValidationSpec::ProbeReference { reference, .. })
            | Some(ValidationSpec::FrontReference { reference, .. }) => reference,
            _ => return Ok(()),
        };
        reference.load(base).map_err(|m| {
            let value = format!("{:?}", reference.file);
            CaseError::new(label, "validation.reference.file", &value, m)
        })
    }

    /// Reads the STL surfaces the shapes name, relative to `base`.
    fn load_meshes(&mut self, base: &Path, label: &str) -> Result<(), CaseError> {
        let names: Vec<String> = (0..self.fluid.len())
            .map(|k| format!("fluid.{k}.shape.file"))
            .chain((0..self.walls.len()).map(|k| format!("walls.{k}.shape.file")))
            .collect();
        let fluid = self.fluid.iter_mut().map(|f| &mut f.shape);
        let walls = self.walls.iter_mut().map(|w| &mut w.shape);
        for (shape, field) in fluid.chain(walls).zip(names) {
            if let ShapeSpec::Stl { file, mesh } = shape {
                let path = base.join(&*file);
                let m = crate::input::stl::Mesh::read(&path).map_err(|m| {
                    let msg = format!("{}: {m}", path.display());
                    CaseError::new(label, &field, format!("{file:?}"), msg)
                })?;
                *mesh = Some(std::sync::Arc::new(m));
            }
        }
        Ok(())
    }

    /// Parses and validates case text without reading the files it names.
    fn parse(text: &str, label: &str, overrides: &[(String, String)]) -> Result<Case, CaseError> {
        let err = |field: &str, value: &str, message: String| {
            CaseError::new(label, field, value, message)
        };
        let mut table: toml::Table = toml::from_str(text).map_err(|e| {
            let message = e.message().trim();
            match e.span() {
                Some(s) => {
                    let (line, field, value) = syntax_location(text, s.start);
                    err(&field, &value, format!("line {line}: {message}"))
                }
                None => err("", "", message.to_string()),
            }
        })?;
        for (k, v) in overrides {
            apply_override(&mut table, k, v).map_err(|m| err(k, v, m))?;
        }
        let gravity_given = table
            .get("physics")
            .and_then(|p| p.get("gravity"))
            .is_some();
        let source = table.clone();
        let mut case: Case =
            serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(|e| {
                let mut field = dotted_path(&e.path().to_string());
                let mut msg = e.inner().message().trim().to_string();
                let value = value_at(&source, &field).unwrap_or_default();
                // toml's wording when a name (an enum) is given as a number, table or array.
                if msg == "invalid type: unit variant, expected string only" {
                    msg = "must be one of the names, in quotes".to_string();
                }
                // A missing field is named with its full path (`phases.0.density`).
                if let Some(name) = msg
                    .strip_prefix("missing field `")
                    .and_then(|r| r.strip_suffix('`'))
                {
                    field = if field.is_empty() {
                        name.to_string()
                    } else {
                        format!("{field}.{name}")
                    };
                    msg = "missing (required)".to_string();
                }
                // Locate the field in the source when possible.
                let line = locate_field(text, &msg)
                    .map(|l| format!(" (line {l})"))
                    .unwrap_or_default();
                err(&field, &value, format!("{msg}{line}"))
            })?;
        // Only for a dimension the solver has (any other is refused by `validate`, naming it;
        // a huge one must not size a vector first: the fuzz target found that).
        if !gravity_given && matches!(case.dimension, 2 | 3) {
            case.physics.gravity = default_gravity_of(case.dimension);
        }
        case.validate(label)?;
        Ok(case)
    }

    /// The resolved scheme of this case (`label` names the case in errors).
    pub fn scheme(&self, label: &str) -> Result<crate::numerics::Scheme, CaseError> {
        let courant = self.time.dt_fixed.is_none().then_some(self.time.courant);
        self.scheme.resolve(courant, self.particles.spacing, label)
    }

    /// A fingerprint of everything that shapes the particle state (domain, particles, physics,
    /// time stepping, scheme, solver, phases, regions, walls, constants), not of what only
    /// says how long to run or what to write (end time, step limit, output, probes,
    /// validation, breakdown limits): a checkpoint of this case may continue under any of
    /// those. FNV-1a 64 of the canonical TOML.
    pub fn fingerprint(&self) -> u64 {
        let mut c = self.clone();
        c.name = String::new();
        c.description = String::new();
        c.time.end = 0.0;
        c.time.max_steps = None;
        c.output = OutputSpec::default();
        c.probes = Vec::new();
        c.validation = None;
        c.breakdown = BreakdownSpec::default();
        let text = toml::to_string(&c).expect("a case serialises");
        text.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }

    /// Index of the phase called `name`.
    pub fn phase_index(&self, name: &str) -> Option<usize> {
        self.phases.iter().position(|p| p.name == name)
    }
}

/// A settled start names one source, a relaxation a positive time and a fraction in (0, 1).
fn check_initial(init: &InitialSpec, label: &str) -> Result<(), CaseError> {
    let relax = match (&init.state, &init.relax) {
        (Some(_), None) => return Ok(()),
        (None, Some(r)) => r,
        (s, _) => {
            let value = if s.is_some() {
                "state and relax"
            } else {
                "neither"
            };
            let msg = "a settled start takes `state` (a checkpoint) or `relax` (a relaxation first), one of them";
            return Err(CaseError::new(label, "initial", value, msg));
        }
    };
    if !(relax.time > 0.0) || !relax.time.is_finite() {
        let msg = "the longest relaxation must be a positive number of seconds";
        return Err(CaseError::new(
            label,
            "initial.relax.time",
            relax.time.to_string(),
            msg,
        ));
    }
    if let Some(f) = relax.kinetic_fraction.filter(|f| !(*f > 0.0 && *f < 1.0)) {
        let msg = "a fraction of the largest kinetic energy, between 0 and 1";
        return Err(CaseError::new(
            label,
            "initial.relax.kinetic_fraction",
            f.to_string(),
            msg,
        ));
    }
    Ok(())
}

/// Finds the line of the first back-quoted name in a serde message within the TOML text.
fn locate_field(text: &str, msg: &str) -> Option<usize> {
    let start = msg.find('`')? + 1;
    let end = start + msg[start..].find('`')?;
    let name = &msg[start..end];
    text.lines()
        .position(|l| {
            let t = l.trim_start();
            t.starts_with(name) && t[name.len()..].trim_start().starts_with(['=', '.'])
        })
        .map(|l| l + 1)
}

/// `phases[0].density` (serde's path) as `phases.0.density` (the `--set` form).
/// The value at dotted `field` (`walls.0.shape.type`) of `table`, as TOML writes it.
fn value_at(table: &toml::Table, field: &str) -> Option<String> {
    let mut keys = field.split('.');
    let mut v = table.get(keys.next()?)?;
    for k in keys {
        v = match v {
            toml::Value::Table(t) => t.get(k)?,
            toml::Value::Array(a) => a.get(k.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(v.to_string())
}

fn dotted_path(path: &str) -> String {
    if path == "." {
        return String::new();
    }
    path.replace('[', ".").replace(']', "")
}

/// Where a TOML syntax error at byte `at` of `text` lies: its line (from 1), the dotted
/// field of that line (enclosing table and key, when the line has one) and the line's value.
fn syntax_location(text: &str, at: usize) -> (usize, String, String) {
    let at = (0..=at.min(text.len()))
        .rev()
        .find(|&k| text.is_char_boundary(k))
        .unwrap_or(0);
    let before = &text[..at];
    let line_no = before.matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
    let table = before
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string())
        .unwrap_or_default();
    let (key, value) = match line.split_once('=') {
        Some((k, v)) if !line.starts_with('[') => (k.trim().to_string(), v.trim().to_string()),
        _ => (String::new(), String::new()),
    };
    let field = match (table.is_empty(), key.is_empty()) {
        (_, true) => table,
        (true, false) => key,
        (false, false) => format!("{table}.{key}"),
    };
    (line_no, field, value)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A minimal valid case: a water block in a 1 m box, no walls.
    pub(crate) const MINIMAL: &str = r#"
name = "t"
[domain]
min = [0.0, 0.0]
max = [1.0, 1.0]
[particles]
spacing = 0.05
[time]
end = 0.1
[[phases]]
name = "water"
density = 1000.0
[[fluid]]
phase = "water"
shape = { type = "rectangle", min = [0.0, 0.0], max = [0.5, 0.5] }
"#;

    #[test]
    fn minimal_case_parses() {
        let c = Case::from_str_named(MINIMAL, "t.toml", &[]).unwrap();
        assert_eq!(c.particles.re_lap, 3.1);
        assert_eq!(c.scheme.name, "MPS");
    }

    /// A dimension other than 2 or 3, however large, is one error naming the field.
    #[test]
    fn a_huge_dimension_is_refused_not_allocated() {
        for d in ["4289940482258035260", "0", "4"] {
            let text = format!("dimension = {d}\n{MINIMAL}");
            let e = Case::from_str_named(&text, "t.toml", &[]).unwrap_err();
            let s = e.to_string();
            assert!(s.contains("dimension") && s.contains(d), "{s}");
        }
    }

    /// Interfaces name two different known phases once each, with a positive tension.
    #[test]
    fn a_bad_interface_is_named() {
        let two = format!("{MINIMAL}[[phases]]\nname = \"oil\"\ndensity = 800.0\n");
        let with = |t: &str| format!("{two}[[interfaces]]\n{t}\n");
        let ok = with("phases = [\"water\", \"oil\"]\ntension = 0.03");
        let c = Case::from_str_named(&ok, "t.toml", &[]).unwrap();
        assert_eq!(c.interfaces[0].tension, 0.03);
        for (text, field, value) in [
            (
                "phases = [\"water\", \"gas\"]\ntension = 0.03",
                "interfaces.0.phases",
                "\"gas\"",
            ),
            (
                "phases = [\"water\", \"water\"]\ntension = 0.03",
                "interfaces.0.phases",
                "",
            ),
            (
                "phases = [\"water\"]\ntension = 0.03",
                "interfaces.0.phases",
                "",
            ),
            (
                "phases = [\"water\", \"oil\"]\ntension = -1.0",
                "interfaces.0.tension",
                "-1",
            ),
        ] {
            let e = Case::from_str_named(&with(text), "t.toml", &[]).unwrap_err();
            assert_eq!(e.field, field, "{e}");
            assert!(e.value.contains(value), "{e}");
            assert!(e.to_string().contains("t.toml"), "{e}");
        }
        let twice = format!("{ok}[[interfaces]]\nphases = [\"oil\", \"water\"]\ntension = 0.02\n");
        let e = Case::from_str_named(&twice, "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "interfaces.1.phases", "{e}");
    }

    /// A phase's free-surface tension is zero or positive; the free drop's Laplace check (no
    /// outside probe) needs exactly one phase with one.
    #[test]
    fn a_bad_surface_tension_is_named() {
        let tension = |v: &str| {
            MINIMAL.replace(
                "density = 1000.0",
                &format!("density = 1000.0\nsurface_tension = {v}"),
            )
        };
        let c = Case::from_str_named(&tension("0.072"), "t.toml", &[]).unwrap();
        assert_eq!(c.phases[0].surface_tension, 0.072);
        for v in ["-0.1", "nan"] {
            let e = Case::from_str_named(&tension(v), "t.toml", &[]).unwrap_err();
            assert_eq!(e.field, "phases.0.surface_tension", "{e}");
        }
        let check = "[[probes]]\nname = \"c\"\nposition = [0.0, 0.0]\n[validation]\nkind = \"laplace\"\ninside = \"c\"\nradius = 0.1\n";
        let e = Case::from_str_named(&format!("{MINIMAL}{check}"), "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "phases", "{e}");
        Case::from_str_named(&format!("{}{check}", tension("0.072")), "t.toml", &[]).unwrap();
    }

    #[test]
    fn unknown_field_is_named() {
        let text = MINIMAL.replace("spacing = 0.05", "spacing = 0.05\nspacin = 1");
        let e = Case::from_str_named(&text, "t.toml", &[]).unwrap_err();
        let s = e.to_string();
        assert!(s.contains("t.toml") && s.contains("spacin"), "{s}");
        assert!(!s.contains('\n'));
    }

    #[test]
    fn negative_spacing_is_named_with_its_value() {
        let e = Case::from_str_named(
            MINIMAL,
            "t.toml",
            &[("particles.spacing".into(), "-0.01".into())],
        )
        .unwrap_err();
        assert_eq!(e.field, "particles.spacing");
        assert_eq!(e.value, "-0.01");
    }

    /// A spacing beyond the domain's shortest side is refused: its wall layers (1e308 m
    /// each) once overflowed to an unbounded lattice box and the set-up never ended.
    #[test]
    fn a_spacing_beyond_the_domain_is_named() {
        let e = Case::from_str_named(
            MINIMAL,
            "t.toml",
            &[("particles.spacing".into(), "1e308".into())],
        )
        .unwrap_err();
        assert_eq!(e.field, "particles.spacing", "{e}");
        assert!(e.to_string().contains("shortest side"), "{e}");
    }

    /// The PPE's volume tolerance is a dimensionless fraction in [0, 1), 1e-8 by default and
    /// off under a tolerance of the case's own: 0 is off, a negative
    /// or NaN value is named with the field and its value.
    #[test]
    fn a_bad_volume_tolerance_is_named() {
        let set = |v: &str| [("solver.volume_tolerance".to_string(), v.to_string())];
        let c = Case::from_str_named(MINIMAL, "t.toml", &set("1e-9")).unwrap();
        assert_eq!(c.solver.volume_rule(), 1e-9);
        let off = Case::from_str_named(MINIMAL, "t.toml", &set("0")).unwrap();
        assert_eq!(off.solver.volume_rule(), 0.0);
        let plain = Case::from_str_named(MINIMAL, "t.toml", &[]).unwrap();
        assert_eq!(plain.solver.volume_rule(), 1e-8);
        // A tolerance of the case's own is solved to, unless the rule is set too.
        let tight = [("solver.tolerance".to_string(), "1e-12".to_string())];
        let own = Case::from_str_named(MINIMAL, "t.toml", &tight).unwrap();
        assert_eq!(own.solver.volume_rule(), 0.0);
        let both = [tight[0].clone(), set("1e-9")[0].clone()];
        let both = Case::from_str_named(MINIMAL, "t.toml", &both).unwrap();
        assert_eq!(both.solver.volume_rule(), 1e-9);
        for bad in ["-1e-8", "1.5", "nan"] {
            let e = Case::from_str_named(MINIMAL, "t.toml", &set(bad)).unwrap_err();
            assert_eq!(e.field, "solver.volume_tolerance", "{e}");
            assert!(e.to_string().contains("t.toml"), "{e}");
        }
    }

    #[test]
    fn region_outside_domain_is_an_error() {
        let text = MINIMAL.replace("max = [0.5, 0.5]", "max = [1.5, 0.5]");
        let e = Case::from_str_named(&text, "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "fluid.0.shape");
    }

    #[test]
    fn override_sets_nested_and_indexed_fields() {
        let c = Case::from_str_named(
            MINIMAL,
            "t.toml",
            &[
                ("time.end".into(), "0.5".into()),
                ("fluid.0.phase".into(), "water".into()),
                ("scheme.name".into(), "MPS-HS-GC-DS".into()),
            ],
        )
        .unwrap();
        assert_eq!(c.time.end, 0.5);
        assert_eq!(c.scheme.name, "MPS-HS-GC-DS");
    }

    #[test]
    fn a_missing_field_is_named_with_its_full_path() {
        let text = MINIMAL.replace("density = 1000.0", "");
        let e = Case::from_str_named(&text, "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "phases.0.density", "{e}");
        assert!(e.message.contains("missing"), "{e}");
        let e =
            Case::from_str_named(&MINIMAL.replace("name = \"t\"", ""), "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "name", "{e}");
        let e = Case::from_str_named(
            MINIMAL,
            "t.toml",
            &[("particles.spacing".into(), "abc".into())],
        )
        .unwrap_err();
        assert_eq!(e.field, "particles.spacing", "{e}");
        assert_eq!(e.value, "\"abc\"", "{e}");
    }

    /// A value of the wrong type is named with its field and its value; a name (an enum)
    /// given as a number says that a quoted name is wanted, not toml's "unit variant".
    #[test]
    fn a_value_of_the_wrong_type_is_shown() {
        let set = |k: &str, v: &str| {
            Case::from_str_named(MINIMAL, "t.toml", &[(k.into(), v.into())]).unwrap_err()
        };
        let e = set("scheme.wall_pressure", "3");
        assert_eq!(
            (e.field.as_str(), e.value.as_str()),
            ("scheme.wall_pressure", "3")
        );
        assert!(e.message.contains("in quotes"), "{e}");
        let e = set("scheme.surface_pressure", "\"edge\"");
        assert_eq!(e.value, "\"edge\"", "{e}");
        assert!(e.message.contains("mean-surface"), "{e}");
    }

    #[test]
    fn the_fingerprint_ignores_how_long_and_what_to_write_but_not_the_physics() {
        let base = Case::from_str_named(MINIMAL, "t.toml", &[])
            .unwrap()
            .fingerprint();
        let with = |k: &str, v: &str| {
            Case::from_str_named(MINIMAL, "t.toml", &[(k.into(), v.into())])
                .unwrap()
                .fingerprint()
        };
        assert_eq!(with("time.end", "5.0"), base);
        assert_eq!(with("output.interval", "0.2"), base);
        assert_ne!(with("physics.gravity", "[0.0, -1.0]"), base);
        assert_ne!(with("scheme.name", "MPS-HS-GC-DS"), base);
        assert_ne!(with("scheme.shifting.enabled", "true"), base);
        assert_ne!(with("domain.max", "[1.0, 2.0]"), base);
    }

    #[test]
    fn unknown_phase_is_named() {
        let e = Case::from_str_named(MINIMAL, "t.toml", &[("fluid.0.phase".into(), "oil".into())])
            .unwrap_err();
        assert_eq!(e.field, "fluid.0.phase");
        assert_eq!(e.value, "\"oil\"");
    }

    #[test]
    fn a_syntax_error_names_the_line_and_the_field() {
        let text = "name = \"t\"\n[time]\nend = 1.0\nend = 2.0\n";
        let e = Case::from_str_named(text, "c.toml", &[]).unwrap_err();
        assert_eq!(e.field, "time.end");
        assert_eq!(e.value, "2.0");
        assert!(e.message.starts_with("line 4: "), "{e}");
        let e = Case::from_str_named("name = \"t\"\n[time\n", "c.toml", &[]).unwrap_err();
        assert!(e.message.starts_with("line 2: "), "{e}");
    }

    #[test]
    fn a_validation_without_its_probe_or_with_a_bad_centre_is_refused() {
        let disc = |center: &str, probe: &str| {
            format!(
                "{MINIMAL}\n[[probes]]\nname = \"c\"\nposition = [0.2, 0.2]\n[validation]\n\
                 kind = \"rotating_disc\"\ncenter = {center}\nradius = 0.2\nomega = 1.0\n\
                 probe = \"{probe}\"\n"
            )
        };
        assert!(Case::from_str_named(&disc("[0.2, 0.2]", "c"), "t.toml", &[]).is_ok());
        let e = Case::from_str_named(&disc("[0.2, 0.2]", "x"), "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "validation.probe");
        let e = Case::from_str_named(&disc("[0.2]", "c"), "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "validation.center");
    }

    /// A steady-flow check needs the exact field, the first region's velocity.
    #[test]
    fn a_steady_flow_check_without_an_initial_velocity_is_refused() {
        let steady = format!("{MINIMAL}[validation]\nkind = \"steady_flow\"\ntolerance = 0.1\n");
        let e = Case::from_str_named(&steady, "t.toml", &[]).unwrap_err();
        assert_eq!(e.field, "validation.kind");
        let set = [(
            "fluid.0.velocity".to_string(),
            "{ type = \"uniform\", value = [0.1, 0.0] }".to_string(),
        )];
        assert!(Case::from_str_named(&steady, "t.toml", &set).is_ok());
        let set = [("validation.tolerance".to_string(), "-1".to_string())];
        let e = Case::from_str_named(&steady, "t.toml", &set).unwrap_err();
        assert!(e.field == "validation.tolerance" || e.field == "validation.kind");
    }
}
