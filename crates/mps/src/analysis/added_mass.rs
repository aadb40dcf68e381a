//! The first acceleration of bodies released from rest in a tank of ideal fluid, from their
//! added-mass matrix: the reference for the groups' early acceleration (docs/decisions.md,
//! "The groups' early acceleration against the tank's potential flow").
//!
//! At `t = 0+` the fluid is at rest and every body accelerates from rest, so the flow is the
//! potential flow of the body accelerations `a`: `phi_t = sum_k a_k Phi_k`, with `Phi_k` the
//! potential of body degree of freedom `k` moving at unit speed (`dPhi_k/dn = n_k` on that
//! body, `dPhi/dn = 0` on the other bodies and on the walls, `Phi = 0` on the free surface,
//! where the pressure is 0). The fluid's pressure `-rho phi_t` then gives each body the force
//! `-rho sum_k M_jk a_k` with `M_jk = int_body_j Phi_k n_j ds` (m^2 in 2D), and
//! `(rho_b A I + rho M) a = (rho - rho_b) g A e_up` (Newman, *Marine Hydrodynamics*, 1977,
//! s.4.13-4.15). An isolated circle has `M = pi R^2 I`, which gives the estimate
//! `g |rho_b - rho| / (rho_b + rho)`; walls, the free surface and the other bodies change it.
//!
//! `Phi_k` comes from the direct boundary element method in 2D (Brebbia & Dominguez,
//! *Boundary Elements*, 1992, ch. 2): Green's identity `phi(x) / 2 = int (G dphi/dn -
//! phi dG/dn) ds` with `G = -ln r / (2 pi)`, collocated at the midpoints of straight panels on
//! which `phi` and `dphi/dn` are constant (4-point Gauss rules off the panel, the exact
//! integral of `ln r` on it).

/// What a boundary panel is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Boundary {
    /// A fixed wall (`dphi/dn = 0`).
    Wall,
    /// The free surface (`phi = 0`).
    FreeSurface,
    /// The surface of body number `k` (`dphi/dn = n` of its motion).
    Body(usize),
}

/// A straight boundary panel from `a` to `b` (m), the fluid on its left (so `(b - a)` turned
/// clockwise is the normal out of the fluid).
#[derive(Clone, Copy, Debug)]
pub struct Panel {
    /// Start (m).
    pub a: [f64; 2],
    /// End (m).
    pub b: [f64; 2],
    /// Its boundary condition.
    pub kind: Boundary,
}

impl Panel {
    fn length(&self) -> f64 {
        (self.b[0] - self.a[0]).hypot(self.b[1] - self.a[1])
    }
    fn mid(&self) -> [f64; 2] {
        [(self.a[0] + self.b[0]) / 2.0, (self.a[1] + self.b[1]) / 2.0]
    }
    /// Unit normal out of the fluid.
    fn normal(&self) -> [f64; 2] {
        let l = self.length();
        [(self.b[1] - self.a[1]) / l, -(self.b[0] - self.a[0]) / l]
    }
}

/// Panels of the segment from `a` to `b` (m), each at most `h` (m) long.
pub fn segment(a: [f64; 2], b: [f64; 2], h: f64, kind: Boundary) -> Vec<Panel> {
    let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / h).ceil().max(1.0) as usize;
    let at = |s: f64| [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s];
    (0..n)
        .map(|k| Panel {
            a: at(k as f64 / n as f64),
            b: at((k + 1) as f64 / n as f64),
            kind,
        })
        .collect()
}

/// Panels of a circle of `radius` (m) about `center` (m) in `n` pieces, the fluid outside
/// (`outside`, a body's surface) or inside (a container).
pub fn circle(
    center: [f64; 2],
    radius: f64,
    n: usize,
    kind: Boundary,
    outside: bool,
) -> Vec<Panel> {
    let sign = if outside { -1.0 } else { 1.0 };
    let at = |k: usize| {
        let t = sign * std::f64::consts::TAU * k as f64 / n as f64;
        [center[0] + radius * t.cos(), center[1] + radius * t.sin()]
    };
    (0..n)
        .map(|k| Panel {
            a: at(k),
            b: at(k + 1),
            kind,
        })
        .collect()
}

