//! The faults stage: which measurements and messages arrive and which agents are present, per
//! directed edge, run and step (Li & Rajan §III-A, thesis §6.1). Its output is the
//! [`Faults`](crate::estimate::Faults) every estimator of the run reads.
//!
//! Rules, in one place:
//! - a directed edge `(i, j)` is observed by agent `i` at step k when it is not permanently lost
//!   (`[faults] lost`), its availability draw is below λ (independently per direction and step;
//!   Li & Rajan S1–S2), and both agents are present;
//! - a departed agent (S3) stops moving, measuring and talking: every edge into or out of it is
//!   lost until it rejoins;
//! - one draw removes the measurement and the message together; the chapter 6 link failures of
//!   `rkf-ar`/`jrkf-ar` come on top, from their own uniforms (see
//!   [`Faults::input_arrives`](crate::estimate::Faults::input_arrives)).

use crate::estimate::Faults;
use crate::scenario::FaultPlan;

/// The faults of a chunk of runs.
#[derive(Debug, Clone)]
pub(crate) struct FaultStage {
    plan: FaultPlan,
    edges: Vec<(usize, usize)>,
    runs: usize,
    /// Per run: the randomly departing agents.
    random: Vec<Vec<usize>>,
    /// Per edge: permanently lost.
    lost: Vec<bool>,
    /// Per agent: left at a step no plan foresaw (a swarm's agent whose process ended).
    departed: Vec<bool>,
    pub(crate) out: Faults,
}

impl FaultStage {
    pub(crate) fn new(
        plan: &FaultPlan,
        agents: usize,
        edges: &[(usize, usize)],
        runs: usize,
        random: Vec<Vec<usize>>,
        comm_draws: bool,
    ) -> Self {
        let mut out = Faults::none(agents, edges, runs);
        {
            let p = out.parts_mut();
            *p.measurement_faults = plan.any();
            if comm_draws {
                *p.comm = vec![0.0; edges.len() * runs];
            }
        }
        let mut lost = vec![false; edges.len()];
        for &e in &plan.lost {
            lost[e] = true;
        }
        Self {
            plan: plan.clone(),
            edges: edges.to_vec(),
            runs,
            random,
            lost,
            departed: vec![false; agents],
            out,
        }
    }

    /// The plan `plan` and its random departures `random` (per run) from the next update on: a
    /// value of a sweep that shared the steps before its departures with other values.
    pub(crate) fn set_departures(&mut self, plan: &FaultPlan, random: Vec<Vec<usize>>) {
        self.plan = plan.clone();
        self.random = random;
    }

    /// From now on agents can leave at any step ([`FaultStage::depart`]): presence and the
    /// measurements' arrival are tracked every step.
    pub(crate) fn track_presence(&mut self) {
        *self.out.parts_mut().measurement_faults = true;
    }

    /// Agent `i` has left (from the next update on).
    pub(crate) fn depart(&mut self, i: usize) {
        self.departed[i] = true;
    }

    /// Updates the faults for step `k` from this step's uniforms (empty when not drawn).
    pub(crate) fn update(&mut self, k: usize, avail: &[f64], comm: &[f64]) {
        let runs = self.runs;
        let p = self.out.parts_mut();
        if !comm.is_empty() {
            p.comm.copy_from_slice(comm);
        }
        if !*p.measurement_faults {
            return;
        }
        // Presence.
        p.present.fill(true);
        for d in &self.plan.departures {
            if k >= d.from && k < d.until {
                p.present[d.agent * runs..(d.agent + 1) * runs].fill(false);
            }
        }
        for (a, gone) in self.departed.iter().enumerate() {
            if *gone {
                p.present[a * runs..(a + 1) * runs].fill(false);
            }
        }
        if let Some((_, at)) = self.plan.random_departures {
            if k >= at {
                for (r, agents) in self.random.iter().enumerate() {
                    for &a in agents {
                        p.present[a * runs + r] = false;
                    }
                }
            }
        }
        // Observations.
        let lambda = self.plan.availability;
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            let row = &mut p.observed[e * runs..(e + 1) * runs];
            if self.lost[e] || lambda <= 0.0 {
                row.fill(false);
                continue;
            }
            for (r, o) in row.iter_mut().enumerate() {
                *o = (lambda >= 1.0 || avail[e * runs + r] < lambda)
                    && p.present[i * runs + r]
                    && p.present[j * runs + r];
            }
        }
    }
}
