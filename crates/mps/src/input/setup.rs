//! Set-up: particles from the case's shapes on a lattice of spacing `l0`, with wall and dummy
//! layers generated from solid regions.
//!
//! Lattice sites sit at `(k + 1/2) l0` along each axis, so a region from 0 to `H` holds sites
//! from `l0/2` to `H - l0/2`. Solid sites are classified by their lattice (Chebyshev) distance
//! to the nearest free site inside the domain: 1 = wall layer, 2..=1+dummy_layers = dummy,
//! deeper sites are dropped.

use super::analytic::square_patch_pressure;
use super::case::{Arrangement, Case, FluidSpec, PressureSpec, ShapeSpec, VelocitySpec};
use super::expression::Expression;
use super::shapes::{inside, shape_bounds, to_vec};
use crate::error::CaseError;
use crate::numerics::kernel::for_each_lattice_offset;
use crate::particles::{Kind, NewParticle, Particles, Vector, NONE};
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};
use std::collections::BTreeMap;

type Site<const D: usize> = [i64; D];

fn site_position<const D: usize>(s: &Site<D>, l0: f64) -> Vector<D> {
    let mut v = Vector::zero();
    for k in 0..D {
        v[k] = (s[k] as f64 + 0.5) * l0;
    }
    v
}

/// The lattice index range `[lo, hi]` (per axis) of the box `min..max` (m).
fn site_range<const D: usize>(min: &[f64], max: &[f64], l0: f64) -> ([i64; D], [i64; D]) {
    let mut lo = [0i64; D];
    let mut hi = [0i64; D];
    for k in 0..D {
        // Saturating float-to-int casts keep far-away shapes finite; the clip does the rest.
        lo[k] = ((min[k] / l0 - 0.5).floor() as i64).saturating_sub(1);
        hi[k] = ((max[k] / l0 - 0.5).ceil() as i64).saturating_add(1);
    }
    (lo, hi)
}

/// Lattice sites inside a shape, within the lattice box `clip` (only sites near the domain
/// can become particles).
fn sites_of<const D: usize>(
    shape: &ShapeSpec,
    l0: f64,
    wall_depth: f64,
    clip: &([i64; D], [i64; D]),
) -> Vec<Site<D>> {
    let (lo, hi) = shape_bounds(shape);
    let pad = if matches!(shape, ShapeSpec::Tank { .. }) {
        wall_depth
    } else {
        0.0
    };
    let padded = |v: &[f64], d: f64| v.iter().map(|x| x + d).collect::<Vec<f64>>();
    let (mut klo, mut khi) = site_range::<D>(&padded(&lo, -pad), &padded(&hi, pad), l0);
    for k in 0..D {
        klo[k] = klo[k].max(clip.0[k]);
        khi[k] = khi[k].min(clip.1[k]);
        if klo[k] > khi[k] {
            return Vec::new();
        }
    }
    let mut out = Vec::new();
    let mut s = klo;
    loop {
        if inside(shape, &site_position(&s, l0), wall_depth) {
            out.push(s);
        }
        let mut k = 0;
        loop {
            if k == D {
                return out;
            }
            s[k] += 1;
            if s[k] <= khi[k] {
                break;
            }
            s[k] = klo[k];
            k += 1;
        }
    }
}

/// The lattice layers of a case's walls: spacing, wall + dummy layers, domain box.
struct Lattice<const D: usize> {
    l0: f64,
    layers: i64,
    wall_depth: f64,
    dmin: Vector<D>,
    dmax: Vector<D>,
}

impl<const D: usize> Lattice<D> {
    fn of(case: &Case) -> Self {
        let l0 = case.particles.spacing;
        let re_max = case.particles.re_grad.max(case.particles.re_lap);
        // Default: enough dummy layers for a full neighbourhood of every wall particle.
        let dummy_layers = case
            .particles
            .dummy_layers
            .unwrap_or(((re_max - 1e-9).ceil() as usize).saturating_sub(1).max(1));
        let layers = 1 + dummy_layers as i64;
        Lattice {
            l0,
            layers,
            wall_depth: layers as f64 * l0,
            dmin: to_vec(&case.domain.min),
            dmax: to_vec(&case.domain.max),
        }
    }

