//! The architecture, checked from the source: the folders of `crates/mps/src` depend on each
//! other only as the crate documentation says (one way, no cycle), sibling modules inside a
//! folder form no cycle, `linalg/sparse.rs` is a leaf (but for the parallel loops), and no
//! library function is longer than 100 lines (`Simulation::advance` at most 60).
//!
//! A child module extending its parent's type (`impl Simulation` in `simulation/stages.rs`)
//! uses the parent; such child -> parent edges are part of one module split over files and
//! are not counted as cycles.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Folder -> the folders (and top-level files) it may use.
const ALLOWED: &[(&str, &[&str])] = &[
    ("error", &[]),
    ("parallel", &[]),
    ("particles", &["parallel"]),
    ("linalg", &["parallel"]),
    ("numerics", &["particles", "linalg", "parallel"]),
    (
        "input",
        &["particles", "numerics", "linalg", "error", "parallel"],
    ),
    (
        "simulation",
        &[
            "particles",
            "numerics",
            "linalg",
            "input",
            "error",
            "parallel",
        ],
    ),
    (
        "analysis",
        &[
            "particles",
            "numerics",
            "input",
            "simulation",
            "error",
            "parallel",
        ],
    ),
    (
        "io",
        &["particles", "simulation", "input", "error", "parallel"],
    ),
    (
        "run",
        &[
            "particles",
            "numerics",
            "input",
            "simulation",
            "analysis",
            "io",
            "error",
            "parallel",
        ],
    ),
    (
        "distributed",
        &[
            "particles",
            "numerics",
            "linalg",
            "input",
            "simulation",
            "analysis",
            "run",
            "error",
            "parallel",
        ],
    ),
];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file below `dir`.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(files(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// The file's text without its test module.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]\nmod tests") {
        Some(k) => text[..k].to_string(),
        None => match text.find("#[cfg(test)]\npub(crate) mod tests") {
            Some(k) => text[..k].to_string(),
            None => text,
        },
    }
}

/// The names that follow `prefix` in `text` (identifier characters).
fn names_after<'a>(text: &'a str, prefix: &str) -> Vec<&'a str> {
    text.match_indices(prefix)
        .map(|(k, _)| {
            let rest = &text[k + prefix.len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            &rest[..end]
        })
        .filter(|n| !n.is_empty())
        .collect()
}

/// The top-level folder (or file) of a path below `src`.
fn folder_of(path: &Path) -> String {
    let rel = path.strip_prefix(src()).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

#[test]
fn folders_depend_on_each_other_one_way() {
    let allowed: BTreeMap<&str, &[&str]> = ALLOWED.iter().copied().collect();
    let mut bad = Vec::new();
    for f in files(&src()) {
        let from = folder_of(&f);
        if from == "lib" {
            continue;
        }
        let Some(ok) = allowed.get(from.as_str()) else {
            panic!("{from} has no entry in ALLOWED");
        };
        for to in names_after(&code(&f), "crate::") {
            if to != from && !ok.contains(&to) {
                bad.push(format!("{} uses crate::{to}", f.display()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "dependencies against the architecture:\n{}",
        bad.join("\n")
    );
    // And the allowed graph itself has no cycle.
    let edges: Vec<(String, String)> = ALLOWED
        .iter()
        .flat_map(|(a, bs)| bs.iter().map(move |b| (a.to_string(), b.to_string())))
        .collect();
    assert_eq!(find_cycle(&edges), None);
}

/// A cycle in a directed graph, if any.
fn find_cycle(edges: &[(String, String)]) -> Option<Vec<String>> {
    let mut adj: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (a, b) in edges {
        adj.entry(a).or_default().push(b);
    }
    fn visit<'a>(
        n: &'a str,
        adj: &BTreeMap<&'a str, Vec<&'a str>>,
        state: &mut BTreeMap<&'a str, u8>,
        path: &mut Vec<&'a str>,
    ) -> Option<Vec<String>> {
        match state.get(n) {
            Some(1) => {
                let k = path.iter().position(|x| *x == n).unwrap();
                return Some(path[k..].iter().map(|s| s.to_string()).collect());
            }
            Some(_) => return None,
            None => {}
        }
        state.insert(n, 1);
        path.push(n);
        for m in adj.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, adj, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(n, 2);
        None
    }
    let mut state = BTreeMap::new();
    let nodes: BTreeSet<&str> = adj.keys().copied().collect();
    for n in nodes {
        if let Some(c) = visit(n, &adj, &mut state, &mut Vec::new()) {
            return Some(c);
        }
    }
    None
}

#[test]
fn sibling_modules_form_no_cycle() {
    // Edges between files of one folder: `super::x` and `crate::<folder>::x` naming a
    // sibling file `x.rs` or folder `x/`.
    let mut edges = Vec::new();
    for f in files(&src()) {
        let dir = f.parent().unwrap();
        let stem = f.file_stem().unwrap().to_string_lossy().to_string();
        if stem == "mod" || stem == "lib" {
            continue;
        }
        let text = code(&f);
        let folder = dir.file_name().unwrap().to_string_lossy().to_string();
        let mut targets = names_after(&text, "super::");
        targets.extend(names_after(&text, &format!("crate::{folder}::")));
        for t in targets {
            let sibling = dir.join(format!("{t}.rs")).exists() || dir.join(t).is_dir();
            if sibling && t != stem {
                let node = |n: &str| format!("{}/{n}", dir.display());
                edges.push((node(&stem), node(t)));
            }
        }
    }
    assert_eq!(find_cycle(&edges), None, "module cycle");
}

#[test]
fn the_sparse_module_is_a_leaf() {
    let text = code(&src().join("linalg/sparse.rs")).replace("crate::parallel::", "");
    assert!(!text.contains("super::") && !text.contains("crate::"));
}

/// Lengths of the functions of a file: (name, first line, lines).
fn functions(text: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        let indent = l.len() - t.len();
        let decl = ["fn ", "pub fn ", "pub(crate) fn ", "pub(super) fn "]
            .iter()
            .find(|p| t.starts_with(*p));
        let Some(p) = decl else { continue };
        let name: String = t[p.len()..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let close = format!("{}}}", " ".repeat(indent));
        if let Some(k) = lines[i + 1..].iter().position(|x| x.starts_with(&close)) {
            out.push((name, i + 1, k + 2));
        }
    }
    out
}

#[test]
fn functions_are_short_and_the_step_reads_as_a_list() {
    let mut long = Vec::new();
    for f in files(&src()) {
        for (name, line, n) in functions(&code(&f)) {
            if n > 100 {
                long.push(format!("{}:{line} {name}: {n} lines", f.display()));
            }
            if name == "advance" {
                assert!(n <= 60, "Simulation::advance has {n} lines");
            }
        }
    }
    assert!(
        long.is_empty(),
        "functions over 100 lines:\n{}",
        long.join("\n")
    );
}
