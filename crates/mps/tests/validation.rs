//! Validation runs against analytic and experimental references. They take seconds to a
//! minute in release mode: `cargo test --release -- --ignored` (CI runs them).

mod common;
use common::{column, sim, tmp};
use mps::particles::Kind;
use mps::run::{run, Silent};

/// Still water, H = 0.3 m, l0 = 5 mm, standard MPS, 3 s: the bottom pressure averaged over
/// the last second lies within 5 % of rho g H, and no particle leaves the tank.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn hydrostatic_tank_bottom_pressure() {
    let mut s = sim("hydrostatic", &[("output.vtu", "false")]);
    let dir = tmp("hydrostatic");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let v = &summary.validation[0];
    eprintln!(
        "bottom pressure {:.1} Pa vs rho g H {:.1} Pa ({:+.2} %)",
        v.value,
        v.reference,
        100.0 * v.error
    );
    assert!(
        v.error.abs() < 0.05,
        "bottom pressure off by {:.2} %",
        100.0 * v.error
    );
    let p = &s.particles;
    for i in 0..p.len() {
        if p.kind[i] == Kind::Fluid {
            let x = p.position[i];
            assert!(
                x[0] > 0.0 && x[0] < 0.2 && x[1] > 0.0 && x[1] < 0.32,
                "particle at {x:?}"
            );
        }
    }
}

/// Dam break, L = 0.146 m at L/l0 = 40 (l0 = 3.65 mm), standard MPS: the surge front against
/// Martin & Moyce (1952) at every experimental point up to T = 3 has an RMS difference in
/// Z of at most 0.3, and the comparison CSV is written.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn dam_break_front_against_martin_moyce() {
    let mut s = sim("dam_break", &[("output.vtu", "false")]);
    let dir = tmp("dam_break");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let path = dir.join("dam_break_front.csv");
    let (tt, exp, simz) = (
        column(&path, "T"),
        column(&path, "Z_experiment"),
        column(&path, "Z_simulation"),
    );
    let rows: Vec<Vec<f64>> = (0..tt.len())
        .map(|k| vec![tt[k], exp[k], simz[k]])
        .filter(|r: &Vec<f64>| r[0] <= 3.0)
        .collect();
    assert!(rows.len() >= 12, "{} points", rows.len());
    let rms = (rows.iter().map(|r| (r[2] - r[1]).powi(2)).sum::<f64>() / rows.len() as f64).sqrt();
    eprintln!(
        "dam break: RMS(Z_sim - Z_exp) = {rms:.3} over {} points up to T = 3",
        rows.len()
    );
    assert!(rms <= 0.3, "RMS {rms}");
}

/// Rotating square patch (seed paper s.3.1), 50 x 50 particles, MPS-HS-GC-DS to t = 3 s:
/// no breakdown, kinetic energy within 5 % and angular momentum within 2 % of their initial
/// values, no pair closer than 0.5 l0 (issue 3 acceptance).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn square_patch_with_dynamic_stabilization() {
    let mut s = sim("square_patch", &[("output.vtu", "false")]);
    let m0 = mps::analysis::metrics::Metrics::measure(&s);
    let dir = tmp("square_patch");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let m = mps::analysis::metrics::Metrics::measure(&s);
    let ke = m.kinetic_energy / m0.kinetic_energy - 1.0;
    let am = m.angular_momentum / m0.angular_momentum - 1.0;
    eprintln!(
        "square patch t = 3 s: KE {ke:+.4}, L {am:+.4}, min pair {:.3} l0",
        m.min_pair_distance
    );
    assert!(ke.abs() < 0.05, "kinetic energy changed by {ke}");
    assert!(am.abs() < 0.02, "angular momentum changed by {am}");
    // Smallest pair distance over the whole run, from steps.csv.
    let min_pair = column(&dir.join("steps.csv"), "min_pair_distance_l0")
        .into_iter()
        .fold(f64::MAX, f64::min);
    assert!(min_pair > 0.5, "closest pair {min_pair} l0");
    // Issue 11: the patch holds together. Particles with at most one fluid neighbour within
    // re_grad below 1 % of all at 2 s and at 3 s, and particles flagged free surface two
    // rows deep in the body below 1 % at every output (metrics.csv; measured 8 / 14 and 3
    // of 2 500, 8 / 8 and 4 with the relative tolerance alone, the paper's kernel-weighted
    // DS everywhere and p = 0 on the mean surface 36 / 64: docs/decisions.md, "DS whole at
    // the free surface", "The volume rule by default").
    let metrics = dir.join("metrics.csv");
    let (t, isolated) = (column(&metrics, "time"), column(&metrics, "isolated"));
    let n = s.particles.len() as f64;
    for at in [2.0, 3.0] {
        let k = (0..t.len())
            .min_by(|&a, &b| (t[a] - at).abs().total_cmp(&(t[b] - at).abs()))
            .unwrap();
        assert!((t[k] - at).abs() < 0.03, "no output near {at} s");
        assert!(
            isolated[k] < 0.01 * n,
            "{} isolated particles at {} s",
            isolated[k],
            t[k]
        );
    }
    let false_surface = column(&metrics, "false_surface")
        .into_iter()
        .fold(0.0, f64::max);
    assert!(false_surface < 0.01 * n, "false surface {false_surface}");
}

