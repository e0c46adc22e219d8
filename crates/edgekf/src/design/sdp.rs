//! The thesis stress SDP (3.5), solved by the tailored interior-point method of `ipm` (default,
//! pure Rust) or, with the opt-in feature `clarabel`, by the Clarabel conic solver
//! ([`SdpSolver`]).
//!
//! Thesis (3.5) reads
//! ```text
//! max_w λ  s.t.  L = B diag(w) Bᵀ,  0 < λ < λ̄,  Q L Qᵀ ≻ λ I,  L q_i = 0 (i = 1..D).
//! ```
//! As printed it is degenerate: the constraints are homogeneous in `w`, so any feasible `w` can be
//! scaled until `λ = λ̄`, and every `w` with `λ_min(Q L Qᵀ) ≥ λ̄` is optimal — the "solution" is
//! whatever the solver happens to return, and its largest eigenvalue (which limits the step
//! `Δt < 2/λ_max` of the discrete loop) is uncontrolled. We therefore offer two bounded forms:
//!
//! - [`SdpObjective::Conditioning`] (**default**): `max s` s.t. `s I ⪯ Q L Qᵀ ⪯ I`, i.e. put the
//!   bound on `λ_max` instead of `λ`. By homogeneity this is `min λ_max / λ_min`, the same as
//!   `min t` s.t. `I ⪯ Q L Qᵀ ⪯ t I` (the form used to make the hexagon preset). It gives the
//!   fastest convergence for a given largest step `Δt λ_max`, has a unique optimal value, and
//!   its optimum `s* > 0` exists iff the framework is universally rigid (Theorem 3.2), so the
//!   same solve is the rigidity test: `s* ≤ 0` (numerically `≤ 1e-8`) rejects the graph.
//!   The output is scaled so that the smallest nonzero eigenvalue is 1.
//! - [`SdpObjective::ThesisGap`]: (3.5) literally, with the scaling fixed by a bound on the
//!   weights: `max λ` s.t. `λ I ⪯ Q L Qᵀ`, `λ ≤ λ̄`, `|w_l| ≤ w̄`. Output unscaled.
//!
//! Both are parametrised over the equilibrium stresses `w = Z c` (see [`super`]), which removes
//! the linearly dependent equality rows `L [P 1] = 0`.

use nalgebra::DVector;

#[cfg(feature = "clarabel")]
use super::conic;
use super::ipm::{self, Mode, Problem};
use super::{finish, validate, Candidate, Design, DesignError, Finish, StressSpace};

/// Which bounded form of thesis (3.5) to solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SdpObjective {
    /// `max s` s.t. `s I ⪯ Q L Qᵀ ⪯ I` (best conditioning); output scaled to gap 1.
    Conditioning,
    /// `max λ` s.t. `λ I ⪯ Q L Qᵀ`, `λ ≤ lambda_bar`, `|w_l| ≤ weight_bound`.
    ThesisGap {
        /// λ̄ of (3.5).
        lambda_bar: f64,
        /// Bound on every weight.
        weight_bound: f64,
    },
}

/// Which solver runs the stress SDPs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SdpSolver {
    /// The tailored log-barrier interior-point method (pure Rust, always available).
    #[default]
    Ipm,
    /// The Clarabel conic interior-point solver (feature `clarabel`; links the system
    /// BLAS/LAPACK).
    #[cfg(feature = "clarabel")]
    Clarabel,
}

/// Options of [`design`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdpOptions {
    /// Objective.
    pub objective: SdpObjective,
    /// Relative accuracy of the optimal value (duality gap over value).
    pub rel_tol: f64,
    /// Solver.
    pub solver: SdpSolver,
}

impl Default for SdpOptions {
    fn default() -> Self {
        Self {
            objective: SdpObjective::Conditioning,
            // 1e-6: the optimal eigenvalue ratio to six digits, far finer than any effect on
            // the closed loop.
            rel_tol: 1e-6,
            solver: SdpSolver::Ipm,
        }
    }
}

/// Clarabel's duality-gap tolerance for the conditioning SDP. Clarabel receives it in the form
/// `min t` s.t. `I ⪯ Q L Qᵀ ⪯ t I` (see `conic`), whose objective `t = κ* ≥ 1` makes its relative
/// gap a relative accuracy of the optimal ratio: the IPM's default 1e-6.
#[cfg(feature = "clarabel")]
pub(crate) const CLARABEL_GAP: f64 = 1e-6;

