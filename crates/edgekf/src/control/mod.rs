//! Formation control on estimated edges: the followers' affine laws and the leaders.
//!
//! Followers (Li & Rajan Table 1; thesis eq. 3.2), each agent using only the estimates of its own
//! edges `ẑ_ij`:
//! - **static**: `u_i = −c Σ_{j ∈ N_i} l_ij ẑ_ij` (thesis 3.2; EUSIPCO eq. 2 drops the minus
//!   sign), with `L = B diag(w) Bᵀ` designed for the configuration and gain `c`;
//! - **pi** (constant-velocity leaders): `u_i = −α Σ_j l_ij ẑ_ij − η Σ_{τ=0}^{k} Σ_j l_ij ẑ_ij(τ)`,
//!   the sum over steps as printed (no Δt), so `η` is per step;
//! - **varying-velocity** (Zhao 2018): `u_i = −(1/γ_i) Σ_j l_ij (ẑ_ij − ż_j)`, `γ_i = Σ_j l_ij`,
//!   with the neighbour's velocity `ż_j` its previous input, received by communication.
//!
//! Leaders:
//! - **distance** (thesis §3.5): the `D + 1` leaders form a complete subgraph and follow the
//!   distance-based gradient law `u_i = −k Σ_{j ∈ leaders} (‖ẑ_ij‖² − d_ij²) ẑ_ij` with
//!   `d_ij = ‖p_i − p_j‖` (Dimarogonas & Johansson, ACC 2009; almost-global convergence for
//!   K_{D+1} formations: Park, Sun, Anderson & Ahn, IEEE TAC 2018). The leaders converge to a
//!   congruent simplex, and with it the followers to a congruent copy of the configuration
//!   (thesis Theorem 3.3).
//! - **target** (Li & Rajan §II-C): the leaders know the target `Z*(t)` and are set on it every
//!   step; they need not be linked to each other. Their input is the target's displacement
//!   `(z*_{i,k+1} − z_{i,k}) / Δt`.
//!
//! A departed agent does not move (`u_i = 0`).

pub mod laws;
pub mod maneuver;

use crate::framework::Framework;
use crate::linalg::with_avx2;
use crate::step::Faults;

/// The followers' control law (Li & Rajan Table 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FollowerLaw {
    /// `u_i = −c Σ_j l_ij ẑ_ij`.
    Static {
        /// The gain `c`.
        gain: f64,
    },
    /// `u_i = −α Σ_j l_ij ẑ_ij − η Σ_τ Σ_j l_ij ẑ_ij(τ)`.
    Pi {
        /// Proportional gain α.
        alpha: f64,
        /// Integral gain η (per step).
        eta: f64,
    },
    /// `u_i = −(1/γ_i) Σ_j l_ij (ẑ_ij − ż_j)` (Zhao 2018).
    VaryingVelocity,
}

/// How the leaders move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LeaderMode {
    /// The distance-based law among the (mutually linked) leaders, with gain `k`.
    Distance {
        /// The gain `k`.
        gain: f64,
    },
    /// Set on the target each step.
    Target,
}

/// Sets target-tracking leaders on their target: `z_i = z*_i` for every run (N·D rows × runs,
/// runs innermost; `target` agent-major). Li & Rajan §II-C: the leaders know `Z*(t)`.
pub fn pin_leaders(z: &mut [f64], leaders: &[usize], target: &[f64], d: usize, runs: usize) {
    for &i in leaders {
        for a in 0..d {
            z[(i * d + a) * runs..(i * d + a + 1) * runs].fill(target[i * d + a]);
        }
    }
}

/// The role of an agent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Follower,
    Leader,
}

/// The closed-loop controller of all agents, for a batch of runs in lockstep (ND rows × runs).
#[derive(Debug, Clone)]
pub struct Controller {
    dim: usize,
    runs: usize,
    dt: f64,
    agents: Vec<(std::ops::Range<usize>, Role)>,
    edges: Vec<(usize, usize)>,
    /// `l_e` per directed edge.
    weights: Vec<f64>,
    /// `γ_i = Σ_j l_ij` per agent.
    gamma: Vec<f64>,
    /// Per edge: `Some(d²)` when both ends are leaders.
    leader_d2: Vec<Option<f64>>,
    law: FollowerLaw,
    leaders: LeaderMode,
    /// PI integrator `Σ_τ Σ_j l_ij ẑ_ij(τ)` (ND × runs).
    integral: Vec<f64>,
    scratch: Vec<f64>,
}

/// What the controller reads at a step.
#[derive(Debug, Clone, Copy)]
pub struct ControlInput<'a> {
    /// The edges it acts on (estimates, or the true edges with `feedback = "truth"`), MD rows.
    pub edges: &'a [f64],
    /// The inputs of the previous step (ND rows): the neighbours' velocities of the
    /// varying-velocity law.
    pub u_prev: &'a [f64],
    /// The positions now (ND rows), for target-tracking leaders.
    pub z: &'a [f64],
    /// The target positions at the next step (agent-major), for target-tracking leaders.
    pub next_target: Option<&'a [f64]>,
    /// Who is present.
    pub faults: &'a Faults,
}

