//! A settled start (`[initial] state`): a run begins from another run's checkpoint of the
//! same geometry, with this case's phases and groups.

mod common;
use common::tmp;
use mps::io::checkpoint::{build_simulation, checkpoint_bytes};
use mps::particles::Kind;
use mps::Case;
use std::collections::HashMap;

/// The settling example at l0 = 1 cm, as text with extra lines at the end.
fn settling(extra: &str, set: &[(&str, &str)], dir: &std::path::Path, name: &str) -> Case {
    let text = format!("{}\n{extra}\n", mps::examples::example("settling").unwrap());
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let mut o = vec![("particles.spacing".to_string(), "0.01".to_string())];
    o.extend(set.iter().map(|(k, v)| (k.to_string(), v.to_string())));
    Case::from_file(&path, &o).unwrap()
}

/// The tank at rest with every region water for 30 steps, then the settling case from that
/// state: every particle (by id) has the rest run's position and velocity, every fluid
/// particle its pressure, the
/// group particles are the heavy phase with its density, and the clock starts at 0.
#[test]
fn a_run_starts_from_a_settled_state_with_its_own_phases() {
    let dir = tmp("settled_start");
    let water = [
        ("fluid.1.phase", "water"),
        ("fluid.2.phase", "water"),
        ("fluid.3.phase", "water"),
    ];
    let mut rest = build_simulation::<2>(settling("", &water, &dir, "rest"), "rest").unwrap();
    for _ in 0..30 {
        rest.step(1.0).unwrap();
    }
    std::fs::write(dir.join("rest.bin"), checkpoint_bytes(&rest)).unwrap();
    let case = settling("[initial]\nstate = \"rest.bin\"", &[], &dir, "settled");
    let s = build_simulation::<2>(case, "settled").unwrap();
    assert_eq!(s.time, 0.0);
    let r = &rest.particles;
    let by_id: HashMap<u32, usize> = r.id.iter().enumerate().map(|(k, &id)| (id, k)).collect();
    let p = &s.particles;
    let heavy = s.case.phase_index("heavy").unwrap() as u16;
    let mut moved = 0;
    for i in 0..p.len() {
        let k = by_id[&p.id[i]];
        assert_eq!(p.position[i], r.position[k]);
        assert_eq!(p.velocity[i], r.velocity[k]);
        if p.kind[i] == Kind::Fluid {
            // (Wall pressures are extrapolated again from the fluid next to them.)
            assert_eq!(p.pressure[i], r.pressure[k]);
            assert_eq!(r.phase[k], 0, "the rest run is all water");
            if p.group[i] != mps::particles::NO_GROUP {
                assert_eq!(p.phase[i], heavy);
                assert_eq!(p.density[i], 2650.0);
            }
            moved += (p.velocity[i].norm() > 0.0) as usize;
        }
    }
    assert!(moved > 0, "the rest run's velocities are carried");
}

/// A checkpoint of another geometry is refused naming `initial.state`; a missing file is
/// refused when the case loads.
#[test]
fn another_geometry_or_a_missing_file_is_refused() {
    let dir = tmp("settled_start_bad");
    let coarse = [("particles.spacing", "0.0125")];
    let mut other = build_simulation::<2>(settling("", &coarse, &dir, "other"), "o").unwrap();
    other.step(1.0).unwrap();
    std::fs::write(dir.join("other.bin"), checkpoint_bytes(&other)).unwrap();
    let case = settling("[initial]\nstate = \"other.bin\"", &[], &dir, "c");
    let e = build_simulation::<2>(case, "c").err().unwrap().to_string();
    assert!(
        e.contains("other.bin") && e.contains("initial.state"),
        "{e}"
    );
    assert!(!e.contains('\n'));
    let path = dir.join("m.toml");
    let text = format!(
        "{}\n[initial]\nstate = \"nowhere.bin\"\n",
        mps::examples::example("settling").unwrap()
    );
    std::fs::write(&path, text).unwrap();
    let e = Case::from_file(&path, &[]).unwrap_err().to_string();
    assert!(
        e.contains("initial.state") && e.contains("nowhere.bin"),
        "{e}"
    );
}

