//! Assembly of the pressure Poisson equation (equations.md section 4, variable density of
//! section 7) into a symmetric positive-definite CSR system `A p = b`.
//!
//! Row `i` reads `sum_j c_ij (p_i - p_j) + (kappa/dt^2) p_i = b_i` with
//! `c_ij = (2d/(lambda n0)) w(r_ij) / rho_ij` (re_lap), i.e. `-(1/rho) lap p = b`, `b` from
//! [`super::source`]. Unknowns: fluid and wall particles; free-surface fluid and dry walls are
//! Dirichlet, at `p = 0` or, for free-surface fluid with `surface_pressure = "mean-surface"`,
//! at the value of [`super::surface_pressure`] (a known term `c p_j` on the neighbours' rows). Dummy particles are left out (a zero-gradient wall), except with the
//! study option `wall_pressure = "hydrostatic"`, where each dummy neighbour contributes the
//! known hydrostatic difference `p_j - p_i = rho g . (r_j - r_i)`; the matrix stays symmetric
//! either way. Why zero-gradient is the default: docs/decisions.md, "Wall pressure".
//!
//! Air ghosts (`air_ghosts`, default for the HS presets; a departure from the paper): the part
//! of a row's neighbourhood that is missing (`n0 - n_i` at re_lap, dummies counted as present)
//! is air at `p = 0`, a term `c (p_i - 0)` on the diagonal (docs/decisions.md, "Air ghosts").

use super::kernel::Kernels;
use super::pairs::count_pairs;
use super::scheme::Scheme;
use super::source::source;
use super::surface_pressure::{dirichlet_values_into, SurfacePressure};
use super::walls::WallPressure;
use crate::linalg::team::Shared;
use crate::linalg::CsrMatrix;
use crate::parallel;
use crate::particles::{Kind, Vector, View, NONE};

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
    /// In a closed domain (no Dirichlet row): the reference particle, held out of the
    /// unknowns, and its pressure (Pa), which is added to every solved pressure.
    pub level: Option<(u32, f64)>,
    /// The reference particle's own row's right-hand side (1/s^2) when the caller chose it
    /// ([`PressureReference::at`]) and holds it, else 0: with the caller's sums it makes
    /// the system consistent (a distributed run's rows are on several processes).
    pub level_source: f64,
    /// Dirichlet value of every particle (Pa): 0 but for free-surface fluid particles with
    /// `surface_pressure = "mean-surface"`; empty when all are 0.
    pub dirichlet_value: Vec<f64>,
    /// The Young-Laplace jump (Pa) each free-surface particle adds to its Dirichlet value
    /// (`numerics::free_surface_tension`), set before the assembly; empty for none.
    pub surface_jump: Vec<f64>,
    /// Per particle, whether it has no row (the assembly's scratch, kept).
    no_row: Vec<bool>,
}

/// Where the pressure level of a closed domain is fixed: the fluid particle nearest to
/// `position` (m) takes `value` (Pa); without a position, the highest fluid particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PressureReference<const D: usize> {
    /// Reference point (m), if given.
    pub position: Option<Vector<D>>,
    /// Pressure there (Pa).
    pub value: f64,
    /// Another process of a distributed run holds a Dirichlet row: the domain is not closed
    /// even where this process's rows have none.
    pub open_elsewhere: bool,
    /// The reference particle as the caller chose it over every process (its index here,
    /// `NONE` where another process holds it); the caller then removes the sources' mean
    /// (with [`PressureSystem::level_source`]). `None`: chosen here, mean removed here.
    pub at: Option<u32>,
}

