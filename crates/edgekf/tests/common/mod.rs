//! Shared helpers for the integration tests: reduced-size scenarios on the thesis hexagon.
#![allow(dead_code)]

use edgekf::scenario::{
    ControlSpec, EstimatorEntry, EstimatorTable, FrameworkSpec, InitSpec, NoiseSpec, Scenario,
    ScenarioSpec, SimSpec,
};

/// A hexagon scenario with the given noise, size and estimators (names or tables).
pub fn hexagon(
    sigma_w: f64,
    sigma_v: f64,
    steps: usize,
    runs: usize,
    every: usize,
    estimators: Vec<EstimatorEntry>,
) -> Scenario {
    let spec = ScenarioSpec {
        name: "test".into(),
        description: String::new(),
        framework: FrameworkSpec {
            preset: Some("hexagon".into()),
            ..Default::default()
        },
        sim: SimSpec {
            steps,
            runs,
            every,
            seed: 7,
            ..Default::default()
        },
        init: InitSpec::default(),
        noise: NoiseSpec {
            sigma_w,
            sigma_v,
            ..Default::default()
        },
        control: ControlSpec::default(),
        comm: Default::default(),
        estimators,
        plots: vec![],
    };
    Scenario::from_spec(&spec, None).expect("valid test scenario")
}

/// Estimator entries from names.
pub fn names(list: &[&str]) -> Vec<EstimatorEntry> {
    list.iter()
        .map(|s| EstimatorEntry::Name((*s).to_string()))
        .collect()
}

/// An estimator entry with options.
pub fn table(
    kind: &str,
    label: &str,
    samples: Option<usize>,
    prior_var: Option<f64>,
) -> EstimatorEntry {
    EstimatorEntry::Table(EstimatorTable {
        kind: kind.into(),
        label: Some(label.into()),
        samples,
        prior_var,
        p_fail: None,
    })
}

/// Mean of `v[from..]`.
pub fn tail_mean(v: &[f64], from: usize) -> f64 {
    v[from..].iter().sum::<f64>() / (v.len() - from) as f64
}
