//! Assembly of the pressure Poisson equation (equations.md section 4, variable density of
//! section 7) into a symmetric positive-definite CSR system `A p = b`.
//!
//! Row `i` reads `sum_j c_ij (p_i - p_j) + (kappa/dt^2) p_i = b_i` with
//! `c_ij = (2d/(lambda n0)) w(r_ij) / rho_ij` (re_lap), i.e. `-(1/rho) lap p = b`, `b` from
//! [`super::source`]. Unknowns: fluid and wall particles; free-surface fluid and dry walls are
//! Dirichlet `p = 0`. Dummy particles are left out (a zero-gradient wall), except with the
//! study option `wall_pressure = "hydrostatic"`, where each dummy neighbour contributes the
//! known hydrostatic difference `p_j - p_i = rho g . (r_j - r_i)`; the matrix stays symmetric
//! either way. Why zero-gradient is the default: docs/decisions.md, "Wall pressure".
//!
//! Air ghosts (`air_ghosts`, default for the HS presets; a departure from the paper): the part
//! of a row's neighbourhood that is missing (`n0 - n_i` at re_lap, dummies counted as present)
//! is air at `p = 0`, a term `c (p_i - 0)` on the diagonal (docs/decisions.md, "Air ghosts").

use super::kernel::Kernels;
use super::scheme::Scheme;
use super::source::source;
use super::walls::WallPressure;
use crate::linalg::CsrMatrix;
use crate::particles::{Kind, Vector, View, NONE};
use rayon::prelude::*;

/// Rows per chunk of the parallel assembly (docs/decisions.md, "Parallel chunk sizes").
const CHUNK: usize = 256;

/// The assembled PPE.
#[derive(Clone, Debug, Default)]
pub struct PressureSystem {
    /// The SPD matrix (rows in particle order of the unknowns).
    pub matrix: CsrMatrix,
    /// Right-hand side (1/s^2).
    pub rhs: Vec<f64>,
    /// Particle index -> row, `NONE` for Dirichlet and dummy particles.
    pub row_of: Vec<u32>,
    /// Row -> particle index.
    pub particle_of: Vec<u32>,
}

/// True when particle `i` is a Dirichlet (`p = 0`) particle: free-surface fluid, a dummy, a
/// wall particle flagged by the surface test (open to the air above the waterline), or a wall
/// particle with no fluid within `re_lap` (m) ("dry").
pub fn is_dirichlet<const D: usize>(i: usize, v: &View<D>, re_lap: f64) -> bool {
    match v.kind[i] {
        Kind::Fluid => v.free_surface[i],
        Kind::Dummy => true,
        Kind::Wall => v.free_surface[i] || !v.pairs(i, re_lap).any(|q| v.kind[q.j] == Kind::Fluid),
    }
}

/// What every row of the assembly reads.
struct Rows<'a, const D: usize> {
    v: &'a View<'a, D>,
    previous: &'a [f64],
    row_of: &'a [u32],
    k: &'a Kernels,
    s: &'a Scheme,
    gravity: Vector<D>,
    dt: f64,
}

impl<const D: usize> Rows<'_, D> {
    /// Row `row` of particle `i`: its sorted `(column, value)` entries into `entries`, and
    /// its right-hand side (1/s^2).
    fn assemble(&self, i: usize, row: u32, entries: &mut Vec<(u32, f64)>) -> f64 {
        let (v, k, s) = (self.v, self.k, self.s);
        let coef = 2.0 * D as f64 / (k.lap.lambda * k.lap.n0);
        let rho_i = v.density[i];
        let mut diag = s.compressibility / (self.dt * self.dt);
        let mut bi = source(i, v, k, &s.source, self.dt);
        let mut n_lap = 0.0;
        entries.clear();
        for q in v.pairs(i, k.lap.re) {
            n_lap += q.w;
            let c = coef * q.w / s.pair_density(rho_i, v.density[q.j]);
            match v.kind[q.j] {
                Kind::Fluid | Kind::Wall => {
                    diag += c;
                    if self.row_of[q.j] != NONE {
                        entries.push((self.row_of[q.j], -c));
                    }
                }
                Kind::Dummy => {
                    if s.wall_pressure == WallPressure::Hydrostatic {
                        bi += c * v.density[q.j] * self.gravity.dot(&q.xij);
                    }
                }
            }
        }
        if let Some(c) = s.sound_speed {
            // Slight compressibility: div u = -(1/(rho c^2)) Dp/Dt, i.e.
            // (p - p^n) / (rho c^2 dt^2) on the row (docs/decisions.md, "Sound speed").
            let beta = 1.0 / (rho_i * c * c * self.dt * self.dt);
            diag += beta;
            bi += beta * self.previous[i];
        }
        if s.air_ghosts {
            // Missing neighbourhood = air at p = 0: sum_air c (p_i - 0).
            let deficit = (k.lap.n0 - n_lap).max(0.0);
            diag += coef * deficit / rho_i;
        }
        entries.push((row, diag));
        entries.sort_unstable_by_key(|e| e.0);
        bi
    }
}

/// Assembles the PPE at the intermediate state (rows in parallel chunks, joined in order);
/// `previous` holds every particle's pressure of the last step (Pa).
pub fn assemble<const D: usize>(
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    s: &Scheme,
    gravity: Vector<D>,
    dt: f64,
) -> PressureSystem {
    let n = v.pos.len();
    let dirichlet: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| is_dirichlet(i, v, k.lap.re))
        .collect();
    let mut row_of = vec![NONE; n];
    let mut particle_of = Vec::new();
    for i in 0..n {
        if !dirichlet[i] {
            row_of[i] = particle_of.len() as u32;
            particle_of.push(i as u32);
        }
    }
    let rows = particle_of.len();
    let ctx = Rows {
        v,
        previous,
        row_of: &row_of,
        k,
        s,
        gravity,
        dt,
    };
    // Per chunk of rows: (row lengths, columns, values, right-hand sides).
    type Chunk = (Vec<u32>, Vec<u32>, Vec<f64>, Vec<f64>);
    let parts: Vec<Chunk> = (0..rows.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(rows));
            let mut lens = Vec::with_capacity(b - a);
            let mut cols = Vec::with_capacity((b - a) * 30);
            let mut vals = Vec::with_capacity((b - a) * 30);
            let mut rhs = Vec::with_capacity(b - a);
            let mut entries: Vec<(u32, f64)> = Vec::with_capacity(64);
            for row in a..b {
                let i = particle_of[row] as usize;
                let bi = ctx.assemble(i, row as u32, &mut entries);
                for &(cj, val) in &entries {
                    cols.push(cj);
                    vals.push(val);
                }
                lens.push(entries.len() as u32);
                rhs.push(bi);
            }
            (lens, cols, vals, rhs)
        })
        .collect();
    let (mut lens, mut cols, mut vals, mut rhs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (l, c, v, r) in parts {
        lens.push(l);
        cols.push(c);
        vals.push(v);
        rhs.push(r);
    }
    PressureSystem {
        matrix: CsrMatrix {
            row_ptr: crate::parallel::offsets(&lens),
            col: crate::parallel::concat(&cols),
            val: crate::parallel::concat(&vals),
        },
        rhs: crate::parallel::concat(&rhs),
        row_of,
        particle_of,
    }
}
