//! The engine's contract: a checked scenario with the documented defaults, refusals that name the
//! key, faults shared by every estimator, target-tracking leaders, shards that merge into the
//! unsharded results, and bit-identical results for any thread count for every estimator.

mod common;

use common::{ar, build, names, run, spec, with_faults};
use edgekf::scenario::{
    CommSpec, DepartureSpec, EstimatorEntry, InitAround, KeyframesSpec, LeaderSpec, ManeuverSpec,
    Resolved, Scenario, ScenarioSpec,
};
use edgekf::sim::{self, Outcome, Results};

const MINIMAL: &str = r#"
name = "smallest"
estimators = ["rkf"]
[framework]
preset = "hexagon"
"#;

/// `ScenarioSpec::minimal` (how code and unit tests build a scenario without parsing TOML) is
/// the smallest file: its defaults are the file's.
#[test]
fn minimal_spec_is_the_smallest_file() {
    let parsed = edgekf_io::spec_from_toml(MINIMAL).unwrap();
    let built = ScenarioSpec::minimal("smallest", &["rkf"]);
    let resolved = |s: &ScenarioSpec| Scenario::from_spec(s, None).unwrap().to_resolved();
    assert_eq!(resolved(&built), resolved(&parsed));
}

/// The smallest documented scenario carries the defaults of the user guide's Scenario files,
/// and runs.
#[test]
fn minimal_scenario_has_the_papers_defaults_and_runs() {
    let spec = edgekf_io::spec_from_toml(MINIMAL).unwrap();
    let sc = Scenario::from_spec(&spec, None).unwrap();
    assert_eq!(sc.dt(), 1e-3);
    assert_eq!((sc.steps(), sc.runs(), sc.seed()), (30_000, 50, 1));
    assert_eq!((sc.samples(), sc.every(), sc.paths_run()), (10, 10, 0));
    let m = sc.model();
    // σ_v = 0.1, ρ = 0.3: R = σ_v² [[1, .3], [.3, 1]] (to the rounding of two products).
    assert!((m.r()[0][(0, 0)] - 0.01).abs() < 1e-16 && (m.r()[0][(0, 1)] - 0.003).abs() < 1e-16);
    // σ_w = 0.001 with the thesis kernel (unit diagonal): Q_ii = σ_w².
    assert!((m.q()[(0, 0)] - 1e-6).abs() < 1e-20);
    assert!(
        m.q()[(0, 2)] > 0.0,
        "the spatial kernel (4.14) correlates agents"
    );
    assert_eq!(*m.p(), nalgebra::DMatrix::identity(2, 2));
    let sc = sc.with_steps(300).unwrap().with_runs(2).unwrap();
    let res = run(&sc);
    assert_eq!(res.estimator("rkf").unwrap().outcome, Outcome::Completed);
}

fn refused(spec: &ScenarioSpec) -> (String, String) {
    let e = Scenario::from_spec(spec, None).unwrap_err();
    (e.key, e.message)
}

