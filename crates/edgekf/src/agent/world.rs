//! The simulated world of a swarm of agents: the true positions, the draws, the faults and the
//! noisy relative measurements each agent receives, and the motion under the inputs that come
//! back — the engine's stages ([`crate::sim`]) for one run, with the estimators replaced by
//! what the agents report. A robot on real hardware replaces exactly this.
//!
//! The world also computes the metrics (it alone knows the truth): from the agents' reports it
//! forms a [`Gathered`] view of each estimator — the estimates of every edge in incidence
//! order, `cov_trace` as the sum of the agents' parts, the per-agent quantities summarised as
//! the engine summarises them — and measures it with the engine's own metrics, so that the
//! swarm's `metrics.csv` is the engine's.

use super::messages::{LaneSensing, Output, Report, Sensing};
use super::reported_quantities;
use crate::control::pin_leaders;
use crate::estimate::{AgentStat, Estimator, Reads};
use crate::scenario::{Feedback, Scenario};
use crate::sim::divergence::{self, Stop};
use crate::sim::frames::{self, FrameRecorder};
use crate::sim::lane::{measure, At, Context};
use crate::sim::metrics::{metrics_for, Measure, Metric};
use crate::sim::observe::{LaneObserver, PathRecorder};
use crate::sim::sensing::EdgeStates;
use crate::sim::stages::Shared;
use crate::sim::{assemble, motion, Chunk, LaneOut, Options, Results};
use crate::step::{Means, Step};

/// One estimator's closed loop in the world.
struct WorldLane {
    metrics: Vec<Box<dyn Metric>>,
    z: Vec<f64>,
    /// The inputs of the previous step, as the agents sent them (held where one was missing).
    u: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    du: Vec<f64>,
    gathered: Gathered,
    values: Vec<Vec<f64>>,
    stop: Option<Stop>,
    observers: Vec<Box<dyn LaneObserver>>,
}

/// The world of a swarm: one run of the scenario.
pub struct World<'a> {
    sc: &'a Scenario,
    shared: Shared<'a>,
    cx: Context<'a>,
    lanes: Vec<WorldLane>,
    report: Vec<usize>,
    index: usize,
    k: usize,
    /// Each agent's first edge and number of edges.
    spans: Vec<(usize, usize)>,
    /// What the results keep beyond the metrics (the frames, [`World::record_frames`]).
    opt: Options,
}

impl<'a> World<'a> {
    /// The world of run 0 of `sc` (its draws are run 0's of `edgekf run`).
    pub fn new(sc: &'a Scenario) -> Self {
        let range = 0..1;
        let (shared, z0) = Shared::new(sc, range.clone());
        let cx = Context::new(sc, &shared, &range, false);
        let fw = sc.framework();
        let (n, d) = (fw.agents(), fw.dim());
        let (nd, md) = (n * d, fw.graph().num_edges() * d);
        let nr = sc.report_count();
        let record = (sc.paths_run() == 0).then_some(0);
        let lanes = sc
            .estimators()
            .iter()
            .map(|def| {
                let metrics = metrics_for(sc, def);
                let mut observers: Vec<Box<dyn LaneObserver>> = Vec::new();
                if let Some(r) = record {
                    observers.push(Box::new(PathRecorder::new(r, 1, nd, nr)));
                }
                WorldLane {
                    values: vec![vec![f64::NAN; nr]; metrics.len()],
                    metrics,
                    z: z0.clone(),
                    u: vec![0.0; nd],
                    x: vec![0.0; md],
                    y: vec![0.0; md],
                    du: vec![0.0; md],
                    gathered: Gathered::new(n, (md, d), reported_quantities(sc, def)),
                    stop: None,
                    observers,
                }
            })
            .collect();
        let spans = (0..n)
            .map(|i| {
                let r = fw.graph().edges_of(i);
                (r.start, r.len())
            })
            .collect();
        Self {
            sc,
            shared,
            cx,
            lanes,
            report: sc.report_steps(),
            index: 0,
            k: 0,
            spans,
            opt: Options::default(),
        }
    }

    /// Also record frames of the run (`frames.json`: the positions, the agents' edge estimates
    /// and their covariances at the reports `opt` chooses), as `edgekf run` does with `opt`.
    pub fn record_frames(&mut self, opt: Options) {
        self.opt = opt;
        let Some(plan) = frames::plan(self.sc, &(0..1), opt) else {
            return;
        };
        let fw = self.sc.framework();
        let size = (fw.agents(), fw.graph().num_edges(), fw.dim());
        for lane in &mut self.lanes {
            lane.observers
                .push(Box::new(FrameRecorder::new(&plan, size, 1)));
        }
    }

