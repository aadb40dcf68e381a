//! Set-up: particles from the case's shapes on a lattice of spacing `l0`, with wall and dummy
//! layers generated from solid regions.
//!
//! Lattice sites sit at `(k + 1/2) l0` along each axis, so a region from 0 to `H` holds sites
//! from `l0/2` to `H - l0/2`. Solid sites are classified by their lattice (Chebyshev) distance
//! to the nearest free site inside the domain: 1 = wall layer, 2..=1+dummy_layers = dummy,
//! deeper sites are dropped.

use crate::analytic::square_patch_pressure;
use crate::case::{Case, CaseError, PressureSpec, ShapeSpec, VelocitySpec};
use crate::kernel::for_each_lattice_offset;
use crate::particles::{Kind, Particles};
use crate::vector::Vector;
use std::collections::{BTreeMap, HashMap};

type Site<const D: usize> = [i64; D];

fn site_position<const D: usize>(s: &Site<D>, l0: f64) -> Vector<D> {
    let mut v = Vector::zero();
    for k in 0..D {
        v[k] = (s[k] as f64 + 0.5) * l0;
    }
    v
}

fn to_vec<const D: usize>(v: &[f64]) -> Vector<D> {
    Vector::from_slice(v).expect("validated length")
}

fn point_in_polygon(p: (f64, f64), pts: &[Vec<f64>]) -> bool {
    let mut inside = false;
    let n = pts.len();
    let mut j = n - 1;
    for i in 0..n {
        let (xi, yi, xj, yj) = (pts[i][0], pts[i][1], pts[j][0], pts[j][1]);
        if (yi > p.1) != (yj > p.1) && p.0 < (xj - xi) * (p.1 - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}

fn distance_to_segment(p: (f64, f64), a: &[f64], b: &[f64]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a[0]) * dx + (p.1 - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p.0 - a[0] - t * dx).powi(2) + (p.1 - a[1] - t * dy).powi(2)).sqrt()
}

/// True when point `x` lies inside `shape`; `wall_depth` (m) is the tank wall thickness.
fn inside<const D: usize>(shape: &ShapeSpec, x: &Vector<D>, wall_depth: f64) -> bool {
    let eps = 1e-9;
    let in_box =
        |min: &[f64], max: &[f64]| (0..D).all(|k| x[k] >= min[k] - eps && x[k] < max[k] - eps);
    match shape {
        ShapeSpec::Rectangle { min, max } => in_box(min, max),
        ShapeSpec::Circle { center, radius } => {
            (*x - to_vec::<D>(center)).norm2() < radius * radius
        }
        ShapeSpec::Polygon { points } => point_in_polygon((x[0], x[1]), points),
        ShapeSpec::Polyline { points, thickness } => points
            .windows(2)
            .any(|w| distance_to_segment((x[0], x[1]), &w[0], &w[1]) <= *thickness),
        ShapeSpec::Tank { min, max, open_top } => {
            let mut omin: Vec<f64> = min.iter().map(|v| v - wall_depth).collect();
            let mut omax: Vec<f64> = max.iter().map(|v| v + wall_depth).collect();
            if *open_top {
                omax[D - 1] = max[D - 1];
            }
            omin[D - 1] = min[D - 1] - wall_depth;
            in_box(&omin, &omax) && !in_box(min, max)
        }
    }
}

