//! Sizes are guarded before the work, and flags say what happened: a design or study past the
//! default limits (`--max-hours` 1 h, 80 % of the available memory) is refused before it starts,
//! naming the flag that changes it; each range error names its own flag and a non-empty range;
//! `--allow-divergence` and `sim.allow_divergence` do the same thing, at load time too.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn edgekf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new("edgekf-limits", name)
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn hexagon(dir: &Path, file: &str, estimators: &str, sim: &str) -> PathBuf {
    let p = dir.join(file);
    fs::write(
        &p,
        format!(
            "name = \"limits\"\nestimators = [{estimators}]\n[framework]\npreset = \"hexagon\"\n[sim]\n{sim}\n"
        ),
    )
    .unwrap();
    p
}

/// The case: `design --generate complete --agents 100000` grew to 24 GB and was killed
/// after 92 s. Now it is refused at once, with the estimate and the flag.
#[test]
fn a_design_past_the_limits_is_refused_before_it_starts() {
    let dir = tmp("design");
    let t = Instant::now();
    let o = edgekf(&[
        "design",
        "--generate",
        "complete",
        "--agents",
        "100000",
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    assert!(
        e.contains("--agents") && e.contains("candidate links"),
        "{e}"
    );
    assert!(!dir.join("o").exists());
    // Past the time limit only: names --max-hours, which raises it.
    let o = edgekf(&[
        "design",
        "--generate",
        "trilateration",
        "--agents",
        "3000",
        "--method",
        "sparse",
        "--max-hours",
        "0.001",
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("--max-hours") && e.contains("0.001 h"), "{e}");
}

/// Every estimator refuses a study past the default `--max-hours` (1 h) before it starts; the
/// flag lets it run.
#[test]
fn every_estimator_refuses_past_the_default_time_limit() {
    let dir = tmp("hours");
    for (label, est) in [
        ("none", "\"none\""),
        ("mle", "\"mle\""),
        ("mmse", "{ kind = \"mmse\", prior_var = 1e-3 }"),
        ("rkf", "\"rkf\""),
        ("jrkf", "\"jrkf\""),
        ("crkf", "\"crkf\""),
    ] {
        let sc = hexagon(
            &dir,
            &format!("{label}.toml"),
            est,
            "steps = 4000000000\nevery = 4000000000\nruns = 50",
        );
        let out = dir.join(label);
        let o = edgekf(&["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let e = err(&o);
        assert_eq!(o.status.code(), Some(1), "{label}: {e}");
        assert!(
            e.contains("--max-hours") && e.contains("default 1 h"),
            "{label}: {e}"
        );
        assert!(!out.exists(), "{label}");
    }
}

#[test]
fn fit_ar_range_errors_name_their_own_flag_and_a_non_empty_range() {
    let dir = tmp("fitar");
    let sc = hexagon(&dir, "s.toml", "\"rkf\"", "steps = 200\nruns = 2");
    let o = edgekf(&["fit-ar", sc.to_str().unwrap(), "--order", "100000"]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("flag `--order`: must lie in 1..=199 for 200 steps"),
        "{e}"
    );
    let o = edgekf(&[
        "fit-ar",
        sc.to_str().unwrap(),
        "--order",
        "3",
        "--from",
        "500",
    ]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("flag `--from`: must lie in 1..=197 for 200 steps and order 3"),
        "{e}"
    );
    // The largest order leaves a one-step window: accepted.
    let o = edgekf(&["fit-ar", sc.to_str().unwrap(), "--order", "199"]);
    assert!(!err(&o).contains("must lie in"), "{}", err(&o));
}

/// Δt = 0.06 puts the hexagon's loop past its stability bound: refused at load time, the
/// message naming both the key and the flag; the flag and the key then run the same study.
#[test]
fn allow_divergence_flag_and_key_do_the_same_thing_at_load_time() {
    let dir = tmp("diverge");
    let plain = hexagon(
        &dir,
        "plain.toml",
        "\"rkf\"",
        "dt = 0.06\nsteps = 200\nruns = 2",
    );
    let keyed = hexagon(
        &dir,
        "keyed.toml",
        "\"rkf\"",
        "dt = 0.06\nsteps = 200\nruns = 2\nallow_divergence = true",
    );
    let o = edgekf(&[
        "run",
        plain.to_str().unwrap(),
        "--out",
        dir.join("o0").to_str().unwrap(),
    ]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("sim.dt")
            && e.contains("`sim.allow_divergence = true`")
            && e.contains("--allow-divergence"),
        "{e}"
    );
    let (a, b) = (dir.join("flag"), dir.join("key"));
    let o = edgekf(&[
        "run",
        plain.to_str().unwrap(),
        "--out",
        a.to_str().unwrap(),
        "--allow-divergence",
    ]);
    assert!(o.status.success(), "{}", err(&o));
    let o = edgekf(&["run", keyed.to_str().unwrap(), "--out", b.to_str().unwrap()]);
    assert!(o.status.success(), "{}", err(&o));
    for f in ["metrics.csv", "status.csv", "scenario.json"] {
        assert_eq!(
            fs::read(a.join(f)).unwrap(),
            fs::read(b.join(f)).unwrap(),
            "{f}"
        );
    }
    // The resolved scenario keeps it: re-running it needs no flag.
    let o = edgekf(&[
        "run",
        a.join("scenario.json").to_str().unwrap(),
        "--out",
        dir.join("again").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", err(&o));
    // fit-ar takes the flag the same way.
    let o = edgekf(&["fit-ar", plain.to_str().unwrap(), "--allow-divergence"]);
    assert!(!err(&o).contains("sim.dt"), "{}", err(&o));
}

/// `edgekf run SC --out DIR EXTRA…`.
fn run(sc: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    edgekf(&args)
}

/// A sweep value of the wrong type is named as such (it was reported as a value that needs
/// `sweep.labels`), with the option it would set; the inner key in the file's spelling, not the
/// resolved scenario's.
#[test]
fn a_sweep_value_of_the_wrong_type_is_named() {
    let dir = tmp("sweep-type");
    let out = dir.join("o");
    let sweep = |file: &str, parameter: &str, values: &str| {
        let sim = format!(
            "runs = 2\nsteps = 10\n[sweep]\nparameter = \"{parameter}\"\nvalues = {values}"
        );
        let o = run(&hexagon(&dir, file, "\"rkf\"", &sim), &out, &[]);
        assert_eq!(o.status.code(), Some(1));
        assert!(!out.exists());
        err(&o)
    };
    let e = sweep("s.toml", "estimators.rkf.sigma_w", "[\"a\", 0.002]");
    assert!(e.contains("key `sweep.values[0]`"), "{e}");
    assert!(
        e.contains("option `sigma_w`: invalid type: string \"a\""),
        "{e}"
    );
    assert!(
        e.contains("key `estimators[0]`") && !e.contains("estimator_specs"),
        "{e}"
    );
    let e = sweep("r.toml", "sim.runs", "[2, 0]");
    assert!(e.contains("`sim.runs` = 0: key `sim.runs`"), "{e}");
}

/// `--every` as long as the run is valid but reports two steps: said, not silent.
#[test]
fn a_report_interval_as_long_as_the_run_is_said() {
    let dir = tmp("every");
    let sc = hexagon(&dir, "e.toml", "\"rkf\"", "runs = 2\nsteps = 200");
    let out = dir.join("o");
    let o = run(&sc, &out, &["--every", "1000"]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(
        err(&o).contains("`sim.every` = 1000 ≥ steps = 200"),
        "{}",
        err(&o)
    );
    let o = run(&sc, &out, &["--every", "10"]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(!err(&o).contains("sim.every"), "{}", err(&o));
}
