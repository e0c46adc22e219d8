//! The oracle: the true edge states, as if measured without noise. The noiseless reference of
//! thesis Fig. 4.5 and a baseline for any study; `cov_trace` is 0.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::{
    parse_options, Configured, Consistency, Cost, Estimator, EstimatorKind, Model, Options, Reads,
    Step,
};

/// `kind = "oracle"`.
#[derive(Debug, Clone, Copy)]
pub struct Kind;

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoOptions {}

impl EstimatorKind for Kind {
    fn name(&self) -> &'static str {
        "oracle"
    }
    fn about(&self) -> &'static str {
        "the true edges (noiseless reference)"
    }
    fn fixed_samples(&self) -> Option<usize> {
        Some(1)
    }
    fn configure(&self, o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        parse_options::<NoOptions>(o)?;
        Ok(Arc::new(Config))
    }
}

#[derive(Debug, Clone, Copy)]
struct Config;

impl Configured for Config {
    fn options(&self) -> Options {
        Options::new()
    }
    fn build(&self, m: &Model, _samples: usize, runs: usize) -> Box<dyn Estimator> {
        Box::new(Oracle {
            x: vec![0.0; m.num_edges() * m.dim() * runs],
        })
    }
    fn cost(&self, m: &Model) -> Cost {
        let md = (m.num_edges() * m.dim()) as f64;
        Cost {
            bytes_per_run: md * 8.0,
            flops_per_run_step: md,
            ..Cost::default()
        }
    }
    fn shared_gain(&self, _m: &Model) -> bool {
        true
    }
    fn consistency(&self, _m: &Model) -> Consistency {
        // Its error and its covariance trace are both 0.
        Consistency::Exact
    }
}

/// True edges.
#[derive(Debug, Clone)]
pub struct Oracle {
    x: Vec<f64>,
}

impl Estimator for Oracle {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads {
            increments: false,
            truth: true,
            means: false,
        }
    }
    fn step(&mut self, s: &Step<'_>) {
        self.x.copy_from_slice(s.truth);
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self, _s: &Step<'_>, out: &mut [f64]) {
        out.fill(0.0);
    }
    fn agent_cov_trace(&self, _i: usize, _r: usize, _s: &Step<'_>) -> Option<f64> {
        Some(0.0)
    }
}
