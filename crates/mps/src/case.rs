//! The case file: a TOML description of one simulation, its validation and overrides.
//!
//! Every field is documented in the README's case-file reference. Unknown fields are errors;
//! every error names the file, the field and the offending value.

use serde::Deserialize;
use std::fmt;
use std::path::Path;

/// An error in a case file, naming the file, the field and the value.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseError {
    /// The file (or built-in example name) the case came from.
    pub file: String,
    /// Dotted path of the field, e.g. `particles.spacing` (empty when unknown).
    pub field: String,
    /// The offending value as written (empty when not applicable).
    pub value: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
            if !self.value.is_empty() {
                write!(f, " = {}", self.value)?;
            }
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for CaseError {}

/// A complete simulation case.
#[derive(Debug, Clone, Deserialize)]
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
}

fn default_dimension() -> usize {
    2
}

/// The simulation box.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DomainSpec {
    /// Lower corner (m).
    pub min: Vec<f64>,
    /// Upper corner (m).
    pub max: Vec<f64>,
}

/// Particle spacing and kernel radii.
#[derive(Debug, Clone, Deserialize)]
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
#[derive(Debug, Clone, Deserialize)]
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

/// Time stepping.
#[derive(Debug, Clone, Deserialize)]
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

/// Which pressure-gradient model to use (equations.md section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GradientModel {
    /// Original MPS with `p_hat` (paper Eq. 1, 2): purely repulsive.
    Original,
    /// CMPS (paper Eq. 3): antisymmetric pair terms.
    Cmps,
    /// Taylor-consistent `(p_j - p_i)` (first term of paper Eq. 7).
    Taylor,
}

/// Source term of the pressure Poisson equation (equations.md section 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SourceModel {
    /// Original particle-number-density source.
    Pnd,
    /// Higher-order source (Khayyer & Gotoh 2009).
    Hs,
}

/// Normalisation of the HS source (equations.md section 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HsNormalization {
    /// `d / h0`: exactly `rho div u / dt` for linear velocity fields (default).
    Consistent,
    /// `1 / n0` as published; over-weights `div u`, unstable near free surfaces.
    N0,
}

/// Density-drift control added to the HS source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DriftControl {
    /// No drift control.
    None,
    /// `- gamma (rho/dt^2)(n_i - n0)/n0` on fluid particles (Tanaka & Masunaga 2010).
    Gamma,
    /// Error-compensating source terms (Khayyer & Gotoh 2011).
    Ecs,
}

/// How the pair density `rho_ij` is formed from two particle densities.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DensityAverage {
    /// `(rho_i + rho_j) / 2` (harmonic mean of `1/rho`).
    Arithmetic,
    /// `2 rho_i rho_j / (rho_i + rho_j)`.
    Harmonic,
}

/// Which density divides the pressure gradient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GradientDensity {
    /// The pair density `rho_ij`, as in the PPE (default).
    Pair,
    /// The particle's own density `rho_i`.
    Own,
}

/// Wall treatment (equations.md section 4, "the wall must push back"); see `ppe` and
/// `walls` modules for the measurements behind the default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WallPressure {
    /// PPE with zero-gradient walls (dummies left out); for the gradient, wall and dummy
    /// pressures extrapolated from the fluid with the hydrostatic term (default).
    Extrapolated,
    /// Design candidate: hydrostatic Neumann rows in the PPE, dummy = backing wall pressure +
    /// hydrostatic difference. Double-counts gravity with velocity/PND sources (kept for study).
    Hydrostatic,
    /// Standard MPS: dummies carry no pressure; walls keep their PPE pressure.
    None,
}

/// Weighting of the DS pair terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DsWeighting {
    /// Kernel-weighted average `(1/n0) sum F w` (paper Eq. 7).
    Kernel,
    /// Full restoration per pair, for study.
    None,
}

/// Dynamic Stabilization options (equations.md section 6).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DsSpec {
    /// Switch DS on or off (default: from the preset).
    pub enabled: Option<bool>,
    /// Threshold fraction `alpha_DS` of the particle diameter (default `1 - time.courant`,
    /// paper Eq. 9: 0.9 at the default Courant number 0.1; 0.9 with a fixed time step).
    pub alpha: Option<f64>,
    /// Pair-term weighting (default `kernel`).
    pub weighting: Option<DsWeighting>,
    /// Whether DS acts on fluid-wall pairs (default true).
    pub walls: Option<bool>,
}

