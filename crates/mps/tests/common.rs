//! Helpers shared by the integration tests.
#![allow(dead_code)]

use mps::{Case, Simulation};
use std::path::PathBuf;

/// A case from a built-in example with overrides.
pub fn example(name: &str, set: &[(&str, &str)]) -> Case {
    let text = mps::examples::example(name).expect("example exists");
    let o: Vec<(String, String)> = set
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    Case::from_str_named(text, name, &o).expect("valid case")
}

/// A fresh temporary folder for a test.
pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mps_test_{}_{}", name, std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A built simulation of an example.
pub fn sim(name: &str, set: &[(&str, &str)]) -> Simulation<2> {
    Simulation::<2>::new(example(name, set), name).expect("builds")
}

/// Column `name` of a CSV file written by a run (read through the library's reader).
pub fn column(path: &std::path::Path, name: &str) -> Vec<f64> {
    let t = mps::io::series::read_table(path).expect("readable CSV");
    let k = t
        .header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("{}: no column {name}", path.display()));
    t.columns[k].clone()
}

/// A built 3D simulation of an example.
pub fn sim3(name: &str, set: &[(&str, &str)]) -> Simulation<3> {
    Simulation::<3>::new(example(name, set), name).expect("builds")
}

/// faer's sparse Cholesky solution of a PPE system (the reference the iterative solvers are
/// checked against).
pub fn direct_solve(sys: &mps::numerics::ppe::PressureSystem) -> Vec<f64> {
    use faer::linalg::solvers::Solve;
    use faer::sparse::{SparseColMat, Triplet};
    let a = &sys.matrix;
    let n = a.n();
    let mut trip = Vec::with_capacity(a.nnz());
    for i in 0..n {
        let (c, v) = a.row(i);
        for (&j, &x) in c.iter().zip(v) {
            trip.push(Triplet::new(i, j as usize, x));
        }
    }
    let m = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip).unwrap();
    let llt = m.sp_cholesky(faer::Side::Lower).expect("the PPE is SPD");
    let x = llt.solve(faer::Mat::from_fn(n, 1, |i, _| sys.rhs[i]));
    (0..n).map(|i| x[(i, 0)]).collect()
}

/// `|x - exact| / |exact|` in the 2-norm.
pub fn relative_error(x: &[f64], exact: &[f64]) -> f64 {
    let d = x
        .iter()
        .zip(exact)
        .map(|(p, q)| (p - q) * (p - q))
        .sum::<f64>();
    let n = exact.iter().map(|v| v * v).sum::<f64>();
    (d / n).sqrt()
}
