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