    /// The world of a live swarm, where agents can leave at any step ([`World::depart`]):
    /// presence is tracked every step (run the agents with `messages_lost`, so that their
    /// filters read it too).
    pub fn live(sc: &'a Scenario) -> Self {
        let mut w = Self::new(sc);
        w.shared.faults.track_presence();
        w.cx.faults_active = true;
        w
    }

    /// Agent `i` has left the formation (its process ended): from the next step it is absent —
    /// it does not move, and its edges and its neighbours' edges to it are not measured.
    pub fn depart(&mut self, i: usize) {
        self.shared.faults.depart(i);
    }

    /// Whether agent `i` is present at the current step.
    pub fn present(&self, i: usize) -> bool {
        self.shared.faults.out.present(i, 0)
    }

    /// Number of agents.
    pub fn agents(&self) -> usize {
        self.spans.len()
    }

    /// The step the world is at (0 before the first).
    pub fn step(&self) -> usize {
        self.k
    }

    /// Draws step k + 1 and returns what each agent senses.
    pub fn sense(&mut self) -> Vec<Sensing> {
        self.k += 1;
        let k = self.k;
        self.shared.advance(k);
        for (lane, def) in self.lanes.iter_mut().zip(self.sc.estimators()) {
            let noise = self
                .shared
                .meas_noise(self.shared.sensing.index_of(def.samples()));
            EdgeStates {
                x: &mut lane.x,
                y: &mut lane.y,
                du: &mut lane.du,
            }
            .form(
                self.cx.edges,
                &lane.z,
                &lane.u,
                noise,
                Reads::ALL,
                self.cx.d,
                self.cx.dt,
                1,
            );
        }
        let f = &self.shared.faults.out;
        let d = self.cx.d;
        let truth = self.sc.feedback() == Feedback::Truth;
        let n = self.spans.len();
        let present: Vec<bool> = (0..n).map(|i| f.present(i, 0)).collect();
        self.spans
            .iter()
            .enumerate()
            .map(|(i, &(first, deg))| Sensing {
                k,
                observed: (first..first + deg).map(|e| f.observed(e, 0)).collect(),
                comm: f.comm_row(first, deg),
                present: present.clone(),
                lanes: self
                    .lanes
                    .iter()
                    .map(|l| LaneSensing {
                        y: l.y[first * d..(first + deg) * d].to_vec(),
                        position: l.z[i * d..(i + 1) * d].to_vec(),
                        truth: if truth {
                            l.x[first * d..(first + deg) * d].to_vec()
                        } else {
                            Vec::new()
                        },
                    })
                    .collect(),
            })
            .collect()
    }

    /// The agents' outputs of the current step (`None` for an agent not heard: a departed one
    /// keeps still, a late one keeps its last input and report): the metrics at a reported
    /// step, then the motion to step k + 1.
    pub fn act(&mut self, outputs: &[Option<&Output>]) {
        let k = self.k;
        let at = At {
            k,
            index: self.index,
            now: self.report.get(self.index) == Some(&k),
        };
        let d = self.cx.d;
        for (l, lane) in self.lanes.iter_mut().enumerate() {
            if lane.stop.is_some() {
                continue;
            }
            if let Some(what) = first_breakdown(outputs, l) {
                let b = crate::estimate::Breakdown { what: what.into() };
                lane.stop = Some(divergence::breakdown(&b, k, at.index, 0, &self.cx.hint));
                continue;
            }
            for (i, o) in outputs.iter().enumerate() {
                let Some(lo) = o.and_then(|o| o.lanes.get(l)) else {
                    continue;
                };
                lane.u[i * d..(i + 1) * d].copy_from_slice(&lo.u);
                if let Some(r) = &lo.report {
                    lane.gathered.take(i, self.spans[i], d, r);
                }
            }
            if at.now {
                lane.measure(at, &self.shared, &self.cx);
                if lane.stop.is_some() {
                    continue;
                }
            }
            for o in &mut lane.observers {
                o.on_input(k, &lane.u, at.now);
            }
            let faults = &self.shared.faults.out;
            motion::advance(
                &mut lane.z,
                &lane.u,
                &self.shared.w,
                self.cx.dt,
                self.cx.faults_active.then_some(faults),
            );
            let next = self.shared.targets.as_ref().map(|t| &t.next.positions);
            if let (true, Some(t)) = (self.cx.target_leaders, next) {
                pin_leaders(&mut lane.z, self.cx.fw.leaders(), t, d, 1);
            }
        }
        self.index += usize::from(at.now);
    }

    /// The results, as `edgekf run --runs 1` gives them.
    pub fn results(self) -> Results {
        let lanes = self
            .lanes
            .into_iter()
            .map(|l| {
                let mut out = LaneOut {
                    values: l.values,
                    stop: l.stop,
                    paths: Vec::new(),
                    inputs: Vec::new(),
                    acov: Vec::new(),
                    frames: Vec::new(),
                    frame_targets: Vec::new(),
                };
                for o in l.observers {
                    o.finish(&mut out);
                }
                out
            })
            .collect();
        let parts = vec![Chunk { range: 0..1, lanes }];
        assemble(self.sc, 0..1, parts, self.opt)
    }
}