/// Collision model options (equations.md section 5, step 2).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Switch the collision model on or off (default: from the preset).
    pub enabled: Option<bool>,
    /// Pairs closer than `alpha l0` are treated (default 0.5).
    pub alpha: Option<f64>,
    /// Coefficient of restitution `e` (default 0.2).
    pub restitution: Option<f64>,
}

/// Scheme: a named preset and optional overrides of its parts.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SchemeSpec {
    /// Preset: `MPS`, `CMPS-HS`, `MPS-HS-GC` or `MPS-HS-GC-DS`.
    #[serde(default = "default_scheme_name")]
    pub name: String,
    /// Pressure-gradient model override.
    pub gradient: Option<GradientModel>,
    /// Gradient correction override.
    pub gradient_correction: Option<bool>,
    /// GC falls back to `d I` where the moment matrix's determinant is below this fraction
    /// of the interior lattice value (default 0.2).
    pub gc_min_determinant: Option<f64>,
    /// PPE source override.
    pub source: Option<SourceModel>,
    /// HS normalisation.
    pub hs_normalization: Option<HsNormalization>,
    /// Relaxation coefficient on the PND source (1 = restore the density error in one step).
    pub pnd_relaxation: Option<f64>,
    /// Drift control override.
    pub drift: Option<DriftControl>,
    /// Drift-control coefficient `gamma`.
    pub gamma: Option<f64>,
    /// Clamp negative pressure to zero.
    pub clamp_negative_pressure: Option<bool>,
    /// Free-surface threshold `beta` in `n* < beta n0`.
    pub surface_beta: Option<f64>,
    /// Optional neighbour-count criterion: surface when count < ratio * lattice count.
    pub surface_count_ratio: Option<f64>,
    /// Wall particles with `n* < beta n0` (a side open to the air) are Dirichlet `p = 0`.
    pub wall_surface_test: Option<bool>,
    /// Count the missing part of a PPE row's neighbourhood as air at `p = 0` (Dirichlet)
    /// rather than leaving it out (zero gradient).
    pub air_ghosts: Option<bool>,
    /// Pair density average.
    pub density_average: Option<DensityAverage>,
    /// Density used in the pressure gradient.
    pub gradient_density: Option<GradientDensity>,
    /// Smooth the density near interfaces for the PPE coefficient and the gradient:
    /// `rho~_i = (n0 rho_i + sum_j w_ij rho_j) / (n0 + sum_j w_ij)` over re_grad.
    pub density_smoothing: Option<bool>,
    /// Dummy-particle pressure model.
    pub wall_pressure: Option<WallPressure>,
    /// Artificial compressibility `kappa` (1/Pa, rho-scaled) on the PPE diagonal.
    pub compressibility: Option<f64>,
    /// Collision model.
    #[serde(default)]
    pub collision: CollisionSpec,
    /// Dynamic Stabilization.
    #[serde(default)]
    pub ds: DsSpec,
}

impl Default for SchemeSpec {
    fn default() -> Self {
        toml::from_str("").expect("empty scheme table is valid")
    }
}

fn default_scheme_name() -> String {
    "MPS".into()
}

/// Linear solver choice for the PPE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverKind {
    /// IC(0)-CG below [`AUTO_AMG_UNKNOWNS`] unknowns, AMG-CG from there on (the measured
    /// crossover of their step times).
    Auto,
    /// Unpreconditioned conjugate gradient.
    Cg,
    /// Jacobi (diagonal) preconditioned CG.
    JacobiCg,
    /// Incomplete-Cholesky IC(0) preconditioned CG.
    Ic0Cg,
    /// Smoothed-aggregation algebraic multigrid preconditioned CG (module `amg`).
    AmgCg,
}

/// PPE size (unknowns) from which `auto` picks AMG-CG over IC(0)-CG: on the dam break,
/// 2 threads, IC(0)-CG was faster at 6.8k particles (17.7 vs 21.6 ms/step) and AMG-CG at
/// 12.5k (32 vs 41 ms/step).
pub const AUTO_AMG_UNKNOWNS: usize = 8000;