#[test]
fn refusals_name_the_key() {
    // An option of another kind.
    let s = spec(
        0.001,
        0.1,
        10,
        1,
        1,
        vec![EstimatorEntry::kind("rkf").with("prior_var", 1e-3)],
    );
    let (k, m) = refused(&s);
    assert_eq!(k, "estimators[0]");
    assert!(m.contains("unknown field `prior_var`"), "{m}");
    // A Kalman filter on a noiseless model.
    let (k, m) = refused(&spec(0.0, 0.0, 10, 1, 1, names(&["rkf"])));
    assert_eq!(k, "estimators[0]");
    assert!(
        m.contains("noise.sigma_v") && m.contains("noise.sigma_w"),
        "{m}"
    );
    // ... while the noiseless loop without a filter is fine.
    build(&spec(0.0, 0.0, 10, 1, 1, names(&["none", "oracle"])));
    // The followers' discrete loop past its stability bound (Δt·λ_max = 5.2 on the hexagon).
    let mut s = spec(0.001, 0.1, 10, 1, 1, names(&["rkf"]));
    s.sim.dt = 0.1;
    let (k, m) = refused(&s);
    assert_eq!(k, "sim.dt");
    assert!(m.contains("≥ 2") && m.contains("allow_divergence"), "{m}");
    s.sim.allow_divergence = true;
    build(&s);
    // The leaders' distance law past its bound 2·Δt·k·λ_max(RᵀR) < 2: named with its keys.
    let mut s = spec(0.001, 0.1, 10, 1, 1, names(&["rkf"]));
    s.control.leader_gain = 1e4;
    let (k, m) = refused(&s);
    assert_eq!(k, "sim.dt");
    assert!(
        m.contains("leaders' distance law") && m.contains("control.leader_gain"),
        "{m}"
    );
    s.sim.allow_divergence = true;
    build(&s);
    // Variances f64 cannot carry.
    let mut s = spec(0.001, 0.1, 10, 1, 1, names(&["rkf"]));
    s.noise.sigma_w = 1e80;
    assert_eq!(refused(&s).0, "noise.process_cov");
    // More reported values than any machine holds.
    let mut s = spec(0.001, 0.1, 1_000_000_000_000, 50, 10, names(&["rkf"]));
    s.sim.dt = 1e-6;
    let (k, m) = refused(&s);
    assert_eq!(k, "sim.steps", "{m}");
    assert!(m.contains("every"), "{m}");
    // A maneuver needs target-tracking leaders.
    let mut s = spec(0.001, 0.1, 10, 1, 1, names(&["rkf"]));
    s.maneuver = Some(ManeuverSpec {
        keyframes: KeyframesSpec::Preset("garkf-fig7b".into()),
    });
    s.control.leaders = Some(LeaderSpec::Distance);
    assert_eq!(refused(&s).0, "control.leaders");
    // Faults.
    let mut s = spec(0.001, 0.1, 10, 1, 1, names(&["rkf"]));
    s.faults.lost = vec![[0, 7]];
    assert_eq!(refused(&s).0, "faults.lost[0]");
    s.faults.lost.clear();
    s.faults.departures = vec![DepartureSpec {
        agent: 1,
        at: 1.0,
        rejoin: None,
    }];
    let (k, m) = refused(&s);
    assert_eq!(k, "faults.departures[0].agent");
    assert!(m.contains("leader"), "{m}");
}

#[test]
fn resolved_scenarios_refuse_unknown_keys_and_bad_labels() {
    let sc = build(&spec(0.001, 0.1, 10, 1, 1, names(&["rkf"])));
    let mut v = serde_json::to_value(sc.to_resolved()).unwrap();
    v["nosie"] = serde_json::json!(1);
    let e = serde_json::from_value::<Resolved>(v)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown field `nosie`"), "{e}");
    let mut r = sc.to_resolved();
    r.estimators = vec!["other".into()];
    let e = Scenario::from_resolved(&r).unwrap_err();
    assert_eq!(e.key, "estimator_specs[0].label");
}

/// Li & Rajan's faults: one availability draw per directed edge, step and run, shared by every
/// estimator; a lost edge is never observed; a departed agent stops.
#[test]
fn faults_are_shared_and_departed_agents_stop() {
    let mut s = spec(0.001, 0.1, 2000, 4, 50, names(&["none", "rkf", "jrkf"]));
    s.faults.availability = 0.5;
    s.faults.lost = vec![[4, 0]];
    s.faults.departures = vec![DepartureSpec {
        agent: 6,
        at: 1.0,
        rejoin: None,
    }];
    let sc = build(&s);
    let res = run(&sc);
    for e in &res.estimators {
        assert_eq!(e.outcome, Outcome::Completed, "{}", e.label);
    }
    // Agent 6 does not move after 1 s (paths of run 0, reported every 50 steps).
    let e = res.estimator("rkf").unwrap();
    let nd = 20;
    let k1 = common::at(&res, 1.05);
    let last = res.steps.len() - 1;
    for d in 0..2 {
        assert_eq!(e.paths[k1 * nd + 12 + d], e.paths[last * nd + 12 + d]);
    }
    assert_ne!(
        e.paths[k1 * nd + 14],
        e.paths[last * nd + 14],
        "agent 7 moves"
    );
    // The RKF's covariance grows on the lost edge (no observation for 2 s): per-run covariances,
    // not shared, so its cov_trace differs between runs.
    let ct = res.series("rkf", "cov_trace").unwrap();
    assert!(ct.std[last] > 0.0);
}

