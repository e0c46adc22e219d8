//! Whole-program fuzz (issue 16 point 3), reduced size: 2,000 mutated inputs, each run through the
//! `edgekf` binary as `edgekf run` at tiny size with a 10 s limit per case, four at a time. The
//! harness is in `whole_program`; `cargo bench -p edgekf-cli --bench fuzz_cli` runs 10⁵ cases.
//! Inputs that once failed are kept below as named regression tests.

mod whole_program;

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::path::PathBuf;
use std::time::Duration;

use whole_program::{corpus, run, run_input, Settings, Verdict};

/// The engine's base seed (the bench uses the same, so case numbers agree).
const BASE: u64 = 0x6564_6765_6b66;

/// `--max-hours` of every case: 0.36 s, so any study the cost estimate calls longer is refused
/// and a case still running at the 10 s limit is a hang, not a big study on a busy machine.
const MAX_HOURS: f64 = 1e-4;

fn scratch(name: &str) -> Scratch {
    Scratch::new("edgekf-fuzz", name)
}

#[test]
fn two_thousand_mutated_runs_end_cleanly() {
    let work = scratch("ci");
    let (m, roles) = corpus(BASE, &work);
    let s = Settings {
        limit: Duration::from_secs(10),
        max_hours: MAX_HOURS,
        workers: 4,
        keep: work.join("defects"),
        work: work.to_path_buf(),
    };
    let st = run(&m, &roles, 2_000, &s);
    println!("{}", st.report());
    assert_eq!(st.cases, 2_000);
    assert!(
        st.ran > 100 && st.refused > 100,
        "the mutations reach every stage: {}",
        st.report()
    );
    assert_eq!(
        st.defect_count(),
        0,
        "{}\nreproducers in {}",
        st.report(),
        s.keep.display()
    );
    let _ = std::fs::remove_dir_all(&work);
}

// Regression tests: inputs that once failed, verbatim from the fuzz (tests/fuzz_regressions/).

/// Runs a kept input with `flags`; returns the verdict and stderr.
fn regression(file: &str, flags: &[&str]) -> (Verdict, String) {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(file);
    let text = std::fs::read_to_string(&src).unwrap();
    let dir = scratch(&file.replace('.', "-"));
    let input = dir.join(if text.trim_start().starts_with('{') {
        "scenario.json"
    } else {
        "scenario.toml"
    });
    std::fs::write(&input, &text).unwrap();
    let slam = text.contains("slam");
    let flags: Vec<String> = flags.iter().map(|f| f.to_string()).collect();
    let (v, stderr, _, _) = run_input(&input, &flags, slam, &dir, Duration::from_secs(20), None);
    let _ = std::fs::remove_dir_all(&dir);
    (v, stderr)
}

fn refused_naming(file: &str, flags: &[&str], key: &str) {
    let (v, stderr) = regression(file, flags);
    assert_eq!(v, Verdict::Refused, "{file}: {stderr}");
    assert!(stderr.contains(key), "{file}: names {key}: {stderr}");
}

/// Case #905: `slam-fig3.toml` with `time.horizon = 1e10` aborted on allocating 10¹² samples
/// (killed by SIGABRT). Refused now, naming the key.
#[test]
fn regression_slam_horizon_1e10_is_refused_not_an_allocation_abort() {
    refused_naming("slam-horizon-1e10.toml", &[], "key `time.horizon`");
}

/// Case #653: `slam-disturbed.json` with `gains.k1 = 2⁶³ − 1` panicked in the observer design
/// ("Cannot compute the SVD of an empty matrix"): RK4 at h = 1 ms cannot integrate dynamics that
/// fast. Refused now by the RK4 bound, naming `time.step` and the gains.
#[test]
fn regression_slam_gain_k1_i64_max_is_refused_not_a_panic() {
    refused_naming("slam-gain-k1-i64-max.json", &[], "key `time.step`");
}

/// Case #130: `slam-disturbed.json` with `initial_estimates[0][13] = 1e300` hung in plotters'
/// logarithmic key points (errors.png) after writing `robots.csv` with `inf` errors. Refused now,
/// naming the entry.
#[test]
fn regression_slam_initial_estimate_1e300_is_refused_not_a_hang() {
    refused_naming(
        "slam-initial-estimate-1e300.json",
        &[],
        "key `initial_estimates[0][13]`",
    );
}

