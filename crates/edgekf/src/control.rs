//! Formation control on estimated edges.
//!
//! - Followers: the affine formation law `u_i = −c Σ_{j ∈ N_i} l_ij ẑ_ij` (thesis eq. 3.2; the
//!   EUSIPCO eq. 2 drops the minus sign), with `L = B diag(w) Bᵀ` designed for the configuration.
//! - Leaders (`D + 1` agents forming a complete subgraph, thesis §3.5): the distance-based
//!   gradient law `u_i = −k Σ_{j ∈ leaders} (‖ẑ_ij‖² − d_ij²) ẑ_ij` with `d_ij = ‖p_i − p_j‖`
//!   (Dimarogonas & Johansson, ACC 2009; almost-global convergence for K_{D+1} formations: Park,
//!   Sun, Anderson & Ahn, IEEE TAC 2018). The leaders converge to a congruent simplex, and with it
//!   the followers to a congruent copy of the configuration (thesis Theorem 3.3).
//!
//! Each agent uses only the estimates of its *own* edges.

use crate::framework::Framework;

/// The closed-loop controller of all agents.
#[derive(Debug, Clone)]
pub struct Controller {
    dim: usize,
    runs: usize,
    /// Per agent: its edge range, and whether it is a leader.
    agents: Vec<(std::ops::Range<usize>, bool)>,
    /// `c · l_e` per directed edge.
    weights: Vec<f64>,
    /// Per edge: `Some(d²)` when both ends are leaders.
    leader_d2: Vec<Option<f64>>,
    leader_gain: f64,
    scratch: Vec<f64>,
}

impl Controller {
    /// For a framework, with gains, for `runs` runs in lockstep.
    pub fn new(fw: &Framework, follower_gain: f64, leader_gain: f64, runs: usize) -> Self {
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
        Self {
            dim: fw.dim(),
            runs,
            agents: (0..g.agents())
                .map(|i| (g.edges_of(i), is_leader(i)))
                .collect(),
            weights: fw
                .edge_weights()
                .iter()
                .map(|w| w * follower_gain)
                .collect(),
            leader_d2,
            leader_gain,
            scratch: vec![0.0; runs],
        }
    }

    /// Computes `u` (ND rows × runs) from the edge estimates `xhat` (MD rows × runs).
    pub fn apply(&mut self, xhat: &[f64], u: &mut [f64]) {
        let (d, r) = (self.dim, self.runs);
        u.fill(0.0);
        for (i, (range, leader)) in self.agents.iter().enumerate() {
            let ui = &mut u[i * d * r..(i + 1) * d * r];
            for e in range.clone() {
                let xe = &xhat[e * d * r..(e + 1) * d * r];
                if *leader {
                    let Some(d2) = self.leader_d2[e] else {
                        continue;
                    };
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
                            .zip(&self.scratch)
                        {
                            *uv -= self.leader_gain * s * x;
                        }
                    }
                } else {
                    let l = self.weights[e];
                    for (uv, x) in ui.iter_mut().zip(xe) {
                        *uv -= l * x;
                    }
                }
            }
        }
    }
}