/// Target-tracking leaders sit on the target; the tracking error is reported and the followers
/// converge to the moving target.
#[test]
fn leaders_track_the_target() {
    let mut s = spec(0.0, 0.1, 2000, 2, 100, names(&["oracle"]));
    s.sim.dt = 0.01;
    s.maneuver = Some(ManeuverSpec {
        keyframes: KeyframesSpec::Preset("garkf-fig7b".into()),
    });
    s.control.follower_gain = 5.0;
    let sc = build(&s);
    let res = run(&sc);
    let te = res.series("oracle", "tracking_error").unwrap();
    // Followers start N(0, I) away from the target and converge: below 1e-3 of the start by
    // 20 s (the slowest closed-loop mode is exp(−5 t λ_min(L_ff)); the hold 0–10 s and the
    // translation's velocity lag keep it above 0).
    assert!(te.mean[0] > 0.5, "{}", te.mean[0]);
    assert!(
        te.mean[te.mean.len() - 1] < 1e-3 * te.mean[0],
        "{:?}",
        te.mean.last()
    );
    // The leaders are exactly on the target: δ counts only the followers' errors, so with a
    // perfect estimator and no noise it goes to 0 in the hold phase.
    let hold = common::at(&res, 9.0);
    assert!(te.mean[hold] < 1e-8, "{}", te.mean[hold]);
}

/// `[init] around = "target"` starts each agent at its place in the formation (plus the
/// draw): with a zero spread and a perfect estimator the formation holds its target exactly,
/// where the start around the origin is far from it; without a maneuver the place is the
/// configuration. The resolved scenario carries the key and re-runs to the same bits.
#[test]
fn a_start_around_the_target_is_converged() {
    let mut s = spec(0.0, 0.1, 500, 2, 10, names(&["oracle"]));
    s.sim.dt = 0.01;
    s.maneuver = Some(ManeuverSpec {
        keyframes: KeyframesSpec::Preset("garkf-fig7b".into()),
    });
    s.control.follower_gain = 5.0;
    let origin = run(&build(&s));
    s.init.around = InitAround::Target;
    s.init.cov = Some(vec![vec![0.0, 0.0], vec![0.0, 0.0]]);
    let sc = build(&s);
    let target = run(&sc);
    let te = |r: &Results| r.series("oracle", "tracking_error").unwrap().mean;
    assert!(te(&origin)[0] > 0.5, "{}", te(&origin)[0]);
    // The hold (0–10 s): the formation stays on its target to rounding.
    assert!(te(&target).iter().all(|&v| v < 1e-24), "{:?}", te(&target));
    let json = serde_json::to_value(sc.to_resolved()).unwrap();
    assert_eq!(json["init_around"], "target");
    let back: Resolved = serde_json::from_value(json).unwrap();
    let again = run(&Scenario::from_resolved(&back).unwrap());
    assert_eq!(te(&again), te(&target));
    // Without a maneuver: the configuration, where the Procrustes error is 0 and stays 0.
    s.maneuver = None;
    let res = run(&build(&s));
    let pr = res.series("oracle", "procrustes").unwrap().mean;
    assert!(pr.iter().all(|&v| v < 1e-12), "{pr:?}");
}

fn all_estimators() -> Vec<EstimatorEntry> {
    vec![
        EstimatorEntry::kind("none"),
        EstimatorEntry::kind("mle"),
        EstimatorEntry::kind("mmse").with("prior_var", 1e-3),
        EstimatorEntry::kind("rkf"),
        EstimatorEntry::kind("rkf-zero"),
        EstimatorEntry::kind("rkf-ar").with("p_fail", 0.3),
        EstimatorEntry::kind("rkf-commless"),
        EstimatorEntry::kind("jrkf"),
        EstimatorEntry::kind("jrkf-ar").with("p_fail", 0.3),
        EstimatorEntry::kind("crkf"),
        EstimatorEntry::kind("oracle"),
    ]
}

