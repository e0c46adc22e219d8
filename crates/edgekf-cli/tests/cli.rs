//! The command line as a user meets it: bad input ends with a clear message naming the file, the
//! key and the problem, a non-zero exit code, and no output; good input round-trips exactly.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn edgekf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new("edgekf-cli", name)
}

/// A 4-agent square with the stress of its affine dependency (rank N − D − 1 = 1).
const SQUARE: &str = r#"
name = "square"
estimators = ["mle", "rkf"]

[framework]
dim = 2
config = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
edges = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
weights = [1.0, -1.0, 1.0, 1.0, -1.0, 1.0]
leaders = [0, 1, 2]

[sim]
steps = 200
runs = 3
every = 20

[noise]
sigma_w = 0.001
sigma_v = 0.1
"#;

fn write_scenario(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("scenario.toml");
    fs::write(&p, text).unwrap();
    p
}

/// Runs a scenario that must fail; returns stderr after checking exit code and no output.
fn fails(name: &str, text: &str, extra: &[&str]) -> String {
    let dir = tmp(name);
    let sc = write_scenario(&dir, text);
    let out = dir.join("out");
    let mut args = vec!["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = edgekf(&args);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "{name}: expected failure");
    assert_eq!(
        o.status.code(),
        Some(1),
        "{name}: exit code 1, not a panic (101)"
    );
    assert!(!err.contains("panicked"), "{name}: {err}");
    assert!(!out.exists(), "{name}: no output is left behind");
    assert!(
        err.contains("scenario.toml"),
        "{name}: names the file: {err}"
    );
    err
}

#[test]
fn good_scenario_runs_and_round_trips_exactly() {
    let dir = tmp("good");
    let sc = write_scenario(&dir, SQUARE);
    let out1 = dir.join("out1");
    let o = edgekf(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        out1.to_str().unwrap(),
        "--threads",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["scenario.json", "metrics.csv", "paths.csv"] {
        assert!(out1.join(f).exists(), "{f}");
    }
    let csv = fs::read_to_string(out1.join("metrics.csv")).unwrap();
    assert!(csv.starts_with("estimator,step,time,metric,mean,std\n"));
    // 2 estimators × 4 metrics × reported steps {1, 20, …, 200} = 11.
    assert_eq!(csv.lines().count(), 1 + 2 * 4 * 11);
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out1.join("scenario.json")).unwrap()).unwrap();
    assert_eq!(json["schema"], "edgekf.scenario/1");
    assert_eq!(json["edges"].as_array().unwrap().len(), 12);
    assert_eq!(json["meas_cov"].as_array().unwrap().len(), 12);
    let out2 = dir.join("out2");
    let o = edgekf(&[
        "run",
        out1.join("scenario.json").to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        fs::read(out1.join("metrics.csv")).unwrap(),
        fs::read(out2.join("metrics.csv")).unwrap()
    );
    assert_eq!(
        fs::read(out1.join("scenario.json")).unwrap(),
        fs::read(out2.join("scenario.json")).unwrap()
    );
}

#[test]
fn unknown_key_is_named() {
    let err = fails(
        "unknown",
        &SQUARE.replace("sigma_v = 0.1", "sigma_vv = 0.1"),
        &[],
    );
    assert!(err.contains("sigma_vv"), "{err}");
}

/// A panels plot's wrong keys, each named with what is wrong.
#[test]
fn panel_plot_mistakes_are_named() {
    for (plot, key, says) in [
        ("rows = [[]]", "rows", "needs at least one row of metrics"),
        (
            "rows = [[\"est_error\", \"est_error\"]]",
            "rows",
            "`est_error` is listed twice",
        ),
        ("rows = [[\"speed\"]]", "rows", "unknown metric `speed`"),
        (
            "rows = [[\"est_error\"]]\ncolumns = \"many\"",
            "columns",
            "must be \"single\" or \"points\"",
        ),
        (
            "rows = [[\"est_error\"]]\nseries = \"x\"",
            "series",
            "must be \"estimators\" or \"points\"",
        ),
        (
            "rows = [[\"est_error\"]]\nband = \"wide\"",
            "band",
            "must be \"std\", \"min-max\" or \"none\"",
        ),
        (
            "rows = [[\"est_error\"]]\nband = \"min-max\"",
            "band",
            "unknown metric `est_error_min`",
        ),
        (
            "rows = [[\"est_error\"]]\ncolumns = \"points\"",
            "columns",
            "needs a [sweep]",
        ),
    ] {
        let text = format!("{SQUARE}\n[[plots]]\nfile = \"p\"\nkind = \"panels\"\n{plot}\n");
        let err = fails("panels", &text, &[]);
        assert!(
            err.contains(&format!("key `plots[0].{key}`")) && err.contains(says),
            "{plot}: {err}"
        );
    }
}

#[test]
fn wrong_dimension_is_named() {
    let err = fails(
        "dim",
        &SQUARE.replace("[sim]", "[init]\nmean = [0.0, 0.0, 0.0]\n\n[sim]"),
        &[],
    );
    assert!(
        err.contains("init.mean") && err.contains("dim = 2"),
        "{err}"
    );
}

#[test]
fn non_psd_covariance_is_named() {
    let err = fails(
        "psd",
        &SQUARE.replace("[sim]", "[init]\ncov = [[1.0, 2.0], [2.0, 1.0]]\n\n[sim]"),
        &[],
    );
    assert!(
        err.contains("init.cov") && err.contains("positive semidefinite"),
        "{err}"
    );
}

#[test]
fn leader_not_in_graph_is_named() {
    let err = fails(
        "leader",
        &SQUARE.replace("leaders = [0, 1, 2]", "leaders = [0, 1, 7]"),
        &[],
    );
    assert!(
        err.contains("framework") && err.contains("leader 7 is not an agent"),
        "{err}"
    );
}

#[test]
fn weights_not_matching_the_graph_are_named() {
    let err = fails(
        "weights",
        &SQUARE.replace(
            "weights = [1.0, -1.0, 1.0, 1.0, -1.0, 1.0]",
            "weights = [1.0, -1.0, 1.0, 1.0, -1.0]",
        ),
        &[],
    );
    assert!(err.contains("5 weights given for 6 links"), "{err}");
    let err = fails(
        "stress",
        &SQUARE.replace(
            "weights = [1.0, -1.0, 1.0, 1.0, -1.0, 1.0]",
            "weights = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]",
        ),
        &[],
    );
    assert!(err.contains("rank") || err.contains("null space"), "{err}");
}

#[test]
fn zero_runs_and_bad_flags_are_named() {
    let err = fails("runs", &SQUARE.replace("runs = 3", "runs = 0"), &[]);
    assert!(err.contains("sim.runs"), "{err}");
    // Flags out of range are usage errors (exit code 2) that name the flag and the problem,
    // negative numbers included.
    let dir = tmp("flags");
    let sc = write_scenario(&dir, SQUARE);
    for (flag, value) in [
        ("--runs", "0"),
        ("--steps", "-5"),
        ("--threads", "0"),
        ("--every", "-1"),
        ("--seed", "-3"),
        ("--shard", "4/3"),
        ("--max-hours", "0"),
    ] {
        let o = edgekf(&[
            "run",
            sc.to_str().unwrap(),
            "--out",
            dir.join("o").to_str().unwrap(),
            flag,
            value,
        ]);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(flag), "{flag} {value}: {err}");
        assert!(!err.contains("panicked") && !err.contains("-- -"), "{err}");
        assert!(!dir.join("o").exists());
    }
}

