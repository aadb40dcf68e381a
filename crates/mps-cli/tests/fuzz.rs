//! The fuzz target: property tests (proptest) over mutated case files, `--set` values and
//! checkpoint bytes, run in-process through the library. Seed corpus: the built-in examples
//! and the reliability reproducers (`tests/reproducers`, and `../shared/reliability/repro`
//! where the checkout has it). Every generated input runs in a forked child with a 20 s
//! limit, so a panic, an abort or a hang fails the property and proptest shrinks it to a
//! small reproducer (kept in `tests/fuzz.proptest-regressions`, replayed first on every run).
//!
//! What must hold for every input: no panic, abort or hang; bad input is a one-line error
//! naming the file (and, for `--set`, a field); a case that loads and is small enough builds
//! and runs three steps (output included) or stops with a breakdown.
//!
//! The test command draws the same inputs on every run (a fixed seed), so that a run of the
//! tests never fails on an input no earlier run had. New inputs, more of them:
//! `PROPTEST_RNG_SEED=$RANDOM PROPTEST_CASES=5000 cargo test --release -p mps-cli --test fuzz`.

use mps::io::checkpoint::{build_simulation, checkpoint_bytes, restore};
use mps::run::{run, Silent};
use mps::{Case, Simulation};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The seed of the inputs the test command draws (`PROPTEST_RNG_SEED` draws others).
const FIXED_SEED: u64 = 20_261_206;

/// Numbers a mutation puts in place of a number.
const EXTREMES: &[&str] = &[
    "0",
    "-0.0",
    "-1",
    "1",
    "1e308",
    "-1e308",
    "1e-300",
    "nan",
    "inf",
    "-inf",
    "9223372036854775807",
    "18446744073709551615",
    "4294967296",
    "1e10",
    "1e-10",
    "2",
    "0.5",
    "100000",
    "3.0",
];

/// Strings and other values a mutation puts in place of a string (or a `--set` value).
const STRINGS: &[&str] = &[
    "\"\"",
    "\"water\"",
    "\"air\"",
    "\"MPS-HS-GC-DS\"",
    "\"CMPS-HS\"",
    "\"amg-cg\"",
    "\"rectangle\"",
    "\"circle\"",
    "\"hydrostatic\"",
    "\"remove\"",
    "\"probe_reference\"",
    "\"Cargo.toml\"",
    "{ file = \"Cargo.toml\" }",
    "\"x*y\"",
    "\"1/0\"",
    "\"sqrt(-1)\"",
    "\"../x\"",
    "[1.0, 2.0]",
    "[1e308, -1e308]",
    "[]",
    "{ type = \"tank\", min = [0.0, 0.0], max = [1.0, 1.0] }",
    "true",
    "abc",
];

/// Bytes a mutation inserts.
const JUNK: &[&str] = &[
    "\0",
    "[",
    "]]",
    "=",
    "\"",
    "{",
    "é",
    "\n[x]\n",
    "\n[[walls]]\n",
    "#",
];

/// Examples and reproducer case files: (label, text).
fn seeds() -> &'static [(String, String)] {
    static SEEDS: OnceLock<Vec<(String, String)>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let mut out: Vec<(String, String)> = mps::examples::EXAMPLES
            .iter()
            .map(|(name, _, text)| (format!("{name}.toml"), text.to_string()))
            .collect();
        for dir in repro_dirs() {
            let mut files = Vec::new();
            collect(&dir, "toml", &mut files);
            for f in files {
                if let Ok(text) = std::fs::read_to_string(&f) {
                    out.push((f.display().to_string(), text));
                }
            }
        }
        out
    })
}

fn repro_dirs() -> Vec<PathBuf> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shared = here.join("../../../shared/reliability/repro");
    std::iter::once(here.join("tests/reproducers"))
        .chain(shared.is_dir().then_some(shared))
        .collect()
}

/// Files under `dir` (recursively) ending in `.ext`, sorted.
fn collect(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            collect(&p, ext, out);
        } else if p.extension().is_some_and(|e| e == ext) {
            out.push(p);
        }
    }
}

/// One mutation: a kind and two selectors (which place, which replacement).
type Mutation = (u8, u32, u32);