/// Lattice sites inside a shape.
fn sites_of<const D: usize>(shape: &ShapeSpec, l0: f64, wall_depth: f64) -> Vec<Site<D>> {
    let (lo, hi) = crate::case::shape_bounds(shape);
    let pad = if matches!(shape, ShapeSpec::Tank { .. }) {
        wall_depth
    } else {
        0.0
    };
    let mut klo = [0i64; D];
    let mut khi = [0i64; D];
    for k in 0..D {
        klo[k] = ((lo[k] - pad) / l0 - 0.5).floor() as i64 - 1;
        khi[k] = ((hi[k] + pad) / l0 - 0.5).ceil() as i64 + 1;
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

/// Builds the particles of a case. The fluid comes first, then walls, then dummies.
pub fn build_particles<const D: usize>(
    case: &Case,
    label: &str,
) -> Result<Particles<D>, CaseError> {
    let err = |field: String, value: String, message: String| CaseError {
        file: label.to_string(),
        field,
        value,
        message,
    };
    let l0 = case.particles.spacing;
    let re_max = case.particles.re_grad.max(case.particles.re_lap);
    let dummy_layers = case
        .particles
        .dummy_layers
        .unwrap_or(((re_max - 1e-9).ceil() as usize).saturating_sub(1).max(1));
    let layers = 1 + dummy_layers as i64;
    let wall_depth = layers as f64 * l0;
    let dmin = to_vec::<D>(&case.domain.min);
    let dmax = to_vec::<D>(&case.domain.max);
    let in_domain = |s: &Site<D>| {
        let x = site_position(s, l0);
        (0..D).all(|k| x[k] > dmin[k] && x[k] < dmax[k])
    };

    // Solid sites from every wall.
    let mut solid: HashMap<Site<D>, ()> = HashMap::new();
    for w in &case.walls {
        for s in sites_of::<D>(&w.shape, l0, wall_depth) {
            solid.insert(s, ());
        }
    }

    // Fluid sites, region by region (BTreeMap keeps a deterministic order).
    let mut fluid: BTreeMap<Site<D>, usize> = BTreeMap::new();
    for (r, f) in case.fluid.iter().enumerate() {
        let sites = sites_of::<D>(&f.shape, l0, wall_depth);
        if sites.is_empty() {
            return Err(err(
                format!("fluid.{r}.shape"),
                String::new(),
                format!("region holds no particle at spacing {l0}"),
            ));
        }
        for s in sites {
            if solid.contains_key(&s) {
                return Err(err(
                    format!("fluid.{r}.shape"),
                    format!("{:?}", site_position(&s, l0).0),
                    "fluid region overlaps a wall".into(),
                ));
            }
            if let Some(&prev) = fluid.get(&s) {
                if !f.overrides {
                    return Err(err(
                        format!("fluid.{r}.shape"),
                        format!("{:?}", site_position(&s, l0).0),
                        format!("overlaps fluid.{prev}; set `overrides = true` to replace it"),
                    ));
                }
            }
            fluid.insert(s, r);
        }
    }

    // Classify solid sites by lattice distance to the nearest free site in the domain.
    let depth_of = |s: &Site<D>| -> Option<i64> {
        for m in 1..=layers {
            let mut found = false;
            for_each_lattice_offset::<D>(m, |off| {
                if found {
                    return;
                }
                let cheb = off.0.iter().fold(0.0f64, |a, &c| a.max(c.abs())) as i64;
                if cheb != m {
                    return;
                }
                let mut t = *s;
                for k in 0..D {
                    t[k] += off[k] as i64;
                }
                if !solid.contains_key(&t) && in_domain(&t) {
                    found = true;
                }
            });
            if found {
                return Some(m);
            }
        }
        None
    };
    let mut solid_sites: Vec<Site<D>> = solid.keys().copied().collect();
    solid_sites.sort();
    let mut walls = Vec::new();
    let mut dummies = Vec::new();
    for s in solid_sites {
        match depth_of(&s) {
            Some(1) => walls.push(s),
            Some(_) => dummies.push(s),
            None => {}
        }
    }

    let mut p = Particles::<D>::default();
    let gravity = to_vec::<D>(&case.physics.gravity);
    let mut group_names: Vec<String> = Vec::new();
    for (s, &r) in &fluid {
        let f = &case.fluid[r];
        let ph = case.phase_index(&f.phase).expect("validated phase");
        let rho = case.phases[ph].density;
        let x = site_position(s, l0);
        let u = match &f.velocity {
            None => Vector::zero(),
            Some(VelocitySpec::Uniform { value }) => to_vec(value),
            Some(VelocitySpec::Rotation { center, omega }) => {
                let rel = x - to_vec::<D>(center);
                let mut u = Vector::zero();
                u[0] = -omega * rel[1];
                u[1] = omega * rel[0];
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
        };
        p.push(x, u, Kind::Fluid, ph as u16, rho);
        let i = p.len() - 1;
        p.pressure[i] = match &f.pressure {
            None => 0.0,
            Some(PressureSpec::Uniform { value }) => *value,
            Some(PressureSpec::Hydrostatic {
                surface,
                offset,
                density,
            }) => offset + density.unwrap_or(rho) * gravity.norm() * (surface - x[D - 1]).max(0.0),
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
        };
        if let Some(g) = &f.group {
            let gi = match group_names.iter().position(|n| n == g) {
                Some(k) => k,
                None => {
                    group_names.push(g.clone());
                    group_names.len() - 1
                }
            };
            p.group[i] = gi as u16;
        }
    }
    let rho_wall = case.phases[0].density;
    let mut wall_index: HashMap<Site<D>, u32> = HashMap::new();
    for s in &walls {
        wall_index.insert(*s, p.len() as u32);
        p.push(
            site_position(s, l0),
            Vector::zero(),
            Kind::Wall,
            0,
            rho_wall,
        );
    }
    for s in &dummies {
        p.push(
            site_position(s, l0),
            Vector::zero(),
            Kind::Dummy,
            0,
            rho_wall,
        );
        let i = p.len() - 1;
        // Backing wall: the nearest wall site (ties: first in offset order).
        let x = site_position(s, l0);
        let mut best = (f64::MAX, crate::particles::NONE);
        for_each_lattice_offset::<D>(layers, |off| {
            let mut t = *s;
            for k in 0..D {
                t[k] += off[k] as i64;
            }
            if let Some(&w) = wall_index.get(&t) {
                let d = (site_position(&t, l0) - x).norm2();
                if d < best.0 - 1e-12 * l0 * l0 {
                    best = (d, w);
                }
            }
        });
        p.backing_wall[i] = best.1;
    }
    Ok(p)
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

    fn tank_case(extra: &str) -> Case {
        let text = format!(
            r#"
name = "tank"
[domain]
min = [0.0, 0.0]
max = [0.2, 0.3]
[particles]
spacing = 0.01
[time]
end = 0.1
[[phases]]
name = "water"
density = 1000.0
[[fluid]]
phase = "water"
shape = {{ type = "rectangle", min = [0.0, 0.0], max = [0.2, 0.1] }}
[[walls]]
shape = {{ type = "tank", min = [0.0, 0.0], max = [0.2, 0.3] }}
{extra}
"#
        );
        Case::from_str_named(&text, "tank.toml", &[]).unwrap()
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
