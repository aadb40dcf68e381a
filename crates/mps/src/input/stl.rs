//! Closed triangulated surfaces from STL files (ASCII or binary, read by `stl_io`): the
//! checks that make a mesh usable as a solid or a fluid region, and the inside test.
//!
//! Inside is decided by the generalized winding number (the solid angle the surface
//! subtends, Van Oosterom & Strackee 1983, summed over the facets and divided by 4 pi): 1
//! inside a closed, consistently oriented surface, 0 outside, continuous across near misses,
//! so a lattice point grazing a facet or an edge is decided by where it lies, not by which
//! facet a ray happened to cross. A point on a facet (within round-off) counts as inside.

use std::collections::HashMap;
use std::path::Path;

/// A closed, consistently oriented triangle mesh (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Triangles, vertices counter-clockwise seen from outside (m).
    pub triangles: Vec<[[f64; 3]; 3]>,
    /// Lower corner of the bounding box (m).
    pub lo: [f64; 3],
    /// Upper corner of the bounding box (m).
    pub hi: [f64; 3],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

impl Mesh {
    /// Reads `path`; the error says what is wrong (unreadable, empty, open, inconsistent).
    pub fn read(path: &Path) -> Result<Mesh, String> {
        let mut file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
        let indexed = stl_io::read_stl(&mut file).map_err(|e| format!("not an STL file: {e}"))?;
        let vertices: Vec<[f64; 3]> = indexed
            .vertices
            .iter()
            .map(|v| [v[0] as f64, v[1] as f64, v[2] as f64])
            .collect();
        let faces: Vec<[usize; 3]> = indexed.faces.iter().map(|f| f.vertices).collect();
        Mesh::from_indexed(&vertices, &faces)
    }

    /// A mesh of `faces` (indices into `vertices`, m), checked: finite, not empty, no
    /// degenerate facet, every edge shared by exactly two facets that run it in opposite
    /// directions (closed and consistently oriented), enclosing a positive volume (the
    /// facets are turned inside out when it is negative).
    pub fn from_indexed(vertices: &[[f64; 3]], faces: &[[usize; 3]]) -> Result<Mesh, String> {
        if faces.len() < 4 {
            return Err(format!(
                "{} facets: a closed surface needs at least 4",
                faces.len()
            ));
        }
        if vertices.iter().flatten().any(|c| !c.is_finite()) {
            return Err("a vertex coordinate is not finite".into());
        }
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        for (k, f) in faces.iter().enumerate() {
            if f.iter().any(|&v| v >= vertices.len()) {
                return Err(format!("facet {k} names a vertex that does not exist"));
            }
            let [a, b, c] = f.map(|v| vertices[v]);
            if norm(cross(sub(b, a), sub(c, a))) == 0.0 {
                return Err(format!("facet {k} has no area"));
            }
            for (p, q) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                *edges.entry((p, q)).or_insert(0) += 1;
            }
        }
        for (&(p, q), &n) in &edges {
            let back = edges.get(&(q, p)).copied().unwrap_or(0);
            if n > 1 {
                let [x, y] = [vertices[p], vertices[q]];
                return Err(format!(
                    "facets are not consistently oriented (edge {x:?}-{y:?} runs the same way in {n} facets)"
                ));
            }
            if back != 1 {
                let [x, y] = [vertices[p], vertices[q]];
                return Err(format!(
                    "not a closed surface: edge {x:?}-{y:?} borders only one facet"
                ));
            }
        }
        let mut triangles: Vec<[[f64; 3]; 3]> =
            faces.iter().map(|f| f.map(|v| vertices[v])).collect();
        let volume: f64 = triangles
            .iter()
            .map(|t| dot(t[0], cross(t[1], t[2])) / 6.0)
            .sum();
        if volume < 0.0 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        let mut lo = [f64::MAX; 3];
        let mut hi = [f64::MIN; 3];
        for v in triangles.iter().flatten() {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        Ok(Mesh { triangles, lo, hi })
    }

