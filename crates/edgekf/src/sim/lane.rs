//! One estimator's closed loop over a chunk of runs: the papers' step after the shared stages
//! ([`super::stages`]) — sensing, estimation, the divergence policy, metrics, control and motion
//! — reading as thesis Algorithms 5–7.

use std::ops::Range;

use super::divergence::{self, Stop};
use super::frames::{FramePlan, FrameRecorder};
use super::metrics::{metrics_for, Measure, Metric};
use super::observe::{InputAutocov, LaneObserver, PathRecorder};
use super::sensing::{EdgeStates, MeasNoise};
use super::stages::Shared;
use super::{motion, LaneOut, Options};
use crate::control::{pin_leaders, ControlInput, Controller, LeaderMode};
use crate::estimate::{Estimator, Means, Reads, Step};
use crate::framework::Framework;
use crate::scenario::{EstimatorDef, Feedback, Scenario};

/// What every loop of a chunk reads and nobody changes.
pub(crate) struct Context<'a> {
    pub(crate) fw: &'a Framework,
    pub(crate) edges: &'a [(usize, usize)],
    pub(crate) d: usize,
    pub(crate) dt: f64,
    pub(crate) runs: usize,
    /// The chunk's first run (global index).
    pub(crate) first_run: usize,
    pub(crate) feedback: Feedback,
    pub(crate) target_leaders: bool,
    /// Whether agents can depart (then motion tests presence).
    pub(crate) faults_active: bool,
    /// The likely cause of a divergence, from the scenario.
    pub(crate) hint: String,
    /// The scenario's length scale, for the divergence bound.
    pub(crate) scale: f64,
    /// Divergence judged run by run ([`super::Options::per_run_divergence`]).
    pub(crate) per_run: bool,
}

impl<'a> Context<'a> {
    pub(crate) fn new(
        sc: &'a Scenario,
        sh: &Shared<'_>,
        range: &Range<usize>,
        per_run: bool,
    ) -> Self {
        let fw = sc.framework();
        Self {
            fw,
            edges: fw.graph().edges(),
            d: fw.dim(),
            dt: sc.dt(),
            runs: range.len(),
            first_run: range.start,
            feedback: sc.feedback(),
            target_leaders: sh.target_leaders(sc),
            faults_active: sc.faults().any(),
            hint: sc.divergence_hint(),
            scale: sc.length_scale(),
            per_run,
        }
    }
}

/// The report a step belongs to: `index` is the next report's index, `now` whether step k is it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct At {
    pub(crate) k: usize,
    pub(crate) index: usize,
    pub(crate) now: bool,
}

/// The loop's state, N·D or M·D rows × runs.
#[derive(Clone)]
struct State {
    z: Vec<f64>,
    u: Vec<f64>,
    u_next: Vec<f64>,
    du: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
}

/// One estimator's closed loop.
pub(crate) struct Lane {
    est: Box<dyn Estimator>,
    ctrl: Controller,
    /// Index of its T in the sensing stage.
    noise: usize,
    metrics: Vec<Box<dyn Metric>>,
    state: State,
    /// Per metric, `[report · runs + run]`.
    values: Vec<Vec<f64>>,
    stop: Option<Stop>,
    /// Per run of the chunk, whether it has diverged (only with per-run divergence).
    diverged: Vec<bool>,
    observers: Vec<Box<dyn LaneObserver>>,
}

impl Lane {
    /// The loop of estimator `def`, starting from `z0`; `record` is the chunk index of the run
    /// whose paths are kept, `frames` the frames the chunk records.
    pub(crate) fn new(
        sc: &Scenario,
        def: &EstimatorDef,
        sh: &Shared<'_>,
        z0: &[f64],
        (record, frames): (Option<usize>, Option<&FramePlan>),
        opt: Options,
    ) -> Self {
        let fw = sc.framework();
        let (d, runs) = (fw.dim(), sh.world.runs());
        let (nd, md) = (fw.agents() * d, fw.graph().num_edges() * d);
        let nr = sc.report_count();
        let metrics = metrics_for(sc, def);
        let mut observers: Vec<Box<dyn LaneObserver>> = Vec::new();
        if let Some(r) = record {
            observers.push(Box::new(PathRecorder::new(r, runs, nd, nr)));
        }
        if let Some(plan) = frames {
            let m = fw.graph().num_edges();
            observers.push(Box::new(FrameRecorder::new(
                plan,
                (fw.agents(), m, d),
                runs,
            )));
        }
        if opt.input_lags > 0 {
            observers.push(Box::new(InputAutocov::new(
                opt.input_lags,
                opt.input_from,
                d,
                nd,
                runs,
            )));
        }
        let leaders = sc.leader_mode().unwrap_or(LeaderMode::Target);
        Lane {
            est: def.config().build(sc.model(), def.samples(), runs),
            ctrl: Controller::new(fw, sc.law(), leaders, sc.dt(), runs),
            noise: sh.sensing.index_of(def.samples()),
            values: vec![vec![f64::NAN; nr * runs]; metrics.len()],
            metrics,
            state: State {
                z: z0.to_vec(),
                u: vec![0.0; nd * runs],
                u_next: vec![0.0; nd * runs],
                // NaN until formed: read only by an estimator that has them formed.
                du: vec![f64::NAN; md * runs],
                x: vec![f64::NAN; md * runs],
                y: vec![0.0; md * runs],
            },
            stop: None,
            diverged: vec![false; runs],
            observers,
        }
    }

