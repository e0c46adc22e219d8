//! Shared helpers for the integration tests: reduced-size scenarios on the thesis hexagon.
#![allow(dead_code)]

use edgekf::estimate::ArModel;
use edgekf::scenario::{DepartureSpec, EstimatorEntry, Scenario, ScenarioSpec};
use edgekf::sim::Results;

/// A hexagon scenario spec with the given noise, size and estimators (seed 7).
pub fn spec(
    sigma_w: f64,
    sigma_v: f64,
    steps: usize,
    runs: usize,
    every: usize,
    estimators: Vec<EstimatorEntry>,
) -> ScenarioSpec {
    let mut s = ScenarioSpec::minimal("test", &[]);
    s.estimators = estimators;
    s.sim.steps = steps;
    s.sim.runs = runs;
    s.sim.every = every;
    s.sim.seed = 7;
    s.noise.sigma_w = sigma_w;
    s.noise.sigma_v = sigma_v;
    s
}

/// The faults of the determinism tests: links available 70 % of the time, and agent 5 away
/// from 0.1 s to 0.2 s (its departure and its return within a few hundred steps).
pub fn with_faults(s: &mut ScenarioSpec) {
    s.faults.availability = 0.7;
    s.faults.departures = vec![DepartureSpec {
        agent: 5,
        at: 0.1,
        rejoin: Some(0.2),
    }];
}

/// A checked scenario from a spec.
pub fn build(spec: &ScenarioSpec) -> Scenario {
    Scenario::from_spec(spec, None).expect("valid test scenario")
}

/// A hexagon scenario with the given noise, size and estimators.
pub fn hexagon(
    sigma_w: f64,
    sigma_v: f64,
    steps: usize,
    runs: usize,
    every: usize,
    estimators: Vec<EstimatorEntry>,
) -> Scenario {
    build(&spec(sigma_w, sigma_v, steps, runs, every, estimators))
}

/// One run of a designed 2-trilateration framework of `n` agents (the scale bench's, seed 3)
/// under the thesis's spatial kernel (4.14), `steps` steps reported every `every`.
pub fn trilateration_kernel(
    n: usize,
    steps: usize,
    every: usize,
    estimators: Vec<EstimatorEntry>,
) -> Scenario {
    use edgekf::design::{self, generators};
    use edgekf::scenario::FrameworkSpec;
    use rand::SeedableRng;

    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
    let cand = generators::trilateration(n, 2, 3, &mut rng);
    let fw = design::design(&cand, design::Method::Yang)
        .expect("trilateration graphs design")
        .framework;
    let mut s = ScenarioSpec::minimal("trilateration", &[]);
    s.framework = FrameworkSpec {
        dim: Some(2),
        config: Some((0..n).map(|i| fw.point(i).to_vec()).collect()),
        edges: Some(fw.graph().links().iter().map(|&(i, j)| [i, j]).collect()),
        weights: Some(fw.weights().to_vec()),
        leaders: Some(fw.leaders().to_vec()),
        ..FrameworkSpec::default()
    };
    s.estimators = estimators;
    s.noise.kernel = edgekf::noise::Kernel::default();
    s.sim.runs = 1;
    s.sim.steps = steps;
    s.sim.every = every;
    s.sim.allow_divergence = true;
    build(&s)
}

/// Runs a scenario on the current rayon pool.
pub fn run(sc: &Scenario) -> Results {
    edgekf::sim::run(sc, &edgekf::sim::Quiet).expect("not cancelled")
}

/// Estimator entries from names.
pub fn names(list: &[&str]) -> Vec<EstimatorEntry> {
    list.iter().map(|s| EstimatorEntry::kind(s)).collect()
}

/// An estimator entry with options.
pub fn table(
    kind: &str,
    label: &str,
    samples: Option<usize>,
    prior_var: Option<f64>,
) -> EstimatorEntry {
    let mut e = EstimatorEntry::kind(kind).with("label", label);
    if let Some(t) = samples {
        e = e.with("samples", t);
    }
    if let Some(v) = prior_var {
        e = e.with("prior_var", v);
    }
    e
}

/// The AR(1) model shipped with the chapter 6 scenarios (fitted with `edgekf fit-ar`).
pub fn ar() -> ArModel {
    ArModel {
        coeffs: vec![vec![0.975, 0.979]],
        noise_var: vec![0.0115, 0.0119],
    }
}

/// Mean of `v[from..]`.
pub fn tail_mean(v: &[f64], from: usize) -> f64 {
    v[from..].iter().sum::<f64>() / (v.len() - from) as f64
}

/// Index of the first reported step at or after time `t`.
pub fn at(res: &Results, t: f64) -> usize {
    res.steps
        .iter()
        .position(|&k| k as f64 * res.dt >= t)
        .expect("a reported step at that time")
}
