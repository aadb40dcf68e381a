//! End-to-end tests of the `mps` program.

use std::process::Command;

fn mps() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mps"))
}

/// Runs `c` and fails the test with its error output unless it succeeds.
fn succeed(c: &mut Command) -> std::process::Output {
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
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
    // A bad argument: one line naming it, exit 1, before any work.
    for args in [
        &["run", "--example", "dam_break", "--threads", "0"][..],
        &["run", "--bogus"][..],
        &["bench", "--ladder", "0"][..],
        &["bench", "--baseline", "no/such/baseline.csv"][..],
    ] {
        let out = mps().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.contains(args[args.len() - 2]) || err.contains(args[1]),
            "{err}"
        );
    }
    // A missing argument is named on the same line.
    let out = mps()
        .args(["bench", "--markdown", "x.md"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("--ladder"), "{err}");
}

#[test]
fn list_names_the_examples_and_a_short_run_writes_paraview_files() {
    let out = mps().arg("list").output().unwrap();
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(s.contains("dam_break") && s.contains("hydrostatic"));
    let dir = std::env::temp_dir().join(format!("mps_cli_run_{}", std::process::id()));
    succeed(
        mps()
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
            .arg(&dir),
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
    succeed(
        mps()
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
            .arg(&dir),
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
    succeed(
        mps()
            .arg("run")
            .args(base)
            .args(["--set", "time.end=0.02", "--out"])
            .arg(&dir),
    );
    let ck = dir.join("checkpoint.bin");
    assert!(ck.exists());
    let more = dir.join("more");
    succeed(
        mps()
            .arg("run")
            .args(base)
            .args(["--set", "time.end=0.04", "--restart"])
            .arg(&ck)
            .arg("--out")
            .arg(&more),
    );
    let summary = std::fs::read_to_string(more.join("summary.toml")).unwrap();
    assert!(summary.contains("time = 0.04"), "{summary}");
    // The earlier run's rows are carried over: the series starts at 0 and reaches 0.04.
    let metrics = std::fs::read_to_string(more.join("metrics.csv")).unwrap();
    let time = |line: &str| -> f64 { line.split(',').next().unwrap().parse().unwrap() };
    assert_eq!(
        metrics.lines().filter(|l| l.starts_with("time")).count(),
        1,
        "{metrics}"
    );
    assert_eq!(time(metrics.lines().nth(1).unwrap()), 0.0, "{metrics}");
    assert_eq!(time(metrics.lines().last().unwrap()), 0.04, "{metrics}");
    assert_eq!(metrics.lines().count(), 1 + 5, "{metrics}");
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

/// A short run, then `mps render`, `mps plot` and `mps report`: PNG snapshots and charts are
/// written, and the report is one self-contained HTML page with its tables and images. A
/// headless Chromium (Debian's, installed by .ci/run) loads it, and its screenshot is not
/// blank.
#[test]
fn render_plot_and_report_a_run() {
    let dir = std::env::temp_dir().join(format!("mps_cli_report_{}", std::process::id()));
    succeed(
        mps()
            .args([
                "run",
                "--example",
                "hydrostatic",
                "-q",
                "--set",
                "time.end=0.05",
                "--set",
                "output.interval=0.01",
                "--out",
            ])
            .arg(&dir),
    );
    let out = succeed(
        mps()
            .arg("render")
            .arg(&dir)
            .args(["--time", "0.02", "--vectors"]),
    );
    let png = String::from_utf8_lossy(&out.stdout).trim().to_string();
    assert!(png.ends_with(".png") && std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let out = mps().arg("plot").arg(&dir).output().unwrap();
    assert!(out.status.success());
    let svg = std::fs::read_to_string(dir.join("figures/metric_kinetic_energy.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("kinetic_energy"));
    assert!(dir.join("figures/probe_bottom.svg").exists());
    succeed(mps().arg("report").arg(&dir));
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    assert!(html.matches("<svg").count() >= 10, "charts inlined");
    assert!(html.matches("<img ").count() >= 2, "snapshots embedded");
    assert!(html.contains("src=\"data:image/png;base64,"));
    assert!(html.contains("<th>check</th>") && html.contains("hydrostatic_bottom_pressure"));
    assert!(
        !html.contains("src=\"http") && !html.contains("src=\"/"),
        "no external resources"
    );

    let chromium = ["chromium", "chromium-browser"].into_iter().find(|c| {
        Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    });
    let Some(chromium) = chromium else {
        assert!(
            std::env::var("CI").is_err(),
            "CI must have chromium (installed by .ci/run)"
        );
        eprintln!("chromium not found: headless check skipped outside CI");
        return;
    };
    let shot = dir.join("shot.png");
    let profile = dir.join("chromium-profile");
    let status = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=1000,1400",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", dir.join("report.html").display()))
        .output()
        .unwrap();
    assert!(
        shot.exists(),
        "no screenshot: {}",
        String::from_utf8_lossy(&status.stderr)
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().expect("image size")];
    let info = reader.next_frame(&mut buf).unwrap();
    let px = &buf[..info.buffer_size()];
    let non_white = px
        .chunks(info.color_type.samples())
        .filter(|c| c[..3].iter().any(|&v| v < 200))
        .count();
    assert!(
        non_white > 10_000,
        "screenshot looks blank ({non_white} dark pixels)"
    );
}

/// A run into a folder that holds files is refused (exit 1, one line) unless --force, which
/// clears the earlier run's files (no stale snapshot stays) and keeps the user's own.
#[test]
fn a_second_run_into_a_folder_needs_force_and_leaves_nothing_stale() {
    let dir = std::env::temp_dir().join(format!("mps_cli_force_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let run = |interval: &str, force: bool| {
        let mut c = mps();
        c.args([
            "run",
            "--example",
            "dam_break",
            "-q",
            "--set",
            "time.max_steps=6",
        ])
        .args(["--set", "particles.spacing=0.0073", "--set"])
        .arg(format!("output.interval={interval}"))
        .arg("--out")
        .arg(&dir);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    assert!(run("0.001", false).status.success());
    let snapshots = |d: &std::path::Path| {
        std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".vtu"))
            .count()
    };
    let many = snapshots(&dir);
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    let again = run("0", false);
    assert_eq!(again.status.code(), Some(1));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("--force") && err.trim().lines().count() == 1,
        "{err}"
    );
    assert!(run("0", true).status.success());
    assert!(snapshots(&dir) < many, "stale snapshots stayed");
    assert!(
        dir.join("notes.txt").exists(),
        "the user's file was removed"
    );
}

/// A run killed (SIGKILL) three times, each time restarted in place from its last checkpoint,
/// ends with every file identical to an uninterrupted run: snapshots, index, checkpoint and
/// every series byte for byte, the summary but for its timings.
#[test]
fn a_killed_and_restarted_run_ends_identical_to_an_uninterrupted_one() {
    let base = std::env::temp_dir().join(format!("mps_cli_kill_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let (straight, killed) = (base.join("straight"), base.join("killed"));
    let args = [
        "run",
        "--example",
        "dam_break",
        "-q",
        "--threads",
        "1",
        "--set",
        "particles.spacing=0.0073",
        "--set",
        "time.end=0.12",
        "--set",
        "output.interval=0.01",
    ];
    succeed(mps().args(args).arg("--out").arg(&straight));
    let outputs = |d: &std::path::Path| {
        std::fs::read_to_string(d.join("metrics.csv"))
            .map_or(0, |t| t.lines().count().saturating_sub(1))
    };
    // Kill after 3, 6 and 9 outputs, restarting in place after each kill.
    let mut first = true;
    for at in [3, 6, 9] {
        let mut c = mps();
        c.args(args);
        if first {
            c.arg("--out").arg(&killed);
        } else {
            c.arg("--restart").arg(killed.join("checkpoint.bin"));
        }
        first = false;
        let mut child = c.spawn().unwrap();
        let start = std::time::Instant::now();
        while outputs(&killed) < at && start.elapsed() < std::time::Duration::from_secs(60) {
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    succeed(
        mps()
            .args(args)
            .arg("--restart")
            .arg(killed.join("checkpoint.bin")),
    );
    let names = |d: &std::path::Path| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().to_string())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(&straight), names(&killed));
    for name in names(&straight) {
        let (a, b) = (straight.join(&name), killed.join(&name));
        if name == "summary.toml" {
            let strip = |p: &std::path::Path| -> Vec<String> {
                std::fs::read_to_string(p)
                    .unwrap()
                    .lines()
                    .filter(|l| {
                        !["wall_seconds", "particle_steps_per_second", "threads"]
                            .iter()
                            .any(|k| l.starts_with(k))
                            && !l.starts_with("stages")
                            && !l.starts_with("    [\"")
                            && !l.starts_with("    \"")
                            && !l.contains("\", ")
                    })
                    .map(String::from)
                    .collect()
            };
            assert_eq!(strip(&a), strip(&b), "summary.toml");
        } else if name != "case.toml" {
            assert!(
                std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
                "{name} differs"
            );
        }
    }
    std::fs::remove_dir_all(&base).unwrap();
}

/// Mounts a tmpfs of `size` at `dir` (`ro` for read-only); false where the machine does not
/// allow it (no privilege): the test then says so and skips.
fn mount_tmpfs(dir: &std::path::Path, size: &str, ro: bool) -> bool {
    std::fs::create_dir_all(dir).unwrap();
    let opts = format!("size={size}{}", if ro { ",ro" } else { "" });
    Command::new("mount")
        .args(["-t", "tmpfs", "-o", &opts, "tmpfs"])
        .arg(dir)
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn a_full_disk_or_a_read_only_folder_exits_3_naming_the_path_and_leaves_no_temporary_file() {
    let base = std::env::temp_dir().join(format!("mps_cli_full_{}", std::process::id()));
    let (full, ro) = (base.join("full"), base.join("ro"));
    if !mount_tmpfs(&full, "1m", false) {
        eprintln!("cannot mount a tmpfs here: skipped");
        return;
    }
    let mounted_ro = mount_tmpfs(&ro, "1m", true);
    let args = ["run", "--example", "dam_break", "-q", "--threads", "1"];
    let out = mps()
        .args(args)
        .arg("--out")
        .arg(full.join("run"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    let listing: Vec<String> = std::fs::read_dir(full.join("run"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .collect();
    let ro_result = mounted_ro.then(|| {
        mps()
            .args(args)
            .arg("--out")
            .arg(ro.join("run"))
            .output()
            .unwrap()
    });
    for d in [&full, &ro] {
        let _ = Command::new("umount").arg(d).output();
    }
    let _ = std::fs::remove_dir_all(&base);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains(&full.join("run").to_string_lossy().to_string()),
        "{err}"
    );
    assert!(err.contains("No space left"), "{err}");
    assert!(!listing.iter().any(|n| n.contains(".tmp")), "{listing:?}");
    // The last complete checkpoint is there to restart from.
    assert!(listing.iter().any(|n| n == "checkpoint.bin"), "{listing:?}");
    if let Some(out) = ro_result {
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(
            err.contains(&ro.join("run").to_string_lossy().to_string()),
            "{err}"
        );
    }
}

/// A run validated against a reference CSV: the comparison is in the summary and
/// `mps plot` draws the probe against the curve.
#[test]
fn a_reference_curve_is_compared_and_plotted() {
    let text = mps::examples::example("hydrostatic").unwrap();
    let cut = text.find("[validation]").unwrap();
    let case = format!(
        "{}[validation]\nkind = \"probe_reference\"\nprobe = \"bottom\"\n\
         reference = {{ file = \"gauge.csv\", columns = [\"t\", \"p\"] }}\n\
         rms_tolerance = 300.0\npeak_tolerance = 600.0\n",
        &text[..cut]
    );
    let path = write_case("reference_plot", &case);
    let dir = path.parent().unwrap().to_path_buf();
    let _ = std::fs::remove_dir_all(dir.join("run"));
    std::fs::write(
        dir.join("gauge.csv"),
        "t,p\n0.01,2943\n0.02,2943\n0.03,2943\n",
    )
    .unwrap();
    let run = dir.join("run");
    succeed(
        mps()
            .arg("run")
            .arg(&path)
            .args([
                "-q",
                "--set",
                "time.end=0.04",
                "--set",
                "output.vtu=false",
                "--out",
            ])
            .arg(&run),
    );
    let summary = std::fs::read_to_string(run.join("summary.toml")).unwrap();
    assert!(summary.contains("probe_bottom_rms_difference"), "{summary}");
    succeed(mps().arg("plot").arg(&run));
    let svg = std::fs::read_to_string(run.join("figures/validation_reference.svg")).unwrap();
    assert!(svg.contains("reference (the case") && svg.contains("probe bottom"));
}

/// A 3D case with a wrong STL wall exits 1 with one line naming the case, the field, the
/// STL file and what is wrong: a missing file, an open surface, text that is no STL.
#[test]
fn a_wrong_stl_wall_exits_1_naming_the_file_and_the_fault() {
    let case = include_str!("../../mps/cases/dam_break_obstacle_3d.toml");
    let stl = include_str!("../../mps/cases/obstacle.stl");
    // The block without its last facet: an open surface.
    let cut = stl.rfind("  facet").unwrap();
    let open = format!("{}endsolid obstacle\n", &stl[..cut]);
    let p = write_case("stl_wrong", case);
    let dir = p.parent().unwrap().to_path_buf();
    for (file, content, needle) in [
        ("missing.stl", None, "cannot read"),
        ("open.stl", Some(open.as_str()), "not a closed surface"),
        (
            "junk.stl",
            Some("solid x\nfacet nonsense\n"),
            "not an STL file",
        ),
    ] {
        if let Some(c) = content {
            std::fs::write(dir.join(file), c).unwrap();
        }
        let out = mps()
            .args(["run", "-q", "--set"])
            .arg(format!("walls.1.shape.file={file}"))
            .arg(&p)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{file}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{file}: {err}");
        assert!(
            err.contains(file) && err.contains("walls.1.shape.file") && err.contains(needle),
            "{file}: {err}"
        );
    }
}

/// A 3D run renders as a slice and as a view, compares and reports like a 2D one; a slice
/// on no axis is refused naming it.
#[test]
fn a_3d_run_renders_compares_and_reports() {
    let dir = std::env::temp_dir().join(format!("mps_cli_3d_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let set = ["--set", "time.end=0.04", "--set", "output.interval=0.02"];
    succeed(
        mps()
            .args([
                "compare",
                "--example",
                "hydrostatic_3d",
                "--schemes",
                "MPS-HS-GC-DS",
            ])
            .args(set)
            .arg("--out")
            .arg(&dir),
    );
    assert!(dir.join("compare.png").is_file());
    let run = dir.join("MPS-HS-GC-DS");
    let out = succeed(
        mps()
            .args(["render", "--time", "0.04", "--slice", "x=0.045"])
            .arg(&run),
    );
    let png = String::from_utf8_lossy(&out.stdout).trim().to_string();
    assert!(
        png.ends_with(".png") && png.contains("slicex0.045"),
        "{png}"
    );
    let out = succeed(
        mps()
            .args(["render", "--time", "0.04", "--view", "z"])
            .arg(&run),
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("viewz"));
    succeed(mps().arg("report").arg(&dir));
    assert!(dir.join("report.html").is_file());
    let bad = mps()
        .args(["render", "--slice", "q=1"])
        .arg(&run)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("q=1"));
}

/// `mps bench --baseline` prints each figure of a row against the stored row of the same
/// thread and particle count as new / old; the stored table splits the rest of the step by
/// stage.
#[test]
fn bench_against_a_baseline_prints_ratios() {
    let dir = std::env::temp_dir().join(format!("mps_cli_bench_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("base.csv");
    let small = [
        "bench",
        "--steps",
        "3",
        "--threads",
        "1",
        "--set",
        "particles.spacing=0.02",
    ];
    succeed(mps().args(small).arg("--csv").arg(&csv));
    // The rest of the step split by stage: the four stages' times lie within it.
    let table = std::fs::read_to_string(&csv).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|c| c.parse().unwrap())
        .collect();
    let at = |name: &str| row[header.iter().position(|h| *h == name).unwrap()];
    let stages = [
        "explicit_ms",
        "density_surface_ms",
        "gradient_ms",
        "correction_ms",
    ];
    let sum: f64 = stages.iter().map(|s| at(s)).sum();
    assert!(stages.iter().all(|s| at(s) > 0.0), "{table}");
    assert!(sum <= 1.05 * at("rest_ms"), "{table}");
    let out = mps()
        .args(small)
        .arg("--baseline")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(out.status.success());
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        s.contains("(new / old)")
            && s.contains("ppe_iterations 1.00x")
            && s.contains("ms_per_step"),
        "{s}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `mps run` built without the `mpi` feature and started by an MPI launcher as several
/// processes (Open MPI's or PMI's size in the environment) is refused with one line and exit
/// 1, before anything is written: each copy would run the whole case into the same folder.
/// One process is a plain run. (With the feature, `tests/mpi_run.rs`.)
#[cfg(not(feature = "mpi"))]
#[test]
fn a_run_started_as_several_mpi_processes_is_refused() {
    let dir = std::env::temp_dir().join(format!("mps_cli_mpirun_{}", std::process::id()));
    for var in ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"] {
        let out = mps()
            .env(var, "4")
            .args(["run", "--example", "hydrostatic", "-q", "--out"])
            .arg(&dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(
            err.contains("4 MPI processes") && err.contains(var) && err.contains("--features mpi"),
            "{err}"
        );
        assert!(!dir.exists());
    }
    succeed(
        mps()
            .env("OMPI_COMM_WORLD_SIZE", "1")
            .args(["run", "--example", "hydrostatic", "-q"])
            .args([
                "--set",
                "time.end=0.002",
                "--set",
                "output.vtu=false",
                "--out",
            ])
            .arg(&dir),
    );
    let _ = std::fs::remove_dir_all(&dir);
}