/// What the first agent (in id order) that reports a breakdown of estimator `l` says.
fn first_breakdown<'o>(outputs: &[Option<&'o Output>], l: usize) -> Option<&'o str> {
    outputs.iter().find_map(|o| {
        o.and_then(|o| o.lanes.get(l))
            .and_then(|lo| lo.breakdown.as_deref())
    })
}

impl WorldLane {
    /// Every metric at report `at.index` on the gathered view.
    fn measure(&mut self, at: At, sh: &Shared<'_>, cx: &Context<'_>) {
        let step = Step {
            k: at.k,
            dt: cx.dt,
            y: &self.y,
            means: Means::formed(&self.y, cx.d, cx.runs),
            u_prev: &self.u,
            du: &self.du,
            faults: &sh.faults.out,
            truth: &self.x,
            target: sh.targets.as_ref().map(|t| &t.now),
        };
        let meas = Measure {
            step: &step,
            estimator: &self.gathered,
            z: &self.z,
            framework: cx.fw,
            runs: 1,
        };
        self.stop = measure(&self.metrics, &mut self.values, &meas, at, cx);
        if self.stop.is_none() {
            for o in &mut self.observers {
                o.on_report(&self.z);
                o.on_measure(&meas);
            }
        }
    }
}

/// An estimator seen through its agents' reports: what the metrics read.
#[derive(Debug, Clone)]
struct Gathered {
    /// `x̂` of every edge, in incidence order.
    estimates: Vec<f64>,
    /// Each agent's part of `cov_trace`.
    cov: Vec<f64>,
    /// Each agent's quantities, in the order of `quantities`.
    values: Vec<Vec<Option<f64>>>,
    quantities: Vec<&'static str>,
    /// Every edge's covariance as its agent reported it, the upper triangle row by row (NaN:
    /// none), and D.
    covariances: Vec<f64>,
    d: usize,
}

impl Gathered {
    fn new(n: usize, (md, d): (usize, usize), quantities: Vec<&'static str>) -> Self {
        Self {
            estimates: vec![0.0; md],
            cov: vec![0.0; n],
            values: vec![Vec::new(); n],
            quantities,
            covariances: vec![f64::NAN; md / d * tri(d)],
            d,
        }
    }

    /// Agent i's report (its edges `span` = (first, count)).
    fn take(&mut self, i: usize, (first, deg): (usize, usize), d: usize, r: &Report) {
        if r.estimates.len() == deg * d {
            self.estimates[first * d..(first + deg) * d].copy_from_slice(&r.estimates);
        }
        self.cov[i] = r.cov_trace;
        self.values[i].clone_from(&r.quantities);
        let t = tri(d);
        if r.covariances.len() == deg * t {
            self.covariances[first * t..(first + deg) * t].copy_from_slice(&r.covariances);
        }
    }
}

/// Entries of a symmetric D × D matrix's upper triangle.
fn tri(d: usize) -> usize {
    d * (d + 1) / 2
}

impl Estimator for Gathered {
    fn step(&mut self, _s: &Step<'_>) {}

    fn estimates(&self) -> &[f64] {
        &self.estimates
    }

    /// As the edge's agent reported it at the last report.
    fn edge_covariance(&self, e: usize, _r: usize, out: &mut [f64]) -> bool {
        let d = self.d;
        let t = tri(d);
        let c = &self.covariances[e * t..(e + 1) * t];
        if c.iter().any(|v| v.is_nan()) {
            return false;
        }
        frames::unpack_upper(c, d, out);
        true
    }

    /// The sum of the present agents' parts, as the engine's filters give it (a departed
    /// agent's part is none; its last report stays in `cov` but does not count).
    fn cov_trace(&self, s: &Step<'_>, out: &mut [f64]) {
        let mut t = 0.0;
        for (i, c) in self.cov.iter().enumerate() {
            if s.faults.present(i, 0) {
                t += c;
            }
        }
        out[0] = t;
    }

    /// Summarised over the present agents, as [`crate::estimate::quantity_of_agents`] does.
    fn quantity(&self, name: &str, s: &Step<'_>, out: &mut [f64]) -> bool {
        let Some(q) = self.quantities.iter().position(|x| *x == name) else {
            return false;
        };
        let values = self.values.iter().enumerate().map(|(i, v)| {
            v.get(q)
                .copied()
                .flatten()
                .filter(|_| s.faults.present(i, 0))
        });
        out[0] = AgentStat::of(name).summarise(values);
        true
    }
}
