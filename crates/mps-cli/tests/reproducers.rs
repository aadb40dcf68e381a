//! The reliability reproducers of `../shared/reliability/repro/` (case files, checkpoints and
//! a run folder with a truncated VTU, found by fuzzing): every one must end with exit 0, 1
//! or 2 within 10 s, with at most a one-line message, never a panic, abort or hang.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The reproducer folders: the project's own copy (`tests/reproducers`, always there) and
/// `../shared/reliability/repro` where the checkout has it (new reproducers land there first).
fn repro_dirs() -> Vec<PathBuf> {
    let own = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reproducers");
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reliability/repro");
    std::iter::once(own)
        .chain(shared.is_dir().then_some(shared))
        .collect()
}

/// Copies `src` into `dst` (files and folders), writable.
fn copy_tree(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap().flatten() {
        let to = dst.join(e.file_name());
        if e.path().is_dir() {
            copy_tree(&e.path(), &to);
        } else {
            std::fs::copy(e.path(), &to).unwrap();
            let mut perm = std::fs::metadata(&to).unwrap().permissions();
            #[allow(clippy::permissions_set_readonly_false)]
            perm.set_readonly(false);
            std::fs::set_permissions(&to, perm).unwrap();
        }
    }
}

/// Runs `mps args` in `dir`, killing it after `limit`: (exit code, stderr).
fn run(dir: &Path, args: &[&str], limit: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_mps"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return (status.code(), err);
        }
        if start.elapsed() > limit {
            child.kill().unwrap();
            let _ = child.wait();
            return (None, format!("still running after {limit:?}"));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn every_reproducer_ends_cleanly_within_ten_seconds() {
    let mut bad = Vec::new();
    for (k, src) in repro_dirs().iter().enumerate() {
        bad.extend(run_folder(src, k));
    }
    assert!(
        bad.is_empty(),
        "reproducers that did not end cleanly:\n{}",
        bad.join("\n")
    );
}

/// Runs every reproducer of `src` (copied to a temporary folder): the failures.
fn run_folder(src: &Path, k: usize) -> Vec<String> {
    let dir = std::env::temp_dir().join(format!("mps_repro_{}_{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    copy_tree(src, &dir);
    let mut commands: Vec<Vec<String>> = Vec::new();
    let mut cases: Vec<PathBuf> = Vec::new();
    for sub in [dir.clone(), dir.join("oom-all")] {
        for e in std::fs::read_dir(&sub).into_iter().flatten().flatten() {
            if e.path().extension().is_some_and(|x| x == "toml") {
                cases.push(e.path());
            }
        }
    }
    cases.sort();
    assert!(cases.len() >= 30, "{} reproducer cases", cases.len());
    for c in &cases {
        let c = c.to_string_lossy().to_string();
        commands.push(
            ["run", &c, "--quiet", "--threads", "1", "--out", "out"]
                .map(String::from)
                .to_vec(),
        );
    }
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if name.starts_with("ckpt_") {
            commands.push(
                [
                    "run",
                    "--example",
                    "dam_break",
                    "--quiet",
                    "--threads",
                    "1",
                    "--set",
                    "time.end=0.11",
                    "--restart",
                    &name,
                    "--out",
                    "out",
                ]
                .map(String::from)
                .to_vec(),
            );
        }
    }
    for verb in ["render", "report", "plot"] {
        commands.push(vec![verb.into(), "run_trunc_vtu".into()]);
    }
    let mut bad = Vec::new();
    for args in &commands {
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, err) = run(&dir, &refs, Duration::from_secs(10));
        let lines = err.trim().lines().count();
        if !matches!(code, Some(0..=2)) || lines > 1 {
            bad.push(format!(
                "mps {}: exit {code:?}, {lines} lines: {}",
                args.join(" "),
                err.trim()
            ));
        }
        let _ = std::fs::remove_dir_all(dir.join("out"));
    }
    std::fs::remove_dir_all(&dir).unwrap();
    bad
}