/// Issue 11 item 5: the square patch under water's tension (0.072 N/m) at 50 x 50 and 100 x
/// 100 (l0 = 0.02, 0.01 m), DS preset, to 3 s: the fraction of particles with at most one
/// neighbour within re_grad at 1, 2 and 3 s below 0.1 % at both and no larger at the finer
/// spacing (measured 0 at both, and at 200 x 200; 12 and 6 at 3 s without the particle-scale
/// tension), kinetic energy within 10 % and 5 % (measured -7.8 % and -2.8 %), angular
/// momentum within 2 % (docs/decisions.md, "Free-surface tension").
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn square_patch_under_tension_sheds_no_particles_as_l0_falls() {
    let mut fractions = Vec::new();
    for (spacing, ke_bound) in [("0.02", 0.10), ("0.01", 0.05)] {
        let set = [
            ("output.vtu", "false"),
            ("output.interval", "0.5"),
            ("phases.0.surface_tension", "0.072"),
            ("particles.spacing", spacing),
        ];
        let mut s = sim("square_patch", &set);
        let m0 = mps::analysis::metrics::Metrics::measure(&s);
        let dir = tmp(&format!("square_patch_tension_{spacing}"));
        let summary = run(&mut s, &dir, &mut Silent).unwrap();
        assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
        let m = mps::analysis::metrics::Metrics::measure(&s);
        let ke = m.kinetic_energy / m0.kinetic_energy - 1.0;
        let am = m.angular_momentum / m0.angular_momentum - 1.0;
        let metrics = dir.join("metrics.csv");
        let (t, isolated) = (column(&metrics, "time"), column(&metrics, "isolated"));
        let n = s.particles.len() as f64;
        let at: Vec<f64> = [1.0, 2.0, 3.0]
            .iter()
            .map(|&at| {
                let k = (0..t.len())
                    .min_by(|&a, &b| (t[a] - at).abs().total_cmp(&(t[b] - at).abs()))
                    .unwrap();
                assert!((t[k] - at).abs() < 0.03, "no output near {at} s");
                isolated[k] / n
            })
            .collect();
        eprintln!("square patch l0 = {spacing} under tension: isolated fractions {at:?} at 1 / 2 / 3 s, KE {ke:+.4}, L {am:+.4}");
        assert!(at.iter().all(|&f| f < 1e-3), "isolated fractions {at:?}");
        assert!(ke.abs() < ke_bound, "kinetic energy changed by {ke}");
        assert!(am.abs() < 0.02, "angular momentum changed by {am}");
        fractions.push(at);
    }
    for k in 0..3 {
        assert!(
            fractions[1][k] <= fractions[0][k],
            "the finer patch sheds more: {fractions:?}"
        );
    }
}

/// The paper's MPS-HS-GC at the paper's spacing and step in still water: the paper reports
/// its free surface unstable in the settling and surfacing tanks and the runs breaking at
/// 0.41 s and 0.35 s (l0 = 2.5 mm, Courant 0.1). The still tank (H = 0.3 m) at l0 = 2.5 mm
/// with the step a Courant cap gives at rest, `0.1 sqrt(l0/g)`, must break the same way:
/// within a factor of two of those times, at the free surface (every fluid particle of the
/// breakdown within 4 l0 of the water line); the DS preset must hold the same tank for 1 s
/// (RMS speed below 0.1 sqrt(g l0), bottom pressure within 3 % of rho g H). Measured
/// 0.33 s, at the corners where the surface meets the walls (docs/decisions.md, "MPS-HS-GC's
/// still free surface breaks as the paper's").
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn mps_hs_gc_still_surface_breaks_as_the_paper_reports() {
    let l0: f64 = 0.0025;
    let dt = (0.1 * (l0 / 9.81).sqrt()).to_string();
    for scheme in ["MPS-HS-GC", "MPS-HS-GC-DS"] {
        let mut s = sim(
            "hydrostatic",
            &[
                ("output.vtu", "false"),
                ("scheme.name", scheme),
                ("particles.spacing", "0.0025"),
                ("time.dt_fixed", dt.as_str()),
                ("time.end", "1.0"),
            ],
        );
        let dir = tmp(&format!("paper_still_surface_{scheme}"));
        let summary = run(&mut s, &dir, &mut Silent).unwrap();
        if scheme == "MPS-HS-GC" {
            let message = summary.breakdown.expect("MPS-HS-GC held the still tank");
            eprintln!("MPS-HS-GC: {message}");
            let record = std::fs::read_to_string(dir.join("breakdown.toml")).unwrap();
            let record: toml::Table = toml::from_str(&record).unwrap();
            let time = record["time"].as_float().unwrap();
            assert!((0.175..=0.82).contains(&time), "breakdown at {time} s");
            let p = &s.particles;
            for id in record["particles"].as_array().unwrap() {
                let id = id.as_integer().unwrap() as u32;
                let i = p.id.iter().position(|&x| x == id).unwrap();
                let y = p.position[i][1];
                if p.kind[i] == Kind::Fluid {
                    assert!(y > 0.3 - 4.0 * l0, "particle {id} at y = {y} m");
                }
            }
            continue;
        }
        assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
        let limit = 0.1 * (9.81 * l0).sqrt();
        let worst = column(&dir.join("metrics.csv"), "rms_speed")
            .into_iter()
            .fold(0.0, f64::max);
        let v = &summary.validation[0];
        eprintln!(
            "{scheme}: RMS speed at most {worst:.4} m/s, bottom {:+.2} %",
            100.0 * v.error
        );
        assert!(worst < limit, "RMS speed {worst}");
        assert!(v.error.abs() < 0.03, "bottom pressure {v:?}");
    }
}

/// Runs the still tank (H = 0.3 m, l0 = 5 mm) for 2 s under `scheme` with the extra `set`
/// into `tmp(dir)`: no breakdown, the RMS speed below 0.1 sqrt(g l0) at every output.
/// Returns the bottom pressure averaged over the last second (Pa) and the largest RMS speed.
fn still_tank(scheme: &str, set: &[(&str, &str)], dir: &str) -> (f64, f64) {
    let mut all = vec![
        ("output.vtu", "false"),
        ("scheme.name", scheme),
        ("time.end", "2.0"),
    ];
    all.extend_from_slice(set);
    let mut s = sim("hydrostatic", &all);
    let dir = tmp(dir);
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(
        summary.breakdown.is_none(),
        "{scheme} {set:?}: {:?}",
        summary.breakdown
    );
    let max_rms = column(&dir.join("metrics.csv"), "rms_speed")
        .into_iter()
        .fold(0.0, f64::max);
    let limit = 0.1 * (9.81f64 * 0.005).sqrt();
    assert!(max_rms < limit, "{scheme} {set:?}: RMS speed {max_rms}");
    (summary.validation[0].value, max_rms)
}