/// Byte ranges of the numbers (or quoted strings) in `text`.
fn spans(text: &str, strings: bool) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let start = i;
        if strings && b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' && b[i] != b'\n' {
                i += 1;
            }
            if i < b.len() && b[i] == b'"' {
                out.push((start, i + 1));
            }
        } else if !strings
            && (b[i].is_ascii_digit() || b[i] == b'-')
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'))
        {
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b"+-.".contains(&b[i])) {
                i += 1;
            }
            if i > start + usize::from(b[start] == b'-') {
                out.push((start, i));
            }
            continue;
        }
        i += 1;
    }
    out
}

/// `text` with mutation `m` applied.
fn mutate(text: &str, (kind, a, b): Mutation) -> String {
    let (a, b) = (a as usize, b as usize);
    let lines: Vec<&str> = text.lines().collect();
    let replace = |spans: Vec<(usize, usize)>, with: &str| match spans.get(a % spans.len().max(1)) {
        Some(&(s, e)) => format!("{}{with}{}", &text[..s], &text[e..]),
        None => text.to_string(),
    };
    let floor = |k: usize| {
        (0..=k.min(text.len()))
            .rev()
            .find(|&k| text.is_char_boundary(k))
    };
    match kind % 7 {
        0 => replace(spans(text, false), EXTREMES[b % EXTREMES.len()]),
        1 => replace(spans(text, true), STRINGS[b % STRINGS.len()]),
        2 if !lines.is_empty() => {
            let k = a % lines.len();
            let kept: Vec<&str> = (0..lines.len())
                .filter(|&i| i != k)
                .map(|i| lines[i])
                .collect();
            kept.join("\n")
        }
        3 if !lines.is_empty() => {
            let k = a % lines.len();
            let mut v = lines.clone();
            v.insert(k, lines[k]);
            v.join("\n")
        }
        4 => text[..floor(a % (text.len() + 1)).unwrap_or(0)].to_string(),
        5 => {
            let at = floor(a % (text.len() + 1)).unwrap_or(0);
            format!("{}{}{}", &text[..at], JUNK[b % JUNK.len()], &text[at..])
        }
        6 if !lines.is_empty() => {
            let k = a % lines.len();
            let mut v: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            v[k] = v[k].replacen(" =", "_x =", 1);
            v.join("\n")
        }
        _ => text.to_string(),
    }
}

/// Appends an outcome to the file `MPS_FUZZ_LOG` names, when set (counts per outcome:
/// `sort FILE | uniq -c`).
fn log(outcome: &str) {
    if let Some(path) = std::env::var_os("MPS_FUZZ_LOG") {
        use std::io::Write;
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
        {
            let _ = writeln!(f, "{outcome}");
        }
    }
}

/// The lattice sites of the case's domain at its spacing (a bound on the set-up's work).
fn sites(case: &Case) -> f64 {
    let h = case.particles.spacing;
    (0..case.domain.min.len())
        .map(|k| (case.domain.max[k] - case.domain.min[k]) / h + 1.0)
        .product()
}