/// Pressure solver settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Which solver.
    #[serde(default = "default_solver")]
    pub kind: SolverKind,
    /// Relative residual tolerance.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Iteration limit; not converging within it is a breakdown.
    #[serde(default = "default_max_iter")]
    pub max_iterations: usize,
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec {
            kind: default_solver(),
            tolerance: default_tolerance(),
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
fn default_max_iter() -> usize {
    5000
}

/// Output settings.
#[derive(Debug, Clone, Deserialize)]
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
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseSpec {
    /// Name used by regions.
    pub name: String,
    /// Density (kg/m^3).
    pub density: f64,
    /// Kinematic viscosity (m^2/s).
    #[serde(default)]
    pub viscosity: f64,
}

/// A geometric shape.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Axis-aligned box between two corners (m).
    Rectangle {
        /// Lower corner (m).
        min: Vec<f64>,
        /// Upper corner (m).
        max: Vec<f64>,
    },
    /// Disc of a centre and radius (m).
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
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocitySpec {
    /// The same velocity everywhere (m/s).
    Uniform {
        /// Velocity (m/s).
        value: Vec<f64>,
    },
    /// Solid-body rotation about `center` (m) at `omega` (rad/s, counter-clockwise positive).
    Rotation {
        /// Centre of rotation (m).
        center: Vec<f64>,
        /// Angular velocity (rad/s), counter-clockwise positive.
        omega: f64,
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
}

/// Initial pressure of a fluid region: a built-in analytic field.
#[derive(Debug, Clone, Deserialize)]
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
#[derive(Debug, Clone, Deserialize)]
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
}

/// A solid wall region.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallSpec {
    /// Its shape.
    pub shape: ShapeSpec,
}

/// A pressure probe.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// Name (CSV column).
    pub name: String,
    /// Location (m).
    pub position: Vec<f64>,
}

/// Breakdown criteria (cases.md, "Breakdown").
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BreakdownSpec {
    /// Interpenetration: a pair closer than this fraction of `l0`.
    #[serde(default = "default_min_pair")]
    pub min_pair_distance: f64,
    /// Largest allowed speed (m/s); default 50 x the case velocity scale.
    #[serde(default)]
    pub max_speed: Option<f64>,
    /// Smallest allowed time step as a fraction of the largest.
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
fn default_min_dt_ratio() -> f64 {
    1e-3
}

/// A comparison against reference data, written by the run.
#[derive(Debug, Clone, Deserialize)]
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
}

fn default_window() -> f64 {
    1.0
}

fn default_group_distance() -> f64 {
    0.03
}

fn default_early_time() -> f64 {
    0.05
}

/// Sets `key` (dotted path; numbers index arrays, e.g. `fluid.0.phase`) to `value` in `table`.
/// The value is parsed as TOML (`0.01`, `true`, `[1, 2]`, `"text"`), or taken as a string.
pub fn apply_override(table: &mut toml::Table, key: &str, value: &str) -> Result<(), String> {
    let parsed: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(value.to_string()),
    };
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!("--set {key}: empty path segment"));
    }
    let mut cur = table;
    for (k, part) in parts.iter().enumerate() {
        let last = k + 1 == parts.len();
        let next_is_index = !last && parts[k + 1].parse::<usize>().is_ok();
        if last {
            cur.insert(part.to_string(), parsed);
            return Ok(());
        }
        let entry = cur
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if next_is_index {
            let idx: usize = parts[k + 1].parse().unwrap();
            let arr = entry
                .as_array_mut()
                .ok_or_else(|| format!("--set {key}: `{part}` is not an array"))?;
            let len = arr.len();
            let item = arr.get_mut(idx).ok_or_else(|| {
                format!("--set {key}: index {idx} out of range (`{part}` has {len} entries)")
            })?;
            if k + 2 == parts.len() {
                *item = parsed;
                return Ok(());
            }
            // Skip the index segment.
            let rest = parts[k + 2..].join(".");
            let t = item
                .as_table_mut()
                .ok_or_else(|| format!("--set {key}: `{part}.{idx}` is not a table"))?;
            return apply_override(t, &rest, value);
        }
        cur = entry
            .as_table_mut()
            .ok_or_else(|| format!("--set {key}: `{part}` is not a table"))?;
    }
    Ok(())
}