/// `(int G ds, int dG/dn_y ds)` over panel `p` seen from point `x` (`own`: `x` is `p`'s
/// midpoint).
fn influence(p: &Panel, x: [f64; 2], own: bool) -> (f64, f64) {
    let l = p.length();
    let two_pi = std::f64::consts::TAU;
    if own {
        // int_{-l/2}^{l/2} ln|s| ds = l (ln(l/2) - 1); dG/dn vanishes on a straight panel.
        return (-l * ((l / 2.0).ln() - 1.0) / two_pi, 0.0);
    }
    const GAUSS: [(f64, f64); 4] = [
        (-0.861_136_311_594_052_6, 0.347_854_845_137_453_8),
        (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
        (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
        (0.861_136_311_594_052_6, 0.347_854_845_137_453_8),
    ];
    let n = p.normal();
    let (mut g, mut dg) = (0.0, 0.0);
    for (s, w) in GAUSS {
        let t = (1.0 + s) / 2.0;
        let dx = p.a[0] + (p.b[0] - p.a[0]) * t - x[0];
        let dy = p.a[1] + (p.b[1] - p.a[1]) * t - x[1];
        let r2 = dx * dx + dy * dy;
        g -= w * 0.5 * r2.ln() / two_pi;
        dg -= w * (dx * n[0] + dy * n[1]) / (r2 * two_pi);
    }
    (g * l / 2.0, dg * l / 2.0)
}

/// Solves `a x = b` for the columns of `b` in place by Gaussian elimination with partial
/// pivoting (`a` row-major `n x n`, `b` row-major `n x m`); `false` if `a` is singular.
fn solve_dense(a: &mut [f64], b: &mut [f64], n: usize, m: usize) -> bool {
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&r, &s| a[r * n + c].abs().total_cmp(&a[s * n + c].abs()))
            .expect("c < n");
        if a[piv * n + c].abs() < 1e-300 {
            return false;
        }
        if piv != c {
            for k in 0..n {
                a.swap(c * n + k, piv * n + k);
            }
            for k in 0..m {
                b.swap(c * m + k, piv * m + k);
            }
        }
        let pc = a[c * n + c];
        for r in c + 1..n {
            let f = a[r * n + c] / pc;
            if f == 0.0 {
                continue;
            }
            for k in c..n {
                a[r * n + k] -= f * a[c * n + k];
            }
            for k in 0..m {
                b[r * m + k] -= f * b[c * m + k];
            }
        }
    }
    for r in (0..n).rev() {
        for k in 0..m {
            let mut s = b[r * m + k];
            for c in r + 1..n {
                s -= a[r * n + c] * b[c * m + k];
            }
            b[r * m + k] = s / a[r * n + r];
        }
    }
    true
}

/// The added-mass matrix per unit fluid density (m^2) of the `bodies` bodies bounded by
/// `panels`: entry `(2 j + c, 2 k + e)` is the force on body `j` along axis `c` per unit
/// acceleration of body `k` along axis `e`, over `rho`. `None` if the system is singular.
pub fn added_mass(panels: &[Panel], bodies: usize) -> Option<Vec<f64>> {
    let n = panels.len();
    let m = 2 * bodies;
    let mids: Vec<[f64; 2]> = panels.iter().map(Panel::mid).collect();
    // Unknowns: phi on walls and bodies, dphi/dn on the free surface.
    let mut a = vec![0.0; n * n];
    let mut rhs = vec![0.0; n * m];
    for (i, x) in mids.iter().enumerate() {
        for (j, p) in panels.iter().enumerate() {
            let (g, dg) = influence(p, *x, i == j);
            match p.kind {
                Boundary::FreeSurface => a[i * n + j] = -g,
                Boundary::Wall => a[i * n + j] = dg + if i == j { 0.5 } else { 0.0 },
                Boundary::Body(k) => {
                    a[i * n + j] = dg + if i == j { 0.5 } else { 0.0 };
                    let nrm = p.normal();
                    for (c, nc) in nrm.iter().enumerate() {
                        rhs[i * m + 2 * k + c] += g * nc;
                    }
                }
            }
        }
    }
    if !solve_dense(&mut a, &mut rhs, n, m) {
        return None;
    }
    let mut mass = vec![0.0; m * m];
    for (j, p) in panels.iter().enumerate() {
        if let Boundary::Body(b) = p.kind {
            let (nrm, l) = (p.normal(), p.length());
            for (c, nc) in nrm.iter().enumerate() {
                for k in 0..m {
                    mass[(2 * b + c) * m + k] += rhs[j * m + k] * nc * l;
                }
            }
        }
    }
    Some(mass)
}

/// A circular body: centre (m), radius (m), density (kg/m^3).
#[derive(Clone, Copy, Debug)]
pub struct Disc {
    /// Centre (m).
    pub center: [f64; 2],
    /// Radius (m).
    pub radius: f64,
    /// Density (kg/m^3).
    pub density: f64,
}

