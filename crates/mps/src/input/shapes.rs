//! Geometry of the case's shapes: inside tests and bounding boxes.

use super::case::ShapeSpec;
use crate::particles::Vector;

/// A vector from a case-file list already checked to have `D` components.
pub(crate) fn to_vec<const D: usize>(v: &[f64]) -> Vector<D> {
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
pub fn inside<const D: usize>(shape: &ShapeSpec, x: &Vector<D>, wall_depth: f64) -> bool {
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
        ShapeSpec::Cylinder { base, axis, radius } => {
            let rel = *x - to_vec::<D>(base);
            let a = to_vec::<D>(axis);
            let t = rel.dot(&a) / a.norm2();
            (-eps..1.0 - eps).contains(&t) && (rel - a * t).norm2() < radius * radius
        }
        ShapeSpec::Stl { mesh, .. } => mesh.as_ref().is_some_and(|m| m.contains(x.padded())),
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
        ShapeSpec::Cylinder { base, axis, radius } => {
            // The box of both end discs: a disc of radius R normal to a reaches
            // R sqrt(1 - a_k^2 / |a|^2) along axis k.
            let a2: f64 = axis.iter().map(|c| c * c).sum();
            let reach = |k: usize| radius * (1.0 - axis[k] * axis[k] / a2).max(0.0).sqrt();
            let lo = (0..base.len()).map(|k| base[k].min(base[k] + axis[k]) - reach(k));
            let hi = (0..base.len()).map(|k| base[k].max(base[k] + axis[k]) + reach(k));
            (lo.collect(), hi.collect())
        }
        ShapeSpec::Stl { mesh, .. } => match mesh {
            Some(m) => (m.lo.to_vec(), m.hi.to_vec()),
            None => (vec![0.0; 3], vec![0.0; 3]),
        },
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
