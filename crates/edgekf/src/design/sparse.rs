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
//!    penalised, so candidates that link the leaders keep those links (the distance-based
//!    leader law of thesis §3.5 needs them; a stress itself does not depend on who leads).
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
use super::ipm;
use super::sdp::{best_conditioned, conditioned, SdpSolver};
use super::Mode;
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
    let rel_tol = super::sdp::SdpOptions::default().rel_tol;
    // Step 1: the best conditioning on all candidates.
    let first = conditioned(
        &flat,
        candidate.dim,
        &links,
        &space,
        expected_rank,
        options.solver,
        rel_tol,
    )?;
    // Step 2: the ℓ1 problem, from a strictly feasible start.
    let is_leader_link =
        |&(i, j): &(usize, usize)| candidate.leaders.contains(&i) && candidate.leaders.contains(&j);
    let penalised: Vec<bool> = links.iter().map(|l| !is_leader_link(l)).collect();
    let (mode, y0) = l1_start(&space, &first.w, first.ratio, penalised, options.slack);
    let (y, l1_steps, l1_gap) = solve_l1(&space, mode, y0, options.solver)?;
    let w = &space.z * y.rows(0, space.z.ncols());
    let mut steps = first.iterations + l1_steps;
    // Step 3: threshold and polish, the threshold lowered tenfold at most three times.
    let wmax = w.amax();
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
                let best = best_conditioned(&sub, expected_rank, options.solver, rel_tol)?;
                Ok((sub, best))
            });
        match polished {
            Ok((sub, best)) => {
                steps += best.iterations;
                let f = sparse_finish(steps, best.solver, best.gap);
                return finish(candidate, &support, best.w.as_slice(), &sub, f);
            }
            Err(DesignError::NotUniversallyRigid(_) | DesignError::Graph(_)) => {
                threshold *= 0.1;
            }
            Err(e) => return Err(e),
        }
    }
    // The ℓ1 weights themselves are a valid stress on all candidates; return them if no
    // thresholded support could be certified (the gap is then the ℓ1 solve's).
    let f = sparse_finish(steps, first.solver, l1_gap);
    finish(candidate, &links, w.as_slice(), &space, f)
}

/// How a sparse design is finished: tiny weights dropped, normalised, named "sparse".
fn sparse_finish(newton_steps: usize, solver: &'static str, gap: f64) -> Finish {
    Finish {
        drop_rel: 1e-10,
        normalise: true,
        method: "sparse",
        newton_steps,
        solver,
        gap,
    }
}

/// The ℓ1 problem of step 2 (its spectrum band `[1, κ̄]`, `κ̄ = slack · max(κ*, κ_start)`) and
/// a strictly feasible start: the best-conditioned weights `w0` (ratio `kappa_best`) scaled so
/// that their spectrum `[λ_min, κ0 λ_min]` sits strictly inside the band (λ_min = √slack > 1 and
/// κ0 √slack < slack κ0 ≤ κ̄), each penalised link's bound `t_l = |w_l| + mean |w|`.
fn l1_start(
    space: &StressSpace,
    w0: &DVector<f64>,
    kappa_best: f64,
    penalised: Vec<bool>,
    slack: f64,
) -> (Mode, DVector<f64>) {
    let eig = space.spectrum(w0.as_slice());
    let lmin = eig[0];
    let kappa_start = eig[eig.len() - 1] / lmin;
    let kappa_bar = slack * kappa_best.max(kappa_start);
    let w_start = w0 * (slack.sqrt() / lmin);
    let m = space.z.ncols();
    let npen = penalised.iter().filter(|&&p| p).count();
    let mean_abs = w_start.iter().map(|v| v.abs()).sum::<f64>() / w_start.len() as f64;
    let mut y0 = DVector::zeros(m + npen);
    y0.rows_mut(0, m).copy_from(&(space.z.tr_mul(&w_start)));
    let mut k = 0;
    for (l, &p) in penalised.iter().enumerate() {
        if p {
            y0[m + k] = w_start[l].abs() + mean_abs;
            k += 1;
        }
    }
    let mode = Mode::L1 {
        kappa: kappa_bar,
        penalised,
    };
    (mode, y0)
}

/// Solves the ℓ1 problem from `y0`: the solution `(c, t)`, the solver's iterations and its
/// relative duality gap.
fn solve_l1(
    space: &StressSpace,
    mode: Mode,
    y0: DVector<f64>,
    solver: SdpSolver,
) -> Result<(DVector<f64>, usize, f64), DesignError> {
    match solver {
        SdpSolver::Ipm => {
            // Every iterate is a strictly feasible stress with spectrum in [1, κ̄], so a solve
            // that stops short of the tolerance still gives a valid (less sparse) support.
            let out = ipm::solve_robust(space, mode, y0, |lo, up| up - lo <= 1e-7 * lo.abs())?;
            let gap = (out.upper - out.lower) / out.lower.abs().max(f64::MIN_POSITIVE);
            Ok((out.y, out.iterations, gap))
        }
        #[cfg(feature = "clarabel")]
        SdpSolver::Clarabel => {
            // Clarabel's default gap tolerance, 1e-8 relative to max(1, ℓ1 norm): at least as
            // tight as the IPM's 1e-7 relative.
            let (m, npen) = (space.z.ncols(), y0.len() - space.z.ncols());
            let out = conic::solve(space, &mode, 1e-8)?;
            let gap = out.gap / out.x.rows(m, npen).sum().abs().max(f64::MIN_POSITIVE);
            Ok((out.x, out.iterations, gap))
        }
    }
}