/// A scratch folder for one generated input (each runs in its own child process).
fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("mps_fuzz_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Builds a loaded case and runs three steps with output, when it is small enough to do
/// so quickly; every error must be one line.
fn exercise(case: Case, label: &str) -> Result<(), TestCaseError> {
    let n = sites(&case);
    if n.is_nan() || n > 1e6 {
        log("loaded, too large to build here");
        return Ok(());
    }
    match case.dimension {
        3 => exercise_in::<3>(case, label),
        _ => exercise_in::<2>(case, label),
    }
}

/// [`exercise`] in `D` dimensions, as the program runs a case.
fn exercise_in<const D: usize>(mut case: Case, label: &str) -> Result<(), TestCaseError> {
    // A relaxation first (the 3D two-phase examples settle for 0.5 s) is cut to about two
    // steps here, as the run itself is cut to three steps below, and left out where the run
    // would be skipped as too large (the relaxation is part of the set-up, so it would run).
    let big = sites(&case) > 30_000.0;
    let g = case
        .physics
        .gravity
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt();
    let dt = case
        .time
        .dt_fixed
        .unwrap_or(case.time.courant * (case.particles.spacing / g).sqrt());
    if let Some(init) = case.initial.as_mut() {
        if big {
            init.relax = None;
        } else if let Some(r) = init.relax.as_mut() {
            // (A step that is not finite or positive is refused before any relaxation.)
            r.time = r.time.min(1e-3).min(2.0 * dt.abs().max(1e-12));
        }
    }
    // (A settled start's checkpoint error names that file, not the case.)
    let mut sim = match build_simulation::<D>(case, label) {
        Ok(s) => s,
        Err(e) => {
            log("set-up refused");
            let m = e.to_string();
            prop_assert!(!m.contains('\n'), "{m}");
            return Ok(());
        }
    };
    // Left on disk only if this child dies or hangs (MPS_FUZZ_LOG set): the input itself.
    let dump = std::env::var_os("MPS_FUZZ_LOG")
        .map(|_| std::env::temp_dir().join(format!("mps_fuzz_case_{}.toml", std::process::id())));
    if let Some(d) = &dump {
        let _ = std::fs::write(d, toml::to_string(&sim.case).unwrap_or_default());
    }
    if sim.particles.len() > 30_000 {
        log("built, too large to run here");
        dump.map(std::fs::remove_file);
        return Ok(());
    }
    sim.case.time.max_steps = Some(3);
    let dir = scratch();
    match run(&mut sim, &dir, &mut Silent) {
        Ok(s) if s.breakdown.is_some() => log("ran, breakdown"),
        Ok(_) => log("ran"),
        Err(e) => {
            log("run error");
            prop_assert!(!e.to_string().contains('\n'), "{e}")
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    if let Some(d) = &dump {
        let _ = std::fs::remove_file(d);
    }
    Ok(())
}

/// The properties' settings: `cases` inputs (or `PROPTEST_CASES`), each in a forked child
/// with a 20 s limit, drawn from a fixed seed unless `PROPTEST_RNG_SEED` names one, so that
/// the test command replays the same inputs on every run (new inputs: set the seed).
fn config(cases: u32) -> Config {
    let default = Config::default();
    let seeded = std::env::var_os("PROPTEST_RNG_SEED").is_some();
    Config {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(cases),
        fork: true,
        timeout: 20_000,
        rng_seed: if seeded {
            default.rng_seed
        } else {
            RngSeed::Fixed(FIXED_SEED)
        },
        ..default
    }
}

proptest! {
    #![proptest_config(config(160))]

    /// Mutated case files: no panic, abort or hang; a one-line error naming the file.
    #[test]
    fn mutated_case_files_fail_cleanly_or_run(
        seed in any::<prop::sample::Index>(),
        example in any::<bool>(),
        mutations in prop::collection::vec((any::<u8>(), any::<u32>(), any::<u32>()), 1..4),
    ) {
        // Half the inputs start from an example (most reproducers are refused as they are).
        let pool = if example { &seeds()[..mps::examples::EXAMPLES.len()] } else { seeds() };
        let (label, text) = seed.get(pool);
        let text = mutations.iter().fold(text.clone(), |t, &m| mutate(&t, m));
        match Case::from_str_named(&text, label, &[]) {
            Err(e) => {
                log("case: refused");
                let m = e.to_string();
                prop_assert!(!m.contains('\n') && m.starts_with(label.as_str()), "{m}");
            }
            Ok(case) => exercise(case, label)?,
        }
    }
}

/// Every dotted key of a TOML table (`phases.0.density`), tables and arrays included.
fn keys(prefix: &str, v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.push(key.clone());
                keys(&key, v, out);
            }
        }
        toml::Value::Array(a) => {
            for (k, v) in a.iter().enumerate() {
                let key = format!("{prefix}.{k}");
                out.push(key.clone());
                keys(&key, v, out);
            }
        }
        _ => {}
    }
}