impl Controller {
    /// For a framework, laws and Δt, for `runs` runs in lockstep.
    pub fn new(
        fw: &Framework,
        law: FollowerLaw,
        leaders: LeaderMode,
        dt: f64,
        runs: usize,
    ) -> Self {
        let g = fw.graph();
        let is_leader = |a: usize| fw.leaders().contains(&a);
        let leader_d2 = g
            .edges()
            .iter()
            .map(|&(i, j)| {
                (is_leader(i) && is_leader(j)).then(|| {
                    fw.point(i)
                        .iter()
                        .zip(fw.point(j))
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                })
            })
            .collect();
        let weights = fw.edge_weights();
        let gamma = (0..g.agents())
            .map(|i| g.edges_of(i).map(|e| weights[e]).sum())
            .collect();
        Self {
            dim: fw.dim(),
            runs,
            dt,
            agents: (0..g.agents())
                .map(|i| {
                    (
                        g.edges_of(i),
                        if is_leader(i) {
                            Role::Leader
                        } else {
                            Role::Follower
                        },
                    )
                })
                .collect(),
            edges: g.edges().to_vec(),
            weights,
            gamma,
            leader_d2,
            law,
            leaders,
            integral: if matches!(law, FollowerLaw::Pi { .. }) {
                vec![0.0; g.agents() * fw.dim() * runs]
            } else {
                Vec::new()
            },
            scratch: vec![0.0; runs],
        }
    }

    /// Δt.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The leaders' mode.
    pub fn leader_mode(&self) -> LeaderMode {
        self.leaders
    }

    /// Computes `u` (ND rows × runs).
    pub fn apply(&mut self, input: &ControlInput<'_>, u: &mut [f64]) {
        let dr = self.dim * self.runs;
        for (i, ui) in u.chunks_exact_mut(dr).enumerate() {
            self.apply_agent(i, input, 0, ui);
        }
    }

    /// Computes agent `i`'s input `u_i` (D rows × runs) from the edges it owns: `input.edges`
    /// holds the edges of [`crate::estimate::Model::edges`] from edge `first` on (0 for every
    /// agent's edges; agent `i`'s first edge when the input holds only its edges). The same
    /// arithmetic as [`Controller::apply`], so an agent that computes its own input reproduces
    /// the engine bit for bit.
    pub fn apply_agent(
        &mut self,
        i: usize,
        input: &ControlInput<'_>,
        first: usize,
        ui: &mut [f64],
    ) {
        // Element-wise products and sums over the runs, no fused multiply–add: AVX2 gives the
        // bits of the portable code.
        with_avx2(
            #[inline(always)]
            || self.agent_input(i, input, first, ui),
        );
    }

    /// The body of [`Controller::apply_agent`].
    #[inline(always)]
    fn agent_input(&mut self, i: usize, input: &ControlInput<'_>, first: usize, ui: &mut [f64]) {
        let (d, r) = (self.dim, self.runs);
        ui.fill(0.0);
        let (range, role) = self.agents[i].clone();
        let edges = |e: usize| &input.edges[(e - first) * d * r..(e - first + 1) * d * r];
        match (role, self.leaders) {
            (Role::Leader, LeaderMode::Target) => {
                if let Some(t) = input.next_target {
                    for k in 0..d {
                        let zk = &input.z[(i * d + k) * r..(i * d + k + 1) * r];
                        for (uv, z) in ui[k * r..(k + 1) * r].iter_mut().zip(zk) {
                            *uv = (t[i * d + k] - z) / self.dt;
                        }
                    }
                }
            }
            (Role::Leader, LeaderMode::Distance { gain }) => {
                for e in range {
                    let Some(d2) = self.leader_d2[e] else {
                        continue;
                    };
                    let xe = edges(e);
                    // s = ‖ẑ‖² − d² per run.
                    self.scratch.fill(-d2);
                    for k in 0..d {
                        for (s, x) in self.scratch.iter_mut().zip(&xe[k * r..(k + 1) * r]) {
                            *s += x * x;
                        }
                    }
                    for k in 0..d {
                        for ((uv, x), s) in ui[k * r..(k + 1) * r]
                            .iter_mut()
                            .zip(&xe[k * r..(k + 1) * r])
                            .zip(self.scratch.iter())
                        {
                            *uv -= gain * s * x;
                        }
                    }
                }
            }
            (Role::Follower, _) => self.follower(i, range, &edges, input.u_prev, ui),
        }
        if input.faults.measurement_faults() {
            for run in 0..r {
                if !input.faults.present(i, run) {
                    for k in 0..d {
                        ui[k * r + run] = 0.0;
                    }
                }
            }
        }
    }

    /// A follower's law from its edges `range` (read through `edges`).
    #[inline(always)]
    fn follower<'e>(
        &mut self,
        i: usize,
        range: std::ops::Range<usize>,
        edges: &dyn Fn(usize) -> &'e [f64],
        u_prev: &[f64],
        ui: &mut [f64],
    ) {
        let dr = self.dim * self.runs;
        // Σ_j l_ij ẑ_ij into ui (negated below).
        for e in range.clone() {
            let l = self.weights[e];
            for (uv, x) in ui.iter_mut().zip(edges(e)) {
                *uv += l * x;
            }
        }
        match self.law {
            FollowerLaw::Static { gain } => {
                for uv in ui.iter_mut() {
                    *uv *= -gain;
                }
            }
            FollowerLaw::Pi { alpha, eta } => {
                let integ = &mut self.integral[i * dr..(i + 1) * dr];
                for (uv, iv) in ui.iter_mut().zip(integ.iter_mut()) {
                    *iv += *uv;
                    *uv = -alpha * *uv - eta * *iv;
                }
            }
            FollowerLaw::VaryingVelocity => {
                // − (1/γ_i) (Σ_j l_ij ẑ_ij − Σ_j l_ij ż_j)
                for e in range {
                    let l = self.weights[e];
                    let j = self.edges[e].1;
                    let uj = &u_prev[j * dr..(j + 1) * dr];
                    for (uv, v) in ui.iter_mut().zip(uj) {
                        *uv -= l * v;
                    }
                }
                let g = self.gamma[i];
                for uv in ui.iter_mut() {
                    *uv = -*uv / g;
                }
            }
        }
    }
}