/// Still tank (H = 0.3 m, l0 = 5 mm) for 2 s with MPS-HS-GC and MPS-HS-GC-DS (issue 3): no
/// breakdown, the RMS speed stays below 0.1 sqrt(g l0) at every output, and the bottom
/// pressure averaged over the last second lies within 3 % of the discrete hydrostatic value
/// rho g (H - l0/2) (p = 0 sits at the top row's centres).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn still_tank_with_gradient_correction_and_dynamic_stabilization() {
    for scheme in ["MPS-HS-GC", "MPS-HS-GC-DS"] {
        let (mean, max_rms) = still_tank(scheme, &[], &format!("still_{scheme}"));
        let discrete = 1000.0 * 9.81 * (0.3 - 0.0025);
        eprintln!(
            "still tank {scheme}: max RMS speed {max_rms:.4} m/s, bottom {mean:.1} Pa vs {discrete:.1} Pa ({:+.2} %)",
            100.0 * (mean / discrete - 1.0)
        );
        assert!(
            (mean / discrete - 1.0).abs() < 0.03,
            "{scheme}: bottom pressure {mean}"
        );
    }
}

/// Where the free surface's `p = 0` lies, against hydrostatics (still tank, H = 0.3 m,
/// l0 = 5 mm, MPS-HS-GC-DS, 2 s): on the mean surface of the top row's centres
/// (`mean-surface`) the bottom pressure over the last second is `rho g (H - l0/2)`, half a
/// spacing out at the edge of the particles (`edge-surface`) `rho g H`, each within 0.3 %
/// (the two differ by 0.83 %, so a half-spacing error fails either), the RMS speed below
/// 0.1 sqrt(g l0).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn still_tank_pressure_from_where_the_surface_lies() {
    let (rho_g, h, l0) = (1000.0 * 9.81, 0.3, 0.005);
    for (surface, depth) in [("mean-surface", h - l0 / 2.0), ("edge-surface", h)] {
        let set = [("scheme.surface_pressure", surface)];
        let (mean, max_rms) = still_tank("MPS-HS-GC-DS", &set, &format!("still_{surface}"));
        let want = rho_g * depth;
        eprintln!(
            "{surface}: bottom {mean:.1} Pa against {want:.1} ({:+.2} %), max RMS speed {max_rms:.4} m/s",
            100.0 * (mean / want - 1.0)
        );
        assert!(
            (mean / want - 1.0).abs() < 0.003,
            "{surface}: bottom {mean} Pa against {want}"
        );
    }
}

/// A linear standing wave (`standing_wave`: mode 1 in a tank 0.5 m long and 0.25 m deep,
/// a = 1 cm, l0 = 5 mm, MPS-HS-GC-DS, three periods) against `omega^2 = g k tanh(k h)`
/// (T = 0.8357 s): the kinetic energy's minima (a parabola through each output minimum)
/// fall at T/4 + n T/2, the first within 2 %, their mean spacing within 1 % of T/2 and each
/// within 2.5 %. A wrong gravity, depth or pressure-gradient scale moves the period by more.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn standing_wave_period_against_linear_theory() {
    let mut s = sim("standing_wave", &[]);
    let dir = tmp("standing_wave");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let metrics = dir.join("metrics.csv");
    let (t, ke) = (column(&metrics, "time"), column(&metrics, "kinetic_energy"));
    let (mut minima, mut peaks) = (Vec::new(), Vec::new());
    for k in 1..t.len() - 1 {
        if ke[k] > ke[k - 1] && ke[k] >= ke[k + 1] {
            peaks.push(ke[k]);
        }
        if ke[k] < ke[k - 1] && ke[k] <= ke[k + 1] {
            let curvature = ke[k - 1] - 2.0 * ke[k] + ke[k + 1];
            let shift = 0.5 * (ke[k - 1] - ke[k + 1]) / curvature * (t[k] - t[k - 1]);
            minima.push(t[k] + shift);
        }
    }
    let k = std::f64::consts::PI / 0.5;
    let period = 2.0 * std::f64::consts::PI / (9.81 * k * (k * 0.25f64).tanh()).sqrt();
    let halves: Vec<f64> = minima.windows(2).map(|w| w[1] - w[0]).collect();
    let mean = (minima[minima.len() - 1] - minima[0]) / halves.len() as f64;
    eprintln!(
        "standing wave: kinetic-energy minima at {minima:.4?} s; mean half period {mean:.4} s \
         against {:.4} ({:+.2} %); kinetic energy {:.4} J/m at t = 0, its peaks {peaks:.4?}",
        period / 2.0,
        100.0 * (2.0 * mean / period - 1.0),
        ke[0],
    );
    assert!(minima.len() >= 6, "minima {minima:?}");
    assert!(
        (minima[0] / (period / 4.0) - 1.0).abs() < 0.02,
        "first {}",
        minima[0]
    );
    assert!(
        (2.0 * mean / period - 1.0).abs() < 0.01,
        "mean half period {mean}"
    );
    for h in halves {
        assert!((2.0 * h / period - 1.0).abs() < 0.025, "half period {h}");
    }
}

/// Two-layer stratified tank (2650 under 1000 kg/m^3, l0 = 5 mm) with MPS-HS-GC-DS for 2 s
/// (issue 4): the RMS speed stays below 0.1 sqrt(g l0), the heavy layer's centroid moves less
/// than l0, and the bottom pressure averaged over the last second lies within 5 % of the
/// two-layer hydrostatic value rho_L g h_L + rho_H g h_H.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn two_layer_tank_stays_at_rest() {
    let mut s = sim("two_layer", &[("output.vtu", "false")]);
    let dir = tmp("two_layer");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let max_rms = column(&dir.join("metrics.csv"), "rms_speed")
        .into_iter()
        .fold(0.0, f64::max);
    let g = &summary.groups[0];
    let moved = ((g.centroid.1 .0 - g.centroid.0 .0).powi(2)
        + (g.centroid.1 .1 - g.centroid.0 .1).powi(2))
    .sqrt();
    let v = &summary.validation[0];
    eprintln!(
        "two-layer tank: max RMS speed {max_rms:.4} m/s, heavy centroid moved {:.2} mm, bottom {:.1} Pa vs {:.1} Pa ({:+.2} %)",
        moved * 1e3,
        v.value,
        v.reference,
        100.0 * v.error
    );
    assert!(
        max_rms < 0.1 * (9.81f64 * 0.005).sqrt(),
        "RMS speed {max_rms}"
    );
    assert!(moved < 0.005, "heavy layer moved {moved} m");
    assert!(v.error.abs() < 0.05, "bottom pressure off by {}", v.error);
}