/// Largest eigenvalue ratio we accept as "nonzero": a stress with `λ_max / λ_min > 1e8` cannot
/// be told from a singular one by the rank test (relative tolerance 1e-9 N) of the checks.
pub const MAX_CONDITION: f64 = 1e8;

/// Result of the conditioning SDP on a stress space: weights `w` (in link order), the achieved
/// ratio `λ_max / λ_min` of `Q L Qᵀ`, and the Newton steps.
pub(crate) fn best_conditioned(
    space: &StressSpace,
    expected_rank: usize,
    solver: SdpSolver,
) -> Result<(DVector<f64>, f64, usize), DesignError> {
    if space.z.ncols() == 0 {
        return Err(DesignError::NotUniversallyRigid(
            "the graph carries no nonzero equilibrium stress (the only w with L(w) [P 1] = 0 is w = 0)"
                .into(),
        ));
    }
    let problem = Problem::new(space, Mode::Condition);
    let m = space.z.ncols();
    let mut x0 = DVector::zeros(m + 1);
    x0[m] = -1.0;
    let floor = 1.0 / MAX_CONDITION;
    let rel = SdpOptions::default().rel_tol;
    let (x, gap, steps) = match solver {
        SdpSolver::Ipm => {
            let out = ipm::solve(&problem, x0, |x, gap| {
                let s = x[m];
                (s > 0.0 && gap <= rel * s) || s + gap < floor
            })?;
            (out.x, out.gap, out.newton_steps)
        }
        #[cfg(feature = "clarabel")]
        SdpSolver::Clarabel => {
            // x = (c, t) with I ⪯ M(c) ⪯ t I: the same weights up to the scale 1/t, s = 1/t.
            let out = conic::solve(space, &Mode::Condition, CLARABEL_GAP)?;
            let mut x = out.x;
            let t = x[m];
            x /= t;
            x[m] = 1.0 / t;
            (x, out.gap / (t * t), out.iterations)
        }
    };
    let s = x[m];
    if s < floor {
        return Err(DesignError::NotUniversallyRigid(format!(
            "no positive semidefinite stress of rank N − D − 1 = {expected_rank} exists on this graph \
             (the best λ_min/λ_max of Q L Qᵀ is {:.1e} ≤ {floor:.0e})",
            (s + gap).max(0.0)
        )));
    }
    Ok((problem.weights(&x), 1.0 / s, steps))
}

/// [`best_conditioned`], with the closed-form optimum on complete graphs.
pub(crate) fn conditioned(
    flat: &[f64],
    dim: usize,
    links: &[(usize, usize)],
    space: &StressSpace,
    expected_rank: usize,
    solver: SdpSolver,
) -> Result<(DVector<f64>, f64, usize), DesignError> {
    let n = flat.len() / dim;
    if links.len() == n * (n - 1) / 2 {
        Ok((complete_graph_optimum(flat, dim, links), 1.0, 0))
    } else {
        best_conditioned(space, expected_rank, solver)
    }
}

/// The exact optimum of the conditioning SDP on a complete graph: every stress is allowed, so
/// `Q L Qᵀ = I` (ratio 1) is attained by `L = Qᵀ Q`, the projector onto the complement of
/// `span{1, q_1, …, q_D}`; `w_ij = −(Qᵀ Q)_ij`. (The interior-point method reaches the same
/// point, measured: ratio 1.000 after 51 Newton steps and 28 s for N = 50.)
fn complete_graph_optimum(flat: &[f64], dim: usize, links: &[(usize, usize)]) -> DVector<f64> {
    let (q, _) = super::complement_basis(&affine_basis(flat, dim));
    let proj = &q * q.transpose();
    DVector::from_iterator(links.len(), links.iter().map(|&(i, j)| -proj[(i, j)]))
}

/// `[1 P]` (N × (D + 1)).
fn affine_basis(flat: &[f64], dim: usize) -> nalgebra::DMatrix<f64> {
    let n = flat.len() / dim;
    nalgebra::DMatrix::from_fn(
        n,
        dim + 1,
        |i, c| if c == 0 { 1.0 } else { flat[i * dim + c - 1] },
    )
}

