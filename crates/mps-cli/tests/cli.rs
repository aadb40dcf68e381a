//! End-to-end tests of the `mps` program.

use std::process::Command;

fn mps() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mps"))
}

fn write_case(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("mps_cli_{}_{}", name, std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn base_case() -> String {
    mps::examples::example("hydrostatic").unwrap().to_string()
}

/// A malformed case file gives a one-line error naming the file, the field and the value,
/// and exits non-zero.
#[test]
fn malformed_case_gives_one_line_error_naming_the_field() {
    let cases = [
        (
            "unknown",
            base_case().replace("spacing = 0.005", "spacing = 0.005\nspaceing = 2"),
            "spaceing",
        ),
        (
            "negative",
            base_case().replace("spacing = 0.005", "spacing = -0.005"),
            "particles.spacing = -0.005",
        ),
        (
            "phase",
            base_case().replace("phase = \"water\"", "phase = \"oil\""),
            "fluid.0.phase = \"oil\"",
        ),
        (
            "outside",
            base_case().replace("max = [0.2, 0.3] }", "max = [0.5, 0.3] }"),
            "fluid.0.shape",
        ),
    ];
    for (name, text, needle) in cases {
        let p = write_case(name, &text);
        let out = mps().args(["run", "-q"]).arg(&p).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{name}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{name}: {err}");
        assert!(
            err.contains(needle) && err.contains(&p.display().to_string()),
            "{name}: {err}"
        );
    }
}

#[test]
fn missing_file_is_a_clear_error() {
    let out = mps().args(["run", "no/such/case.toml"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no/such/case.toml") && err.contains("cannot read"),
        "{err}"
    );
}

#[test]
fn list_names_the_examples_and_a_short_run_writes_paraview_files() {
    let out = mps().arg("list").output().unwrap();
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(s.contains("dam_break") && s.contains("hydrostatic"));
    let dir = std::env::temp_dir().join(format!("mps_cli_run_{}", std::process::id()));
    let out = mps()
        .args([
            "run",
            "--example",
            "dam_break",
            "-q",
            "--set",
            "time.max_steps=5",
            "--set",
            "particles.spacing=0.0073",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "particles.pvd",
        "particles_000000.vtu",
        "metrics.csv",
        "steps.csv",
        "summary.toml",
        "probes.csv",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
}

/// `mps compare` runs each scheme into its own folder and writes the comparison table with
/// one row per scheme, naming a breakdown where one happens.
#[test]
fn compare_writes_one_row_per_scheme() {
    let dir = std::env::temp_dir().join(format!("mps_cli_cmp_{}", std::process::id()));
    let out = mps()
        .args([
            "compare",
            "--example",
            "square_patch",
            "--schemes",
            "MPS-HS-GC,MPS-HS-GC-DS",
            "--set",
            "time.max_steps=5",
            "--set",
            "output.vtu=false",
            "--set",
            "breakdown.min_pair_distance=0.9999",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(dir.join("compare.md")).unwrap();
    assert_eq!(
        md.lines().filter(|l| l.starts_with("| MPS-HS-GC")).count(),
        2,
        "{md}"
    );
    // The rotating lattice closes pairs below 0.9999 l0 at once: both runs break down, and the table says so.
    assert_eq!(md.matches("interpenetrated").count(), 2, "{md}");
    for s in ["MPS-HS-GC", "MPS-HS-GC-DS"] {
        assert!(dir.join(s).join("summary.toml").exists());
    }
    let csv = std::fs::read_to_string(dir.join("compare_metrics.csv")).unwrap();
    assert!(csv.starts_with("scheme,time,"));
    let bad = mps()
        .args([
            "compare",
            "--example",
            "square_patch",
            "--schemes",
            "MPS,SPH",
        ])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("scheme.name = \"SPH\""));
}

/// A run writes `checkpoint.bin`; `--restart` extends it to a later end time; a file that is
/// no checkpoint is a clear error.
#[test]
fn restart_extends_a_run() {
    let dir = std::env::temp_dir().join(format!("mps_cli_restart_{}", std::process::id()));
    let base = [
        "--example",
        "dam_break",
        "-q",
        "--set",
        "particles.spacing=0.0073",
        "--set",
        "output.vtu=false",
        "--set",
        "output.interval=0.01",
    ];
    let out = mps()
        .arg("run")
        .args(base)
        .args(["--set", "time.end=0.02", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ck = dir.join("checkpoint.bin");
    assert!(ck.exists());
    let more = dir.join("more");
    let out = mps()
        .arg("run")
        .args(base)
        .args(["--set", "time.end=0.04", "--restart"])
        .arg(&ck)
        .arg("--out")
        .arg(&more)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = std::fs::read_to_string(more.join("summary.toml")).unwrap();
    assert!(summary.contains("time = 0.04"), "{summary}");
    let metrics = std::fs::read_to_string(more.join("metrics.csv")).unwrap();
    assert!(
        metrics.lines().nth(1).unwrap().starts_with("0.02"),
        "{metrics}"
    );
    let junk = dir.join("junk.bin");
    std::fs::write(&junk, b"not a checkpoint").unwrap();
    let out = mps()
        .arg("run")
        .args(base)
        .arg("--restart")
        .arg(&junk)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not an MPS checkpoint"));
}