impl Case {
    /// Reads and validates a case file, applying `key=value` overrides first.
    pub fn from_file(path: &Path, overrides: &[(String, String)]) -> Result<Case, CaseError> {
        let label = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| CaseError {
            file: label.clone(),
            field: String::new(),
            value: String::new(),
            message: format!("cannot read case file: {e}"),
        })?;
        Case::from_str_named(&text, &label, overrides)
    }

    /// Parses and validates case text; `label` names its source in errors.
    pub fn from_str_named(
        text: &str,
        label: &str,
        overrides: &[(String, String)],
    ) -> Result<Case, CaseError> {
        let err = |field: &str, value: &str, message: String| CaseError {
            file: label.to_string(),
            field: field.to_string(),
            value: value.to_string(),
            message,
        };
        let mut table: toml::Table = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| format!("line {}: ", text[..s.start].lines().count().max(1)))
                .unwrap_or_default();
            err("", "", format!("{line}{}", e.message().trim()))
        })?;
        for (k, v) in overrides {
            apply_override(&mut table, k, v).map_err(|m| err(k, v, m))?;
        }
        let case: Case = Case::deserialize(toml::Value::Table(table.clone())).map_err(|e| {
            let msg = e.message().trim().replace('\n', " ");
            // Locate the field in the source when possible.
            let line = locate_field(text, &msg)
                .map(|l| format!(" (line {l})"))
                .unwrap_or_default();
            err("", "", format!("{msg}{line}"))
        })?;
        case.validate(label)?;
        Ok(case)
    }

    /// Checks values that the types cannot: signs, lengths, references, ranges.
    pub fn validate(&self, label: &str) -> Result<(), CaseError> {
        let err = |field: &str, value: String, message: &str| {
            Err(CaseError {
                file: label.to_string(),
                field: field.to_string(),
                value,
                message: message.to_string(),
            })
        };
        let d = self.dimension;
        if d != 2 {
            return err(
                "dimension",
                d.to_string(),
                "only 2D is supported in this version (3D is planned)",
            );
        }
        let vec_ok = |field: &str, v: &[f64]| -> Result<(), CaseError> {
            if v.len() != d {
                return err(field, format!("{v:?}"), &format!("expected {d} components"));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return err(field, format!("{v:?}"), "components must be finite");
            }
            Ok(())
        };
        vec_ok("domain.min", &self.domain.min)?;
        vec_ok("domain.max", &self.domain.max)?;
        for k in 0..d {
            if self.domain.max[k] <= self.domain.min[k] {
                return err(
                    "domain.max",
                    format!("{:?}", self.domain.max),
                    "must exceed domain.min in every component",
                );
            }
        }
        let l0 = self.particles.spacing;
        if !(l0 > 0.0 && l0.is_finite()) {
            return err("particles.spacing", l0.to_string(), "must be positive");
        }
        for (f, v) in [
            ("particles.re_grad", self.particles.re_grad),
            ("particles.re_lap", self.particles.re_lap),
        ] {
            if !(v > 1.0 && v <= 6.0) {
                return err(f, v.to_string(), "must lie in (1, 6] (units of spacing)");
            }
        }
        let ncell = self
            .domain
            .max
            .iter()
            .zip(&self.domain.min)
            .map(|(a, b)| (a - b) / l0)
            .product::<f64>();
        if ncell > 5e8 {
            return err(
                "particles.spacing",
                l0.to_string(),
                "too fine for the domain (more than 5e8 lattice sites)",
            );
        }
        vec_ok("physics.gravity", &self.physics.gravity)?;
        let t = &self.time;
        if !(t.end > 0.0 && t.end.is_finite()) {
            return err("time.end", t.end.to_string(), "must be positive");
        }
        if !(t.courant > 0.0 && t.courant <= 1.0) {
            return err("time.courant", t.courant.to_string(), "must lie in (0, 1]");
        }
        for (f, v) in [("time.dt_max", t.dt_max), ("time.dt_fixed", t.dt_fixed)] {
            if let Some(v) = v {
                if !(v > 0.0 && v.is_finite()) {
                    return err(f, v.to_string(), "must be positive");
                }
            }
        }
        if !(self.output.interval >= 0.0) {
            return err(
                "output.interval",
                self.output.interval.to_string(),
                "must be zero or positive",
            );
        }
        if !(self.solver.tolerance > 0.0 && self.solver.tolerance < 1.0) {
            return err(
                "solver.tolerance",
                self.solver.tolerance.to_string(),
                "must lie in (0, 1)",
            );
        }
        if let Err(m) = crate::scheme::Scheme::from_spec(&self.scheme) {
            return Err(CaseError {
                file: label.to_string(),
                field: m.0,
                value: m.1,
                message: m.2,
            });
        }
        if self.phases.is_empty() {
            return err("phases", "[]".into(), "at least one phase is needed");
        }
        for (k, p) in self.phases.iter().enumerate() {
            if !(p.density > 0.0 && p.density.is_finite()) {
                return err(
                    &format!("phases.{k}.density"),
                    p.density.to_string(),
                    "must be positive",
                );
            }
            if !(p.viscosity >= 0.0 && p.viscosity.is_finite()) {
                return err(
                    &format!("phases.{k}.viscosity"),
                    p.viscosity.to_string(),
                    "must be zero or positive",
                );
            }
            if self.phases[..k].iter().any(|q| q.name == p.name) {
                return err(
                    &format!("phases.{k}.name"),
                    format!("{:?}", p.name),
                    "duplicate phase name",
                );
            }
        }
        if self.fluid.is_empty() {
            return err("fluid", "[]".into(), "at least one fluid region is needed");
        }
        for (k, f) in self.fluid.iter().enumerate() {
            let base = format!("fluid.{k}");
            if !self.phases.iter().any(|p| p.name == f.phase) {
                return err(
                    &format!("{base}.phase"),
                    format!("{:?}", f.phase),
                    "no phase of this name",
                );
            }
            self.check_shape(label, &format!("{base}.shape"), &f.shape, false)?;
            let (lo, hi) = shape_bounds(&f.shape);
            for c in 0..d {
                if lo[c] < self.domain.min[c] - 1e-12 || hi[c] > self.domain.max[c] + 1e-12 {
                    return err(
                        &format!("{base}.shape"),
                        format!("{:?}..{:?}", lo, hi),
                        "region lies (partly) outside the domain",
                    );
                }
            }
            match &f.velocity {
                Some(VelocitySpec::Uniform { value }) => {
                    vec_ok(&format!("{base}.velocity.value"), value)?
                }
                Some(VelocitySpec::Rotation { center, omega }) => {
                    vec_ok(&format!("{base}.velocity.center"), center)?;
                    if !omega.is_finite() {
                        return err(
                            &format!("{base}.velocity.omega"),
                            omega.to_string(),
                            "must be finite",
                        );
                    }
                }
                Some(VelocitySpec::Affine { u0, x0, a }) => {
                    vec_ok(&format!("{base}.velocity.u0"), u0)?;
                    vec_ok(&format!("{base}.velocity.x0"), x0)?;
                    if a.len() != d {
                        return err(
                            &format!("{base}.velocity.a"),
                            format!("{a:?}"),
                            &format!("expected {d} rows"),
                        );
                    }
                    for row in a {
                        vec_ok(&format!("{base}.velocity.a"), row)?;
                    }
                }
                None => {}
            }
            if let Some(PressureSpec::SquarePatch { center, side, .. }) = &f.pressure {
                vec_ok(&format!("{base}.pressure.center"), center)?;
                if *side <= 0.0 {
                    return err(
                        &format!("{base}.pressure.side"),
                        side.to_string(),
                        "must be positive",
                    );
                }
            }
        }
        for (k, w) in self.walls.iter().enumerate() {
            self.check_shape(label, &format!("walls.{k}.shape"), &w.shape, true)?;
        }
        for (k, p) in self.probes.iter().enumerate() {
            vec_ok(&format!("probes.{k}.position"), &p.position)?;
        }
        if let Some(ValidationSpec::Hydrostatic { probe, .. }) = &self.validation {
            if !self.probes.iter().any(|p| &p.name == probe) {
                return err(
                    "validation.probe",
                    format!("{probe:?}"),
                    "no probe of this name",
                );
            }
        }
        if !(self.breakdown.min_pair_distance >= 0.0 && self.breakdown.min_pair_distance < 1.0) {
            return err(
                "breakdown.min_pair_distance",
                self.breakdown.min_pair_distance.to_string(),
                "must lie in [0, 1)",
            );
        }
        Ok(())
    }

    fn check_shape(
        &self,
        label: &str,
        field: &str,
        s: &ShapeSpec,
        wall: bool,
    ) -> Result<(), CaseError> {
        let d = self.dimension;
        let e = |f: &str, v: String, m: &str| {
            Err(CaseError {
                file: label.into(),
                field: format!("{field}.{f}"),
                value: v,
                message: m.into(),
            })
        };
        let len = |f: &str, v: &[f64]| {
            if v.len() != d || v.iter().any(|x| !x.is_finite()) {
                e(
                    f,
                    format!("{v:?}"),
                    &format!("expected {d} finite components"),
                )
            } else {
                Ok(())
            }
        };
        match s {
            ShapeSpec::Rectangle { min, max } | ShapeSpec::Tank { min, max, .. } => {
                len("min", min)?;
                len("max", max)?;
                if min.iter().zip(max).any(|(a, b)| b <= a) {
                    return e(
                        "max",
                        format!("{max:?}"),
                        "must exceed min in every component",
                    );
                }
                if !wall && matches!(s, ShapeSpec::Tank { .. }) {
                    return e("type", "\"tank\"".into(), "tank is a wall shape");
                }
            }
            ShapeSpec::Circle { center, radius } => {
                len("center", center)?;
                if !(*radius > 0.0) {
                    return e("radius", radius.to_string(), "must be positive");
                }
            }
            ShapeSpec::Polygon { points } | ShapeSpec::Polyline { points, .. } => {
                let need = if matches!(s, ShapeSpec::Polygon { .. }) {
                    3
                } else {
                    2
                };
                if points.len() < need {
                    return e(
                        "points",
                        format!("{points:?}"),
                        &format!("needs at least {need} points"),
                    );
                }
                for p in points {
                    len("points", p)?;
                }
                if let ShapeSpec::Polyline { thickness, .. } = s {
                    if !wall {
                        return e("type", "\"polyline\"".into(), "polyline is a wall shape");
                    }
                    if !(*thickness > 0.0) {
                        return e("thickness", thickness.to_string(), "must be positive");
                    }
                }
            }
        }
        Ok(())
    }

    /// Index of the phase called `name`.
    pub fn phase_index(&self, name: &str) -> Option<usize> {
        self.phases.iter().position(|p| p.name == name)
    }
}

