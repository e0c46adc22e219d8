//! ℓ1-penalised sparse stress design, in the spirit of Li, Leus & Rajan (EUSIPCO 2025): most
//! candidate links get zero weight, under the PSD / rank / equilibrium conditions.
//!
//! 1. Solve the conditioning SDP ([`super::sdp`]) on all candidate links: it certifies
//!    universal rigidity and gives the best achievable ratio `κ* = λ_max / λ_min` of `Q L Qᵀ`.
//! 2. Minimise the ℓ1 norm of the weights with the spectrum kept in a band:
//!    ```text
//!    min Σ_l |w_l|  s.t.  w = Z c,  I ⪯ Q L(w) Qᵀ ⪯ κ̄ I,   κ̄ = slack · κ*.
//!    ```
//!    The lower bound keeps the rank `N − D − 1` and fixes the scale (the convergence rate); the
//!    upper bound keeps the design from trading all of its conditioning for sparsity. `slack`
//!    is the one knob: larger means sparser and slower. Links among the leaders are not
//!    penalised (they must stay, Theorem 3.3).
//! 3. Links with `|w_l|` below `threshold · max |w|` are dropped; on the remaining support the
//!    conditioning SDP is solved again ("polish"), which re-certifies universal rigidity of the
//!    reduced graph and gives the best weights on it. If the support is too small (the polish
//!    finds no full-rank stress), the threshold is lowered tenfold, at most three times.
//!
//! # References
//! Z. Li, G. Leus, R. T. Rajan, "Fast multiagent formation stabilization with sparse universally
//! rigid frameworks", EUSIPCO 2025 (ref. \[26\] of Li & Rajan's GA-RKF paper).

use nalgebra::DVector;

#[cfg(feature = "clarabel")]
use super::conic;
use super::ipm::{self, Mode, Problem};
use super::sdp::{best_conditioned, conditioned, SdpSolver};
use super::{finish, validate, Candidate, Design, DesignError, Finish, StressSpace};
use crate::graph::Graph;

/// Options of [`design`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SparseOptions {
    /// `κ̄ / κ*`: how much worse than the best conditioning the sparse design may be (> 1).
    pub slack: f64,
    /// Relative weight below which a link is dropped.
    pub threshold: f64,
    /// Solver of the conditioning, ℓ1 and polishing SDPs.
    pub solver: SdpSolver,
}

impl Default for SparseOptions {
    fn default() -> Self {
        Self {
            // A factor 10 in λ_max/λ_min: convergence ≈ 10 × slower per unit step than the best
            // conditioned design on all candidates, still well-posed for Δt λ_max < 2.
            slack: 10.0,
            // The ℓ1 solve is stopped at a relative duality gap of 1e-7, so weights that the exact
            // optimum sets to zero come out ≲ 1e-6 of the largest; 1e-4 separates them safely.
            threshold: 1e-4,
            solver: SdpSolver::Ipm,
        }
    }
}