/// Designs the weights on the candidate links by the thesis SDP (3.5) (see the module docs for
/// the bounded forms). Links whose optimal weight is below 1e-10 of the largest are dropped.
///
/// # Errors
/// [`DesignError::NonGeneric`] for a degenerate configuration, [`DesignError::NotUniversallyRigid`]
/// when no PSD stress of rank `N − D − 1` exists on the candidate graph,
/// [`DesignError::Solver`] when the interior-point method fails, and graph/framework errors.
///
/// ```
/// use edgekf::design::{generators, sdp};
/// let c = generators::hexagon_candidate();
/// let d = sdp::design(&c, &sdp::SdpOptions::default()).unwrap();
/// assert!((d.framework.stress_gap() - 1.0).abs() < 1e-9);
/// ```
pub fn design(candidate: &Candidate, options: &SdpOptions) -> Result<Design, DesignError> {
    let flat = validate(candidate)?;
    let graph = crate::graph::Graph::new(candidate.config.len(), &candidate.links)?;
    let links = graph.links().to_vec();
    let space = StressSpace::new(&flat, candidate.dim, &links)?;
    let expected_rank = candidate.config.len() - candidate.dim - 1;
    // Below 1e-10 of the largest weight a link changes L by less than the checks' tolerance.
    const DROP: f64 = 1e-10;
    match options.objective {
        SdpObjective::Conditioning => {
            let (w, _, steps) = conditioned(
                &flat,
                candidate.dim,
                &links,
                &space,
                expected_rank,
                options.solver,
            )?;
            finish(
                candidate,
                &links,
                w.as_slice(),
                &space,
                Finish {
                    drop_rel: DROP,
                    normalise: true,
                    method: "sdp",
                    newton_steps: steps,
                },
            )
        }
        SdpObjective::ThesisGap {
            lambda_bar,
            weight_bound,
        } => {
            if !(lambda_bar > 0.0 && weight_bound > 0.0) {
                return Err(DesignError::Input(format!(
                    "λ̄ = {lambda_bar} and the weight bound {weight_bound} must be positive"
                )));
            }
            if space.z.ncols() == 0 {
                return Err(DesignError::NotUniversallyRigid(
                    "the graph carries no nonzero equilibrium stress".into(),
                ));
            }
            let mode = Mode::Gap {
                lambda_bar,
                wmax: weight_bound,
            };
            let m = space.z.ncols();
            let scale = lambda_bar.min(weight_bound);
            let floor = scale / MAX_CONDITION;
            let (x, steps) = match options.solver {
                SdpSolver::Ipm => {
                    let problem = Problem::new(&space, mode);
                    let mut x0 = DVector::zeros(m + 1);
                    x0[m] = -lambda_bar.min(1.0);
                    let rel = options.rel_tol;
                    let out = ipm::solve(&problem, x0, |x, gap| {
                        let s = x[m];
                        (s > 0.0 && gap <= rel * s) || s + gap < floor
                    })?;
                    (out.x, out.newton_steps)
                }
                #[cfg(feature = "clarabel")]
                SdpSolver::Clarabel => {
                    // Clarabel's gap is relative to max(1, |λ|), i.e. absolute for λ < 1: at
                    // most rel_tol (1e-6), and never coarser than the acceptance floor allows.
                    let tol = options.rel_tol.min(CLARABEL_GAP.max(1e-2 * floor));
                    let out = conic::solve(&space, &mode, tol)?;
                    (out.x, out.iterations)
                }
            };
            if x[m] < floor {
                return Err(DesignError::NotUniversallyRigid(format!(
                    "no positive semidefinite stress of rank N − D − 1 = {expected_rank} exists on this graph"
                )));
            }
            let w = &space.z * x.rows(0, m);
            finish(
                candidate,
                &links,
                w.as_slice(),
                &space,
                Finish {
                    drop_rel: DROP,
                    normalise: false,
                    method: "sdp",
                    newton_steps: steps,
                },
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::generators;
    use rand::SeedableRng;

    #[test]
    fn interior_point_reaches_the_closed_form_on_a_complete_graph() {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
        let config = generators::random_config(7, 2, 3.0, &mut rng);
        let c = generators::complete("k7", 2, config);
        let flat: Vec<f64> = c.config.iter().flatten().copied().collect();
        let space = StressSpace::new(&flat, 2, &c.links).unwrap();
        let (w_ipm, ratio, steps) = best_conditioned(&space, 4, SdpSolver::Ipm).unwrap();
        assert!(steps > 0);
        // Optimal ratio 1; the solver stops at relative gap 1e-6 on s = 1/ratio.
        assert!((ratio - 1.0).abs() < 1e-5, "{ratio}");
        // Same weights as the projector, up to the scale and the solver accuracy.
        let w_exact = complete_graph_optimum(&flat, 2, &c.links);
        let scale = w_exact.dot(&w_ipm) / w_ipm.norm_squared();
        assert!((&w_ipm * scale - &w_exact).amax() < 1e-4 * w_exact.amax());
    }
}
