//! Maximum likelihood estimator (`mle`), and `none` as its T = 1 case.
//!
//! Thesis (4.16): `ẑ_ij = (Hᵀ R̃⁻¹ H)⁻¹ Hᵀ R̃⁻¹ y_ij = (1/T) Hᵀ y_ij`, the mean of the T samples;
//! posterior covariance (4.17) `R_ij / T`. With T = 1 it is the raw measurement used without any
//! estimator (thesis Alg. 2; `cov_trace` = Σ tr R_ij).
//!
//! Without a measurement (a lost edge, Li & Rajan's intermittent observations) there is no
//! estimate: the edge holds 0, which drops it from the control law — the "no estimator" baseline
//! of Li & Rajan Figs 11–12, whose controller runs on the functional graph. `cov_trace` then sums
//! over the edges that were observed.
//!
//! # References
//! van der Marel, MSc thesis, TU Delft 2021, §4.3; van der Marel & Rajan, EUSIPCO 2022, §2.1;
//! Li & Rajan, OJCSYS 2026, §VI-C.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use nalgebra::DMatrix;

use super::{
    cov_trace_of_agents, edge_trace_sum, parse_options, Configured, Consistency, Cost, Estimator,
    EstimatorKind, Model, Options, Reads, Step,
};

/// `kind = "none"`: one raw sample per step.
#[derive(Debug, Clone, Copy)]
pub struct NoneKind;
/// `kind = "mle"`: the mean of the T samples.
#[derive(Debug, Clone, Copy)]
pub struct MleKind;

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoOptions {}

impl EstimatorKind for NoneKind {
    fn name(&self) -> &'static str {
        "none"
    }
    fn about(&self) -> &'static str {
        "no estimator: one raw measurement per step (thesis Alg. 2)"
    }
    fn fixed_samples(&self) -> Option<usize> {
        Some(1)
    }
    fn configure(&self, o: &Options, _m: &Model) -> Result<Arc<dyn Configured>, String> {
        parse_options::<NoOptions>(o)?;
        Ok(Arc::new(Config))
    }
}

impl EstimatorKind for MleKind {
    fn name(&self) -> &'static str {
        "mle"
    }
    fn about(&self) -> &'static str {
        "maximum likelihood: the mean of the T measurements (thesis 4.16)"
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
    fn build(&self, m: &Model, samples: usize, runs: usize) -> Box<dyn Estimator> {
        Box::new(Mle::new(m, samples, runs))
    }
    fn cost(&self, m: &Model) -> Cost {
        let md = (m.num_edges() * m.dim()) as f64;
        Cost {
            bytes_per_run: md * 8.0,
            flops_per_run_step: md,
            ..Cost::default()
        }
    }
    fn consistency(&self, m: &Model) -> Consistency {
        if m.measurement_faults() {
            Consistency::Approximate(
                "an edge without a measurement has no estimate (0), an error its covariance does not count",
            )
        } else {
            Consistency::Exact
        }
    }
}

/// The MLE: the edge estimate is the measurement mean.
#[derive(Debug, Clone)]
pub struct Mle {
    runs: usize,
    dim: usize,
    x: Vec<f64>,
    /// `tr(R_ij / T)` per edge.
    traces: Vec<f64>,
    /// `R_ij / T` per edge.
    covs: Vec<DMatrix<f64>>,
    /// Each agent's edges.
    owners: Vec<std::ops::Range<usize>>,
}

impl Mle {
    /// For `runs` runs with `samples` measurements per step.
    pub fn new(m: &Model, samples: usize, runs: usize) -> Self {
        let covs = m.mean_cov(samples);
        Self {
            runs,
            dim: m.dim(),
            x: vec![0.0; m.num_edges() * m.dim() * runs],
            traces: covs.iter().map(|w| w.trace()).collect(),
            covs,
            owners: m.agent_edges().to_vec(),
        }
    }
}

impl Estimator for Mle {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        // The estimate is the means: formed straight into it.
        Reads::MEANS.forming_means()
    }
    fn step(&mut self, s: &Step<'_>) {
        s.means.all_into(&mut self.x);
        if s.faults.measurement_faults() {
            let (r, d) = (self.runs, self.dim);
            for e in 0..self.traces.len() {
                for (run, &seen) in s.faults.observed_row(e).iter().enumerate() {
                    if !seen {
                        for a in 0..d {
                            self.x[(e * d + a) * r + run] = 0.0;
                        }
                    }
                }
            }
        }
    }
    fn estimates(&self) -> &[f64] {
        &self.x
    }
    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }
    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        Some(edge_trace_sum(
            self.owners[i].clone(),
            |e| s.faults.observed(e, r),
            |e| self.traces[e],
        ))
    }
    fn covariances(&self, _r: usize) -> Vec<DMatrix<f64>> {
        self.covs.clone()
    }

    fn edge_covariance(&self, e: usize, _r: usize, out: &mut [f64]) -> bool {
        super::copy_position_block(&self.covs[e], self.dim, out)
    }
}