/// Designs sparse weights on the candidate links (see the module docs).
///
/// # Errors
/// As [`super::sdp::design`]; [`DesignError::Input`] for `slack ≤ 1` or a threshold outside
/// `(0, 1)`.
pub fn design(candidate: &Candidate, options: &SparseOptions) -> Result<Design, DesignError> {
    let valid = options.slack > 1.0 && options.threshold > 0.0 && options.threshold < 1.0;
    if !valid {
        return Err(DesignError::Input(format!(
            "sparse design needs slack > 1 and 0 < threshold < 1, got {} and {}",
            options.slack, options.threshold
        )));
    }
    let flat = validate(candidate)?;
    let n = candidate.config.len();
    let graph = Graph::new(n, &candidate.links)?;
    let links = graph.links().to_vec();
    let space = StressSpace::new(&flat, candidate.dim, &links)?;
    let expected_rank = n - candidate.dim - 1;
    let (w0, kappa0, steps0) = conditioned(
        &flat,
        candidate.dim,
        &links,
        &space,
        expected_rank,
        options.solver,
    )?;
    // Scale the start so that its spectrum [λ_min, κ0 λ_min] sits strictly inside [1, κ̄]:
    // λ_min = √slack > 1 and κ0 √slack < slack κ0 = κ̄.
    let eig = space.projected(w0.as_slice()).symmetric_eigen().eigenvalues;
    let lmin = eig.min();
    let kappa_start = eig.max() / lmin;
    let kappa_bar = options.slack * kappa0.max(kappa_start);
    let w_start = &w0 * (options.slack.sqrt() / lmin);
    let is_leader_link =
        |&(i, j): &(usize, usize)| candidate.leaders.contains(&i) && candidate.leaders.contains(&j);
    let penalised: Vec<bool> = links.iter().map(|l| !is_leader_link(l)).collect();
    let problem = Problem::new(
        &space,
        Mode::L1 {
            kappa: kappa_bar,
            penalised: penalised.clone(),
        },
    );
    let m = space.z.ncols();
    let npen = penalised.iter().filter(|&&p| p).count();
    let mean_abs = w_start.iter().map(|v| v.abs()).sum::<f64>() / links.len() as f64;
    let mut x0 = DVector::zeros(m + npen);
    x0.rows_mut(0, m)
        .copy_from(&(space.z.transpose() * &w_start));
    let mut k = 0;
    for (l, &p) in penalised.iter().enumerate() {
        if p {
            x0[m + k] = w_start[l].abs() + mean_abs;
            k += 1;
        }
    }
    let (x, l1_steps) = match options.solver {
        SdpSolver::Ipm => {
            let out = ipm::solve(&problem, x0, |x, gap| {
                gap <= 1e-7 * problem.objective(x).abs().max(f64::MIN_POSITIVE)
            })?;
            (out.x, out.newton_steps)
        }
        #[cfg(feature = "clarabel")]
        SdpSolver::Clarabel => {
            // Clarabel's default gap tolerance, 1e-8 relative to max(1, ℓ1 norm): at least as
            // tight as the IPM's 1e-7 relative.
            let mode = Mode::L1 {
                kappa: kappa_bar,
                penalised: penalised.clone(),
            };
            let out = conic::solve(&space, &mode, 1e-8)?;
            (out.x, out.iterations)
        }
    };
    let w = problem.weights(&x);
    let wmax = w.amax();
    let mut steps = steps0 + l1_steps;
    let mut threshold = options.threshold;
    for _ in 0..4 {
        let support: Vec<(usize, usize)> = links
            .iter()
            .zip(w.iter())
            .filter(|(l, wl)| wl.abs() > threshold * wmax || is_leader_link(l))
            .map(|(l, _)| *l)
            .collect();
        let polished = Graph::new(n, &support)
            .map_err(DesignError::from)
            .and_then(|_| StressSpace::new(&flat, candidate.dim, &support))
            .and_then(|sub| {
                let (ws, _, st) = best_conditioned(&sub, expected_rank, options.solver)?;
                Ok((sub, ws, st))
            });
        match polished {
            Ok((sub, ws, st)) => {
                steps += st;
                return finish(
                    candidate,
                    &support,
                    ws.as_slice(),
                    &sub,
                    Finish {
                        drop_rel: 1e-10,
                        normalise: true,
                        method: "sparse",
                        newton_steps: steps,
                    },
                );
            }
            Err(DesignError::NotUniversallyRigid(_) | DesignError::Graph(_)) => {
                threshold *= 0.1;
            }
            Err(e) => return Err(e),
        }
    }
    // The ℓ1 weights themselves are a valid stress on all candidates; return them if no
    // thresholded support could be certified.
    finish(
        candidate,
        &links,
        w.as_slice(),
        &space,
        Finish {
            drop_rel: 1e-10,
            normalise: true,
            method: "sparse",
            newton_steps: steps,
        },
    )
}
