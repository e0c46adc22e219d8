//! One agent of the formation as a library type, free of any transport: what a robot runs.
//!
//! An [`Agent`] is built from a checked scenario and its id. It runs, for every estimator of the
//! scenario, that estimator's filters of **its own edges only** (built on
//! [`Model::for_agent`]) and its own control law ([`Controller::apply_agent`]); it reads its
//! relative measurements ([`Sensing`], from the world or a robot's sensors) and its neighbours'
//! messages, and returns its input and the messages it sends ([`Output`], [`Exchange`]). The
//! arithmetic is the engine's, so N agents stepped in lockstep on the world's draws reproduce
//! `edgekf run` with one run bit for bit ([`lockstep`]; tested for every decentralised kind).
//!
//! A message that did not arrive is handled by the scenario's comm model, never by waiting: a
//! lost input `u^j_{k−1}` is predicted by the AR model where the estimator has one (`rkf-ar`,
//! `jrkf-ar`; the prediction also enters the input history, as a real agent has nothing
//! better), taken as zero by the filters of `rkf`, `rkf-zero`, `jrkf` (and held at its last
//! value for the varying-velocity law's neighbour velocity); GA-RKF leaves a neighbour it did
//! not hear out of its consensus and ψ and falls back on its geometric observation where the
//! measurement itself is missing. `crkf` (centralised) and `oracle` (reads the true edges) are
//! refused.
//!
//! # Protocol of step k
//! 1. [`Agent::begin`] with the world's [`Sensing`] and the neighbours' outputs of step k − 1
//!    (`None` where one was not heard): predicts and, for an estimator that exchanges within
//!    the step, returns this agent's [`Exchange`];
//! 2. [`Agent::finish`] with the neighbours' exchanges (`None` where not heard): updates,
//!    controls, and returns this agent's [`Output`].

mod lockstep;
pub mod messages;
mod world;

use crate::control::{ControlInput, Controller, LeaderMode};
use crate::estimate::{ArModel, Estimator, Model};
use crate::scenario::{EstimatorDef, Scenario};
use crate::sim::world::Targets;
use crate::step::{Faults, Means, Step};

pub use lockstep::{lockstep, LockstepError};
pub use messages::{Exchange, LaneOutput, LaneSensing, Output, Report, Sensing};
pub use world::World;

/// Why an agent cannot be built or stepped.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AgentError {
    /// The id is not an agent of the scenario.
    #[error("agent id {id} is out of range: the scenario has agents 0..{agents}")]
    NoSuchAgent {
        /// The id given.
        id: usize,
        /// N.
        agents: usize,
    },
    /// An estimator kind that cannot run on one agent.
    #[error("estimator `{label}` ({kind}) cannot run on agents: {why}")]
    NotDistributed {
        /// Its label.
        label: String,
        /// Its kind.
        kind: String,
        /// Why.
        why: &'static str,
    },
    /// A message of another step, agent or shape.
    #[error("agent {agent}: {what}")]
    BadMessage {
        /// The agent.
        agent: usize,
        /// What is wrong.
        what: String,
    },
}

/// The built-in metrics, which the world computes; every other metric of an estimator is a
/// quantity its agents report.
const WORLD_METRICS: &[&str] = &[
    "est_error",
    "est_error_sq",
    "cov_trace",
    "procrustes",
    "tracking_error",
];

/// The quantities agent i reports for estimator `def` (its metrics beyond the world's).
pub(crate) fn reported_quantities(sc: &Scenario, def: &EstimatorDef) -> Vec<&'static str> {
    sc.metrics_of(def)
        .into_iter()
        .filter(|m| !WORLD_METRICS.contains(m))
        .collect()
}

/// Refuses the kinds that cannot run on one agent.
fn check_distributed(def: &EstimatorDef) -> Result<(), AgentError> {
    let why = match def.kind() {
        "crkf" => "the CRKF is centralised: one filter of every edge, which no agent has",
        "oracle" => "the oracle reads the true edges, which no agent has",
        _ => return Ok(()),
    };
    Err(AgentError::NotDistributed {
        label: def.label().into(),
        kind: def.kind().into(),
        why,
    })
}

