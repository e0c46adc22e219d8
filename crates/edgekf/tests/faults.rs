//! The faults stage against Li & Rajan's scenarios S1–S3 (and the GA-RKF issue's text): per
//! directed edge and step a Bernoulli(λ) availability, the two directions independent (S1);
//! permanently lost edges (λ_ij = 0, S2); agents that depart and rejoin (S3: every edge into or
//! out of a departed agent is lost); one draw for measurement and message; the same draws for
//! every estimator of a run, reproducible from the seed.
//!
//! A recording estimator defined here stores, per step and run, what the faults stage told it.

mod common;

use std::sync::{Arc, Mutex};

use edgekf::estimate::{
    Configured, Cost, Estimator, EstimatorKind, Model, Options, Registry, Step,
};
use edgekf::scenario::{DepartureSpec, EstimatorEntry, Scenario, ScenarioSpec};

/// Per step (1-based index − 1), per run: which directed edges were observed, whether the input
/// message arrived with `p_fail = 0`, and which agents were present.
#[derive(Debug, Default, Clone, PartialEq)]
struct Log {
    observed: Vec<Vec<Vec<bool>>>,
    message: Vec<Vec<Vec<bool>>>,
    present: Vec<Vec<Vec<bool>>>,
}

type Shared = Arc<Mutex<Vec<Log>>>;

/// `kind = "recorder"`: records the faults; every instance appends its own log.
struct RecorderKind(Shared);

impl EstimatorKind for RecorderKind {
    fn name(&self) -> &'static str {
        "recorder"
    }
    fn about(&self) -> &'static str {
        "records the faults stage's output"
    }
    fn configure(&self, _o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        Ok(Arc::new(Config(self.0.clone())))
    }
}

#[derive(Debug)]
struct Config(Shared);

impl Configured for Config {
    fn options(&self) -> Options {
        Options::new()
    }
    fn build(&self, m: &Model, _samples: usize, runs: usize) -> Box<dyn Estimator> {
        let mut logs = self.0.lock().unwrap();
        logs.push(Log::default());
        Box::new(Recorder {
            shared: self.0.clone(),
            slot: logs.len() - 1,
            edges: m.num_edges(),
            agents: m.agents(),
            runs,
            x: vec![0.0; m.num_edges() * m.dim() * runs],
        })
    }
    fn cost(&self, _m: &Model) -> Cost {
        Cost::default()
    }
}

struct Recorder {
    shared: Shared,
    slot: usize,
    edges: usize,
    agents: usize,
    runs: usize,
    x: Vec<f64>,
}

impl Estimator for Recorder {
    fn step(&mut self, s: &Step<'_>) {
        let f = s.faults;
        let mut logs = self.shared.lock().unwrap();
        let log = &mut logs[self.slot];
        log.observed.push(
            (0..self.runs)
                .map(|r| (0..self.edges).map(|e| f.observed(e, r)).collect())
                .collect(),
        );
        log.message.push(
            (0..self.runs)
                .map(|r| {
                    (0..self.edges)
                        .map(|e| f.input_arrives(e, r, 0.0))
                        .collect()
                })
                .collect(),
        );
        log.present.push(
            (0..self.runs)
                .map(|r| (0..self.agents).map(|i| f.present(i, r)).collect())
                .collect(),
        );
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self, _s: &Step<'_>, out: &mut [f64]) {
        out.fill(0.0);
    }
}

/// Runs `spec` (one thread: one chunk, so each recorder sees every run) with two recorders and
/// returns their logs.
fn record(spec: &ScenarioSpec) -> (Log, Log) {
    let shared: Shared = Arc::new(Mutex::new(Vec::new()));
    let registry = Registry::default().with(RecorderKind(shared.clone()));
    let sc = Scenario::from_spec_in(spec, None, &registry).unwrap();
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| common::run(&sc));
    let logs = shared.lock().unwrap().clone();
    assert_eq!(logs.len(), 2);
    (logs[0].clone(), logs[1].clone())
}

fn base(steps: usize, runs: usize) -> ScenarioSpec {
    let mut s = common::spec(
        0.0,
        0.1,
        steps,
        runs,
        steps,
        vec![
            EstimatorEntry::kind("recorder"),
            EstimatorEntry::kind("recorder").with("label", "again"),
        ],
    );
    s.sim.dt = 0.01;
    s.sim.samples_per_step = 1;
    s
}