/// The first accelerations (m/s^2, `[x, vertical]` per disc) of `discs` released from rest
/// in fluid of density `rho` (kg/m^3) filling the rectangle `min`-`max` (m) of a tank (walls
/// below and on both sides, the free surface on top), under gravity `g` (m/s^2) downward.
/// `None` unless every disc lies inside the fluid clear of its boundary.
pub fn first_accelerations(
    (min, max): ([f64; 2], [f64; 2]),
    discs: &[Disc],
    rho: f64,
    g: f64,
) -> Option<Vec<[f64; 2]>> {
    let r_min = discs.iter().map(|d| d.radius).fold(f64::INFINITY, f64::min);
    let clear = discs.iter().all(|d| {
        (0..2).all(|c| d.center[c] - d.radius > min[c] && d.center[c] + d.radius < max[c])
    });
    if discs.is_empty() || !clear || !(r_min > 0.0) {
        return None;
    }
    // Panels of a fifth of the smallest radius, at most about 1200 on the tank (checked in
    // the tests: 0.1 % from halving them on the settling tank).
    let perimeter = 2.0 * (max[0] - min[0] + max[1] - min[1]);
    let h = (r_min / 5.0).max(perimeter / 1200.0);
    let (x0, y0, x1, y1) = (min[0], min[1], max[0], max[1]);
    let mut panels = segment([x0, y0], [x1, y0], h, Boundary::Wall);
    panels.extend(segment([x1, y0], [x1, y1], h, Boundary::Wall));
    panels.extend(segment([x1, y1], [x0, y1], h, Boundary::FreeSurface));
    panels.extend(segment([x0, y1], [x0, y0], h, Boundary::Wall));
    for (k, d) in discs.iter().enumerate() {
        let n = ((std::f64::consts::TAU * d.radius / h).ceil() as usize).max(32);
        panels.extend(circle(d.center, d.radius, n, Boundary::Body(k), true));
    }
    let m = 2 * discs.len();
    let mass = added_mass(&panels, discs.len())?;
    // (rho_b A I + rho M) a = (rho - rho_b) g A e_up.
    let mut lhs = vec![0.0; m * m];
    let mut f = vec![0.0; m];
    for (j, d) in discs.iter().enumerate() {
        let area = std::f64::consts::PI * d.radius * d.radius;
        for c in 0..2 {
            let r = 2 * j + c;
            for k in 0..m {
                lhs[r * m + k] = rho * mass[r * m + k];
            }
            lhs[r * m + r] += d.density * area;
        }
        f[2 * j + 1] = (rho - d.density) * g * area;
    }
    if !solve_dense(&mut lhs, &mut f, m, 1) {
        return None;
    }
    Some(f.chunks_exact(2).map(|a| [a[0], a[1]]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A circle inside a concentric circular container: `M = pi a^2 (b^2 + a^2) / (b^2 - a^2)`
    /// exactly (Lamb, *Hydrodynamics*, s.72), 1.0833 pi a^2 for `b = 5 a`.
    #[test]
    fn a_circle_in_a_concentric_container_has_the_exact_added_mass() {
        let (a, b) = (0.1, 0.5);
        for n in [64, 128] {
            let mut panels = circle([0.0, 0.0], b, 5 * n, Boundary::Wall, false);
            panels.extend(circle([0.0, 0.0], a, n, Boundary::Body(0), true));
            let m = added_mass(&panels, 1).unwrap();
            let exact = std::f64::consts::PI * a * a * (b * b + a * a) / (b * b - a * a);
            for (k, v) in [m[0], m[3]].iter().enumerate() {
                assert!(
                    (v / exact - 1.0).abs() < 1e-3,
                    "n {n}, axis {k}: {v} vs {exact}"
                );
            }
            // No cross coupling by symmetry.
            assert!(m[1].abs() < 1e-3 * exact && m[2].abs() < 1e-3 * exact);
        }
    }

    /// Far from every boundary a disc has `M = pi R^2`, so it starts at
    /// `g (rho - rho_b) / (rho_b + rho)`; at a distance `d` from a wall the added-mass
    /// coefficient grows by `2 (R / 2 d)^2` and below a free surface it shrinks by as much, to
    /// leading order (the image dipoles in a wall and in a free surface have opposite signs).
    #[test]
    fn an_isolated_disc_starts_at_the_estimate_and_the_boundaries_act_as_images() {
        let g = 9.81;
        let tank = ([0.0, 0.0], [2.0, 2.0]);
        for rho_b in [600.0, 2650.0] {
            let disc = Disc {
                center: [1.0, 1.0],
                radius: 0.02,
                density: rho_b,
            };
            let a = first_accelerations(tank, &[disc], 1000.0, g).unwrap()[0];
            let est = g * (1000.0 - rho_b) / (rho_b + 1000.0);
            assert!((a[1] / est - 1.0).abs() < 2e-3, "{} vs {est}", a[1]);
            assert!(a[0].abs() < 1e-3 * est.abs());
        }
        // A light disc (density 0, so a = g / C_a) 3 radii from the bottom or below the
        // surface, in a wide tank.
        let (r, d) = (0.02, 0.06);
        let tank = ([0.0, 0.0], [2.0, 1.0]);
        let near = |y: f64| {
            let disc = Disc {
                center: [1.0, y],
                radius: r,
                density: 1e-9,
            };
            g / first_accelerations(tank, &[disc], 1000.0, g).unwrap()[0][1]
        };
        let (wall, surface) = (near(d), near(1.0 - d));
        // The image dipole at 2 d changes C_a by 2 (R / 2 d)^2 (0.056 here; 0.057 and -0.052
        // computed, the rest higher orders).
        let lead = 2.0 * (r / (2.0 * d)).powi(2);
        let (dw, ds) = (wall - 1.0, surface - 1.0);
        assert!((dw / lead - 1.0).abs() < 0.1, "C_a {wall} near the wall");
        assert!(
            (ds / lead + 1.0).abs() < 0.1,
            "C_a {surface} below the surface"
        );
    }
}
