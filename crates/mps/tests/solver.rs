//! Solver-level tests: PPE symmetry and sign, determinism, breakdown records.

mod common;
use common::{example, sim, tmp};
use mps::fields::{Fields, Kernels};
use mps::linsolve::{pcg, Preconditioner};
use mps::neighbors::build_neighbor_list;
use mps::particles::Kind;
use mps::ppe::assemble;
use mps::run::{run, Silent};
use mps::scheme::Scheme;
use mps::vector::Vector;

/// A fluid lattice block in a tank, uniformly compressed toward its centre, gives positive
/// pressure everywhere inside, with the PND and with the HS source.
#[test]
fn uniform_compression_gives_positive_pressure() {
    for scheme in ["MPS", "MPS-HS-GC"] {
        let s = sim("hydrostatic", &[("scheme.name", scheme)]);
        let p = &s.particles;
        let l0 = s.l0();
        let centre = Vector([0.1, 0.15]);
        let eps = 1e-3; // compression rate (1/s) times dt, small
        let dt = 1e-3;
        let pos: Vec<Vector<2>> = (0..p.len())
            .map(|i| {
                if p.kind[i] == Kind::Fluid {
                    centre + (p.position[i] - centre) * (1.0 - eps)
                } else {
                    p.position[i]
                }
            })
            .collect();
        let vel: Vec<Vector<2>> = (0..p.len())
            .map(|i| {
                if p.kind[i] == Kind::Fluid {
                    (p.position[i] - centre) * (-eps / dt)
                } else {
                    Vector::zero()
                }
            })
            .collect();
        let k = Kernels::new::<2>(l0, 2.1, 3.1);
        let nl = build_neighbor_list(&pos, 3.4 * l0);
        let nd: Vec<f64> = (0..pos.len())
            .map(|i| mps::operators::number_density(i, &pos, nl.of(i), k.grad.re))
            .collect();
        let surface: Vec<bool> = (0..pos.len())
            .map(|i| p.kind[i] == Kind::Fluid && nd[i] < 0.97 * k.grad.n0)
            .collect();
        let f = Fields {
            pos: &pos,
            vel: &vel,
            kind: &p.kind,
            density: &p.density,
            free_surface: &surface,
            number_density: &nd,
            neighbors: &nl,
        };
        let sc =
            Scheme::from_spec(&example("hydrostatic", &[("scheme.name", scheme)]).scheme).unwrap();
        let sys = assemble(&f, &k, &sc, Vector([0.0, 0.0]), dt);
        let mut x = vec![0.0; sys.rhs.len()];
        pcg(
            &sys.matrix,
            &sys.rhs,
            &mut x,
            &Preconditioner::Identity,
            1e-10,
            10000,
        )
        .unwrap();
        let inner: Vec<f64> = sys
            .particle_of
            .iter()
            .zip(&x)
            .filter(|(&i, _)| {
                let q = pos[i as usize];
                p.kind[i as usize] == Kind::Fluid && (q - centre).norm() < 0.08
            })
            .map(|(_, &v)| v)
            .collect();
        assert!(!inner.is_empty());
        let min = inner.iter().cloned().fold(f64::MAX, f64::min);
        assert!(
            min > 0.0,
            "{scheme}: interior pressure {min} must be positive"
        );
    }
}

/// The assembled PPE matrix is symmetric, on a disordered mid-run dam-break state with
/// free surface and walls.
#[test]
fn ppe_matrix_is_symmetric_mid_run() {
    let mut s = sim("dam_break", &[("particles.spacing", "0.0073")]);
    for _ in 0..60 {
        s.step(1.0).unwrap();
    }
    let l0 = s.l0();
    let k = Kernels::new::<2>(l0, 2.1, 3.1);
    let p = &s.particles;
    let nl = build_neighbor_list(&p.position, 3.4 * l0);
    let f = Fields {
        neighbors: &nl,
        ..s.fields()
    };
    let sys = assemble(&f, &k, &s.scheme, s.gravity, 1e-4);
    let maxv = sys.matrix.val.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(sys.matrix.n() > 500);
    assert!(
        sys.matrix.asymmetry() <= 1e-13 * maxv,
        "asymmetry {}",
        sys.matrix.asymmetry()
    );
    // Diagonal dominance with positive diagonal (an M-matrix): CG applies.
    for i in 0..sys.matrix.n() {
        let (c, v) = sys.matrix.row(i);
        let mut off = 0.0;
        let mut diag = 0.0;
        for (j, a) in c.iter().zip(v) {
            if *j as usize == i {
                diag = *a;
            } else {
                assert!(*a <= 0.0);
                off += -a;
            }
        }
        assert!(diag > 0.0 && diag >= off * (1.0 - 1e-12));
    }
}

/// The same case with 1 and 2 threads writes byte-identical output files.
#[test]
fn one_and_two_threads_give_identical_output() {
    let set = [
        ("particles.spacing", "0.0073"),
        ("time.max_steps", "40"),
        ("output.interval", "0.005"),
    ];
    let mut dirs = Vec::new();
    for threads in [1, 2] {
        let dir = tmp(&format!("threads{threads}"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut s = sim("dam_break", &set);
            run(&mut s, &dir, &mut Silent).unwrap();
        });
        dirs.push(dir);
    }
    let mut compared = 0;
    for entry in std::fs::read_dir(&dirs[0]).unwrap() {
        let name = entry.unwrap().file_name();
        let n = name.to_string_lossy().to_string();
        if n == "summary.toml" {
            continue; // holds wall-clock timings
        }
        let a = std::fs::read(dirs[0].join(&name)).unwrap();
        let b = std::fs::read(dirs[1].join(&name)).unwrap();
        assert!(a == b, "{n} differs between 1 and 2 threads");
        compared += 1;
    }
    assert!(compared >= 5, "only {compared} files compared");
}