#[test]
fn availability_is_bernoulli_per_directed_edge_and_independent_per_direction() {
    let (steps, runs) = (2000, 4);
    let mut s = base(steps, runs);
    s.faults.availability = 0.4;
    let (a, b) = record(&s);
    // Every estimator of a run sees the same faults (paired comparisons).
    assert_eq!(a, b);
    let fw = edgekf::framework::Framework::hexagon();
    let g = fw.graph();
    let m = g.num_edges();
    let n = (steps * runs) as f64;
    // Frequency of each directed edge: binomial, sd √(λ(1−λ)/n) = 0.0055; 5 sd.
    let mut both = 0.0;
    for e in 0..m {
        let hits = a
            .observed
            .iter()
            .flat_map(|st| st.iter().map(|r| r[e]))
            .filter(|&o| o)
            .count() as f64;
        assert!(
            (hits / n - 0.4).abs() < 5.0 * (0.24f64 / n).sqrt(),
            "edge {e}: {}",
            hits / n
        );
        // The reverse direction is independent: P(both) = λ² = 0.16.
        let rev = g.reverse_of(e);
        both += a
            .observed
            .iter()
            .flat_map(|st| st.iter().map(|r| r[e] && r[rev]))
            .filter(|&o| o)
            .count() as f64;
    }
    let p_both = both / (n * m as f64);
    // 120 000 pairs (each counted twice): sd of the pooled frequency ≤ √(0.16·0.84/60 000).
    assert!(
        (p_both - 0.16).abs() < 5.0 * (0.16f64 * 0.84 / (n * m as f64 / 2.0)).sqrt(),
        "{p_both}"
    );
    // One draw removes the measurement and the message together.
    assert_eq!(a.observed, a.message);
}

#[test]
fn lost_edges_and_departures_follow_s2_and_s3() {
    let (steps, runs) = (400, 3);
    let mut s = base(steps, runs);
    s.faults.availability = 0.7;
    s.faults.lost = vec![[5, 0]];
    s.faults.departures = vec![DepartureSpec {
        agent: 6,
        at: 1.0,
        rejoin: Some(2.5),
    }];
    let (a, b) = record(&s);
    assert_eq!(a, b);
    let fw = edgekf::framework::Framework::hexagon();
    let g = fw.graph();
    let lost = g.edge_index(5, 0).unwrap();
    let reverse = g.edge_index(0, 5).unwrap();
    let (mut rev_seen, mut rejoined_seen) = (0, 0);
    for (k0, st) in a.observed.iter().enumerate() {
        let t = (k0 + 1) as f64 * 0.01;
        let away = (1.0..2.5).contains(&(t + 1e-9));
        for (r, obs) in st.iter().enumerate() {
            // S2: the lost direction never; the other direction at λ.
            assert!(!obs[lost]);
            rev_seen += usize::from(obs[reverse]);
            // S3: agent 6 absent in [1, 2.5) s, every edge into or out of it lost.
            assert_eq!(a.present[k0][r][6], !away, "step {}", k0 + 1);
            for (e, &(i, j)) in g.edges().iter().enumerate() {
                if i == 6 || j == 6 {
                    if away {
                        assert!(!obs[e], "edge ({i}, {j}) at t = {t}");
                    } else if t > 2.5 {
                        rejoined_seen += usize::from(obs[e]);
                    }
                }
            }
            // Nobody else leaves.
            assert!((0..10).filter(|&i| i != 6).all(|i| a.present[k0][r][i]));
        }
    }
    assert!(
        rev_seen > 0 && rejoined_seen > 0,
        "{rev_seen} {rejoined_seen}"
    );
}

#[test]
fn faults_are_reproducible_from_the_seed_and_shards_see_the_same() {
    let mut s = base(300, 4);
    s.faults.availability = 0.5;
    let (a, _) = record(&s);
    let (again, _) = record(&s);
    assert_eq!(a, again, "same seed, same faults");
    s.sim.seed += 1;
    let (other, _) = record(&s);
    assert_ne!(a.observed, other.observed, "another seed, other faults");
    // Every run has its own stream: run r's faults do not depend on how many runs are
    // simulated with it.
    s.sim.seed -= 1;
    s.sim.runs = 2;
    let (two, _) = record(&s);
    for (k, st) in two.observed.iter().enumerate() {
        assert_eq!(st[..], a.observed[k][..2]);
    }
}

#[test]
fn random_departures_take_a_share_of_the_followers_per_run() {
    let mut s = base(200, 6);
    s.faults.random_departures = Some(edgekf::scenario::RandomDepartureSpec {
        share: 0.3,
        at: 1.0,
    });
    let (a, b) = record(&s);
    assert_eq!(a, b);
    // 7 followers × 0.3 = 2.1 → 2 agents per run, never a leader, from t = 1 s on.
    let mut subsets = Vec::new();
    for r in 0..6 {
        let gone: Vec<usize> = (0..10).filter(|&i| !a.present[199][r][i]).collect();
        assert_eq!(gone.len(), 2, "run {r}: {gone:?}");
        assert!(gone.iter().all(|&i| i >= 3), "leaders stay: {gone:?}");
        assert!(
            (0..10).all(|i| a.present[98][r][i]),
            "all present before 1 s"
        );
        subsets.push(gone);
    }
    subsets.sort();
    subsets.dedup();
    assert!(subsets.len() > 1, "the subset differs between runs");
}