/// Taylor-Green cell in a slip box (`taylor_green`: an exact steady Euler flow under strong
/// strain), 40 x 40, MPS-HS-GC with particle shifting, to t = 2 s (four turnovers): no
/// breakdown, the velocities within 10 % (relative L2) of the exact field at their positions,
/// kinetic energy within 3 %, no pair below 0.5 l0. The check fails a scheme that loses the
/// flow: without shifting MPS-HS-GC breaks down before 0.2 s, and MPS-HS-GC-DS's field is
/// off by more than 25 % at 2 s (Dynamic Stabilization dissipates the strained flow).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn taylor_green_cell_keeps_its_exact_field_with_particle_shifting() {
    let no_vtu = ("output.vtu", "false");
    let mut s = sim("taylor_green", &[no_vtu]);
    let m0 = mps::analysis::metrics::Metrics::measure(&s);
    let dir = tmp("taylor_green");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let ke = mps::analysis::metrics::Metrics::measure(&s).kinetic_energy / m0.kinetic_energy;
    let v = &summary.validation[0];
    let min_pair = column(&dir.join("steps.csv"), "min_pair_distance_l0")
        .into_iter()
        .fold(f64::MAX, f64::min);
    eprintln!(
        "Taylor-Green, shifting, 2 s: L2 error {:.4}, KE ratio {ke:.4}, closest pair {min_pair:.3} l0",
        v.error
    );
    assert!(v.passed && v.error < 0.1, "{v:?}");
    assert!((ke - 1.0).abs() < 0.03, "kinetic energy ratio {ke}");
    assert!(min_pair > 0.5, "closest pair {min_pair} l0");
    // Without shifting: MPS-HS-GC breaks, MPS-HS-GC-DS keeps running but loses the flow.
    let off = ("scheme.shifting.enabled", "false");
    let mut s = sim("taylor_green", &[no_vtu, off, ("time.end", "0.2")]);
    let gc = run(&mut s, &tmp("taylor_green_gc"), &mut Silent).unwrap();
    assert!(
        gc.breakdown.is_some(),
        "MPS-HS-GC without shifting ran to 0.2 s"
    );
    let mut s = sim(
        "taylor_green",
        &[no_vtu, off, ("scheme.name", "MPS-HS-GC-DS")],
    );
    let ds = run(&mut s, &tmp("taylor_green_ds"), &mut Silent).unwrap();
    let e = ds.validation[0].error;
    eprintln!("Taylor-Green, MPS-HS-GC-DS, 2 s: L2 error {e:.4}");
    assert!(
        ds.breakdown.is_none() && e > 0.25,
        "DS: {:?}",
        ds.validation[0]
    );
}

/// Settling groups (2650 in water) and surfacing groups (600 in water) at the paper's
/// resolution (l0 = 2.5 mm, 7000 fluid particles) and step (Courant 0.1, so alpha_DS = 0.9 by
/// paper Eq. 9), under MPS-HS-GC-DS-IR (beyond the paper: the DS preset with the interface
/// repulsion), issue 12: no breakdown; stray fraction (group particles with no same-phase
/// neighbour) below 0.05 at 0.5 s and below 0.10 at 1 s; the early acceleration (first
/// 0.05 s) within 15 % of the ideal fluid's first acceleration in the tank (walls, free
/// surface and the other groups included: 4.230 / 2.156 m/s^2) and within 30 % of the
/// unbounded estimate g |rho_g - rho_w| / (rho_g + rho_w) (4.43 / 2.45 m/s^2); settling: the
/// mean group centroid within 0.03 m of the bottom already at t = 1 s (the issue asks by
/// 2 s); surfacing, to 2 s: the mean centroid within 0.03 m of the free surface.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn settling_and_surfacing_groups() {
    for (case, end) in [("settling", "1.0"), ("surfacing", "2.0")] {
        let mean_y = groups_within_tolerance(case, &[("time.end", end)], case);
        if case == "settling" {
            assert!(
                mean_y < 0.03,
                "settling: mean centroid at {mean_y} m above the bottom"
            );
        } else {
            let below = 0.175 - mean_y;
            assert!(
                below < 0.03,
                "surfacing: mean centroid {below} m below the free surface at {end} s"
            );
        }
    }
}

/// The two-phase projection against an exact solution: the surfacing groups under
/// MPS-HS-GC (no stabilising term) accelerate as the tank's ideal-fluid potential flow
/// (`analysis::added_mass`, 2.156 m/s^2) over the first 30 ms, `2 dy / t^2` of the groups'
/// mean centroid within 2.5 % at 10, 20 and 30 ms (the run goes to 50 ms, where the tank's
/// value is reported). Harmonic pair densities read +3.3 % at 10 ms; the particle's own
/// density in the gradient or no gradient correction break down before 45 ms
/// (docs/decisions.md, "What slows the groups' start").
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn surfacing_groups_start_as_the_tanks_potential_flow() {
    let set = [
        ("time.end", "0.05"),
        ("scheme.name", "MPS-HS-GC"),
        ("output.vtu", "false"),
    ];
    let mut s = sim("surfacing", &set);
    let dir = tmp("surfacing_start");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let exact = summary
        .validation
        .iter()
        .find(|v| v.name == "group_early_acceleration_tank")
        .expect("the tank's potential-flow value")
        .reference;
    assert!((exact - 2.156).abs() < 0.01, "tank value {exact}");
    let tracks = dir.join("group_tracks.csv");
    let time = column(&tracks, "time");
    let ys: Vec<Vec<f64>> = (1..=3)
        .map(|g| column(&tracks, &format!("group{g}_y")))
        .collect();
    let mean = |k: usize| ys.iter().map(|y| y[k]).sum::<f64>() / 3.0;
    for at in [0.01, 0.02, 0.03] {
        let k = (0..time.len())
            .min_by(|&a, &b| (time[a] - at).abs().total_cmp(&(time[b] - at).abs()))
            .unwrap();
        let acc = 2.0 * (mean(k) - mean(0)) / (time[k] * time[k]);
        eprintln!(
            "t = {:.4} s: 2 dy / t^2 = {acc:.4} m/s^2 against {exact:.4} ({:+.2} %)",
            time[k],
            100.0 * (acc / exact - 1.0)
        );
        assert!(
            (acc / exact - 1.0).abs() < 0.025,
            "at {} s the groups accelerate at {acc} m/s^2, the potential flow {exact}",
            time[k]
        );
    }
}

