//! The frames a viewer animates (`sim::Options::frame_runs`, `frames.json`): the same bits for
//! any thread count and shard split, metrics unchanged by recording them, positions equal to the
//! recorded paths, estimates and covariances that give back each run's own `est_error` and
//! `cov_trace`, and the faults (lost links, departed agents) as the filters saw them.

mod common;

use common::{build, names, spec, table, with_faults};
use edgekf::scenario::Scenario;
use edgekf::sim::{self, Options, Results};

const KINDS: &[&str] = &["none", "mle", "rkf", "jrkf", "crkf"];
const RUNS: usize = 5;

fn framed(limit: usize) -> Options {
    Options {
        frame_runs: 3,
        frame_limit: limit,
        ..Options::default()
    }
}

fn on_threads(sc: &Scenario, threads: usize, opt: Options) -> Results {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| sim::run_with(sc, &sim::Quiet, opt).unwrap())
}

fn scenario(faults: bool) -> Scenario {
    let mut kinds = names(KINDS);
    kinds.push(table("mmse", "mmse", None, Some(1.0)));
    let mut s = spec(0.001, 0.1, 300, RUNS, 10, kinds);
    if faults {
        with_faults(&mut s);
    }
    build(&s)
}

/// Recording frames changes no metric, and the frames are the same bits on 1, 2 and 3 threads
/// and when the runs are split into shards and merged.
#[test]
fn frames_are_deterministic_and_change_nothing_else() {
    for faults in [false, true] {
        let sc = scenario(faults);
        let plain = on_threads(&sc, 1, Options::default());
        let one = on_threads(&sc, 1, framed(12));
        assert_eq!(one.frame_steps.len(), 12, "thinned to the limit");
        assert_eq!(one.frame_steps[0], one.steps[0]);
        assert_eq!(one.frame_steps.last(), one.steps.last());
        for (a, b) in plain.estimators.iter().zip(&one.estimators) {
            assert_eq!(a.values, b.values, "{}: frames change the metrics", a.label);
            let runs: Vec<usize> = b.frames.iter().map(|f| f.run).collect();
            assert_eq!(runs, vec![0, 1, 2], "{}", b.label);
            assert!(b.frames.iter().all(|f| f.frames == 12), "{}", b.label);
        }
        for t in [2, 3] {
            assert_eq!(
                one,
                on_threads(&sc, t, framed(12)),
                "faults {faults}, {t} threads"
            );
        }
        let parts: Vec<Results> = (1..=3)
            .map(|i| sim::run_range(&sc, sim::shard_range(RUNS, i, 3), &sim::Quiet, framed(12)))
            .map(Result::unwrap)
            .collect();
        assert_eq!(Results::merge(parts).unwrap(), one, "faults {faults}");
    }
}

/// Each frame is the step the metrics measured: run 0's positions are its paths, and the edge
/// errors and covariance traces recomputed from the frame give that run's `est_error` and
/// `cov_trace` (to rounding).
#[test]
fn frames_give_back_each_runs_own_metrics() {
    let sc = scenario(false);
    let res = on_threads(&sc, 2, framed(30));
    let fw = sc.framework();
    let (n, d) = (fw.agents(), fw.dim());
    let edges = fw.graph().edges();
    let m = edges.len();
    let t = d * (d + 1) / 2;
    let diag: Vec<usize> = (0..d).map(|a| a * d - a * (a.max(1) - 1) / 2).collect();
    assert_eq!(diag, if d == 2 { vec![0, 2] } else { vec![0, 3, 5] });
    for e in &res.estimators {
        let metric = |name: &str| e.metrics.iter().position(|x| x == name).unwrap();
        let (err, cov) = (metric("est_error"), metric("cov_trace"));
        for rf in &e.frames {
            for (f, &k) in res.frame_steps.iter().enumerate() {
                let idx = res.steps.iter().position(|&s| s == k).unwrap();
                let z = &rf.positions[f * n * d..(f + 1) * n * d];
                if rf.run == res.paths_run {
                    assert_eq!(z, &e.paths[idx * n * d..(idx + 1) * n * d], "{}", e.label);
                }
                let xh = &rf.estimates[f * m * d..(f + 1) * m * d];
                let sq: f64 = edges
                    .iter()
                    .enumerate()
                    .flat_map(|(q, &(i, j))| (0..d).map(move |c| (q, i, j, c)))
                    .map(|(q, i, j, c)| (z[i * d + c] - z[j * d + c] - xh[q * d + c]).powi(2))
                    .sum();
                let want = e.values[err][idx * RUNS + rf.run];
                assert!(
                    (sq.sqrt() - want).abs() <= 1e-9 * want.max(1e-12),
                    "{} run {} step {k}: ε from the frame {} vs {want}",
                    e.label,
                    rf.run,
                    sq.sqrt()
                );
                let c = &rf.covariances[f * m * t..(f + 1) * m * t];
                let tr: f64 = (0..m)
                    .flat_map(|q| diag.iter().map(move |&a| c[q * t + a]))
                    .sum();
                let want = e.values[cov][idx * RUNS + rf.run];
                assert!(
                    (tr - want).abs() <= 1e-9 * want.abs().max(1e-12),
                    "{} run {} step {k}: Σ tr Σ_e {tr} vs cov_trace {want}",
                    e.label,
                    rf.run
                );
                assert!(rf.observed[f * m..(f + 1) * m].iter().all(|&o| o));
                assert!(rf.present[f * n..(f + 1) * n].iter().all(|&p| p));
            }
        }
    }
}

/// With faults: the departed agent is absent exactly while it is away (0.1–0.2 s), its links
/// unmeasured then, and other links are lost about 30 % of the time (availability 0.7).
#[test]
fn frames_show_lost_links_and_departed_agents() {
    let sc = scenario(true);
    let res = on_threads(&sc, 1, framed(60));
    let fw = sc.framework();
    let (n, m) = (fw.agents(), fw.graph().num_edges());
    let edges = fw.graph().edges();
    let rkf = res.estimators.iter().find(|e| e.label == "rkf").unwrap();
    let (mut lost, mut total) = (0usize, 0usize);
    for rf in &rkf.frames {
        for (f, &k) in res.frame_steps.iter().enumerate() {
            let time = k as f64 * res.dt;
            let away = !rf.present[f * n + 5];
            let should = (0.1..0.2).contains(&time);
            if (time - 0.1).abs() > 2e-3 && (time - 0.2).abs() > 2e-3 {
                assert_eq!(away, should, "run {} t = {time}", rf.run);
            }
            for (q, &(i, j)) in edges.iter().enumerate() {
                let seen = rf.observed[f * m + q];
                if away && (i == 5 || j == 5) {
                    assert!(!seen, "a departed agent's link measured at t = {time}");
                } else if !away || (i != 5 && j != 5) {
                    lost += usize::from(!seen);
                    total += 1;
                }
            }
        }
    }
    let p = lost as f64 / total as f64;
    // Binomial with n = `total` draws (edges within a frame are independent draws): 4 σ.
    let se = (0.3 * 0.7 / total as f64).sqrt();
    assert!(
        (p - 0.3).abs() < 4.0 * se + 0.02,
        "lost {p:.3} of {total}, expected 0.3 ± {se:.3}"
    );
}