/// Axis-aligned bounds of a shape (m).
pub fn shape_bounds(s: &ShapeSpec) -> (Vec<f64>, Vec<f64>) {
    match s {
        ShapeSpec::Rectangle { min, max } | ShapeSpec::Tank { min, max, .. } => {
            (min.clone(), max.clone())
        }
        ShapeSpec::Circle { center, radius } => (
            center.iter().map(|c| c - radius).collect(),
            center.iter().map(|c| c + radius).collect(),
        ),
        ShapeSpec::Polygon { points } | ShapeSpec::Polyline { points, .. } => {
            let pad = match s {
                ShapeSpec::Polyline { thickness, .. } => *thickness,
                _ => 0.0,
            };
            let d = points[0].len();
            let mut lo = vec![f64::MAX; d];
            let mut hi = vec![f64::MIN; d];
            for p in points {
                for k in 0..d {
                    lo[k] = lo[k].min(p[k] - pad);
                    hi[k] = hi[k].max(p[k] + pad);
                }
            }
            (lo, hi)
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
    fn unknown_phase_is_named() {
        let e = Case::from_str_named(MINIMAL, "t.toml", &[("fluid.0.phase".into(), "oil".into())])
            .unwrap_err();
        assert_eq!(e.field, "fluid.0.phase");
        assert_eq!(e.value, "\"oil\"");
    }
}