    /// The lattice box a site must lie in to become a particle: the domain, padded by the
    /// wall and dummy layers.
    fn clip(&self) -> ([i64; D], [i64; D]) {
        let pad = self.wall_depth + self.l0;
        let lo: Vec<f64> = (0..D).map(|k| self.dmin[k] - pad).collect();
        let hi: Vec<f64> = (0..D).map(|k| self.dmax[k] + pad).collect();
        site_range::<D>(&lo, &hi, self.l0)
    }

    fn in_domain(&self, s: &Site<D>) -> bool {
        let x = site_position(s, self.l0);
        (0..D).all(|k| x[k] > self.dmin[k] && x[k] < self.dmax[k])
    }

    /// Lattice (Chebyshev) distance from solid site `s` to the nearest free site inside the
    /// domain, up to the number of layers; `None` beyond. `shells[m - 1]` holds the offsets
    /// at Chebyshev distance `m` ([`offsets_by_length`]).
    fn depth(&self, s: &Site<D>, solid: &HashSet<Site<D>>, shells: &[Vec<Site<D>>]) -> Option<i64> {
        (1..=self.layers).find(|&m| {
            shells[m as usize - 1].iter().any(|off| {
                let t = shifted(s, off);
                !solid.contains(&t) && self.in_domain(&t)
            })
        })
    }
}

/// Every lattice offset with coordinates in `-k..=k`, shortest first; offsets of equal length
/// keep the order of [`for_each_lattice_offset`] (a stable sort).
fn offsets_by_length<const D: usize>(k: i64) -> Vec<Site<D>> {
    let mut out = Vec::new();
    for_each_lattice_offset::<D>(k, |off| {
        let mut t = [0i64; D];
        for c in 0..D {
            t[c] = off[c] as i64;
        }
        out.push(t);
    });
    out.sort_by_key(|t| t.iter().map(|c| c * c).sum::<i64>());
    out
}

/// Chebyshev distance of a lattice offset (lattice spacings).
fn chebyshev<const D: usize>(t: &Site<D>) -> i64 {
    t.iter().fold(0, |a, c| a.max(c.abs()))
}

fn shifted<const D: usize>(s: &Site<D>, off: &Site<D>) -> Site<D> {
    let mut t = *s;
    for k in 0..D {
        t[k] += off[k];
    }
    t
}

/// Fluid sites, region by region (later regions may override earlier ones); the BTreeMap
/// keeps a deterministic order.
fn fluid_sites<const D: usize>(
    case: &Case,
    lat: &Lattice<D>,
    solid: &HashSet<Site<D>>,
    label: &str,
) -> Result<BTreeMap<Site<D>, usize>, CaseError> {
    let l0 = lat.l0;
    let mut fluid: BTreeMap<Site<D>, usize> = BTreeMap::new();
    for (r, f) in case.fluid.iter().enumerate() {
        let field = format!("fluid.{r}.shape");
        let sites = sites_of::<D>(&f.shape, l0, lat.wall_depth, &lat.clip());
        if sites.is_empty() {
            let msg = format!("region holds no particle at spacing {l0}");
            return Err(CaseError::new(label, field, "", msg));
        }
        for s in sites {
            let at = || format!("{:?}", site_position(&s, l0).0);
            if solid.contains(&s) {
                return Err(CaseError::new(
                    label,
                    field,
                    at(),
                    "fluid region overlaps a wall",
                ));
            }
            if let Some(&prev) = fluid.get(&s) {
                if !f.overrides {
                    let msg =
                        format!("overlaps fluid.{prev}; set `overrides = true` to replace it");
                    return Err(CaseError::new(label, field, at(), msg));
                }
            }
            fluid.insert(s, r);
        }
    }
    Ok(fluid)
}