    /// The enclosed volume (m^3).
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| dot(t[0], cross(t[1], t[2])) / 6.0)
            .sum()
    }

    /// True when `x` (m) lies inside the surface or on it.
    pub fn contains(&self, x: [f64; 3]) -> bool {
        if (0..3).any(|k| x[k] < self.lo[k] || x[k] > self.hi[k]) {
            return false;
        }
        let mut solid_angle = 0.0;
        for t in &self.triangles {
            let (a, b, c) = (sub(t[0], x), sub(t[1], x), sub(t[2], x));
            let (la, lb, lc) = (norm(a), norm(b), norm(c));
            let det = dot(a, cross(b, c));
            let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
            let scale = la * lb * lc;
            if scale == 0.0 || (det.abs() <= 1e-12 * scale && den <= 1e-12 * scale) {
                // On a vertex, or in the plane of the facet and within it: on the surface.
                return true;
            }
            solid_angle += 2.0 * det.atan2(den);
        }
        solid_angle / (4.0 * std::f64::consts::PI) > 0.5
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The cube `[lo, hi]^3` as 12 facets, outward.
    pub(crate) fn cube(lo: f64, hi: f64) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
        let v = (0..8)
            .map(|k| {
                let c = |b: usize| if k >> b & 1 == 1 { hi } else { lo };
                [c(0), c(1), c(2)]
            })
            .collect();
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (v, f)
    }

    /// A UV sphere of radius `r` about `c` with `n` bands (vertices on the sphere).
    pub(crate) fn sphere(c: [f64; 3], r: f64, n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
        use std::f64::consts::PI;
        let m = 2 * n;
        let mut v = vec![[c[0], c[1], c[2] + r], [c[0], c[1], c[2] - r]];
        for i in 1..n {
            let th = PI * i as f64 / n as f64;
            for j in 0..m {
                let ph = 2.0 * PI * j as f64 / m as f64;
                v.push([
                    c[0] + r * th.sin() * ph.cos(),
                    c[1] + r * th.sin() * ph.sin(),
                    c[2] + r * th.cos(),
                ]);
            }
        }
        let at = |i: usize, j: usize| 2 + (i - 1) * m + j % m;
        let mut f = Vec::new();
        for j in 0..m {
            f.push([0, at(1, j), at(1, j + 1)]);
            f.push([1, at(n - 1, j + 1), at(n - 1, j)]);
            for i in 1..n - 1 {
                f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        (v, f)
    }

    #[test]
    fn the_cube_mesh_agrees_with_the_cube_on_a_lattice_that_touches_its_faces() {
        let (v, f) = cube(0.0, 1.0);
        let m = Mesh::from_indexed(&v, &f).unwrap();
        assert!((m.volume() - 1.0).abs() < 1e-12);
        // Lattice with spacing 0.1 from -0.2 to 1.2: sites on the faces, edges and corners.
        let mut checked = 0;
        for i in -2..=12 {
            for j in -2..=12 {
                for k in -2..=12 {
                    let x = [i as f64 * 0.1, j as f64 * 0.1, k as f64 * 0.1];
                    let want = x.iter().all(|c| (-1e-12..=1.0 + 1e-12).contains(c));
                    assert_eq!(m.contains(x), want, "{x:?}");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 15 * 15 * 15);
    }

    #[test]
    fn the_sphere_mesh_agrees_with_the_sphere_away_from_its_facets() {
        let (c, r) = ([0.1, -0.2, 0.3], 0.5);
        let (v, f) = sphere(c, r, 24);
        let m = Mesh::from_indexed(&v, &f).unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!((m.volume() / exact - 1.0).abs() < 0.02, "{}", m.volume());
        // The facets lie between the inscribed polyhedron and the sphere: points farther
        // than the chord sag (r (1 - cos(pi / 24)) < 0.005) from the sphere are decided.
        let mut decided = 0;
        for i in -12..=12 {
            for j in -12..=12 {
                for k in -12..=12 {
                    let x = [
                        c[0] + i as f64 * 0.045,
                        c[1] + j as f64 * 0.045,
                        c[2] + k as f64 * 0.045,
                    ];
                    let d = norm(sub(x, c));
                    if (d - r).abs() > 0.006 {
                        assert_eq!(m.contains(x), d < r, "{x:?} at {d}");
                        decided += 1;
                    }
                }
            }
        }
        assert!(decided > 10_000);
    }

    #[test]
    fn open_inconsistent_and_inside_out_meshes() {
        let (v, mut f) = cube(0.0, 1.0);
        let e = Mesh::from_indexed(&v, &f[..11]).unwrap_err();
        assert!(e.contains("not a closed surface"), "{e}");
        f[0].swap(1, 2);
        let e = Mesh::from_indexed(&v, &f).unwrap_err();
        assert!(e.contains("consistently oriented"), "{e}");
        f[0].swap(1, 2);
        // All facets inward: accepted, turned outward.
        let inward: Vec<[usize; 3]> = f.iter().map(|t| [t[0], t[2], t[1]]).collect();
        let m = Mesh::from_indexed(&v, &inward).unwrap();
        assert!((m.volume() - 1.0).abs() < 1e-12);
        assert!(m.contains([0.5, 0.5, 0.5]) && !m.contains([1.5, 0.5, 0.5]));
    }
}
