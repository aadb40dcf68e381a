//! Outflow (`domain.outflow = "remove"`): a water column collapses along a floor that ends at
//! the domain's right edge and pours out of the domain.

mod common;
use common::{column, tmp};
use mps::particles::Kind;
use mps::run::{run, Silent};
use mps::{BreakdownReason, Case, Simulation};
use std::path::Path;

/// The spill case (`tests/data/spill.toml`: a column at L/20 on a floor that ends at the
/// domain's right edge) with `domain.outflow` and the end time (s) given.
fn spill(outflow: &str, end: f64) -> Simulation<2> {
    let text = include_str!("data/spill.toml");
    let set = [
        ("domain.outflow".to_string(), format!("{outflow:?}")),
        ("time.end".to_string(), end.to_string()),
    ];
    let case = Case::from_str_named(text, "spill.toml", &set).expect("valid case");
    Simulation::<2>::new(case, "spill").expect("builds")
}

fn fluid(s: &Simulation<2>) -> usize {
    s.particles.count(Kind::Fluid)
}

/// With the default the first particle past the edge is a breakdown naming it; with
/// `remove` the two runs are bit-identical up to that step, the particle is removed there
/// instead, and the run goes on.
#[test]
fn removal_changes_nothing_before_the_first_particle_leaves() {
    let (mut stop, mut go) = (spill("breakdown", 1.0), spill("remove", 1.0));
    let n0 = fluid(&go);
    let left = loop {
        match stop.step(1.0) {
            Ok(_) => {
                go.step(1.0).expect("same step");
                assert_eq!(go.particles.position, stop.particles.position);
                assert_eq!(go.outflow_removed, 0);
            }
            Err(b) => break b,
        }
    };
    assert_eq!(left.reason, BreakdownReason::LeftDomain, "{left}");
    assert!(!left.particles.is_empty());
    assert_eq!(go.particles.position, stop.particles.position);
    let r = go.step(1.0).expect("the outflow run goes on");
    assert!(r.removed as usize >= left.particles.len(), "{}", r.removed);
    assert_eq!(fluid(&go) as u64 + go.outflow_removed, n0 as u64);
    assert!(go
        .particles
        .id
        .iter()
        .all(|id| !left.particles.contains(id)));
}

/// The whole spill to 0.6 s: no breakdown, particles leave, every fluid particle that is
/// left lies inside the domain, and the count balances in the summary, `metrics.csv` and
/// `steps.csv`.
#[test]
fn a_spill_runs_on_and_counts_what_left() {
    let mut s = spill("remove", 0.6);
    let n0 = fluid(&s);
    let dir = tmp("outflow");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    assert!(summary.breakdown.is_none(), "{:?}", summary.breakdown);
    let removed = summary.outflow_removed;
    eprintln!("{removed} of {n0} fluid particles left by 0.6 s");
    assert!(removed as usize > n0 / 20, "{removed} of {n0}");
    assert_eq!(fluid(&s) as u64 + removed, n0 as u64);
    let p = &s.particles;
    for i in 0..p.len() {
        if p.kind[i] == Kind::Fluid {
            let x = p.position[i];
            assert!(x[0] <= 0.3 + 0.0073 && x[1] >= -0.0073, "{x:?}");
        }
    }
    let per_step: f64 = column(&dir.join("steps.csv"), "removed").iter().sum();
    assert_eq!(per_step as u64, removed);
    let m = column(&dir.join("metrics.csv"), "outflow_removed");
    assert_eq!(*m.last().unwrap() as u64, removed);
    assert!(m.windows(2).all(|w| w[1] >= w[0]));
}

/// A checkpoint taken after particles left restores into a fresh build of the case (fewer
/// particles than it builds) and continues bit for bit.
#[test]
fn a_checkpoint_after_outflow_restarts_identically() {
    let mut a = spill("remove", 1.0);
    while a.outflow_removed == 0 {
        a.step(1.0).unwrap();
    }
    a.reset_solver_cache();
    let bytes = mps::io::checkpoint::checkpoint_bytes(&a);
    let mut b = spill("remove", 1.0);
    mps::io::checkpoint::restore(&mut b, &bytes, Path::new("ck")).unwrap();
    assert_eq!(b.outflow_removed, a.outflow_removed);
    for _ in 0..40 {
        a.step(1.0).unwrap();
        b.step(1.0).unwrap();
    }
    assert_eq!(a.particles.position, b.particles.position);
    assert_eq!(a.particles.pressure, b.particles.pressure);
    assert_eq!(a.outflow_removed, b.outflow_removed);
}
