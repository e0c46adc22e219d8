//! `rkf` and `jrkf` with `adaptive`: the single-edge and the joint relative Kalman filters whose
//! agents learn the noise scales online ([`super::adaptive`]).
//!
//! The filters are those of [`super::rkf`] (EUSIPCO (5a)–(5g)) and [`super::jrkf`] (EUSIPCO
//! (14a)–(14g)) with the process noise `c_w Q_ij` (`c_w B̄_iᵀ Q B̄_i`) and the measurement noise
//! `c_v R_ij / T`: the same prediction with the known inputs (`û^j = 0` when the message is lost
//! with the measurement), the same Joseph-form correction over the edges observed this step.
//! Because the gain now depends on each run's data, every (filter, run) carries its own
//! covariance and the sensitivities of `adaptive::Bank`; agent `i` learns
//! `θ_i = (ln c_w, ln c_v)` from the innovations of its own filters (its edges, or its joint
//! filter), one Gauss–Newton step per time step.
//!
//! # References
//! van der Marel & Rajan, EUSIPCO 2022, eqs. (5), (14); Gupta & Mehra, IEEE TAC 19(6), 1974;
//! Ljung & Söderström, *Theory and Practice of Recursive Identification*, 1983.

use std::ops::Range;

use super::adaptive::{Adaptation, Assumed, Bank, BlockModel, Obs};
use super::{cov_trace_of_agents, quantity_of_agents, Breakdown, Estimator, Model, Reads, Step};

/// Which filter runs on the edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// One filter per edge (`rkf`).
    Edge,
    /// One joint filter per agent over its edges (`jrkf`).
    Joint,
}

/// The adaptive `rkf` or `jrkf` on every directed edge for a batch of runs.
#[derive(Debug, Clone)]
pub struct AdaptiveRw {
    runs: usize,
    dim: usize,
    dt: f64,
    edges: Vec<(usize, usize)>,
    agent_edges: Vec<Range<usize>>,
    owners: Range<usize>,
    /// The edges of each filter, and each edge's filter and row in it.
    block_edges: Vec<Range<usize>>,
    edge_block: Vec<(usize, usize)>,
    bank: Bank,
    assumed: Assumed,
    x: Vec<f64>,
    inc: Vec<f64>,
    y: Vec<f64>,
    seen: Vec<bool>,
    breakdown: Option<Breakdown>,
}

impl AdaptiveRw {
    /// For `runs` runs with `samples` measurements per step.
    pub(crate) fn new(
        m: &Model,
        samples: usize,
        runs: usize,
        form: Form,
        assumed: Assumed,
        adapt: Adaptation,
    ) -> Self {
        let d = m.dim();
        let (qs, rs) = (assumed.q_scale(m), assumed.r_scale(m));
        let w = m.mean_cov(samples);
        let block_edges: Vec<Range<usize>> = match form {
            Form::Edge => (0..m.num_edges()).map(|e| e..e + 1).collect(),
            Form::Joint => m
                .agent_edges()
                .iter()
                .filter(|r| !r.is_empty())
                .cloned()
                .collect(),
        };
        let mut edge_block = vec![(0, 0); m.num_edges()];
        let mut blocks = Vec::with_capacity(block_edges.len());
        let mut p0 = Vec::with_capacity(block_edges.len());
        let mut nmax = 0;
        for (b, range) in block_edges.iter().enumerate() {
            let n = range.len() * d;
            nmax = nmax.max(n);
            let (mut q, mut r, mut p) = (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
            for (a, e) in range.clone().enumerate() {
                edge_block[e] = (b, a * d);
                for (c, f) in range.clone().enumerate() {
                    let (qef, pef) = (m.edge_q(e, f), m.edge_p0(e, f));
                    for i in 0..d {
                        for j in 0..d {
                            let at = (a * d + i) * n + c * d + j;
                            q[at] = qs.map_or(qef[(i, j)], |s| s * qef[(i, j)]);
                            p[at] = pef[(i, j)];
                            if a == c {
                                r[at] = rs.map_or(w[e][(i, j)], |s| s * w[e][(i, j)]);
                            }
                        }
                    }
                }
            }
            blocks.push(BlockModel {
                n,
                m: n,
                f: None,
                q,
                r,
                owner: m.edges()[range.start].0,
            });
            p0.push(p);
        }
        Self {
            runs,
            dim: d,
            dt: m.dt(),
            edges: m.edges().to_vec(),
            agent_edges: m.agent_edges().to_vec(),
            owners: m.owners(),
            block_edges,
            edge_block,
            bank: Bank::new(blocks, &p0, m.agents(), runs, adapt),
            assumed,
            x: vec![0.0; m.num_edges() * d * runs],
            inc: vec![0.0; nmax],
            y: vec![0.0; nmax],
            seen: vec![false; nmax],
            breakdown: None,
        }
    }

    /// The state (`x̂` then `Λ`, row-major) of the filter of edge `e` in run `r`, and the edge's
    /// first row in it.
    pub fn filter_of(&self, e: usize, r: usize) -> (&[f64], &[f64], usize) {
        let (b, row) = self.edge_block[e];
        let (x, p) = self.bank.state(b, r);
        (x, p, row)
    }
}

impl Estimator for AdaptiveRw {
    fn fork(&self) -> Option<Box<dyn Estimator>> {
        Some(Box::new(self.clone()))
    }