/// The same two tanks at half the spacing (l0 = 1.25 mm, 28 000 fluid particles) to 0.5 s:
/// the strays must not grow with resolution (issue 12), and the start stays within 15 % of
/// the tank's ideal-fluid acceleration. The cases give the repulsion as an interface energy,
/// so its `P` doubles here (200 and 40 Pa).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn settling_and_surfacing_groups_at_half_the_spacing() {
    for case in ["settling", "surfacing"] {
        let set = [("time.end", "0.5"), ("particles.spacing", "0.00125")];
        groups_within_tolerance(case, &set, &format!("{case}_half"));
    }
}

/// Runs `case` with `set` (VTU off) into `tmp(dir)` and checks it: no breakdown, the early
/// acceleration within 15 % of the tank's ideal-fluid value and 30 % of the unbounded
/// estimate, stray fraction below 0.05 at 0.5 s and below 0.10 at 1 s (where the run gets
/// there). Returns the groups' mean centroid height (m) at the end.
fn groups_within_tolerance(case: &str, set: &[(&str, &str)], dir: &str) -> f64 {
    let mut set = set.to_vec();
    set.push(("output.vtu", "false"));
    let mut s = sim(case, &set);
    let dir = tmp(dir);
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(
        summary.breakdown.is_none(),
        "{case}: {:?}",
        summary.breakdown
    );
    let n = summary.groups.len() as f64;
    let mean_y = summary.groups.iter().map(|g| g.centroid.1 .1).sum::<f64>() / n;
    let named = |name: &str| {
        summary
            .validation
            .iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("{case}: no {name}"))
    };
    let (acc, tank) = (
        named("group_early_acceleration"),
        named("group_early_acceleration_tank"),
    );
    eprintln!(
        "{case} {set:?}: mean centroid y {mean_y:.4} m, early acceleration {:.2} m/s^2 \
         against {:.2} unbounded ({:+.1} %) and {:.3} in the tank ({:+.1} %), arrivals {:?}",
        acc.value,
        acc.reference,
        100.0 * acc.error,
        tank.reference,
        100.0 * tank.error,
        summary
            .groups
            .iter()
            .map(|g| g.arrival_time)
            .collect::<Vec<_>>()
    );
    assert!(
        acc.error.abs() < 0.3,
        "{case}: early acceleration off the unbounded estimate by {}",
        acc.error
    );
    assert!(
        tank.error.abs() < 0.15,
        "{case}: early acceleration off the tank's by {}",
        tank.error
    );
    let groups = dir.join("groups.csv");
    let (time, stray) = (column(&groups, "time"), column(&groups, "stray_fraction"));
    for (t, limit) in [(0.5, 0.05), (1.0, 0.10)] {
        if time.last().is_none_or(|&end| end < t - 1e-9) {
            continue; // the run ends before t
        }
        let k = (0..time.len())
            .min_by(|&a, &b| (time[a] - t).abs().total_cmp(&(time[b] - t).abs()))
            .unwrap();
        assert!((time[k] - t).abs() < 0.01, "{case}: no output near {t} s");
        eprintln!("{case}: stray fraction {:.3} at {t} s", stray[k]);
        assert!(
            stray[k] < limit,
            "{case}: stray fraction {} at {t} s",
            stray[k]
        );
    }
    mean_y
}

/// A box closed on all sides, full of fluid at rest (two layers 2650 under 1000, and one
/// fluid): 5 s with MPS-HS-GC-DS. No free surface, so the pressure level comes from the
/// stated reference (0 Pa at the top of the water): the mid-depth probe within 1 % of the
/// hydrostatic value from it, the RMS speed below 0.1 sqrt(g l0) throughout, and no
/// particle flagged free surface at any output (the fluid fills the closed tank: no air).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn closed_boxes_stay_at_rest_with_a_pressure_level_from_the_reference() {
    // (extra settings, exact pressure at the probe from the reference, Pa)
    let cases: [(&[(&str, &str)], f64); 2] = [
        (&[], 1000.0 * 9.81 * 0.1975 + 2650.0 * 9.81 * 0.05),
        (
            &[
                ("fluid.0.phase", "water"),
                ("fluid.0.pressure.offset", "0.0"),
            ],
            1000.0 * 9.81 * 0.2475,
        ),
    ];
    for (k, (set, exact)) in cases.iter().enumerate() {
        let mut set = set.to_vec();
        set.push(("output.vtu", "false"));
        let mut s = sim("closed_box", &set);
        let fluid = s.particles.count(Kind::Fluid) as f64;
        let dir = tmp(&format!("closed_box_{k}"));
        let summary = run(&mut s, &dir, &mut Silent).unwrap();
        assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
        let mean = summary.validation[0].value;
        let metrics = dir.join("metrics.csv");
        let max_rms = column(&metrics, "rms_speed")
            .into_iter()
            .fold(0.0, f64::max);
        let max_false = column(&metrics, "surface_particles")
            .into_iter()
            .fold(0.0, f64::max);
        eprintln!(
            "closed box {k}: probe {mean:.1} Pa vs {exact:.1} ({:+.2} %), max RMS speed {max_rms:.4} m/s, most surface flags {max_false}",
            100.0 * (mean / exact - 1.0)
        );
        assert!((mean / exact - 1.0).abs() < 0.01, "probe {mean} vs {exact}");
        assert!(
            max_rms < 0.1 * (9.81f64 * 0.005).sqrt(),
            "RMS speed {max_rms}"
        );
        assert!(fluid > 2000.0);
        assert_eq!(
            max_false, 0.0,
            "{max_false} surface flags in a full closed box"
        );
    }
}