fn threads(sc: &Scenario, t: usize) -> Results {
    rayon::ThreadPoolBuilder::new()
        .num_threads(t)
        .build()
        .unwrap()
        .install(|| run(sc))
}

/// Every estimator, with and without faults: bit-identical results for 1, 2 and 3 threads, and
/// shards that merge into the unsharded results (so `edgekf merge` can write the same bytes).
#[test]
fn every_estimator_is_deterministic_and_shards_merge_exactly() {
    for faults in [false, true] {
        let mut s = spec(0.001, 0.1, 300, 5, 20, all_estimators());
        s.comm = CommSpec {
            p_fail: 0.0,
            ar: Some(ar()),
        };
        if faults {
            with_faults(&mut s);
        }
        let sc = build(&s);
        let one = threads(&sc, 1);
        for t in [2, 3] {
            assert_eq!(one, threads(&sc, t), "faults {faults}, {t} threads");
        }
        for e in &one.estimators {
            assert_eq!(e.outcome, Outcome::Completed, "{}", e.label);
        }
        let parts: Vec<Results> = (1..=3)
            .map(|i| {
                sim::run_range(
                    &sc,
                    sim::shard_range(5, i, 3),
                    &sim::Quiet,
                    sim::Options::default(),
                )
                .unwrap()
            })
            .collect();
        assert_eq!(Results::merge(parts).unwrap(), one, "faults {faults}");
    }
}

/// The per-run filters' `cov_trace` is the mean over all runs of each run's trace: with faults
/// the runs differ, without they are all the RKF's (std 0).
#[test]
fn per_run_cov_trace_is_reduced_over_all_runs() {
    let mut s = spec(
        0.001,
        0.1,
        200,
        6,
        50,
        vec![
            EstimatorEntry::kind("rkf"),
            EstimatorEntry::kind("rkf-ar")
                .with("p_fail", 0.0)
                .with("label", "ar0"),
            EstimatorEntry::kind("rkf-ar")
                .with("p_fail", 0.5)
                .with("label", "ar5"),
        ],
    );
    s.comm.ar = Some(ar());
    let res = run(&build(&s));
    let (a, b) = (
        res.series("rkf", "cov_trace").unwrap(),
        res.series("ar0", "cov_trace").unwrap(),
    );
    assert_eq!(a, b);
    assert!(a.std.iter().all(|&v| v == 0.0));
    let c = res.values("ar5", "cov_trace").unwrap();
    let last = res.steps.len() - 1;
    let row = &c[last * 6..(last + 1) * 6];
    assert!(
        row.iter().any(|&v| v != row[0]),
        "each run has its own failures"
    );
    let mean = row.iter().sum::<f64>() / 6.0;
    assert_eq!(res.series("ar5", "cov_trace").unwrap().mean[last], mean);
}

/// A loop past its stability bound (allowed) whose error grows without reaching infinity within
/// the run is diverged, not completed: it stops where `est_error` passes 10⁶ length scales, and
/// the cause names the key (`sim.dt`).
#[test]
fn a_finite_but_exploding_error_is_a_divergence() {
    let mut s = spec(0.001, 0.1, 120, 2, 1, names(&["none", "rkf"]));
    s.sim.dt = 0.1;
    s.sim.allow_divergence = true;
    let sc = build(&s);
    // L is the hexagon's diameter here (4 m): the noise, prior and walk are smaller.
    assert!(
        (sc.length_scale() - 4.0).abs() < 1e-9,
        "{}",
        sc.length_scale()
    );
    let res = run(&sc);
    for e in &res.estimators {
        let Outcome::Diverged { step, cause, .. } = &e.outcome else {
            panic!("{}: {:?}", e.label, e.outcome);
        };
        // |1 − Δt·λ| ≈ 4.2 per step: 10⁶ · 4 m is passed within some 10–40 steps, long
        // before f64 overflows (≈ 490 steps).
        assert!((5..=60).contains(step), "{}: step {step}", e.label);
        assert!(
            cause.contains("divergence bound") && cause.contains("sim.dt"),
            "{cause}"
        );
    }
}