    fn reads(&self) -> Reads {
        Reads::INCREMENTS
    }
    fn step(&mut self, s: &Step<'_>) {
        if self.breakdown.is_some() {
            return;
        }
        let (runs, d) = (self.runs, self.dim);
        for (b, range) in self.block_edges.iter().enumerate() {
            let n = range.len() * d;
            for r in 0..runs {
                let mut any = false;
                for (a, e) in range.clone().enumerate() {
                    let i = self.edges[e].0;
                    let heard = s.faults.hears(e, r);
                    let observed = s.faults.observed(e, r);
                    any |= observed;
                    for c in 0..d {
                        let row = (e * d + c) * runs + r;
                        self.inc[a * d + c] = if heard {
                            s.du[row]
                        } else {
                            self.dt * s.u_prev[(i * d + c) * runs + r]
                        };
                        self.y[a * d + c] = s.y[row];
                        self.seen[a * d + c] = observed;
                    }
                }
                self.bank.predict(b, r, Some(&self.inc[..n]));
                if any
                    && self
                        .bank
                        .correct(b, r, &self.y[..n], Some(&self.seen[..n]), Obs::Direct)
                        .is_err()
                {
                    let (i, j) = self.edges[range.start];
                    self.breakdown = Some(Breakdown {
                        what: format!(
                            "the innovation covariance of the filter of edge ({i}, {j}) is not positive definite"
                        ),
                    });
                    return;
                }
                let (x, _) = self.bank.state(b, r);
                for (a, e) in range.clone().enumerate() {
                    for c in 0..d {
                        self.x[(e * d + c) * runs + r] = x[a * d + c];
                    }
                }
            }
        }
        self.bank.end_step(self.owners.clone());
    }

    fn estimates(&self) -> &[f64] {
        &self.x
    }

    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        cov_trace_of_agents(self, s, out);
    }

    fn agent_cov_trace(&self, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        let mut t = 0.0;
        for e in self.agent_edges[i].clone() {
            if s.faults.tracked(e, r) {
                let (b, row) = self.edge_block[e];
                t += self.bank.rows_trace(b, r, row..row + self.dim);
            }
        }
        Some(t)
    }

    fn quantity(&self, name: &str, s: &Step<'_>, out: &mut [f64]) -> bool {
        if !provides(self.bank.adaptation(), name) {
            return false;
        }
        quantity_of_agents(self, name, s, out);
        true
    }

    fn agent_quantity(&self, name: &str, i: usize, r: usize, s: &Step<'_>) -> Option<f64> {
        if self.agent_edges[i].is_empty() || !s.faults.present(i, r) {
            return None;
        }
        agent_scale(&self.bank, self.assumed, name, i, r)
    }

    fn breakdown(&self) -> Option<&Breakdown> {
        self.breakdown.as_ref()
    }
}

/// Whether an adaptive filter provides the metric `name`.
pub(crate) fn provides(a: &Adaptation, name: &str) -> bool {
    name == "sigma_w_hat" || (a.measurement && name == "sigma_v_hat")
}

/// Agent `i`'s `sigma_w_hat` / `sigma_v_hat` in run `r`.
pub(crate) fn agent_scale(
    bank: &Bank,
    assumed: Assumed,
    name: &str,
    i: usize,
    r: usize,
) -> Option<f64> {
    let (cw, cv) = bank.scales(i, r);
    match name {
        "sigma_w_hat" => Some(assumed.sigma_w * cw.sqrt()),
        "sigma_v_hat" if bank.adaptation().measurement => Some(assumed.sigma_v * cv.sqrt()),
        _ => None,
    }
}

/// The cost of the adaptive filters of `form`.
pub(crate) fn adaptive_cost(m: &Model, form: Form) -> super::Cost {
    let d = m.dim() as f64;
    let sizes: Vec<f64> = if form == Form::Edge {
        vec![d; m.num_edges()]
    } else {
        m.agent_edges().iter().map(|r| r.len() as f64 * d).collect()
    };
    // x̂, Λ and two sensitivities each; ≈ 12 n³ operations per step for the correction and
    // the sensitivities.
    let bytes: f64 = sizes.iter().map(|n| 3.0 * (n + n * n) * 8.0).sum();
    let flops: f64 = sizes.iter().map(|n| 12.0 * n * n * n + 40.0).sum();
    super::Cost {
        bytes_per_run: bytes,
        bytes_shared: 0.0,
        flops_per_run_step: flops,
        flops_shared_step: 0.0,
    }
}