/// One estimator's closed loop on this agent.
struct AgentLane {
    est: Box<dyn Estimator>,
    ctrl: Controller,
    faults: Faults,
    quantities: Vec<&'static str>,
    /// Inputs of step k − 1 (N·D): its own, and its neighbours' as heard or predicted.
    u: Vec<f64>,
    /// Past inputs (newest first), for the AR prediction of a neighbour's lost input.
    hist: Vec<Vec<f64>>,
    ar: Option<ArModel>,
    /// Which agents were present at step k − 1 (the last sensing's presence): a neighbour
    /// absent then kept still, so its input `u^j_{k−1}` was zero.
    was_present: Vec<bool>,
    /// This step's measurement means, prediction increments, true edges (zero: unknown here),
    /// positions (its own row), and the input computed.
    y: Vec<f64>,
    du: Vec<f64>,
    truth: Vec<f64>,
    z: Vec<f64>,
    u_next: Vec<f64>,
    /// The true edges for the control law, with `feedback = "truth"` (from the world; empty
    /// otherwise).
    control_truth: Vec<f64>,
    stopped: bool,
    /// D.
    d: usize,
}

/// One agent of the formation.
pub struct Agent {
    id: usize,
    d: usize,
    dt: f64,
    /// Its edges `(i, j)` and the first one's index in the formation's incidence order.
    edges: Vec<(usize, usize)>,
    first: usize,
    lanes: Vec<AgentLane>,
    report_steps: Vec<usize>,
    next_report: usize,
    /// The scenario (for the maneuver's targets).
    sc: Scenario,
    targets: Option<Targets>,
    target_leader: bool,
    config: Vec<f64>,
    k: usize,
}

impl Agent {
    /// Agent `id` of scenario `sc`. With `messages_lost`, its neighbours' messages can be lost
    /// on their own (a real network): its filters then take the per-run path that reads what
    /// was heard; without, they run exactly as the engine's.
    ///
    /// # Errors
    /// [`AgentError::NoSuchAgent`] for an id out of range; [`AgentError::NotDistributed`] for
    /// `crkf` or `oracle`.
    pub fn new(sc: &Scenario, id: usize, messages_lost: bool) -> Result<Self, AgentError> {
        let fw = sc.framework();
        let n = fw.agents();
        if id >= n {
            return Err(AgentError::NoSuchAgent { id, agents: n });
        }
        let full = sc.model();
        let mut local = full.for_agent(id);
        if messages_lost {
            local = local.with_measurement_faults();
        }
        let lanes = sc
            .estimators()
            .iter()
            .map(|def| {
                check_distributed(def)?;
                Ok(AgentLane::new(sc, def, &local, messages_lost))
            })
            .collect::<Result<Vec<_>, AgentError>>()?;
        let range = full.agent_edges()[id].clone();
        Ok(Self {
            id,
            d: fw.dim(),
            dt: sc.dt(),
            edges: local.edges().to_vec(),
            first: range.start,
            lanes,
            report_steps: sc.report_steps(),
            next_report: 0,
            targets: sc.trajectory().map(|_| Targets::new(n, fw.dim())),
            sc: sc.clone(),
            target_leader: matches!(sc.leader_mode(), Some(LeaderMode::Target))
                && fw.leaders().contains(&id),
            config: fw.config().to_vec(),
            k: 0,
        })
    }

    /// Its id.
    pub fn id(&self) -> usize {
        self.id
    }

    /// The neighbours it measures and hears, `j` of its edges `(i, j)`, ascending.
    pub fn neighbours(&self) -> Vec<usize> {
        self.edges.iter().map(|&(_, j)| j).collect()
    }

    /// Whether some estimator exchanges messages within a step (then [`Agent::begin`] returns
    /// an [`Exchange`] to send before [`Agent::finish`]).
    pub fn exchanges(&mut self) -> bool {
        self.lanes.iter_mut().any(|l| l.est.exchange().is_some())
    }