/// Case #482: `thesis-fig3.3.toml` whose `plots[0].estimators` lists one label 2000 times drew
/// 2000 panels (33 s, 2.5 GB). A label listed twice is refused now.
#[test]
fn regression_plot_estimators_listed_2000_times_is_refused() {
    refused_naming(
        "plot-estimators-listed-2000-times.toml",
        &["--runs", "2", "--steps", "30"],
        "key `plots[0].estimators`",
    );
}

/// Case #10481: `thesis-fig6.2.toml` with `comm.ar.noise_var[0] = 1e300` ran and exited 0 with
/// `inf` in metrics.csv: the per-run covariance traces (≈ 1e292) were finite, their std across
/// runs overflowed. The AR model's variance is now refused before the run like the process
/// noise, naming `comm.ar` (and the std of huge finite values is computed without overflow).
#[test]
fn regression_ar_noise_var_1e300_is_refused_not_inf_with_exit_0() {
    refused_naming(
        "fig6.2-ar-noise-var-1e300.toml",
        &["--runs", "2", "--steps", "30", "--threads", "1"],
        "key `comm.ar`",
    );
}

/// Case #14327: `thesis-fig4.6.toml` with `every = 1` wrote 160 MB of CSV for 30000 reported
/// steps, 7 s spent on outputs the time estimate did not count: it passed `--max-hours` for
/// 0.36 s. The estimate now counts the output rows and refuses it.
#[test]
fn regression_every_step_reported_counts_in_the_time_estimate() {
    refused_naming(
        "fig4.6-every-1.toml",
        &["--runs", "2", "--max-hours", "0.0001"],
        "--max-hours",
    );
}

/// Issue 16 point 1: `thesis-fig6.1.toml` with `sigma_w = 1e12` and no `every` span in
/// plotters' `compute_f64_key_points` drawing the inputs figure; the figure toolkit's guarded
/// ranges and ticks (`figure/`) ended it.
#[test]
fn plotting_hang_inputs_figure_with_sigma_w_1e12() {
    let (v, stderr) = regression(
        "fig6.1-sigma-w-1e12-without-every.toml",
        &["--runs", "2", "--steps", "30", "--threads", "1"],
    );
    assert!(!matches!(v, Verdict::Defect(..)), "{v:?}: {stderr}");
}

/// Case #9209 of the first 10⁵-case run: `garkf-fig11.toml` with `faults.availability = 0`
/// wrote `NaN` rows of `psi` and `theta_ral_*` (no agent ever has a feasible RAL) and exited 0.
/// A value no run defines has no row now (docs/formats.md).
#[test]
fn regression_availability_0_writes_no_nan_rows() {
    let (v, stderr) = regression(
        "garkf-fig11-availability-0.toml",
        &["--runs", "2", "--steps", "30", "--threads", "1"],
    );
    assert_eq!(v, Verdict::Ran, "{stderr}");
}

/// Cases #2205 and #3224: `garkf-fig10.toml` with the CA filters' `sigma_w` = 1e150 or 1e12
/// ran and wrote a NaN PCRB (and, at 1e12, a covariance collapsed to 1e-16): the process noise
/// swamps the measurements beyond what f64 carries. Refused now, naming the option.
#[test]
fn regression_ca_sigma_w_beyond_f64_is_refused() {
    for file in [
        "garkf-fig10-sigma-w-1e150.toml",
        "garkf-fig10-sigma-w-1e12.toml",
    ] {
        refused_naming(
            file,
            &["--runs", "2", "--steps", "30", "--threads", "1"],
            "option `sigma_w`",
        );
    }
}

/// Case #5498: a panels figure listing one metric 500 times drew 500 panels past the 10 s
/// limit. A metric listed twice is refused now.
#[test]
fn regression_panel_metric_listed_500_times_is_refused() {
    refused_naming(
        "garkf-panels-metric-listed-500-times.toml",
        &["--runs", "2", "--steps", "30"],
        "key `plots[0].rows`",
    );
}

/// Cases #10147 and #17987: `--steps 30` shortened a GA-RKF sweep below its `sweep.window`; the run
/// succeeded but its `scenario.json` was refused ("starts after the end of the run"). A window
/// after the end is accepted on every path now (its summaries are left out, with a warning),
/// so the resolved scenario re-runs.
#[test]
fn regression_window_after_a_shortened_run_round_trips() {
    let (v, stderr) = regression(
        "garkf-sweep-window-after-shortened-run.toml",
        &["--runs", "2", "--steps", "30"],
    );
    assert!(!matches!(v, Verdict::Defect(..)), "{v:?}: {stderr}");
    assert!(
        stderr.contains("starts after the end of the run"),
        "{stderr}"
    );
}