/// A NaN in the state stops the run with a breakdown record and the last good state.
#[test]
fn nan_stops_the_run_with_a_breakdown_record() {
    let mut s = sim(
        "dam_break",
        &[("particles.spacing", "0.0073"), ("time.max_steps", "20")],
    );
    let i = (0..s.particles.len())
        .find(|&i| s.particles.kind[i] == Kind::Fluid)
        .unwrap();
    s.particles.velocity[i] = Vector([f64::NAN, 0.0]);
    let dir = tmp("nan");
    let summary = run(&mut s, &dir, &mut Silent).unwrap();
    let b = summary.breakdown.expect("breakdown reported");
    assert!(b.contains("NaN"), "{b}");
    let record = std::fs::read_to_string(dir.join("breakdown.toml")).unwrap();
    assert!(record.contains("NotFinite"));
    assert!(dir.join("breakdown_last_good_state.vtu").exists());
}

/// The square patch starts from the exact pressure field: at the centre -147.34 Pa within
/// 0.5 % (cases.md), sampled from the particles.
#[test]
fn square_patch_initial_centre_pressure() {
    let s = sim("square_patch", &[]);
    assert_eq!(s.particles.count(Kind::Fluid), 2500);
    let p = s.sample_pressure(&Vector([0.0, 0.0])).unwrap();
    assert!(((p + 147.34) / 147.34).abs() < 0.005, "centre pressure {p}");
    // Clockwise rotation: angular momentum -rho omega L^4 / 6 per unit depth (lattice sum).
    let m = mps::diagnostics::Metrics::measure(&s);
    assert!(
        ((m.angular_momentum + 166.67) / 166.67).abs() < 0.01,
        "{}",
        m.angular_momentum
    );
    assert!(
        ((m.kinetic_energy - 83.33) / 83.33).abs() < 0.01,
        "{}",
        m.kinetic_energy
    );
}

/// Dynamic Stabilization with no active pair gives results bit-identical to MPS-HS-GC
/// (the rotating lattice keeps every pair above 0.9 l0 for its first steps).
#[test]
fn ds_without_active_pairs_is_bit_identical_to_gc() {
    let mut gc = sim("square_patch", &[("scheme.name", "MPS-HS-GC")]);
    let mut ds = sim("square_patch", &[("scheme.name", "MPS-HS-GC-DS")]);
    for _ in 0..10 {
        gc.step(10.0).unwrap();
        let r = ds.step(10.0).unwrap();
        assert_eq!(r.ds_active, 0);
    }
    assert_eq!(gc.particles.position, ds.particles.position);
    assert_eq!(gc.particles.velocity, ds.particles.velocity);
    assert_eq!(gc.particles.pressure, ds.particles.pressure);
    // And DS does act once pairs close in: with a threshold of 0.99 l0 pairs become active
    // within a few steps and the state departs from MPS-HS-GC.
    let mut strong = sim(
        "square_patch",
        &[("scheme.name", "MPS-HS-GC-DS"), ("scheme.ds.alpha", "0.99")],
    );
    let mut gc2 = sim("square_patch", &[("scheme.name", "MPS-HS-GC")]);
    let mut active = 0;
    for _ in 0..200 {
        active += strong.step(10.0).unwrap().ds_active;
        gc2.step(10.0).unwrap();
        if active > 0 {
            break;
        }
    }
    assert!(active > 0);
    assert_ne!(strong.particles.position, gc2.particles.position);
}

/// A run stopped after 20 steps, checkpointed and restored into a fresh simulation continues
/// bit for bit like the uninterrupted run (40 steps, one reordering in between).
#[test]
fn restart_from_checkpoint_is_bit_identical() {
    let set = [("particles.spacing", "0.0073")];
    let mut straight = sim("dam_break", &set);
    for _ in 0..40 {
        straight.step(1.0).unwrap();
    }
    let mut first = sim("dam_break", &set);
    for _ in 0..20 {
        first.step(1.0).unwrap();
    }
    let bytes = mps::checkpoint::checkpoint_bytes(&first);
    let mut resumed = sim("dam_break", &set);
    mps::checkpoint::restore(&mut resumed, &bytes).unwrap();
    assert_eq!(resumed.step_count, 20);
    for _ in 0..20 {
        resumed.step(1.0).unwrap();
    }
    assert_eq!(resumed.time, straight.time);
    assert_eq!(resumed.particles.position, straight.particles.position);
    assert_eq!(resumed.particles.velocity, straight.particles.velocity);
    assert_eq!(resumed.particles.pressure, straight.particles.pressure);
    // A checkpoint of another case is refused with a reason.
    let mut other = sim("hydrostatic", &[]);
    let e = mps::checkpoint::restore(&mut other, &bytes).unwrap_err();
    assert!(e.contains("particles"), "{e}");
    assert!(mps::checkpoint::restore(&mut other, b"garbage").is_err());
}