/// `[initial.relax]` is the two-step settled start made by hand: the relaxation equals the
/// tank run at rest with every region water under the DS preset for the same time, then
/// started from (every position, velocity and fluid pressure bit for bit), with this case's
/// phases; it moved the particles off the lattice.
#[test]
fn a_relaxation_first_is_the_settled_start_made_by_hand() {
    let dir = tmp("relax");
    let water = [
        ("fluid.1.phase", "water"),
        ("fluid.2.phase", "water"),
        ("fluid.3.phase", "water"),
        ("time.end", "0.02"),
    ];
    let mut rest = build_simulation::<2>(settling("", &water, &dir, "rest"), "rest").unwrap();
    while rest.time < 0.02 * (1.0 - 1e-9) {
        rest.step(0.02).unwrap();
    }
    let case = settling("[initial.relax]\ntime = 0.02", &[], &dir, "relaxed");
    let s = build_simulation::<2>(case, "relaxed").unwrap();
    let lattice = build_simulation::<2>(settling("", &[], &dir, "plain"), "plain").unwrap();
    let by_id = |p: &mps::particles::Particles<2>| -> HashMap<u32, usize> {
        p.id.iter().enumerate().map(|(k, &id)| (id, k)).collect()
    };
    let (r, l) = (by_id(&rest.particles), by_id(&lattice.particles));
    let p = &s.particles;
    let heavy = s.case.phase_index("heavy").unwrap() as u16;
    let mut moved = 0;
    for i in 0..p.len() {
        let k = r[&p.id[i]];
        assert_eq!(p.position[i], rest.particles.position[k]);
        assert_eq!(p.velocity[i], rest.particles.velocity[k]);
        if p.kind[i] == Kind::Fluid {
            assert_eq!(p.pressure[i], rest.particles.pressure[k]);
            if p.group[i] != mps::particles::NO_GROUP {
                assert_eq!(p.phase[i], heavy);
            }
            moved += (p.position[i] != lattice.particles.position[l[&p.id[i]]]) as usize;
        }
    }
    let fluid = p.count(Kind::Fluid);
    assert!(
        2 * moved > fluid,
        "{moved} of {fluid} fluid particles off the lattice"
    );
    assert_eq!(s.time, 0.0);
}

/// A relaxation may end early: with `kinetic_fraction` the state is taken once the kinetic
/// energy has fallen below that fraction of its peak, before the longest time.
#[test]
fn a_relaxation_ends_when_the_tank_has_calmed() {
    let dir = tmp("relax_early");
    let case = settling("", &[], &dir, "c");
    let spec = mps::input::case::RelaxSpec {
        time: 0.5,
        kinetic_fraction: Some(0.5),
    };
    let rest = mps::simulation::relax::relaxation_case(&case, &spec);
    assert_eq!(rest.scheme.name, "MPS-HS-GC-DS");
    assert!(rest.fluid.iter().all(|f| f.phase == "water"));
    let mut full = mps::simulation::Simulation::<2>::new(rest, "c").unwrap();
    let (mut peak, mut calm_at) = (0.0f64, None);
    while full.time < 0.5 * (1.0 - 1e-9) && calm_at.is_none() {
        full.step(0.5).unwrap();
        let p = &full.particles;
        let e: f64 = (0..p.len())
            .filter(|&i| p.kind[i] == Kind::Fluid)
            .map(|i| 0.5 * p.density[i] * p.velocity[i].norm2())
            .sum();
        peak = peak.max(e);
        if e < 0.5 * peak {
            calm_at = Some(full.step_count);
        }
    }
    let calm_at = calm_at.expect("the lattice's first motion calms within 0.5 s");
    let relaxed = mps::simulation::relax::relax::<2>(&case, &spec, "c").unwrap();
    assert_eq!(
        relaxed.position, full.particles.position,
        "stopped at step {calm_at}"
    );
}

/// Bad relaxations are refused naming the field: both sources, neither, a time that is not
/// positive, a fraction outside (0, 1).
#[test]
fn bad_relaxations_are_refused_naming_the_field() {
    let dir = tmp("relax_bad");
    let base = mps::examples::example("settling").unwrap();
    for (extra, field) in [
        (
            "[initial]\nstate = \"x.bin\"\nrelax = { time = 1.0 }",
            "initial",
        ),
        ("[initial]", "initial"),
        ("[initial.relax]\ntime = 0.0", "initial.relax.time"),
        (
            "[initial.relax]\ntime = 1.0\nkinetic_fraction = 1.5",
            "initial.relax.kinetic_fraction",
        ),
    ] {
        let path = dir.join("bad.toml");
        std::fs::write(&path, format!("{base}\n{extra}\n")).unwrap();
        let e = Case::from_file(&path, &[]).unwrap_err().to_string();
        assert!(e.contains(field) && !e.contains('\n'), "{extra}: {e}");
    }
}