impl<const D: usize> PressureReference<D> {
    /// The reference particle of view `v`: the fluid particle nearest to the position, or
    /// the highest one (largest last coordinate, lowest index on ties).
    fn particle(&self, v: &View<D>) -> Option<usize> {
        let fluid = (0..v.pos.len()).filter(|&i| v.kind[i] == Kind::Fluid);
        match self.position {
            Some(x) => {
                fluid.min_by(|&a, &b| (v.pos[a] - x).norm2().total_cmp(&(v.pos[b] - x).norm2()))
            }
            None => {
                fluid.max_by(|&a, &b| v.pos[a][D - 1].total_cmp(&v.pos[b][D - 1]).then(b.cmp(&a)))
            }
        }
    }
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
    /// Count the missing neighbourhood as air (the scheme's choice, off in a closed domain).
    ghosts: bool,
    row_of: &'a [u32],
    k: &'a Kernels,
    s: &'a Scheme,
    gravity: Vector<D>,
    dt: f64,
    /// Dirichlet values (Pa), empty when all are 0.
    dirichlet: &'a [f64],
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
        // A neighbour of the particle's own density (all of them in one phase): the pair
        // density is rho_i, a product instead of a division.
        let coef_i = coef / rho_i;
        entries.clear();
        for q in v.pairs(i, k.lap.re) {
            n_lap += q.w;
            let rho_j = v.density[q.j];
            let c = match rho_j == rho_i {
                true => coef_i * q.w,
                false => coef * q.w / s.pair_density(rho_i, rho_j),
            };
            match v.kind[q.j] {
                Kind::Fluid | Kind::Wall => {
                    diag += c;
                    if self.row_of[q.j] != NONE {
                        entries.push((self.row_of[q.j], -c));
                    } else if let Some(p_j) = self.dirichlet.get(q.j) {
                        // A known neighbour: -c p_j moves to the right-hand side.
                        bi += c * p_j;
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
        if self.ghosts {
            // Missing neighbourhood = air at p = 0: sum_air c (p_i - 0).
            let deficit = (k.lap.n0 - n_lap).max(0.0);
            diag += coef * deficit / rho_i;
        }
        entries.push((row, diag));
        sort_by_column(entries);
        bi
    }
}

/// Sorts a row's entries by column (unique columns). Insertion sort: the neighbour lists
/// follow the cell order the particles are numbered in, so a row arrives nearly sorted
/// (docs/decisions.md, "Assembly sort").
fn sort_by_column(entries: &mut [(u32, f64)]) {
    for k in 1..entries.len() {
        let e = entries[k];
        let mut m = k;
        while m > 0 && entries[m - 1].0 > e.0 {
            entries[m] = entries[m - 1];
            m -= 1;
        }
        entries[m] = e;
    }
}

impl<const D: usize> Rows<'_, D> {
    /// The number of entries of particle `i`'s row: its diagonal and one per neighbour that
    /// [`Rows::assemble`] gives a column (a fluid or wall particle that is an unknown).
    fn row_length(&self, i: usize) -> u32 {
        let (v, row_of) = (self.v, self.row_of);
        let unknown = |j: usize| matches!(v.kind[j], Kind::Fluid | Kind::Wall) && row_of[j] != NONE;
        1 + count_pairs(v.pos, v.neighbors, i, self.k.lap.re, unknown) as u32
    }
}

thread_local! {
    /// A row's entries while it is assembled, kept per thread (no allocation per row or step).
    static ENTRIES: std::cell::RefCell<Vec<(u32, f64)>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Every row of `particle_of` written into its place: `col` and `val`
/// hold exactly their entries (offsets from `row_ptr`), `rhs` their right-hand sides; in
/// parallel over pieces of rows.
fn fill_rows<const D: usize>(
    ctx: &Rows<D>,
    particle_of: &[u32],
    row_ptr: &[u32],
    (col, val, rhs): (&mut [u32], &mut [f64], &mut [f64]),
) {
    let (cols, vals, rhss) = (Shared::new(col), Shared::new(val), Shared::new(rhs));
    parallel::for_ranges(rhs.len(), |rows| {
        let (lo, hi) = (row_ptr[rows.start] as usize, row_ptr[rows.end] as usize);
        // SAFETY: the pieces' rows, and so their entries, are disjoint.
        let (col, val, rhs) = unsafe {
            (
                cols.part(lo..hi),
                vals.part(lo..hi),
                rhss.part(rows.clone()),
            )
        };
        write_rows(ctx, particle_of, row_ptr, rows.start, (col, val, rhs));
    });
}

/// Rows `first..` (as many as `rhs` holds) of `particle_of` written into their entries
/// `col`, `val` (from row `first`'s offset on) and right-hand sides `rhs`.
fn write_rows<const D: usize>(
    ctx: &Rows<D>,
    particle_of: &[u32],
    row_ptr: &[u32],
    first: usize,
    (col, val, rhs): (&mut [u32], &mut [f64], &mut [f64]),
) {
    ENTRIES.with_borrow_mut(|entries| {
        let base = row_ptr[first] as usize;
        for (k, b) in rhs.iter_mut().enumerate() {
            let row = first + k;
            *b = ctx.assemble(particle_of[row] as usize, row as u32, entries);
            let at = row_ptr[row] as usize - base;
            debug_assert_eq!(entries.len(), (row_ptr[row + 1] - row_ptr[row]) as usize);
            for (e, &(cj, x)) in entries.iter().enumerate() {
                col[at + e] = cj;
                val[at + e] = x;
            }
        }
    });
}

/// The rows of `particle_of` assembled into the matrix and right-hand side of `sys`, in
/// their memory: on one thread each row appended after the last; on more, the row lengths
/// first, then every row written into its place in parallel (no per-chunk copies, no
/// allocation once the arrays have grown). The same matrix either way.
fn assemble_rows<const D: usize>(ctx: &Rows<D>, particle_of: &[u32], sys: &mut PressureSystem) {
    if rayon::current_num_threads() == 1 {
        append_rows(ctx, particle_of, sys);
        return;
    }
    let rows = particle_of.len();
    let m = &mut sys.matrix;
    let len = |_: &mut (), r: usize| ctx.row_length(particle_of[r] as usize);
    crate::linalg::sparse::size_rows_into(rows, m, || (), len);
    sys.rhs.clear();
    sys.rhs.resize(rows, 0.0);
    let parts = (&mut m.col[..], &mut m.val[..], &mut sys.rhs[..]);
    fill_rows(ctx, particle_of, &m.row_ptr, parts);
}

/// [`assemble_rows`] on one thread: each row appended to the matrix in turn, so its
/// offsets need no counting pass over the neighbours first (docs/decisions.md, "The PPE
/// on one thread without its counting pass").
fn append_rows<const D: usize>(ctx: &Rows<D>, particle_of: &[u32], sys: &mut PressureSystem) {
    let m = &mut sys.matrix;
    m.row_ptr.clear();
    m.col.clear();
    m.val.clear();
    m.row_ptr.push(0);
    sys.rhs.clear();
    ENTRIES.with_borrow_mut(|entries| {
        for (row, &i) in particle_of.iter().enumerate() {
            sys.rhs.push(ctx.assemble(i as usize, row as u32, entries));
            m.col.extend(entries.iter().map(|e| e.0));
            m.val.extend(entries.iter().map(|e| e.1));
            m.row_ptr.push(m.col.len() as u32);
        }
    });
}

/// Assembles the PPE at the intermediate state; `previous` holds every particle's pressure
/// of the last step (Pa).
///
/// A closed domain (no fluid or wall particle is Dirichlet) has no pressure level: its
/// matrix is singular up to a constant. Then there is no air (no ghosts), the right-hand side
/// is made consistent (its mean removed), and the reference particle of `reference` is held
/// at its value: a well-posed system whose solution is the consistent one, shifted.
pub fn assemble<const D: usize>(
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    s: &Scheme,
    gravity: Vector<D>,
    dt: f64,
    reference: &PressureReference<D>,
) -> PressureSystem {
    let mut sys = PressureSystem::default();
    assemble_into(v, previous, k, s, (gravity, dt), reference, &mut sys);
    sys
}

/// [`assemble`] into `sys`, reusing the memory of the system it held (the last step's).
pub fn assemble_into<const D: usize>(
    v: &View<D>,
    previous: &[f64],
    k: &Kernels,
    s: &Scheme,
    (gravity, dt): (Vector<D>, f64),
    reference: &PressureReference<D>,
    sys: &mut PressureSystem,
) {
    let n = v.pos.len();
    let mut dirichlet = std::mem::take(&mut sys.no_row);
    parallel::map_into(&mut dirichlet, n, |i| is_dirichlet(i, v, k.lap.re));
    let closed =
        !reference.open_elsewhere && !(0..n).any(|i| dirichlet[i] && v.kind[i] != Kind::Dummy);
    let level_particle: Option<u32> = match (closed, reference.at) {
        (false, _) => None,
        (true, Some(r)) => Some(r),
        (true, None) => reference.particle(v).map(|r| r as u32),
    };
    let held = level_particle.filter(|&r| r != NONE).map(|r| r as usize);
    if let Some(r) = held {
        dirichlet[r] = true;
    }
    let mut row_of = std::mem::take(&mut sys.row_of);
    let mut particle_of = std::mem::take(&mut sys.particle_of);
    row_of.clear();
    row_of.resize(n, NONE);
    particle_of.clear();
    particle_of.reserve(n);
    for i in 0..n {
        if !dirichlet[i] {
            row_of[i] = particle_of.len() as u32;
            particle_of.push(i as u32);
        }
    }
    sys.no_row = dirichlet;
    let mut dirichlet = std::mem::take(&mut sys.dirichlet_value);
    dirichlet.clear();
    if s.surface_pressure != SurfacePressure::Zero && !closed {
        let edge = s.surface_pressure.edge(k.l0);
        dirichlet_values_into(v, previous, k, (edge, &sys.surface_jump), &mut dirichlet);
    }
    if !sys.surface_jump.is_empty() && !closed {
        dirichlet.resize(n, 0.0);
        for (i, d) in dirichlet.iter_mut().enumerate() {
            if sys.no_row[i] && v.free_surface[i] && Some(i) != held {
                *d += sys.surface_jump[i];
            }
        }
    }
    let ctx = Rows {
        dirichlet: &dirichlet,
        v,
        previous,
        ghosts: s.air_ghosts && !closed,
        row_of: &row_of,
        k,
        s,
        gravity,
        dt,
    };
    assemble_rows(&ctx, &particle_of, sys);
    let rhs = &mut sys.rhs;
    let own = held.map_or(0.0, |r| ctx.assemble(r, NONE, &mut Vec::new()));
    sys.level_source = 0.0;
    if level_particle.is_some() && reference.at.is_some() {
        sys.level_source = own;
    } else if level_particle.is_some() {
        // The singular system is solvable only if its sources sum to zero (the constant is
        // its null vector): remove their mean, the reference particle's own row included.
        let mean = (rhs.iter().sum::<f64>() + own) / (rhs.len() + 1) as f64;
        rhs.iter_mut().for_each(|b| *b -= mean);
    }
    sys.row_of = row_of;
    sys.particle_of = particle_of;
    sys.level = level_particle.map(|r| (r, reference.value));
    sys.dirichlet_value = dirichlet;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{pcg, Jacobi};
    use crate::numerics::scheme::Scheme;
    use crate::particles::view::Cloud;

    /// A block of 15 x 15 particles in uniform compression, its outer row Dirichlet.
    fn block() -> (Cloud<2>, Kernels) {
        let l0 = 0.01;
        let (mut pos, mut vel) = (Vec::new(), Vec::new());
        for a in 0..15 {
            for b in 0..15 {
                let x = Vector([a as f64 * l0, b as f64 * l0]);
                pos.push(x);
                vel.push((x - Vector([0.07, 0.07])) * -0.5);
            }
        }
        let n = pos.len();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let mut cloud = Cloud::new(pos, vel, vec![1000.0; n], k.grad.n0, 3.4 * l0);
        cloud.set_surface(|x| (0..2).any(|c| x[c] < 0.005 || x[c] > 0.135));
        (cloud, k)
    }

    fn solve(sys: &PressureSystem) -> Vec<f64> {
        let mut x = vec![0.0; sys.rhs.len()];
        pcg(
            &sys.matrix,
            &sys.rhs,
            &mut x,
            &Jacobi::new(&sys.matrix),
            1e-12,
            10_000,
        )
        .unwrap();
        let offset = sys.level.map_or(0.0, |l| l.1);
        let mut p = vec![0.0; sys.row_of.len()];
        for (r, &i) in sys.particle_of.iter().enumerate() {
            p[i as usize] = x[r] + offset;
        }
        if let Some((r, value)) = sys.level {
            p[r as usize] = value;
        }
        p
    }

    /// A closed domain (no free surface, no Dirichlet row): the pressure level is fixed at the
    /// reference particle, and the solution satisfies every row of the singular system with
    /// its sources made consistent, the reference particle's row included.
    #[test]
    fn a_closed_domain_takes_its_level_from_the_reference() {
        let (mut cloud, k) = block();
        cloud.set_surface(|_| false);
        let v = cloud.view();
        let s = Scheme::preset("MPS-HS-GC").unwrap();
        let reference = PressureReference {
            position: Some(Vector([0.07, 0.14])),
            value: 1234.0,
            open_elsewhere: false,
            at: None,
        };
        let zero = vec![0.0; v.pos.len()];
        let g = Vector([0.0, 0.0]);
        let sys = assemble(&v, &zero, &k, &s, g, 1e-3, &reference);
        let (r, value) = sys.level.expect("no Dirichlet row: a closed domain");
        assert_eq!(v.pos[r as usize], Vector([0.07, 0.14]));
        assert_eq!(value, 1234.0);
        let p = solve(&sys);
        assert_eq!(p[r as usize], 1234.0);
        // Every row, the reference's too, of the full singular system holds with the
        // consistent sources (the rows' own, less their mean).
        let n = v.pos.len();
        let all: Vec<u32> = (0..n as u32).collect();
        let ctx = Rows {
            v: &v,
            previous: &zero,
            ghosts: false,
            row_of: &all,
            k: &k,
            s: &s,
            gravity: g,
            dt: 1e-3,
            dirichlet: &[],
        };
        let mut full = PressureSystem::default();
        assemble_rows(&ctx, &all, &mut full);
        let (a, b) = (full.matrix, full.rhs);
        let mean = b.iter().sum::<f64>() / n as f64;
        assert!(
            mean.abs() > 1e-3,
            "uniform compression: inconsistent sources to begin with"
        );
        let mut ap = vec![0.0; n];
        a.spmv(&p, &mut ap);
        let scale = b.iter().map(|x| x.abs()).fold(0.0, f64::max);
        for i in 0..n {
            let res = (ap[i] - (b[i] - mean)).abs();
            assert!(res < 1e-8 * scale, "row {i}: residual {res} of {scale}");
        }
    }

    /// With a sound speed, the pressure of the last step is a fixed point (a steady pressure
    /// is unaffected), and from zero the pressure rises only part of the way (compressible
    /// response), both against the incompressible solution.
    #[test]
    fn a_sound_speed_leaves_a_steady_pressure_unchanged() {
        let (cloud, k) = block();
        let v = cloud.view();
        let dt = 1e-3;
        let mut s = Scheme::preset("MPS-HS-GC").unwrap();
        let zero = vec![0.0; v.pos.len()];
        let g = Vector([0.0, 0.0]);
        let level = PressureReference {
            position: None,
            value: 0.0,
            open_elsewhere: false,
            at: None,
        };
        let incompressible = solve(&assemble(&v, &zero, &k, &s, g, dt, &level));
        let centre = 7 * 15 + 7;
        assert!(incompressible[centre] > 0.0, "compression gives pressure");
        s.sound_speed = Some(5.0);
        let steady = solve(&assemble(&v, &incompressible, &k, &s, g, dt, &level));
        for i in 0..steady.len() {
            let d = (steady[i] - incompressible[i]).abs();
            assert!(d < 1e-6 * incompressible[centre], "particle {i}: {d}");
        }
        let from_rest = solve(&assemble(&v, &zero, &k, &s, g, dt, &level));
        let ratio = from_rest[centre] / incompressible[centre];
        assert!(ratio > 0.0 && ratio < 0.99, "ratio {ratio}");
    }

    /// The matrix assembled in place (on two threads row lengths first, rows written into
    /// their slots in parallel halves; on one, rows appended) is, row for row, what
    /// `Rows::assemble` gives each particle, on a shaken block of 40 x 40 (seven row chunks)
    /// whose unknowns then change (the system's memory reused for fewer and for more rows).
    #[test]
    fn rows_assembled_in_place_are_each_particles_row() {
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(rows_in_place_on_this_pool);
        }
    }

    fn rows_in_place_on_this_pool() {
        let l0 = 0.01;
        let m = 40;
        let (mut pos, mut vel) = (Vec::new(), Vec::new());
        for a in 0..m {
            for b in 0..m {
                let shake = 0.2 * l0 * ((a * 31 + b * 17) as f64).sin();
                pos.push(Vector([a as f64 * l0 + shake, b as f64 * l0 - 0.5 * shake]));
                vel.push(Vector([0.01 * (b as f64).cos(), -0.02 * (a as f64).sin()]));
            }
        }
        let n = pos.len();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let mut cloud = Cloud::new(pos, vel, vec![1000.0; n], k.grad.n0, 3.4 * l0);
        let s = Scheme::preset("MPS-HS-GC").unwrap();
        let (g, dt) = (Vector([0.0, -9.81]), 1e-3);
        let level = PressureReference {
            position: None,
            value: 0.0,
            open_elsewhere: false,
            at: None,
        };
        let mut sys = PressureSystem::default();
        for edge in [0.015, 0.055, 0.005] {
            let hi = (m - 1) as f64 * l0 - edge;
            cloud.set_surface(|x| (0..2).any(|c| x[c] < edge || x[c] > hi));
            let v = cloud.view();
            let previous = vec![0.0; n];
            assemble_into(&v, &previous, &k, &s, (g, dt), &level, &mut sys);
            let ctx = Rows {
                dirichlet: &[],
                v: &v,
                previous: &previous,
                ghosts: s.air_ghosts,
                row_of: &sys.row_of,
                k: &k,
                s: &s,
                gravity: g,
                dt,
            };
            assert!(sys.particle_of.len() > 100, "several pieces of rows");
            let mut entries = Vec::new();
            for (row, &i) in sys.particle_of.iter().enumerate() {
                let b = ctx.assemble(i as usize, row as u32, &mut entries);
                let (c, x) = sys.matrix.row(row);
                let want: Vec<(u32, f64)> = c.iter().copied().zip(x.iter().copied()).collect();
                assert_eq!(want, entries, "edge {edge}, row {row}");
                assert_eq!(sys.rhs[row], b, "edge {edge}, row {row}");
            }
            assert_eq!(sys.matrix.row_ptr.len(), sys.particle_of.len() + 1);
        }
    }

    /// The insertion sort orders a row as the library sort does, from any arrival order.
    #[test]
    fn rows_are_sorted_by_column() {
        for seed in 0..50u32 {
            let n = (seed % 31) as usize;
            let mut row: Vec<(u32, f64)> = (0..n as u32)
                .map(|k| ((k * 7919 + seed * 104_729) % 997, k as f64))
                .collect();
            row.sort_unstable_by_key(|e| e.0);
            row.dedup_by_key(|e| e.0);
            let mut shuffled = row.clone();
            shuffled.reverse();
            shuffled.rotate_left(n / 3);
            sort_by_column(&mut shuffled);
            assert_eq!(shuffled, row, "seed {seed}");
        }
    }
}