/// An expression of an initial field that does not evaluate to a number at a point: the
/// field's name under the region (`velocity.u`, `pressure.p`), the expression, the fault.
type FieldFault = (&'static str, String, String);

/// The value of an expression of the case at `x` (m), `t = 0`, or what is wrong with it
/// there (the case validation parses it; a value can still be of the wrong type at some
/// points, e.g. `if(x > 0, true, 1)`).
fn evaluate<const D: usize>(text: &str, case: &Case, x: Vector<D>) -> Result<f64, String> {
    let names = ["x", "y", "z"];
    let vars: Vec<(&str, f64)> = (0..D).map(|k| (names[k], x[k])).collect();
    Expression::parse(text, &["x", "y", "z", "t"], &case.constants)
        .and_then(|e| e.eval(&vars))
        .map_err(|e| e.to_string())
}

/// Initial velocity (m/s) of region `f` of `case` at `x` (m).
fn initial_velocity<const D: usize>(
    f: &FluidSpec,
    case: &Case,
    x: Vector<D>,
) -> Result<Vector<D>, FieldFault> {
    velocity_field(f, x, |e| evaluate(e, case, x))
}

/// Region `f`'s initial velocity field (m/s) at any point `x` (m), NaN in a component whose
/// expression does not evaluate to a number there.
pub fn velocity_at<const D: usize>(f: &FluidSpec, case: &Case, x: Vector<D>) -> Vector<D> {
    velocity_field(f, x, |e| Ok(evaluate(e, case, x).unwrap_or(f64::NAN)))
        .unwrap_or(Vector([f64::NAN; D]))
}

/// Region `f`'s velocity field (m/s) at `x` (m), expressions evaluated by `eval`.
fn velocity_field<const D: usize>(
    f: &FluidSpec,
    x: Vector<D>,
    eval: impl Fn(&str) -> Result<f64, String>,
) -> Result<Vector<D>, FieldFault> {
    Ok(match &f.velocity {
        None => Vector::zero(),
        Some(VelocitySpec::Uniform { value }) => to_vec(value),
        Some(VelocitySpec::Rotation {
            center,
            omega,
            axis,
        }) => {
            // u = omega a x (x - c), a the unit axis (z in 2D).
            let a = axis.as_deref().unwrap_or(&[0.0, 0.0, 1.0]);
            let norm = a.iter().map(|c| c * c).sum::<f64>().sqrt();
            let a = Vector([a[0] / norm, a[1] / norm, a[2] / norm]);
            let rel = Vector((x - to_vec::<D>(center)).padded());
            let w = a.cross3(&rel);
            let mut u = Vector::zero();
            for k in 0..D {
                u[k] = omega * w[k];
            }
            u
        }
        Some(VelocitySpec::Affine { u0, x0, a }) => {
            let rel = x - to_vec::<D>(x0);
            let mut u = to_vec::<D>(u0);
            for (row, arow) in a.iter().enumerate() {
                for c in 0..D {
                    u[row] += arow[c] * rel[c];
                }
            }
            u
        }
        Some(VelocitySpec::Expression { u, v, w }) => {
            let mut out = Vector::zero();
            let names = ["velocity.u", "velocity.v", "velocity.w"];
            for (k, e) in [Some(u), Some(v), w.as_ref()]
                .into_iter()
                .enumerate()
                .take(D)
            {
                if let Some(e) = e {
                    out[k] = eval(e).map_err(|why| (names[k], e.clone(), why))?;
                }
            }
            out
        }
    })
}

/// Initial pressure (Pa) of region `f` of `case`, density `rho` (kg/m^3), at `x` (m).
fn initial_pressure<const D: usize>(
    f: &FluidSpec,
    case: &Case,
    x: Vector<D>,
    rho: f64,
    g: f64,
) -> Result<f64, FieldFault> {
    Ok(match &f.pressure {
        None => 0.0,
        Some(PressureSpec::Uniform { value }) => *value,
        Some(PressureSpec::Hydrostatic {
            surface,
            offset,
            density,
        }) => offset + density.unwrap_or(rho) * g * (surface - x[D - 1]).max(0.0),
        Some(PressureSpec::SquarePatch {
            center,
            side,
            omega,
        }) => {
            let c = to_vec::<D>(center);
            let xp = x[0] - (c[0] - side / 2.0);
            let yp = x[1] - (c[1] - side / 2.0);
            square_patch_pressure(xp, yp, *side, rho, *omega, 60)
        }
        Some(PressureSpec::Expression { p }) => {
            evaluate(p, case, x).map_err(|why| ("pressure.p", p.clone(), why))?
        }
    })
}

/// Builds the particles of a case. The fluid comes first, then walls, then dummies.
pub fn build_particles<const D: usize>(
    case: &Case,
    label: &str,
) -> Result<Particles<D>, CaseError> {
    let lat = Lattice::<D>::of(case);
    let l0 = lat.l0;
    let clip = lat.clip();
    let solid: HashSet<Site<D>> = case
        .walls
        .iter()
        .flat_map(|w| sites_of::<D>(&w.shape, l0, lat.wall_depth, &clip))
        .collect();
    let fluid = fluid_sites(case, &lat, &solid, label)?;

    // Solid sites by lattice distance to the nearest free site: 1 = wall, deeper = dummy.
    let mut solid_sites: Vec<Site<D>> = solid.iter().copied().collect();
    solid_sites.sort();
    let near = offsets_by_length::<D>(lat.layers);
    let shells: Vec<Vec<Site<D>>> = (1..=lat.layers)
        .map(|m| near.iter().copied().filter(|t| chebyshev(t) == m).collect())
        .collect();
    let (mut walls, mut dummies) = (Vec::new(), Vec::new());
    for s in solid_sites {
        match lat.depth(&s, &solid, &shells) {
            Some(1) => walls.push(s),
            Some(_) => dummies.push(s),
            None => {}
        }
    }

    let mut p = Particles::<D>::default();
    let g = to_vec::<D>(&case.physics.gravity).norm();
    let groups = group_names(case);
    let lattice_sites = fluid
        .iter()
        .filter(|(_, &r)| case.fluid[r].arrangement == Arrangement::Lattice)
        .map(|(s, &r)| (site_position(s, l0), r));
    let ring_points = case
        .fluid
        .iter()
        .enumerate()
        .filter(|(_, f)| f.arrangement == Arrangement::Rings)
        .flat_map(|(r, f)| rings::<D>(&f.shape, l0).into_iter().map(move |x| (x, r)));
    for (x, r) in lattice_sites.chain(ring_points) {
        let f = &case.fluid[r];
        let ph = case.phase_index(&f.phase).expect("validated phase");
        let rho = case.phases[ph].density;
        let fault = |(field, text, why): FieldFault| {
            let why = format!("{why} at {:?}", x.0);
            CaseError::new(
                label,
                format!("fluid.{r}.{field}"),
                format!("{text:?}"),
                why,
            )
        };
        p.push(NewParticle {
            position: x,
            velocity: initial_velocity(f, case, x).map_err(fault)?,
            kind: Kind::Fluid,
            phase: ph as u16,
            density: rho,
        });
        let i = p.len() - 1;
        p.pressure[i] = initial_pressure(f, case, x, rho, g).map_err(fault)?;
        if let Some(name) = &f.group {
            p.group[i] = groups.iter().position(|n| n == name).expect("listed") as u16;
        }
    }
    let solid_particle = |x: Vector<D>, kind: Kind| NewParticle {
        position: x,
        velocity: Vector::zero(),
        kind,
        phase: 0,
        density: case.phases[0].density,
    };
    let mut wall_index: HashMap<Site<D>, u32> = HashMap::default();
    for s in &walls {
        wall_index.insert(*s, p.len() as u32);
        p.push(solid_particle(site_position(s, l0), Kind::Wall));
    }
    for s in &dummies {
        let x = site_position(s, l0);
        p.push(solid_particle(x, Kind::Dummy));
        // Backing wall: the nearest wall site (ties: first in offset order), the first
        // found in `near`, which lists the offsets shortest first in that order.
        let i = p.len() - 1;
        p.backing_wall[i] = near
            .iter()
            .find_map(|off| wall_index.get(&shifted(s, off)).copied())
            .unwrap_or(NONE);
    }
    Ok(p)
}

/// The points of a circle on concentric rings (`Arrangement::Rings`; a circle in 2D, as the
/// case validation ensures): ring `k` at `(k + 1/2) h`, `h = R / round(R / l0)`, with
/// `round(2 pi (k + 1/2))` points, odd rings turned by half a step.
fn rings<const D: usize>(shape: &ShapeSpec, l0: f64) -> Vec<Vector<D>> {
    let ShapeSpec::Circle { center, radius } = shape else {
        return Vec::new();
    };
    let count = (radius / l0).round().max(1.0) as usize;
    let h = radius / count as f64;
    let mut out = Vec::new();
    for k in 0..count {
        let r = (k as f64 + 0.5) * h;
        let n = (2.0 * std::f64::consts::PI * (k as f64 + 0.5))
            .round()
            .max(1.0) as usize;
        let step = 2.0 * std::f64::consts::PI / n as f64;
        let turn = if k % 2 == 1 { 0.5 * step } else { 0.0 };
        for j in 0..n {
            let t = j as f64 * step + turn;
            let mut x = Vector::<D>::zero();
            x[0] = center[0] + r * t.cos();
            x[1] = center[1] + r * t.sin();
            out.push(x);
        }
    }
    out
}

/// Names of the fluid groups in order of their group index.
pub fn group_names(case: &Case) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for f in &case.fluid {
        if let Some(g) = &f.group {
            if !names.contains(g) {
                names.push(g.clone());
            }
        }
    }
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tank reaching far beyond the domain (min -1e308 m) keeps the walls that lie in it:
    /// its lattice range saturates instead of wrapping round, which left it without a single
    /// wall particle (../shared/reliability/repro/timeout_wall_-1e308.toml).
    #[test]
    fn a_tank_reaching_far_beyond_the_domain_keeps_its_walls_inside() {
        let (lo, hi) = site_range::<2>(&[-1e308, 0.0], &[1.0, 0.6], 0.04);
        assert_eq!(lo[0], i64::MIN);
        assert!(hi[0] > lo[0] && hi[1] > lo[1]);
        let tank = ShapeSpec::Tank {
            min: vec![-1e308, 0.0],
            max: vec![1.0, 0.6],
            open_top: true,
        };
        let clip = ([-5, -5], [30, 20]);
        let sites = sites_of::<2>(&tank, 0.04, 0.12, &clip);
        // The bottom (three layers under y = 0, across the clip) and the right wall.
        assert!(sites.iter().any(|s| s[1] < 0 && s[0] == 0));
        assert!(sites.iter().any(|s| s[0] >= 25 && s[1] == 10));
    }

    /// The offsets the layer depths and backing walls are searched in: shortest first, equal
    /// lengths in the lattice enumeration's order, so the first wall found is the nearest
    /// with the old tie-break.
    #[test]
    fn lattice_offsets_come_shortest_first_in_enumeration_order() {
        let o = offsets_by_length::<2>(1);
        let want: Vec<Site<2>> = vec![
            [0, 0],
            [0, -1],
            [-1, 0],
            [1, 0],
            [0, 1],
            [-1, -1],
            [1, -1],
            [-1, 1],
            [1, 1],
        ];
        assert_eq!(o, want);
        let o3 = offsets_by_length::<3>(2);
        assert_eq!(o3.len(), 125);
        assert!(o3.windows(2).all(|w| {
            let l = |t: &Site<3>| t.iter().map(|c| c * c).sum::<i64>();
            l(&w[0]) <= l(&w[1])
        }));
        assert_eq!(o3.iter().filter(|t| chebyshev(t) == 2).count(), 125 - 27);
    }

    /// A tank 0.2 m x 0.3 m, 10 cm of water, l0 = 1 cm, and `extra` case text.
    fn tank_case(extra: &str) -> Case {
        let text = crate::input::case::tests::MINIMAL
            .replace("max = [1.0, 1.0]", "max = [0.2, 0.3]")
            .replace("spacing = 0.05", "spacing = 0.01")
            .replace("max = [0.5, 0.5] }", "max = [0.2, 0.1] }")
            + "[[walls]]\nshape = { type = \"tank\", min = [0.0, 0.0], max = [0.2, 0.3] }\n"
            + extra;
        Case::from_str_named(&text, "tank.toml", &[]).unwrap()
    }

    /// A disc on concentric rings: ring `k` holds `round(2 pi (k + 1/2))` particles, all
    /// inside the circle, the area per particle `h^2` within 0.1 %, no pair closer than
    /// 0.86 h, the outer ring at `R - h/2` (a smooth edge); another shape, another dimension
    /// or a later overriding region over it is refused naming `fluid.N.arrangement`.
    #[test]
    fn a_disc_on_concentric_rings() {
        let disc = |extra: &str| {
            crate::input::case::tests::MINIMAL.replace(
                "shape = { type = \"rectangle\", min = [0.0, 0.0], max = [0.5, 0.5] }",
                &format!(
                    "shape = {{ type = \"circle\", center = [0.5, 0.5], radius = 0.3 }}\n{extra}"
                ),
            )
        };
        let case = Case::from_str_named(&disc("arrangement = \"rings\""), "d", &[]).unwrap();
        let p = build_particles::<2>(&case, "d").unwrap();
        let (radius, h) = (0.3, 0.05);
        let want: usize = (0..6)
            .map(|k| (2.0 * std::f64::consts::PI * (k as f64 + 0.5)).round() as usize)
            .sum();
        assert_eq!(p.len(), want);
        let area = std::f64::consts::PI * radius * radius / p.len() as f64;
        assert!((area / (h * h) - 1.0).abs() < 1e-3, "{area}");
        let c = Vector([0.5, 0.5]);
        let mut outer: f64 = 0.0;
        for i in 0..p.len() {
            let r = (p.position[i] - c).norm();
            assert!(r < radius);
            outer = outer.max(r);
            for j in 0..i {
                let d = (p.position[i] - p.position[j]).norm();
                assert!(d > 0.86 * h, "{i} {j}: {d}");
            }
        }
        assert!((outer - (radius - 0.5 * h)).abs() < 1e-12);
        // The number density away from the centre and the edge is n0 on average (within
        // 0.5 %), so the drift term sees no compression in a disc at rest (R = 12 h here).
        let big = disc("arrangement = \"rings\"")
            .replace("radius = 0.3", "radius = 0.48")
            .replace("spacing = 0.05", "spacing = 0.04");
        let case = Case::from_str_named(&big, "d", &[]).unwrap();
        let p = build_particles::<2>(&case, "d").unwrap();
        let k = crate::numerics::kernel::Kernels::new::<2>(0.04, 2.1, 3.1);
        let nl = crate::particles::neighbors::build_neighbor_list(&p.position, k.grad.re);
        let (mut sum, mut count) = (0.0, 0.0);
        for i in 0..p.len() {
            let r = (p.position[i] - c).norm();
            if r > 0.12 && r < 0.32 {
                sum += crate::numerics::operators::number_density(i, &p.position, &nl, k.grad.re);
                count += 1.0;
            }
        }
        let mean = sum / count / k.grad.n0;
        assert!(
            count > 100.0 && (mean - 1.0).abs() < 0.005,
            "n/n0 = {mean} over {count}"
        );
        let square = crate::input::case::tests::MINIMAL.replace(
            "max = [0.5, 0.5] }",
            "max = [0.5, 0.5] }\narrangement = \"rings\"",
        );
        let ball = format!("dimension = 3\n{}", disc("arrangement = \"rings\""))
            .replace("min = [0.0, 0.0]", "min = [0.0, 0.0, 0.0]")
            .replace("max = [1.0, 1.0]", "max = [1.0, 1.0, 1.0]")
            .replace("center = [0.5, 0.5]", "center = [0.5, 0.5, 0.5]");
        for text in [square, ball] {
            let e = Case::from_str_named(&text, "d", &[]).unwrap_err();
            assert_eq!(e.field, "fluid.0.arrangement", "{e}");
        }
        let over = disc("arrangement = \"rings\"")
            + "[[fluid]]\nphase = \"water\"\noverrides = true\nshape = { type = \"circle\", center = [0.5, 0.5], radius = 0.1 }\n";
        let e = Case::from_str_named(&over, "d", &[]).unwrap_err();
        assert_eq!(e.field, "fluid.0.arrangement", "{e}");
    }

    /// An expression that is no number at some particle (an `if` of mixed types) is an
    /// error naming the region's field and the expression, not a panic.
    #[test]
    fn an_expression_that_is_no_number_at_a_particle_is_named() {
        let e = "if(x > 0.25, true, 1.0)";
        let velocity = format!("velocity = {{ type = \"expression\", u = \"{e}\", v = \"0\" }}\n");
        let pressure = format!("pressure = {{ type = \"expression\", p = \"{e}\" }}\n");
        for (extra, field) in [
            (velocity, "fluid.0.velocity.u"),
            (pressure, "fluid.0.pressure.p"),
        ] {
            let text = crate::input::case::tests::MINIMAL.to_string() + &extra;
            let case = Case::from_str_named(&text, "e", &[]).unwrap();
            let err = build_particles::<2>(&case, "e").unwrap_err();
            assert_eq!(err.field, field, "{err}");
            assert!(err.value.contains("if(x > 0.25"), "{err}");
        }
    }

    /// A circle on rings may replace part of an earlier region (a group of another phase in
    /// a tank of water): the earlier region keeps no particle inside the circle, and the
    /// circle holds exactly its rings.
    #[test]
    fn a_rings_circle_replaces_part_of_an_earlier_region() {
        let text = crate::input::case::tests::MINIMAL.to_string()
            + "[[phases]]\nname = \"heavy\"\ndensity = 2650.0\n[[fluid]]\nphase = \"heavy\"\n\
               overrides = true\narrangement = \"rings\"\n\
               shape = { type = \"circle\", center = [0.25, 0.25], radius = 0.15 }\n";
        let case = Case::from_str_named(&text, "g", &[]).unwrap();
        let p = build_particles::<2>(&case, "g").unwrap();
        let c = Vector([0.25, 0.25]);
        let heavy: Vec<usize> = (0..p.len()).filter(|&i| p.phase[i] == 1).collect();
        assert_eq!(heavy.len(), 3 + 9 + 16, "three rings");
        assert!(heavy.iter().all(|&i| (p.position[i] - c).norm() < 0.15));
        let water: Vec<usize> = (0..p.len()).filter(|&i| p.phase[i] == 0).collect();
        assert!(water
            .iter()
            .all(|&i| (p.position[i] - c).norm() >= 0.15 - 1e-12));
        let inside = (0..100)
            .map(|n| {
                Vector([
                    (n % 10) as f64 * 0.05 + 0.025,
                    (n / 10) as f64 * 0.05 + 0.025,
                ])
            })
            .filter(|x| (*x - c).norm() < 0.15)
            .count();
        assert_eq!(water.len(), 100 - inside);
    }

    /// A 3D cylinder of fluid along x, rotating about its own axis: the particles fill the
    /// analytic volume pi R^2 L within a lattice cell per surface site, every velocity is
    /// omega a x (x - c) exactly, and gravity defaults to -z.
    #[test]
    fn a_3d_cylinder_rotating_about_its_axis() {
        let text = r#"
name = "cyl"
dimension = 3
[domain]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.2, 0.2]
[particles]
spacing = 0.01
[time]
end = 0.1
[[phases]]
name = "water"
density = 1000.0
[[fluid]]
phase = "water"
shape = { type = "cylinder", base = [0.05, 0.1, 0.1], axis = [0.3, 0.0, 0.0], radius = 0.08 }
velocity = { type = "rotation", center = [0.0, 0.1, 0.1], omega = 2.0, axis = [3.0, 0.0, 0.0] }
"#;
        let c = Case::from_str_named(text, "cyl.toml", &[]).unwrap();
        assert_eq!(c.physics.gravity, vec![0.0, 0.0, -9.81]);
        let p = build_particles::<3>(&c, "cyl.toml").unwrap();
        // The lattice sites ((k + 1/2) l0) inside the disc of radius 8 l0 about (10, 10) l0,
        // counted here: 208 (pi 64 = 201), times the 30 sites along the axis.
        let disc = (0..20)
            .flat_map(|a| (0..20).map(move |b| (a as f64 + 0.5 - 10.0, b as f64 + 0.5 - 10.0)))
            .filter(|(y, z)| y * y + z * z < 64.0)
            .count();
        assert_eq!(disc, 208);
        assert_eq!(p.count(Kind::Fluid), disc * 30);
        for i in (0..p.len()).filter(|&i| p.kind[i] == Kind::Fluid) {
            let x = p.position[i];
            let (y, z) = (x[1] - 0.1, x[2] - 0.1);
            assert!(y * y + z * z < 0.08 * 0.08 && x[0] > 0.05 && x[0] < 0.35);
            let want = Vector([0.0, -2.0 * z, 2.0 * y]);
            assert!((p.velocity[i] - want).norm() < 1e-12, "{:?}", p.velocity[i]);
        }
        // An axis in 2D, or a zero axis, is refused naming the field.
        let bad = text.replace("axis = [3.0, 0.0, 0.0]", "axis = [0.0, 0.0, 0.0]");
        let e = Case::from_str_named(&bad, "cyl.toml", &[]).unwrap_err();
        assert!(e.to_string().contains("velocity.axis"), "{e}");
    }

    #[test]
    fn tank_gets_one_wall_layer_and_dummies() {
        let c = tank_case("");
        let p = build_particles::<2>(&c, "tank.toml").unwrap();
        assert_eq!(p.count(Kind::Fluid), 20 * 10);
        // Wall layer: bottom 20 + 2 corners + two sides of 30 each.
        assert_eq!(p.count(Kind::Wall), 20 + 2 + 2 * 30);
        // re_lap = 3.1 -> 3 dummy layers, so every wall particle has a full neighbourhood.
        // Solid band 4 sites thick (28 x 4 bottom + 2 x 4 x 30 sides) less the wall layer.
        assert_eq!(p.count(Kind::Dummy), 28 * 4 + 2 * 4 * 30 - 82);
        for i in 0..p.len() {
            if p.kind[i] == Kind::Dummy {
                let w = p.backing_wall[i] as usize;
                assert_eq!(p.kind[w], Kind::Wall);
                assert!((p.position[w] - p.position[i]).norm() < 4.0 * 0.01 * 1.5);
            }
        }
    }

    /// Expressions equal to the built-in forms give the same fields to round-off.
    #[test]
    fn expressions_reproduce_the_built_in_fields() {
        let with = |velocity: &str, pressure: &str| {
            let extra = format!(
                "[constants]\nomega = 1.5\n[[fluid]]\nphase = \"water\"\n\
                 shape = {{ type = \"rectangle\", min = [0.0, 0.1], max = [0.2, 0.2] }}\n\
                 velocity = {velocity}\npressure = {pressure}\n"
            );
            build_particles::<2>(&tank_case(&extra), "tank.toml").unwrap()
        };
        let built_in = with(
            "{ type = \"rotation\", center = [0.1, 0.15], omega = 1.5 }",
            "{ type = \"hydrostatic\", surface = 0.2 }",
        );
        let expr = with(
            "{ type = \"expression\", u = \"-omega * (y - 0.15)\", v = \"omega * (x - 0.1)\" }",
            "{ type = \"expression\", p = \"1000 * 9.81 * (0.2 - y)\" }",
        );
        assert_eq!(built_in.len(), expr.len());
        let mut checked = 0;
        for i in 0..built_in.len() {
            if built_in.kind[i] != Kind::Fluid || built_in.position[i][1] < 0.1 {
                continue;
            }
            let du = (built_in.velocity[i] - expr.velocity[i]).norm();
            let dp = (built_in.pressure[i] - expr.pressure[i]).abs();
            assert!(
                du < 1e-14,
                "velocity {:?} vs {:?}",
                built_in.velocity[i],
                expr.velocity[i]
            );
            assert!(
                dp < 1e-9 * built_in.pressure[i].abs().max(1.0),
                "pressure {dp}"
            );
            checked += 1;
        }
        assert_eq!(checked, 20 * 10);
    }

    #[test]
    fn a_bad_expression_names_the_field_and_the_position() {
        let extra = "[[fluid]]\nphase = \"water\"\n\
                     shape = { type = \"rectangle\", min = [0.0, 0.1], max = [0.2, 0.2] }\n\
                     pressure = { type = \"expression\", p = \"1000 * * y\" }\n";
        let text = crate::input::case::tests::MINIMAL
            .replace("max = [1.0, 1.0]", "max = [0.2, 0.3]")
            .replace("max = [0.5, 0.5] }", "max = [0.2, 0.1] }")
            + extra;
        let e = Case::from_str_named(&text, "c.toml", &[]).unwrap_err();
        assert_eq!(e.field, "fluid.1.pressure.p");
        assert!(e.message.contains("character 8"), "{e}");
        assert!(!e.to_string().contains('\n'));
    }

    #[test]
    fn overlapping_regions_are_an_error_unless_overriding() {
        let extra = r#"
[[fluid]]
phase = "water"
shape = { type = "circle", center = [0.1, 0.05], radius = 0.02 }
"#;
        let c = tank_case(extra);
        let e = build_particles::<2>(&c, "tank.toml").unwrap_err();
        assert_eq!(e.field, "fluid.1.shape");
        let c = tank_case(&format!("{extra}overrides = true\n"));
        assert!(build_particles::<2>(&c, "tank.toml").is_ok());
    }
}