/// The example's text with its `[validation]` table replaced by `validation`.
fn with_validation(name: &str, validation: &str) -> String {
    let text = mps::examples::example(name).expect("example exists");
    let start = text
        .find("[validation]")
        .expect("the example has a validation");
    format!("{}{validation}\n", &text[..start])
}

/// A front against a reference curve the case names: Martin & Moyce's points written as a CSV
/// in seconds and metres (ms and mm in the file, scaled when read), the dam break run to its
/// end. The RMS difference must be the `dam_break` kind's dimensionless RMS times L (the
/// same points, linear interpolation commutes with the scaling), within the same 0.3 L,
/// and the comparison file is written.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_front_against_a_reference_csv_agrees_with_the_built_in_comparison() {
    let dir = tmp("front_reference");
    let (l, g): (f64, f64) = (0.146, 9.81);
    let scale = (2.0 * g / l).sqrt();
    let mut csv = String::from("# Martin & Moyce (1952), a = 2.25 in\nt_ms,front_mm\n");
    for (tt, z) in mps::analysis::validation::martin_moyce() {
        csv += &format!("{},{}\n", 1e3 * tt / scale, 1e3 * z * l);
    }
    std::fs::write(dir.join("mm.csv"), csv).unwrap();
    let text = with_validation(
        "dam_break",
        "[validation]\nkind = \"front_reference\"\nwall_x = 0.0\n\
         reference = { file = \"mm.csv\", time_scale = 0.001, value_scale = 0.001 }\n\
         rms_tolerance = 0.0438\npeak_tolerance = 0.1",
    );
    let case_path = dir.join("case.toml");
    std::fs::write(&case_path, text).unwrap();
    let over = [("output.vtu".to_string(), "false".to_string())];
    let case = mps::Case::from_file(&case_path, &over).unwrap();
    let mut s = mps::Simulation::<2>::new(case, "dam_break").unwrap();
    let out = dir.join("run");
    let summary = run(&mut s, &out, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let rms = &summary.validation[0];
    let front = column(&out.join("front.csv"), "front");
    let time = column(&out.join("front.csv"), "time");
    let series: Vec<(f64, f64)> = time.into_iter().zip(front).collect();
    let (rows, rms_z) = mps::analysis::validation::dam_break_front(&series, l, g);
    eprintln!(
        "front vs CSV: RMS {:.4} m over {} points; built-in RMS(Z) {rms_z:.4} x L = {:.4} m",
        rms.value,
        rows.len(),
        rms_z * l
    );
    assert_eq!(rms.name, "front_rms_difference");
    assert!(
        (rms.value - rms_z * l).abs() <= 1e-9 * l,
        "{} vs {}",
        rms.value,
        rms_z * l
    );
    assert!(rms.passed && rms.value <= 0.3 * l);
    let written = column(&out.join("reference_comparison.csv"), "difference");
    assert_eq!(written.len(), rows.len());
    assert!(rows.len() >= 12);
}

/// A probe against a reference curve: still water (the example under MPS-HS-GC-DS, to
/// 1.5 s), the bottom probe's 50 ms moving average against rho g H from 0.5 s to 1.5 s
/// passes 5 % RMS and 10 % peak tolerances; the same run against a curve 20 % high fails
/// both. The comparator is under test, so the signal is a quiet one: plain MPS's average
/// swings by up to 14 % of rho g H from one solver realisation to the next
/// (docs/decisions.md, "Modified D-ILU").
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_probe_against_a_reference_csv_passes_the_right_curve_and_fails_a_wrong_one() {
    let dir = tmp("probe_reference");
    let exact = 1000.0 * 9.81 * 0.3;
    let mut failed = Vec::new();
    for (name, factor) in [("right", 1.0), ("high", 1.2)] {
        let rows: String = (0..=10)
            .map(|k| format!("{},{}\n", 0.5 + 0.1 * k as f64, factor * exact))
            .collect();
        std::fs::write(dir.join(format!("{name}.csv")), format!("time,p\n{rows}")).unwrap();
        let text = with_validation(
            "hydrostatic",
            &format!(
                "[validation]\nkind = \"probe_reference\"\nprobe = \"bottom\"\n\
                 reference = {{ file = \"{name}.csv\", columns = [\"time\", \"p\"] }}\n\
                 rms_tolerance = {}\npeak_tolerance = {}\nsmoothing = 0.05",
                0.05 * exact,
                0.1 * exact
            ),
        );
        let case_path = dir.join(format!("{name}.toml"));
        std::fs::write(&case_path, text).unwrap();
        let over: Vec<(String, String)> = [
            ("output.vtu", "false"),
            ("time.end", "1.5"),
            ("scheme.name", "MPS-HS-GC-DS"),
        ]
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
        let case = mps::Case::from_file(&case_path, &over).unwrap();
        let mut s = mps::Simulation::<2>::new(case, name).unwrap();
        let summary = run(&mut s, &dir.join(name), &mut Silent).unwrap();
        let (rms, peak) = (&summary.validation[0], &summary.validation[1]);
        eprintln!(
            "{name}: RMS {:.1} Pa, peak {:.1} Pa (rho g H {exact:.1} Pa)",
            rms.value, peak.value
        );
        assert!(rms.value.is_finite() && peak.value >= rms.value);
        failed.push((rms.passed, peak.passed));
    }
    assert_eq!(failed, vec![(true, true), (false, false)]);
}