#[test]
fn missing_file_and_unknown_figure_fail_cleanly() {
    let o = edgekf(&["run", "/nonexistent/x.toml", "--out", "/tmp/never"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/x.toml"));
    let o = edgekf(&["reproduce", "thesis-fig9.9", "--out", "/tmp/never"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("thesis-fig9.9"));
}

#[test]
fn reproduce_lists_and_runs_figures() {
    let o = edgekf(&["reproduce", "--list"]);
    assert!(o.status.success());
    let list = String::from_utf8_lossy(&o.stdout).to_string();
    let names: Vec<&str> = list
        .lines()
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    for want in [
        "eusipco-fig3",
        "eusipco-fig4a",
        "eusipco-fig4b",
        "thesis-fig3.3",
        "thesis-fig4.5",
        "thesis-fig5.3",
    ] {
        assert!(names.contains(&want), "{want} in {names:?}");
    }
    let dir = tmp("reproduce");
    let o = edgekf(&[
        "reproduce",
        "thesis-fig4.5",
        "eusipco-fig3",
        "--out",
        dir.to_str().unwrap(),
        "--steps",
        "300",
        "--runs",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.join("thesis-fig4.5/thesis-fig4.5.png").exists());
    // One directory per simulation, its figures beside its data.
    assert!(dir.join("eusipco/eusipco-fig3.png").exists());
    assert!(dir.join("eusipco/metrics.csv").exists());
    // With every other figure of that simulation (they draw the same data).
    for f in [
        "eusipco-fig4a",
        "eusipco-fig4b",
        "thesis-fig5.1",
        "thesis-fig5.3-ratio",
    ] {
        assert!(dir.join(format!("eusipco/{f}.png")).exists(), "{f}");
    }
}

#[test]
fn fit_ar_prints_a_table_a_scenario_can_take() {
    let dir = tmp("fitar");
    let sc = write_scenario(&dir, SQUARE);
    let fit = [
        "fit-ar",
        sc.to_str().unwrap(),
        "--order",
        "2",
        "--estimator",
        "rkf",
    ];
    let o = edgekf(&fit);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let table: toml::Table = toml::from_str(&out).expect("fit-ar prints TOML");
    let ar = &table["comm"]["ar"];
    assert_eq!(ar["coeffs"].as_array().unwrap().len(), 2);
    assert_eq!(ar["noise_var"].as_array().unwrap().len(), 2);
    // Feeding it back: a scenario with rkf-ar and the fitted model runs.
    let text = format!(
        "{}\n{out}",
        SQUARE.replace(
            "estimators = [\"mle\", \"rkf\"]",
            "estimators = [\"rkf\", { kind = \"rkf-ar\", p_fail = 0.5 }]"
        )
    );
    let sc2 = dir.join("with-ar.toml");
    fs::write(&sc2, text).unwrap();
    let o = edgekf(&[
        "run",
        sc2.to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = edgekf(&["fit-ar", sc.to_str().unwrap(), "--from", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--from"));
    // --json: the same fit, for scripts.
    let o = edgekf(&[&fit[..], &["--json"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_slice(&o.stdout).expect("fit-ar --json prints JSON");
    // The same numbers as the table (as f64: TOML reads a whole number as an integer).
    let f64s = |j: &serde_json::Value| -> Vec<f64> {
        let row = |x: &serde_json::Value| match x.as_array() {
            Some(a) => a.iter().map(|y| y.as_f64().unwrap()).collect(),
            None => vec![x.as_f64().unwrap()],
        };
        j.as_array().unwrap().iter().flat_map(row).collect()
    };
    for key in ["coeffs", "noise_var"] {
        let table = serde_json::to_value(&ar[key]).unwrap();
        assert_eq!(f64s(&v[key]), f64s(&table), "{key}");
    }
    assert_eq!(v["estimator"], "rkf");
    // --every has nothing to do in a fit: refused.
    let o = edgekf(&["fit-ar", sc.to_str().unwrap(), "--every", "5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("flag `--every`"));
}

/// `--shard I/K` runs contiguous run ranges with the usual per-run seeds; `merge` writes a
/// metrics.csv byte-identical to the unsharded run's.
#[test]
fn shards_merge_into_the_unsharded_bytes() {
    let dir = tmp("shards");
    let sc = write_scenario(&dir, &SQUARE.replace("runs = 3", "runs = 7"));
    let whole = dir.join("whole");
    let o = edgekf(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        whole.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut parts = Vec::new();
    for i in 1..=3 {
        let d = dir.join(format!("part{i}"));
        let shard = format!("{i}/3");
        let o = edgekf(&[
            "run",
            sc.to_str().unwrap(),
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &shard,
            "--threads",
            "1",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        parts.push(d);
    }
    let merged = dir.join("merged");
    let mut args = vec!["merge"];
    // Any order.
    for p in parts.iter().rev() {
        args.push(p.to_str().unwrap());
    }
    args.extend(["--out", merged.to_str().unwrap()]);
    let o = edgekf(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["metrics.csv", "paths.csv", "status.csv", "scenario.json"] {
        assert_eq!(
            fs::read(whole.join(f)).unwrap(),
            fs::read(merged.join(f)).unwrap(),
            "{f}"
        );
    }
    // A missing shard is refused, naming the gap.
    let o = edgekf(&[
        "merge",
        parts[0].to_str().unwrap(),
        parts[2].to_str().unwrap(),
        "--out",
        dir.join("bad").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("run"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!dir.join("bad/metrics.csv").exists());
}

/// A study whose closed loop overflows ends with a typed outcome: status.csv names the
/// estimator and the step, the summary says it, the exit code is 3 — unless divergence is
/// allowed. Nothing is written as NaN rows.
#[test]
fn divergence_is_an_outcome_not_a_success() {
    let dir = tmp("diverge");
    // A huge process variance on one coordinate (PSD, and representable): the leaders' cubic
    // distance law overflows within a few steps.
    let mut q = vec![vec![0.0; 8]; 8];
    q[1][1] = 9.223372036854776e18;
    let text = SQUARE.replace(
        "sigma_w = 0.001",
        &format!("process_cov = {}", serde_json::to_string(&q).unwrap()),
    );
    let sc = write_scenario(&dir, &text);
    let out = dir.join("o");
    let o = edgekf(&["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("diverged"), "{err}");
    let status = fs::read_to_string(out.join("status.csv")).unwrap();
    assert!(status.contains("rkf,diverged,"), "{status}");
    let metrics = fs::read_to_string(out.join("metrics.csv")).unwrap();
    assert!(
        !metrics.contains("NaN") && !metrics.contains("inf"),
        "no non-finite rows"
    );
    let o = edgekf(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        dir.join("o2").to_str().unwrap(),
        "--allow-divergence",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["estimators"][1]["status"], "diverged");
}

/// The smallest documented scenario runs; a study that cannot fit in memory or time is refused
/// before it starts, with the estimate named.
#[test]
fn smallest_scenario_runs_and_oversized_studies_are_refused() {
    let dir = tmp("smallest");
    let sc = write_scenario(
        &dir,
        "name = \"smallest\"\nestimators = [\"rkf\"]\n[framework]\npreset = \"hexagon\"\n",
    );
    let o = edgekf(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
        "--steps",
        "500",
        "--runs",
        "4",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("rkf"));
    for (every, want) in [("10", "every"), ("1000000000000", "hours")] {
        let o = edgekf(&[
            "run",
            sc.to_str().unwrap(),
            "--out",
            dir.join("big").to_str().unwrap(),
            "--steps",
            "1000000000000",
            "--every",
            every,
        ]);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(want), "{err}");
        assert!(!dir.join("big").exists());
    }
}

/// `sweep.series` keeps in `sweep_metrics.csv` exactly the rows of the listed metrics (the
/// same bytes as without it, the other rows left out); `summary.csv` does not change; a series
/// that names an unknown metric, or leaves out one a per-value figure draws, is refused.
#[test]
fn sweep_series_keeps_the_listed_metrics_and_nothing_else() {
    let shipped = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/garkf-fig11.toml"),
    )
    .unwrap();
    let line = "series = [\"tracking_error\"]";
    assert!(shipped.contains(line), "the shipped Fig. 11 keeps δ only");
    let dir = tmp("series");
    let run = |name: &str, text: &str| {
        let sc = dir.join(format!("{name}.toml"));
        fs::write(&sc, text).unwrap();
        let out = dir.join(name);
        let o = edgekf(&[
            "run",
            sc.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--steps",
            "60",
            "--runs",
            "2",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let kept = run("kept", &shipped);
    let all = run("all", &shipped.replace(line, ""));
    let read = |d: &Path, f: &str| fs::read_to_string(d.join(f)).unwrap();
    assert_eq!(read(&kept, "summary.csv"), read(&all, "summary.csv"));
    assert_eq!(read(&kept, "metrics.csv"), read(&all, "metrics.csv"));
    let (k, a) = (
        read(&kept, "sweep_metrics.csv"),
        read(&all, "sweep_metrics.csv"),
    );
    let metric = |l: &&str| l.split(',').nth(5).unwrap().to_string();
    let expect: Vec<&str> = a
        .lines()
        .enumerate()
        .filter(|(i, l)| *i == 0 || metric(l) == "tracking_error")
        .map(|(_, l)| l)
        .collect();
    assert_eq!(k.lines().collect::<Vec<_>>(), expect);
    assert!(a.lines().skip(1).any(|l| metric(&l) != "tracking_error"));
    assert!(
        expect.len() > 1 + 6 * 3,
        "every value and estimator keeps δ"
    );

    let e = fails(
        "series-unknown",
        &shipped.replace(line, "series = [\"tracking_eror\"]"),
        &[],
    );
    assert!(
        e.contains("sweep.series") && e.contains("tracking_eror"),
        "{e}"
    );
    let e = fails(
        "series-twice",
        &shipped.replace(line, "series = [\"psi\", \"psi\"]"),
        &[],
    );
    assert!(e.contains("sweep.series") && e.contains("twice"), "{e}");
    let fig8 = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/garkf-fig8.toml"),
    )
    .unwrap();
    let e = fails(
        "series-not-drawn",
        &fig8.replace(", \"theta_trace_max\"]", "]"),
        &[],
    );
    assert!(
        e.contains("plots[0].band") && e.contains("theta_trace_max"),
        "{e}"
    );
    let _ = fs::remove_dir_all(&dir);
}

/// A paired-ratio plot names a reference that is not an estimator: refused by key, with the
/// labels there are.
#[test]
fn a_ratio_plot_to_an_unknown_estimator_is_refused() {
    let shipped = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/eusipco.toml"),
    )
    .unwrap();
    assert!(
        shipped.contains("ratio_to = \"mle\""),
        "the shipped Fig. 5.3 pair"
    );
    let e = fails(
        "ratio-unknown",
        &shipped.replace("ratio_to = \"mle\"", "ratio_to = \"mel\""),
        &[],
    );
    assert!(
        e.contains(".ratio_to") && e.contains("`mel`") && e.contains("\"mle\""),
        "{e}"
    );
}

/// Without the feature `swarm` (the default build), `edgekf swarm|agent|world` say how to get
/// them instead of clap's "unrecognized subcommand".
#[cfg(not(feature = "swarm"))]
#[test]
fn swarm_commands_without_the_feature_say_how_to_build_them() {
    for cmd in ["swarm", "agent", "world"] {
        let o = edgekf(&[cmd, "scenario.toml"]);
        assert_eq!(o.status.code(), Some(2), "{cmd}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&format!("`edgekf {cmd}`")) && err.contains("--features swarm"),
            "{cmd}: {err}"
        );
    }
}