proptest! {
    #![proptest_config(config(160))]

    /// `--set key=value` with keys of the example (and some that are not) and hostile
    /// values: no panic, abort or hang; a one-line error naming the file and a field.
    #[test]
    fn hostile_set_values_fail_cleanly_or_run(
        example in 0..mps::examples::EXAMPLES.len(),
        key in any::<prop::sample::Index>(),
        value in any::<prop::sample::Index>(),
        free in "[a-z0-9 .\\[\\]\"=-]{0,12}",
    ) {
        let (name, _, text) = mps::examples::EXAMPLES[example];
        let label = format!("{name}.toml");
        let mut all = Vec::new();
        keys("", &toml::from_str::<toml::Value>(text).unwrap(), &mut all);
        all.extend(
            [
                "a.b.c",
                "phases.99.density",
                "domain.min.7",
                "time",
                "x.",
                "domain.outflow",
                "initial.state",
                "initial",
                "validation.kind",
                "validation.reference",
            ]
            .map(String::from),
        );
        let values: Vec<&str> = EXTREMES.iter().chain(STRINGS).copied().chain([free.as_str()]).collect();
        let set = vec![(key.get(&all).clone(), value.get(&values).to_string())];
        match Case::from_str_named(text, &label, &set) {
            Err(e) => {
                log("set: refused");
                let m = e.to_string();
                prop_assert!(!m.contains('\n') && m.starts_with(label.as_str()), "{m}");
                prop_assert!(!e.field.is_empty(), "no field named: {m}");
            }
            Ok(case) => exercise(case, &label)?,
        }
    }
}

/// A small still-water tank and a checkpoint of it after five steps (groups and every
/// particle kind present: the two-layer example at a coarse spacing).
fn checkpointed() -> (Simulation<2>, &'static [u8]) {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    let build = || {
        let set = [("particles.spacing".to_string(), "0.02".to_string())];
        let text = mps::examples::example("settling").unwrap();
        Simulation::<2>::new(
            Case::from_str_named(text, "settling.toml", &set).unwrap(),
            "s",
        )
        .unwrap()
    };
    let bytes = BYTES.get_or_init(|| {
        let mut s = build();
        for _ in 0..5 {
            s.step(1.0).unwrap();
        }
        checkpoint_bytes(&s)
    });
    (build(), bytes)
}

proptest! {
    #![proptest_config(config(160))]

    /// Checkpoint bytes flipped, overwritten, cut or extended (and the reproducers'
    /// checkpoints as they are): restoring fails with one line or succeeds, and a restored
    /// state steps on or breaks down, never panics.
    #[test]
    fn corrupt_checkpoints_are_refused_or_run(
        edits in prop::collection::vec((0u8..12, any::<prop::sample::Index>(), any::<u8>()), 1..6),
        reproducer in any::<prop::sample::Index>(),
        use_reproducer in prop::bool::weighted(0.2),
    ) {
        let (mut sim, good) = checkpointed();
        let mut files = Vec::new();
        for d in repro_dirs() {
            collect(&d, "bin", &mut files);
        }
        let mut bytes = match (use_reproducer, files.is_empty()) {
            (true, false) => std::fs::read(reproducer.get(&files)).unwrap(),
            _ => good.to_vec(),
        };
        for (kind, at, v) in edits {
            let k = at.index(bytes.len().max(1));
            match kind {
                // Mostly edits that keep the layout (bit flips, overwritten bytes), so that
                // many inputs get past the format and reach the index checks and the step.
                0..=6 if !bytes.is_empty() => bytes[k] ^= 1 << (v % 8),
                7 | 8 if !bytes.is_empty() => bytes[k] = v,
                9 => bytes.truncate(k),
                10 => bytes.insert(k.min(bytes.len()), v),
                11 if !bytes.is_empty() => { bytes.remove(k); }
                _ => {}
            }
        }
        match restore(&mut sim, &bytes, Path::new("checkpoint.bin")) {
            Err(e) => {
                log("checkpoint: refused");
                prop_assert!(!e.to_string().contains('\n'), "{e}")
            }
            Ok(()) => {
                log("checkpoint: restored");
                for _ in 0..3 {
                    if sim.step(sim.case.time.end).is_err() {
                        break;
                    }
                }
                let _ = mps::analysis::metrics::Metrics::measure(&sim);
            }
        }
    }
}

#[test]
fn mutations_change_what_they_say() {
    let t = "a = 1.5\nb = \"x\"\n";
    assert_eq!(mutate(t, (0, 0, 4)), "a = 1e308\nb = \"x\"\n");
    assert_eq!(mutate(t, (1, 0, 1)), "a = 1.5\nb = \"water\"\n");
    assert_eq!(mutate(t, (2, 1, 0)), "a = 1.5");
    assert_eq!(mutate(t, (4, 3, 0)), "a =");
    assert_eq!(mutate(t, (6, 0, 0)), "a_x = 1.5\nb = \"x\"");
    assert!(
        seeds().len() > mps::examples::EXAMPLES.len(),
        "reproducers are seeds"
    );
}