    /// A copy of the loop as it stands, for a value of a sweep that goes on from here
    /// ([`super::fork`]): `sc` is the value's scenario (its metrics are rebuilt: they hold no
    /// state), `frames` whether the value keeps the frame recorder. `None` when the estimator
    /// cannot be copied ([`Estimator::fork`]).
    pub(crate) fn fork(&self, sc: &Scenario, def: &EstimatorDef, frames: bool) -> Option<Lane> {
        Some(Lane {
            est: self.est.fork()?,
            ctrl: self.ctrl.clone(),
            noise: self.noise,
            metrics: metrics_for(sc, def),
            state: self.state.clone(),
            values: self.values.clone(),
            stop: self.stop.clone(),
            diverged: self.diverged.clone(),
            observers: self
                .observers
                .iter()
                .filter(|o| frames || !o.records_frames())
                .map(|o| o.fork())
                .collect(),
        })
    }

    /// Whether the loop still runs (it has not diverged).
    pub(crate) fn running(&self) -> bool {
        self.stop.is_none()
    }

    /// Its estimator.
    pub(crate) fn estimator(&self) -> &dyn Estimator {
        self.est.as_ref()
    }

    /// Step k: sensing → estimation → (metrics at a report) → control → motion.
    pub(crate) fn step(&mut self, at: At, sh: &Shared<'_>, cx: &Context<'_>) {
        let Lane {
            est,
            state: s,
            metrics,
            values,
            observers,
            diverged,
            ..
        } = self;
        let (reads, noise) = (est.reads(), sh.meas_noise(self.noise));
        s.sense(reads, at, noise, cx);
        let targets = sh.targets.as_ref();
        let step = Step {
            k: at.k,
            dt: cx.dt,
            y: &s.y,
            means: if reads.means {
                Means::formed(&s.y, cx.d, cx.runs)
            } else {
                Means::raw(cx.edges, &s.z, noise, cx.d, cx.runs)
            },
            u_prev: &s.u,
            du: &s.du,
            faults: &sh.faults.out,
            truth: &s.x,
            target: targets.map(|t| &t.now),
        };
        est.step(&step);
        if let Some(b) = est.breakdown() {
            self.stop = Some(divergence::breakdown(
                b,
                at.k,
                at.index,
                cx.first_run,
                &cx.hint,
            ));
            return;
        }
        if at.now {
            // Metrics before control, as the papers plot x̂_{k|k} and z_k.
            let meas = Measure {
                step: &step,
                estimator: est.as_ref(),
                z: &s.z,
                framework: cx.fw,
                runs: cx.runs,
            };
            self.stop = if cx.per_run {
                measure_per_run(metrics, values, diverged, &meas, at, cx)
            } else {
                measure(metrics, values, &meas, at, cx)
            };
            if self.stop.is_some() {
                return;
            }
            for o in observers.iter_mut() {
                o.on_report(&s.z);
                o.on_measure(&meas);
            }
        }
        self.control(at, sh, cx);
    }

    /// `u_k` from the estimates (or the true edges), then the move to `z_{k+1}` and the leaders
    /// set on the next target.
    fn control(&mut self, at: At, sh: &Shared<'_>, cx: &Context<'_>) {
        let s = &mut self.state;
        let faults = &sh.faults.out;
        let next_target = sh.targets.as_ref().map(|t| t.next.positions.as_slice());
        let edges_in = match cx.feedback {
            Feedback::Estimates => self.est.estimates(),
            Feedback::Truth => &s.x,
        };
        let input = ControlInput {
            edges: edges_in,
            u_prev: &s.u,
            z: &s.z,
            next_target,
            faults,
        };
        self.ctrl.apply(&input, &mut s.u_next);
        std::mem::swap(&mut s.u, &mut s.u_next);
        for o in &mut self.observers {
            o.on_input(at.k, &s.u, at.now);
        }
        motion::advance(
            &mut s.z,
            &s.u,
            &sh.w,
            cx.dt,
            cx.faults_active.then_some(faults),
        );
        if let (true, Some(t)) = (cx.target_leaders, next_target) {
            pin_leaders(&mut s.z, cx.fw.leaders(), t, cx.d, cx.runs);
        }
    }

