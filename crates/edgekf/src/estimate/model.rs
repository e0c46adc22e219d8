//! The model every estimator is built from, for the whole formation or for one agent.

use std::ops::Range;

use nalgebra::DMatrix;

use super::ArModel;
use crate::framework::Framework;

/// Which agents' edges a model covers: every agent (the Monte Carlo engine), or one agent (an
/// agent that runs its own filters: [`crate::agent`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Every agent's edges, in incidence order.
    All,
    /// Agent `i`'s edges `(i, j)` only, in incidence order.
    Agent(usize),
}

/// What a model is made of (the checked scenario supplies it).
#[derive(Debug, Clone)]
pub(crate) struct ModelParts {
    /// The framework (configuration, graph, weights, leaders).
    pub(crate) framework: Framework,
    /// Q (ND × ND).
    pub(crate) q: DMatrix<f64>,
    /// `R_ij` per directed edge (the covariance of one sample).
    pub(crate) r: Vec<DMatrix<f64>>,
    /// P, the covariance of each initial position.
    pub(crate) p: DMatrix<f64>,
    /// Δt.
    pub(crate) dt: f64,
    /// The AR model of the inputs (thesis chapter 6), if the scenario has one.
    pub(crate) ar: Option<ArModel>,
    /// The scenario-wide default link-failure probability of chapter 6 (`comm.p_fail`).
    pub(crate) p_fail: f64,
    /// Whether measurements can be missing (availability < 1, lost edges, departures).
    pub(crate) measurement_faults: bool,
    /// The directed edge whose covariance `edge_cov_trace` reports (`[metrics] edge`).
    pub(crate) metric_edge: Option<usize>,
}

/// The model every estimator is built from: the framework, the noise, Δt, and what the faults
/// stage may do — for every agent's edges, or for one agent's ([`Model::for_agent`]). It comes
/// only from a checked [`crate::scenario::Scenario`].
#[derive(Debug, Clone)]
pub struct Model {
    framework: Framework,
    dim: usize,
    agents: usize,
    scope: Scope,
    edges: Vec<(usize, usize)>,
    agent_edges: Vec<Range<usize>>,
    q: DMatrix<f64>,
    r: Vec<DMatrix<f64>>,
    /// Every edge's `R_ij` (also in one agent's model).
    formation_r: Vec<DMatrix<f64>>,
    p: DMatrix<f64>,
    dt: f64,
    ar: Option<ArModel>,
    p_fail: f64,
    measurement_faults: bool,
    metric_edge: Option<usize>,
}

impl Model {
    /// The model of every agent's edges.
    pub(crate) fn new(parts: ModelParts) -> Self {
        let g = parts.framework.graph();
        let n = g.agents();
        Self {
            dim: parts.framework.dim(),
            agents: n,
            scope: Scope::All,
            edges: g.edges().to_vec(),
            agent_edges: (0..n).map(|i| g.edges_of(i)).collect(),
            framework: parts.framework,
            q: parts.q,
            formation_r: parts.r.clone(),
            r: parts.r,
            p: parts.p,
            dt: parts.dt,
            ar: parts.ar,
            p_fail: parts.p_fail,
            measurement_faults: parts.measurement_faults,
            metric_edge: parts.metric_edge,
        }
    }

    /// The model of agent `i`'s edges `(i, j)` only: what agent `i` needs to run its own
    /// filters. Its edge `e` is edge `first + e` of this model (`first` the start of
    /// `agent_edges()[i]` here); other agents own no edges, and the metric edge is kept only if
    /// it is one of agent `i`'s.
    ///
    /// # Panics
    /// When `i` is not an agent of this model, or this is already one agent's model.
    pub fn for_agent(&self, i: usize) -> Model {
        assert!(self.scope == Scope::All, "a model of every agent's edges");
        assert!(i < self.agents, "agent {i} of {}", self.agents);
        let own = self.agent_edges[i].clone();
        let deg = own.len();
        let mut local = self.clone();
        local.scope = Scope::Agent(i);
        local.edges = self.edges[own.clone()].to_vec();
        local.r = self.r[own.clone()].to_vec();
        local.agent_edges = (0..self.agents)
            .map(|a| if a == i { 0..deg } else { deg..deg })
            .collect();
        local.metric_edge = self
            .metric_edge
            .filter(|e| own.contains(e))
            .map(|e| e - own.start);
        local
    }