/// A reference file that does not parse is bad input, named with its row, before any run.
#[test]
fn a_bad_reference_csv_is_refused_when_the_case_loads() {
    let dir = tmp("bad_reference");
    std::fs::write(dir.join("r.csv"), "t,p\n0,1\n0.1,oops\n").unwrap();
    let text = with_validation(
        "hydrostatic",
        "[validation]\nkind = \"probe_reference\"\nprobe = \"bottom\"\n\
         reference = { file = \"r.csv\" }\nrms_tolerance = 1.0\npeak_tolerance = 1.0",
    );
    std::fs::write(dir.join("c.toml"), text).unwrap();
    let e = mps::Case::from_file(&dir.join("c.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("c.toml") && e.contains("validation.reference.file") && e.contains("row 3"),
        "{e}"
    );
    assert!(!e.contains('\n'));
}

/// The rotating disc with a mode-6 perturbation (`rotating_disc_mode`, MPS-HS-GC-DS): the
/// surface mode grows as linear theory of the centrifugal Rayleigh-Taylor instability says,
/// `(U / gamma) sinh(gamma t)`, within the case's tolerance up to t = 1.05 s, and a run
/// resumed from a checkpoint at 0.5 s measures the same particles (the same `rim_mode.csv`).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_rotating_disc_surface_mode_grows_as_linear_theory() {
    let set = [("output.vtu", "false")];
    let mut s = sim("rotating_disc_mode", &set);
    let dir = tmp("rotating_disc_mode");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let v = &summary.validation[0];
    eprintln!(
        "rotating disc mode 6: amplitude {:.4} m vs theory {:.4} m at the end, largest error {:+.1} %",
        v.value,
        v.reference,
        100.0 * v.error
    );
    assert_eq!(v.name, "surface_mode_growth");
    assert!(v.passed, "{v:?}");
    // It measures growth, not noise: about one spacing by the end.
    assert!(v.value > 0.015, "{v:?}");

    let first = tmp("rotating_disc_mode_first");
    let mut a = sim(
        "rotating_disc_mode",
        &[("output.vtu", "false"), ("time.end", "0.5")],
    );
    run(&mut a, &first, &mut Silent).unwrap();
    let bytes = std::fs::read(first.join("checkpoint.bin")).unwrap();
    let mut b = sim("rotating_disc_mode", &set);
    mps::io::checkpoint::restore(&mut b, &bytes, &first).unwrap();
    let resumed = tmp("rotating_disc_mode_resumed");
    let again = mps::run::run_from(&mut b, &resumed, Some(&first), &mut Silent).unwrap();
    // The rows before the checkpoint are carried; after it the same rim is measured (the
    // first run's last steps land on 0.5 s, so the states differ by round-off only).
    let (t0, a0) = (
        column(&dir.join("rim_mode.csv"), "time"),
        column(&dir.join("rim_mode.csv"), "amplitude"),
    );
    let (t1, a1) = (
        column(&resumed.join("rim_mode.csv"), "time"),
        column(&resumed.join("rim_mode.csv"), "amplitude"),
    );
    let before = t0.iter().take_while(|&&t| t < 0.49).count();
    assert!(before >= 9 && t1[..before] == t0[..before] && a1[..before] == a0[..before]);
    let (end0, end1) = (a0[a0.len() - 1], a1[a1.len() - 1]);
    assert!((end1 / end0 - 1.0).abs() < 0.02, "{end1} vs {end0}");
    assert!(again.validation[0].passed, "{:?}", again.validation);
}

/// The same disc with a free-surface tension sigma = 1.4 N/m (`T = sigma / (rho R^3)` =
/// 0.0112 /s^2 at R = 0.5 m, so `T n (n + 1)` = 0.47 Omega^2 for n = 6): the mode grows at
/// `gamma^2 = (n - 1) (Omega^2 - T n (n + 1)) = 2.65 /s^2` instead of 5; the measured
/// amplitude follows that theory within the case's 15 % and lies at least 15 % below the
/// tension-free theory's at the end.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn surface_tension_slows_the_rotating_discs_mode_as_linear_theory() {
    let set = [("output.vtu", "false"), ("phases.0.surface_tension", "1.4")];
    let mut s = sim("rotating_disc_mode", &set);
    let dir = tmp("rotating_disc_mode_tension");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let v = &summary.validation[0];
    // The tension-free theory's amplitude for the same U (the ratio does not depend on it).
    let amplitude = |t| mps::analysis::rim_mode::linear_amplitude(1.0, (1.0, t), 6, 1.05);
    let free = v.reference * amplitude(0.0) / amplitude(1.4 / (1000.0 * 0.125));
    eprintln!(
        "rotating disc mode 6 under tension: amplitude {:.4} m vs theory {:.4} m ({:+.1} %), tension-free theory {free:.4} m",
        v.value,
        v.reference,
        100.0 * v.error
    );
    assert!(v.passed, "{v:?}");
    assert!(
        v.value < 0.85 * free,
        "{} against the tension-free {free}",
        v.value
    );
}

/// Monaghan's elliptic drop (`elliptic_drop`, R = 1 m, A0 = 100 /s, l0 = 0.025 m, to
/// 7.6 ms, the shipped MPS-HS-GC-DS-S): a free body under strong strain follows the exact
/// ellipse, both semi-axes within the case's 2 % at every output, and keeps its area.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn an_elliptic_drop_deforms_as_the_exact_solution() {
    let mut s = sim("elliptic_drop", &[("output.vtu", "false")]);
    let dir = tmp("elliptic_drop");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let v = &summary.validation[0];
    eprintln!(
        "elliptic drop: largest semi-axis error {:+.2} %, semi-major axis {:.4} m vs {:.4} m at the end",
        100.0 * v.error,
        v.value,
        v.reference
    );
    assert_eq!(v.name, "elliptic_drop_axes");
    assert!(v.passed && v.error.abs() < 0.02, "{v:?}");
    // The drop stretched: nearly doubled by the end, and its area kept within 2 %.
    assert!(v.value > 1.9, "{v:?}");
    let axes = dir.join("drop_axes.csv");
    let (a, b) = (column(&axes, "a"), column(&axes, "b"));
    for (a, b) in a.iter().zip(&b) {
        assert!((a * b - 1.0).abs() < 0.02, "area {}", a * b);
    }
}