    /// The loop's output.
    pub(crate) fn finish(self) -> LaneOut {
        let mut out = LaneOut {
            values: self.values,
            stop: self.stop,
            paths: Vec::new(),
            inputs: Vec::new(),
            acov: Vec::new(),
            frames: Vec::new(),
            frame_targets: Vec::new(),
        };
        for o in self.observers {
            o.finish(&mut out);
        }
        out
    }
}

impl State {
    /// The sensing stage of step `at` for an estimator that reads `reads`: `ȳ` unless the
    /// estimator forms it, `x` for the estimator that reads it, the metrics of a report and a
    /// control law fed the true edges, `Δu` for the estimator that reads it.
    fn sense(&mut self, reads: Reads, at: At, noise: MeasNoise<'_>, cx: &Context<'_>) {
        let want = Reads {
            truth: reads.truth || at.now || cx.feedback == Feedback::Truth,
            ..reads
        };
        if cfg!(debug_assertions) {
            // Stale arrays read by an estimator that says it does not read them would go
            // unnoticed; NaN does not (the tests run the debug build).
            if !want.truth {
                self.x.fill(f64::NAN);
            }
            if !want.means {
                self.y.fill(f64::NAN);
            }
        }
        EdgeStates {
            x: &mut self.x,
            y: &mut self.y,
            du: &mut self.du,
        }
        .form(
            cx.edges, &self.z, &self.u, noise, want, cx.d, cx.dt, cx.runs,
        );
    }
}

/// Every metric at report `at.index` into `values`; the stop if one is non-finite.
pub(crate) fn measure(
    metrics: &[Box<dyn Metric>],
    values: &mut [Vec<f64>],
    meas: &Measure<'_>,
    at: At,
    cx: &Context<'_>,
) -> Option<Stop> {
    let mut stop = None;
    for (metric, vals) in metrics.iter().zip(values.iter_mut()) {
        let out = &mut vals[at.index * cx.runs..(at.index + 1) * cx.runs];
        metric.measure(meas, out);
        let at3 = (at.k, at.index, cx.first_run);
        if stop.is_none() {
            stop = divergence::non_finite(metric.name(), out, metric.partial(), at3, &cx.hint);
        }
        if let (None, Some(power)) = (&stop, metric.length_power()) {
            let bound = (power, cx.scale);
            stop = divergence::out_of_bound(metric.name(), out, bound, at3, &cx.hint);
        }
    }
    stop
}

/// [`measure`] judging divergence run by run: a run past the bound is marked diverged and its
/// metrics read `+∞` from this report on; a non-finite value of a diverged run is no stop. The
/// stop when a run not yet diverged turns non-finite, or when every run has diverged.
pub(crate) fn measure_per_run(
    metrics: &[Box<dyn Metric>],
    values: &mut [Vec<f64>],
    diverged: &mut [bool],
    meas: &Measure<'_>,
    at: At,
    cx: &Context<'_>,
) -> Option<Stop> {
    let mut stop = None;
    let mut last = None;
    for (metric, vals) in metrics.iter().zip(values.iter_mut()) {
        let out = &mut vals[at.index * cx.runs..(at.index + 1) * cx.runs];
        metric.measure(meas, out);
        for (r, v) in out.iter_mut().enumerate() {
            if diverged[r] {
                *v = f64::INFINITY;
                continue;
            }
            // One run at a time: its own index in the stop.
            let at3 = (at.k, at.index, cx.first_run + r);
            let one = std::slice::from_ref(v);
            if stop.is_none() {
                stop = divergence::non_finite(metric.name(), one, metric.partial(), at3, &cx.hint);
            }
            if let Some(power) = metric.length_power() {
                let bound = (power, cx.scale);
                if let Some(s) = divergence::out_of_bound(metric.name(), one, bound, at3, &cx.hint)
                {
                    diverged[r] = true;
                    *v = f64::INFINITY;
                    last = Some(s);
                }
            }
        }
    }
    // Values measured before a later metric marked the run: +∞ as well.
    for vals in values.iter_mut() {
        let out = &mut vals[at.index * cx.runs..(at.index + 1) * cx.runs];
        for (v, _) in out.iter_mut().zip(diverged.iter()).filter(|(_, &d)| d) {
            *v = f64::INFINITY;
        }
    }
    if diverged.iter().all(|&d| d) {
        return stop.or(last);
    }
    stop
}
