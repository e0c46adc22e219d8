//! The stages every estimator of a chunk shares at step k, before estimation: the world's draws
//! and targets, the faults, and the measurement noise (common random numbers: every estimator's
//! closed loop sees the same draws, so their comparison is paired).
//!
//! [`Shared::advance`] is the papers' step up to the measurements, in the order the
//! reproducibility contract fixes (see [`super::world`]): draws → process noise `w_k = C_Q ξ_k`
//! → targets `Z*(t_k)`, `Z*(t_{k+1})` → faults → measurement-mean noise `v̄_k`.

use std::ops::Range;

use super::faults::FaultStage;
use super::sensing::{MeasNoise, Sensing};
use super::world::{departure_subsets, Factor, Targets, World};
use crate::control::maneuver::Trajectory;
use crate::control::LeaderMode;
use crate::scenario::{InitAround, Scenario};

/// The shared stages of a chunk of runs.
#[derive(Clone)]
pub(crate) struct Shared<'a> {
    pub(crate) world: World,
    q_factor: Factor,
    /// Process noise `w_k` (N·D rows × runs); zero when Q = 0.
    pub(crate) w: Vec<f64>,
    pub(crate) faults: FaultStage,
    pub(crate) sensing: Sensing,
    r_active: bool,
    traj: Option<&'a dyn Trajectory>,
    pub(crate) targets: Option<Targets>,
    config: &'a [f64],
    d: usize,
    dt: f64,
    /// The chunk's first run (global index).
    first_run: usize,
}

/// Per run of `range`, the followers of `sc` that depart at random (none without).
fn random_departures(sc: &Scenario, range: Range<usize>) -> Vec<Vec<usize>> {
    match sc.faults().random_departures {
        Some((count, _)) if count > 0 => {
            let fw = sc.framework();
            let followers: Vec<usize> = (0..fw.agents())
                .filter(|i| !fw.leaders().contains(i))
                .collect();
            departure_subsets(sc.seed(), range, &followers, count)
        }
        _ => vec![Vec::new(); range.len()],
    }
}

impl<'a> Shared<'a> {
    /// The stages of runs `range` of `sc`, and the initial positions `z_1` they drew
    /// (N·D rows × runs).
    pub(crate) fn new(sc: &'a Scenario, range: Range<usize>) -> (Self, Vec<f64>) {
        let fw = sc.framework();
        let model = sc.model();
        let d = fw.dim();
        let (n, m) = (fw.agents(), fw.graph().num_edges());
        let runs = range.len();
        let q_factor = Factor::of(model.q(), d);
        let r_active = model.r().iter().any(|r| r.iter().any(|&v| v != 0.0));
        let comm_active = sc.estimators().iter().any(|e| {
            e.config()
                .link_failure()
                .is_some_and(|p| p > 0.0 && p < 1.0)
        });
        let plan = sc.faults();
        let avail_active = plan.availability > 0.0 && plan.availability < 1.0;
        let first_run = range.start;
        let mut world = World::new(
            sc.seed(),
            range.clone(),
            m,
            m * d,
            n * d,
            r_active,
            !q_factor.is_zero(),
            comm_active,
            avail_active,
        );
        let mut z0 = vec![0.0; n * d * runs];
        world.initial_positions(sc.init_mean(), model.p(), &mut z0);
        let random = random_departures(sc, range);
        let faults = FaultStage::new(plan, n, fw.graph().edges(), runs, random, comm_active);
        let mut t_values: Vec<usize> = sc.estimators().iter().map(|e| e.samples()).collect();
        t_values.sort_unstable();
        t_values.dedup();
        let sensing = Sensing::new(model.r(), d, t_values, runs);
        let traj = sc.trajectory();
        let mut shared = Shared {
            world,
            q_factor,
            w: vec![0.0; n * d * runs],
            faults,
            sensing,
            r_active,
            traj,
            targets: traj.map(|_| Targets::new(n, d)),
            config: fw.config(),
            d,
            dt: sc.dt(),
            first_run,
        };
        shared.place_initial(sc, &mut z0);
        (shared, z0)
    }

    /// From now on, the random departures of `sc` (a value of a sweep that shared the steps
    /// before them with other values: [`super::fork`]).
    pub(crate) fn set_departures(&mut self, sc: &Scenario) {
        let range = self.first_run..self.first_run + self.world.runs();
        self.faults
            .set_departures(sc.faults(), random_departures(sc, range));
    }

    /// Step 1's target, leaders that track it placed on it, and the start shifted to each
    /// agent's place with `init.around = "target"`.
    fn place_initial(&mut self, sc: &Scenario, z0: &mut [f64]) {
        let fw = sc.framework();
        let (d, runs) = (self.d, self.world.runs());
        let target_leaders = self.traj.is_some() && self.target_leaders(sc);
        if let (Some(t), Some(tg)) = (self.traj, self.targets.as_mut()) {
            tg.update(t, self.config, d, 1, self.dt);
            if target_leaders {
                crate::control::pin_leaders(z0, fw.leaders(), &tg.now.positions, d, runs);
            }
        }
        if sc.init_around() == InitAround::Target {
            // Around each agent's place: its target at step 1, else its configuration point
            // (the draws are those of a start around the origin, shifted).
            let place = self
                .targets
                .as_ref()
                .map_or(fw.config(), |tg| &tg.now.positions[..]);
            for (row, &p) in place.iter().enumerate() {
                if target_leaders && fw.leaders().contains(&(row / d)) {
                    continue; // already on the target
                }
                for v in &mut z0[row * runs..(row + 1) * runs] {
                    *v += p;
                }
            }
        }
    }

    /// Whether the leaders are set on the target (the scenario's leader mode).
    pub(crate) fn target_leaders(&self, sc: &Scenario) -> bool {
        matches!(sc.leader_mode(), Some(LeaderMode::Target))
    }

    /// The measurement-mean noise of T value `index` at this step (for [`EdgeStates::form`]).
    ///
    /// [`EdgeStates::form`]: super::sensing::EdgeStates::form
    pub(crate) fn meas_noise(&self, index: usize) -> MeasNoise<'_> {
        self.sensing
            .noise(index, &self.world.draws.eta, self.r_active)
    }

    /// World, faults and sensing of step `k`.
    pub(crate) fn advance(&mut self, k: usize) {
        let runs = self.world.runs();
        self.world.draw_step();
        if !self.q_factor.is_zero() {
            self.q_factor.apply(&self.world.draws.xi, &mut self.w, runs);
        }
        if let (Some(t), Some(tg)) = (self.traj, self.targets.as_mut()) {
            if k > 1 {
                tg.update(t, self.config, self.d, k, self.dt);
            }
        }
        self.faults
            .update(k, &self.world.draws.avail, &self.world.draws.comm);
        if self.r_active {
            self.sensing.update(&self.world.draws.eta);
        }
    }
}