    /// The same model where measurements and messages can go missing (an agent on a real
    /// network): filters then take their per-run path, which reads the faults of every step.
    #[must_use]
    pub fn with_measurement_faults(mut self) -> Model {
        self.measurement_faults = true;
        self
    }

    /// Which agents' edges it covers.
    pub fn scope(&self) -> Scope {
        self.scope
    }

    /// The agents whose edges it covers, ascending.
    pub fn owners(&self) -> Range<usize> {
        match self.scope {
            Scope::All => 0..self.agents,
            Scope::Agent(i) => i..i + 1,
        }
    }

    /// The framework (configuration, graph, weights, leaders) of the whole formation.
    pub fn framework(&self) -> &Framework {
        &self.framework
    }

    /// D.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// N, every agent of the formation (also in one agent's model).
    pub fn agents(&self) -> usize {
        self.agents
    }

    /// The directed edges it covers, in incidence order.
    pub fn edges(&self) -> &[(usize, usize)] {
        &self.edges
    }

    /// Per agent, the range of its edges in [`Model::edges`] (the columns of `B_i`).
    pub fn agent_edges(&self) -> &[Range<usize>] {
        &self.agent_edges
    }

    /// Q (ND × ND).
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }

    /// `R_ij` per directed edge of [`Model::edges`] (the covariance of one sample).
    pub fn r(&self) -> &[DMatrix<f64>] {
        &self.r
    }

    /// `R_ij` of every directed edge of the formation (also in one agent's model: what an
    /// agent knows of the formation, e.g. for a basis common to every edge).
    pub fn formation_r(&self) -> &[DMatrix<f64>] {
        &self.formation_r
    }

    /// P, the covariance of each initial position.
    pub fn p(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// Δt.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The AR model of the inputs (thesis chapter 6), if the scenario has one.
    pub fn ar(&self) -> Option<&ArModel> {
        self.ar.as_ref()
    }

    /// The scenario-wide default link-failure probability of chapter 6 (`comm.p_fail`).
    pub fn p_fail(&self) -> f64 {
        self.p_fail
    }

    /// Whether measurements can be missing (availability < 1, lost edges, departures).
    pub fn measurement_faults(&self) -> bool {
        self.measurement_faults
    }

    /// The edge of [`Model::edges`] whose covariance `edge_cov_trace` reports
    /// (`[metrics] edge`).
    pub fn metric_edge(&self) -> Option<usize> {
        self.metric_edge
    }

    /// Number of directed edges it covers.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// `R_ij / T` per edge: the covariance of the measurement mean.
    pub fn mean_cov(&self, samples: usize) -> Vec<DMatrix<f64>> {
        self.r.iter().map(|r| r / samples as f64).collect()
    }

    /// The D × D block `(a, b)` of Q.
    pub fn q_block(&self, a: usize, b: usize) -> DMatrix<f64> {
        let d = self.dim;
        self.q.view((a * d, b * d), (d, d)).into_owned()
    }

    /// Cross-covariance of the process noise of edges `e` and `f`: block `(e, f)` of
    /// `B̄ᵀ Q B̄` (thesis 5.9 / 4.26).
    pub fn edge_q(&self, e: usize, f: usize) -> DMatrix<f64> {
        let (a, b) = self.edges[e];
        let (c, d) = self.edges[f];
        self.q_block(a, c) - self.q_block(a, d) - self.q_block(b, c) + self.q_block(b, d)
    }

    /// Initial cross-covariance of edges `e` and `f`: block `(e, f)` of `BᵀB ⊗ P`
    /// (thesis 5.7 / 4.28).
    pub fn edge_p0(&self, e: usize, f: usize) -> DMatrix<f64> {
        let (a, b) = self.edges[e];
        let (c, d) = self.edges[f];
        let ind = |x: usize, y: usize| f64::from(u8::from(x == y));
        &self.p * (ind(a, c) - ind(a, d) - ind(b, c) + ind(b, d))
    }
}