    /// The first half of step k: takes the world's sensing and the neighbours' outputs of step
    /// k − 1 (`heard(j)`: `None` where not heard), predicts, and returns the message to send
    /// within the step (`None` when no estimator exchanges one).
    ///
    /// # Errors
    /// [`AgentError::BadMessage`] when the sensing is not of step k or does not fit the agent.
    pub fn begin<'o>(
        &mut self,
        sensing: &Sensing,
        heard: impl Fn(usize) -> Option<&'o Output>,
    ) -> Result<Option<Exchange>, AgentError> {
        self.check_sensing(sensing)?;
        let k = sensing.k;
        self.k = k;
        if let (Some(t), Some(tg)) = (self.sc.trajectory(), self.targets.as_mut()) {
            tg.update(t, &self.config, self.d, k, self.dt);
        }
        let first_step = k == 1;
        let mut any = false;
        let mut lanes_msg = Vec::with_capacity(self.lanes.len());
        for (l, lane) in self.lanes.iter_mut().enumerate() {
            lane.load(sensing, l, self.id, self.d);
            if !lane.stopped {
                lane.hear_inputs(&self.edges, l, first_step, &heard);
            }
            lanes_msg.push(lane.prepare(self.id, k, self.dt, self.targets.as_ref()));
            any |= lane.est.exchange().is_some();
        }
        Ok(any.then_some(Exchange {
            k,
            agent: self.id,
            lanes: lanes_msg,
        }))
    }

    /// The second half of step k: takes the neighbours' exchanges (`None` where not heard),
    /// updates, computes the inputs `u^i_k` and returns this agent's output.
    pub fn finish<'x>(&mut self, heard: impl Fn(usize) -> Option<&'x Exchange>) -> Output {
        let k = self.k;
        let report = self.report_steps.get(self.next_report) == Some(&k);
        self.next_report += usize::from(report);
        let next = self.targets.as_ref().map(|t| t.next.positions.clone());
        let lanes = self
            .lanes
            .iter_mut()
            .enumerate()
            .map(|(l, lane)| {
                let ctx = FinishCtx {
                    id: self.id,
                    k,
                    dt: self.dt,
                    d: self.d,
                    first: self.first,
                    edges: &self.edges,
                    targets: self.targets.as_ref(),
                    next_target: if self.target_leader {
                        next.as_deref()
                    } else {
                        None
                    },
                    report,
                };
                lane.finish(l, &ctx, &heard)
            })
            .collect();
        Output {
            k,
            agent: self.id,
            lanes,
        }
    }

    fn check_sensing(&self, s: &Sensing) -> Result<(), AgentError> {
        let bad = |what: String| AgentError::BadMessage {
            agent: self.id,
            what,
        };
        if s.k != self.k + 1 {
            return Err(bad(format!(
                "sensing of step {} where step {} was next",
                s.k,
                self.k + 1
            )));
        }
        let deg = self.edges.len();
        let comm_ok = s.comm.is_empty() || s.comm.len() == deg;
        let lanes_ok = s.lanes.len() == self.lanes.len()
            && s.lanes
                .iter()
                .all(|l| l.y.len() == deg * self.d && l.position.len() == self.d);
        if s.observed.len() != deg || !comm_ok || !lanes_ok {
            return Err(bad(format!(
                "sensing of step {} does not fit an agent with {deg} edges, {} estimators and D = {}",
                s.k,
                self.lanes.len(),
                self.d
            )));
        }
        Ok(())
    }
}

/// What [`AgentLane::finish`] reads.
struct FinishCtx<'a> {
    id: usize,
    k: usize,
    dt: f64,
    d: usize,
    first: usize,
    edges: &'a [(usize, usize)],
    targets: Option<&'a Targets>,
    next_target: Option<&'a [f64]>,
    report: bool,
}

impl AgentLane {
    fn new(sc: &Scenario, def: &EstimatorDef, local: &Model, lossy: bool) -> Self {
        let fw = sc.framework();
        let (n, d) = (fw.agents(), fw.dim());
        let deg = local.num_edges();
        let leaders = sc.leader_mode().unwrap_or(LeaderMode::Target);
        let mut faults = Faults::none(n, local.edges(), 1);
        {
            let p = faults.parts_mut();
            *p.measurement_faults = local.measurement_faults();
            *p.messages_lost = lossy;
            *p.hears = vec![true; deg];
            if def
                .config()
                .link_failure()
                .is_some_and(|p| p > 0.0 && p < 1.0)
            {
                *p.comm = vec![1.0; deg];
            }
        }
        let ar = def.config().link_failure().and(local.ar().cloned());
        AgentLane {
            est: def.config().build(local, def.samples(), 1),
            ctrl: Controller::new(fw, sc.law(), leaders, sc.dt(), 1),
            faults,
            quantities: reported_quantities(sc, def),
            u: vec![0.0; n * d],
            hist: vec![vec![0.0; n * d]; ar.as_ref().map_or(0, |a| a.order())],
            ar,
            was_present: vec![true; n],
            y: vec![0.0; deg * d],
            du: vec![0.0; deg * d],
            truth: vec![0.0; deg * d],
            z: vec![0.0; n * d],
            u_next: vec![0.0; d],
            control_truth: Vec::new(),
            stopped: false,
            d,
        }
    }