/// A drop at rest under interfacial tension (`laplace_drop`, l0 = 2 mm, R = 12.5 l0,
/// sigma = 0.5 N/m, 0.5 s): the continuum surface force gives the Laplace jump sigma / R =
/// 20 Pa within 6 % for equal densities and for the settling pair's 2650 in 1000, with the
/// spurious currents below 1 mm/s; the same drop without the interface has no jump.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_drop_under_interfacial_tension_has_the_laplace_jump() {
    for (k, density) in ["1000.0", "2650.0"].iter().enumerate() {
        let set = [("output.vtu", "false"), ("phases.1.density", *density)];
        let mut s = sim("laplace_drop", &set);
        let dir = tmp(&format!("laplace_{k}"));
        let summary = run(&mut s, &dir, &mut Silent).unwrap();
        assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
        let v = &summary.validation[0];
        let rms = column(&dir.join("metrics.csv"), "rms_speed");
        let late = rms[rms.len() / 2..].iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "drop density {density}: jump {:.2} Pa against {:.2} ({:+.2} %), RMS speed {late:.2e} m/s",
            v.value,
            v.reference,
            100.0 * v.error
        );
        assert!(
            v.error.abs() < 0.06,
            "jump {} against {}",
            v.value,
            v.reference
        );
        assert!(late < 1e-3, "spurious currents {late} m/s");
    }
    // The disc filled with the outer fluid: no interface, the same probes, no jump.
    let set = [
        ("output.vtu", "false"),
        ("time.end", "0.2"),
        ("fluid.1.phase", "outer"),
    ];
    let mut s = sim("laplace_drop", &set);
    let summary = run(&mut s, &tmp("laplace_none"), &mut Silent).unwrap();
    let jump = summary.validation[0].value;
    assert!(jump.abs() < 1.0, "jump {jump} Pa without an interface");
}

/// A free drop under the tension of its free surface (`free_drop`, R = 0.05 m, sigma = 1 N/m,
/// DS preset, 0.5 s): the centre pressure from 0.1 s is the Laplace jump sigma / R = 20 Pa
/// within 8 % at R / l0 = 20 and within 4.5 % at R / l0 = 40 (the error falls with l0: the
/// surface ring's own curvature is 1 / (R - l0/2)), the drop at rest (RMS speed below 1e-3
/// m/s over the second half).
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_free_drop_under_surface_tension_has_the_laplace_jump() {
    for (spacing, bound) in [("0.0025", 0.08), ("0.00125", 0.045)] {
        let set = [("output.vtu", "false"), ("particles.spacing", spacing)];
        let mut s = sim("free_drop", &set);
        let dir = tmp(&format!("free_drop_{spacing}"));
        let summary = run(&mut s, &dir, &mut Silent).unwrap();
        assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
        let v = &summary.validation[0];
        let rms = column(&dir.join("metrics.csv"), "rms_speed");
        let late = rms[rms.len() / 2..].iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "free drop l0 = {spacing}: centre {:.2} Pa against {:.2} ({:+.2} %), RMS speed {late:.2e} m/s",
            v.value,
            v.reference,
            100.0 * v.error
        );
        assert!(
            v.error.abs() < bound,
            "jump {} against {}",
            v.value,
            v.reference
        );
        assert!(late < 1e-3, "spurious currents {late} m/s");
    }
}

/// A free drop's capillary oscillation (Rayleigh 1879; a 2D column's mode n oscillates at
/// `omega^2 = n (n^2 - 1) sigma / (rho R^3)`, `6 sigma / (rho R^3)` for n = 2): `free_drop`
/// (R = 0.05 m = 20 l0, sigma = 1 N/m, so T = 0.9069 s) with nu = 1e-4 and the mode's
/// potential flow `u = eps (x, -y)` at the start. Its elongation `sqrt(<x^2>) - sqrt(<y^2>)`
/// changes sign at T/2 and T: both within 5 % of the inviscid period.
#[test]
#[ignore = "validation run (release mode): cargo test --release -- --ignored"]
fn a_free_drop_oscillates_at_rayleighs_frequency() {
    let flow = "{ type = \"expression\", u = \"0.35 * x\", v = \"-0.35 * y\" }";
    let set = [
        ("output.vtu", "false"),
        ("phases.0.viscosity", "1.0e-4"),
        ("fluid.0.velocity", flow),
    ];
    let mut s = sim("free_drop", &set);
    s.refresh_diagnostic_fields();
    let elongation = |s: &mps::Simulation<2>| {
        let p = &s.particles;
        let fluid: Vec<usize> = (0..p.len()).filter(|&i| p.kind[i] == Kind::Fluid).collect();
        let n = fluid.len() as f64;
        let (cx, cy) = fluid.iter().fold((0.0, 0.0), |(a, b), &i| {
            (a + p.position[i][0] / n, b + p.position[i][1] / n)
        });
        let (xx, yy) = fluid.iter().fold((0.0, 0.0), |(a, b), &i| {
            let (dx, dy) = (p.position[i][0] - cx, p.position[i][1] - cy);
            (a + dx * dx / n, b + dy * dy / n)
        });
        xx.sqrt() - yy.sqrt()
    };
    let period = 2.0 * std::f64::consts::PI / (6.0f64 / (1000.0 * 0.05f64.powi(3))).sqrt();
    let (end, mut crossings) = (1.1 * period, Vec::new());
    let (mut t0, mut e0) = (0.0, elongation(&s));
    while s.time < end && crossings.len() < 2 {
        s.step(end).expect("no breakdown");
        let e = elongation(&s);
        // The drop starts round and stretches along x first: e > 0 until T/2.
        if (e < 0.0) != (e0 < 0.0) && s.time > 0.1 * period {
            crossings.push(t0 + (s.time - t0) * e0 / (e0 - e));
        }
        (t0, e0) = (s.time, e);
    }
    eprintln!(
        "free drop mode 2: sign changes at {crossings:?} s against T/2, T = {:.4}, {period:.4} s",
        period / 2.0
    );
    assert_eq!(crossings.len(), 2, "sign changes {crossings:?}");
    for (k, t) in crossings.iter().enumerate() {
        let exact = 0.5 * (k + 1) as f64 * period;
        assert!(
            (t / exact - 1.0).abs() < 0.05,
            "crossing {t} s against {exact} s"
        );
    }
}
