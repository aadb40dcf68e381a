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