    /// This step's measurements, faults and own position.
    fn load(&mut self, s: &Sensing, l: usize, id: usize, d: usize) {
        let ls = &s.lanes[l];
        self.y.copy_from_slice(&ls.y);
        self.z[id * d..(id + 1) * d].copy_from_slice(&ls.position);
        self.control_truth.clone_from(&ls.truth);
        let p = self.faults.parts_mut();
        self.was_present.copy_from_slice(p.present);
        p.observed.copy_from_slice(&s.observed);
        p.present.copy_from_slice(&s.present);
        if !s.comm.is_empty() && !p.comm.is_empty() {
            p.comm.copy_from_slice(&s.comm);
        }
    }

    /// The neighbours' inputs of step k − 1: as heard, else predicted (AR) or held; then the
    /// prediction increments `Δt (u^i − u^j)` of its edges.
    fn hear_inputs<'o>(
        &mut self,
        edges: &[(usize, usize)],
        l: usize,
        first_step: bool,
        heard: &impl Fn(usize) -> Option<&'o Output>,
    ) {
        let d = self.z.len() / self.faults.agents();
        let exchanges = self.est.exchange().is_some();
        for (e, &(_, j)) in edges.iter().enumerate() {
            // At step 1 every input u_0 = 0 is known (thesis Alg. 8 line 8).
            let msg = if first_step {
                None
            } else {
                heard(j).and_then(|o| o.lanes.get(l))
            };
            let got = first_step || msg.is_some();
            if let Some(m) = msg {
                self.u[j * d..(j + 1) * d].copy_from_slice(&m.u);
            } else if !first_step && !self.was_present[j] {
                // Absent at step k − 1 (departed): it kept still, its input was zero — as the
                // engine's controller sets it for an absent agent, and as its filters then read
                // it (a departure of `[faults]` and a process that ended give the same bits).
                self.u[j * d..(j + 1) * d].fill(0.0);
            } else if !first_step {
                self.predict_input(j, d);
            }
            if !exchanges {
                let observed = self.faults.observed(e, 0);
                self.faults.parts_mut().hears[e] = observed && got;
            }
        }
        if !self.hist.is_empty() {
            self.hist.rotate_right(1);
            self.hist[0].copy_from_slice(&self.u);
        }
        let dt = self.dt_of();
        for (e, &(i, j)) in edges.iter().enumerate() {
            for a in 0..d {
                self.du[e * d + a] = dt * (self.u[i * d + a] - self.u[j * d + a]);
            }
        }
    }

    /// A lost `u^j_{k−1}`: the AR prediction `Σ_l a_l ∘ u^j_{k−1−l}` from what this agent heard
    /// or predicted before (as the estimator predicts it), else the last value held.
    fn predict_input(&mut self, j: usize, d: usize) {
        let Some(ar) = &self.ar else {
            return;
        };
        for a in 0..d {
            let mut v = 0.0;
            for (l, c) in ar.coeffs.iter().enumerate() {
                v += c[a] * self.hist[l][j * d + a];
            }
            self.u[j * d + a] = v;
        }
    }

    fn dt_of(&self) -> f64 {
        self.ctrl.dt()
    }

    /// Step k up to the in-step message: the whole step for an estimator that exchanges
    /// nothing; [`crate::estimate::Exchange::prepare`] and this agent's message otherwise.
    fn prepare(&mut self, id: usize, k: usize, dt: f64, targets: Option<&Targets>) -> Vec<f64> {
        if self.stopped {
            return Vec::new();
        }
        let step = Step {
            k,
            dt,
            y: &self.y,
            means: Means::formed(&self.y, self.d, 1),
            u_prev: &self.u,
            du: &self.du,
            faults: &self.faults,
            truth: &self.truth,
            target: targets.map(|t| &t.now),
        };
        match self.est.exchange() {
            Some(x) => {
                x.prepare(&step);
                let mut m = vec![0.0; x.message_len()];
                x.message(id, 0, &mut m);
                m
            }
            None => {
                self.est.step(&step);
                Vec::new()
            }
        }
    }

    /// The rest of step k: the neighbours' messages, the update, the report and the input.
    fn finish<'x>(
        &mut self,
        l: usize,
        cx: &FinishCtx<'_>,
        heard: &impl Fn(usize) -> Option<&'x Exchange>,
    ) -> LaneOutput {
        let d = cx.d;
        if self.stopped {
            return LaneOutput {
                u: vec![0.0; d],
                report: None,
                breakdown: None,
            };
        }
        self.exchange_in(l, cx, heard);
        let step = Step {
            k: cx.k,
            dt: cx.dt,
            y: &self.y,
            means: Means::formed(&self.y, self.d, 1),
            u_prev: &self.u,
            du: &self.du,
            faults: &self.faults,
            truth: &self.truth,
            target: cx.targets.map(|t| &t.now),
        };
        if let Some(b) = self.est.breakdown() {
            self.stopped = true;
            return LaneOutput {
                u: vec![0.0; d],
                report: None,
                breakdown: Some(b.what.clone()),
            };
        }
        let report = cx.report.then(|| {
            let mut trace = [0.0];
            self.est.cov_trace(&step, &mut trace);
            Report {
                estimates: self.est.estimates().to_vec(),
                cov_trace: trace[0],
                covariances: edge_covariances(self.est.as_ref(), self.y.len() / d, d),
                quantities: self
                    .quantities
                    .iter()
                    .map(|q| self.est.agent_quantity(q, cx.id, 0, &step))
                    .collect(),
            }
        });
        let edges = if self.control_truth.is_empty() {
            self.est.estimates()
        } else {
            &self.control_truth
        };
        let input = ControlInput {
            edges,
            u_prev: &self.u,
            z: &self.z,
            next_target: cx.next_target,
            faults: &self.faults,
        };
        self.ctrl
            .apply_agent(cx.id, &input, cx.first, &mut self.u_next);
        self.u[cx.id * d..(cx.id + 1) * d].copy_from_slice(&self.u_next);
        LaneOutput {
            u: self.u_next.clone(),
            report,
            breakdown: None,
        }
    }

    /// For an estimator that exchanges within the step: stores what was heard and finishes
    /// the step's update.
    fn exchange_in<'x>(
        &mut self,
        l: usize,
        cx: &FinishCtx<'_>,
        heard: &impl Fn(usize) -> Option<&'x Exchange>,
    ) {
        let AgentLane {
            est,
            faults,
            y,
            u,
            du,
            truth,
            ..
        } = self;
        let Some(x) = est.exchange() else {
            return;
        };
        for (e, &(_, j)) in cx.edges.iter().enumerate() {
            let msg = heard(j)
                .and_then(|m| m.lanes.get(l))
                .filter(|m| m.len() == x.message_len());
            if let Some(m) = msg {
                x.receive(j, 0, m);
            }
            let observed = faults.observed(e, 0);
            faults.parts_mut().hears[e] = observed && msg.is_some();
        }
        let step = Step {
            k: cx.k,
            dt: cx.dt,
            y,
            means: Means::formed(y, cx.d, 1),
            u_prev: u,
            du,
            faults,
            truth,
            target: cx.targets.map(|t| &t.now),
        };
        x.finish(&step);
    }
}

/// Every edge's posterior covariance of `est` (one run), the upper triangle row by row; NaN
/// where it has none (what a frame records).
fn edge_covariances(est: &dyn Estimator, edges: usize, d: usize) -> Vec<f64> {
    let mut cov = vec![0.0; d * d];
    let mut out = Vec::with_capacity(edges * d * (d + 1) / 2);
    for e in 0..edges {
        let has = est.edge_covariance(e, 0, &mut cov);
        crate::sim::frames::push_upper(has.then_some(cov.as_slice()), d, &mut out);
    }
    out
}
