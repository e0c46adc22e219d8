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

use super::barrier;
#[cfg(feature = "clarabel")]
use super::conic;
use super::ipm;
use super::Mode;
use super::{finish, validate, Candidate, Design, DesignError, Finish, SolverStatus, StressSpace};

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

/// Clarabel's duality-gap tolerance for the thesis-gap form of (3.5) (its gap is relative to
/// `max(1, |λ|)`). The conditioning SDP goes to Clarabel in the form `min t` s.t.
/// `I ⪯ Q L Qᵀ ⪯ t I` (see `conic`), whose objective `t = κ* ≥ 1` makes its relative gap a
/// relative accuracy of the optimal ratio; it gets a tenth of the requested accuracy.
#[cfg(feature = "clarabel")]
pub(crate) const CLARABEL_GAP: f64 = 1e-6;

/// Largest eigenvalue ratio `λ_max / λ_min` of `Q L Qᵀ` accepted for N agents: `1e8 / N`. The
/// rank test of the checks (and of `Framework::new`) counts an eigenvalue as zero below
/// `1e-9 · N · λ_max`; a stress with a larger ratio cannot be told from a singular one, with a
/// factor 10 to spare. Above it a framework is refused as (numerically) not universally rigid.
pub fn max_condition(agents: usize) -> f64 {
    MAX_CONDITION / agents.max(1) as f64
}

/// The ratio bound of [`max_condition`] for one agent.
pub const MAX_CONDITION: f64 = 1e8;

/// The best-conditioned stress on a stress space and how it was found.
#[derive(Debug, Clone)]
pub(crate) struct Conditioned {
    /// Weights, in link order.
    pub w: DVector<f64>,
    /// Achieved `λ_max / λ_min` of `Q L Qᵀ` (`1 / s`).
    pub ratio: f64,
    /// Iterations (primal–dual iterations plus fallback Newton steps; Clarabel iterations).
    pub iterations: usize,
    /// The solver that produced `w`.
    pub solver: &'static str,
    /// Relative optimality gap `(s̄ − s) / s` for the certified upper bound `s̄ ≥ s*`.
    pub gap: f64,
}

/// The conditioning SDP `max s` s.t. `s Π ⪯ L(w) ⪯ Π` on a stress space: the best-conditioned
/// stress, or the certified refusal `s* < 1e-8` (not universally rigid).
///
/// `rel_tol` is the relative accuracy asked of the optimal ratio.
pub(crate) fn best_conditioned(
    space: &StressSpace,
    expected_rank: usize,
    solver: SdpSolver,
    rel_tol: f64,
) -> Result<Conditioned, DesignError> {
    if space.z.ncols() == 0 {
        return Err(DesignError::NotUniversallyRigid(
            "the graph carries no nonzero equilibrium stress (the only w with L(w) [P 1] = 0 is w = 0)"
                .into(),
        ));
    }
    let agents = space.agents();
    let floor = 1.0 / max_condition(agents);
    let not_rigid = |upper: f64| {
        DesignError::NotUniversallyRigid(format!(
            "no positive semidefinite stress of rank N − D − 1 = {expected_rank} exists on this graph \
             (the best λ_min/λ_max of Q L Qᵀ is at most {:.1e} < 1e-8·N = {floor:.1e}, below \
             which the rank test cannot tell it from a singular stress)",
            upper.max(0.0)
        ))
    };
    match solver {
        SdpSolver::Ipm => conditioning_ipm(space, rel_tol, not_rigid),
        #[cfg(feature = "clarabel")]
        SdpSolver::Clarabel => {
            // y = (c, t) with I ⪯ M(c) ⪯ t I: the same weights up to the scale 1/t, s = 1/t.
            let m = space.z.ncols();
            // A tenth of the requested accuracy: Clarabel's stopping rule left its ratio up to
            // 1.4e-6 above the optimum at tolerance 1e-6 (measured on the robustness families).
            // Where it cannot get there (status AlmostSolved), the requested accuracy itself.
            let out = match conic::solve(space, &Mode::Condition, 0.1 * rel_tol) {
                Err(DesignError::Solver {
                    status: SolverStatus::Clarabel("AlmostSolved"),
                    ..
                }) => conic::solve(space, &Mode::Condition, rel_tol)?,
                other => other?,
            };
            let t = out.x[m];
            let t_lo = (t - out.gap).max(1.0);
            Ok(Conditioned {
                w: &space.z * out.x.rows(0, m),
                ratio: t,
                iterations: out.iterations,
                solver: "clarabel",
                gap: (t - t_lo) / t_lo,
            })
        }
    }
}

use ipm::PINF;

/// The conditioning SDP by the default solver, in two phases of the primal–dual method
/// ([`ipm`]):
///
/// 1. `max s` s.t. `s Π ⪯ L(w) ⪯ Π` from the strictly feasible `c = 0, s = −1`, until either the
///    upper bound certifies `s* < 1e-8` (not universally rigid) or `s > 1e-8` with `s* ≤ 1.5 s`;
/// 2. the same problem in the scale `λ_min = 1`: `min t` s.t. `Π ⪯ L(w) ⪯ t Π`, started at
///    `(c/s, 1/s)` with the primal iterate scaled alike (the change of scale maps the central path
///    of one form onto the other, so the warm start stays centred), until `t` is within
///    `rel_tol` of the certified lower bound. Phase 1 alone would ask for an absolute gap of
///    `1e-6 s*` in a problem of scale 1, below what double precision delivers when `s* ≲ 1e-4`
///    (measured: it stalls at relative gaps of 1e-4–1e-3 there); in phase 2 the same relative
///    accuracy is a relative gap of the objective.
///
/// If a phase stalls, the barrier method ([`super::barrier`]) continues from the best point;
/// the best strictly feasible point found is returned with its certified gap (every such point
/// is a valid stress).
fn conditioning_ipm(
    space: &StressSpace,
    rel: f64,
    not_rigid: impl Fn(f64) -> DesignError,
) -> Result<Conditioned, DesignError> {
    let floor = 1.0 / max_condition(space.agents());
    let p1 = phase1(space, floor)?;
    certified(p1.s, p1.s_upper, floor, p1.iterations, not_rigid)?;
    Ok(phase2(space, rel, p1))
}

/// The verdict on bounds `[lower, upper]` of the optimal `s` against the acceptance `floor`:
/// an upper bound below it certifies that no stress exists (`not_rigid`); a lower bound not
/// above it, with no such certificate, means the solvers stalled in between.
fn certified(
    lower: f64,
    upper: f64,
    floor: f64,
    iterations: usize,
    not_rigid: impl FnOnce(f64) -> DesignError,
) -> Result<(), DesignError> {
    if upper < floor {
        return Err(not_rigid(upper));
    }
    if lower <= floor {
        return Err(DesignError::Solver {
            status: SolverStatus::Stalled { lower, upper },
            iterations,
        });
    }
    Ok(())
}

/// Where phase 1 of [`conditioning_ipm`] ended.
struct Phase1 {
    /// Its start, the barrier's fallback start in phase 2.
    y0: DVector<f64>,
    /// The best point `(c, s)`, its `s` and the certified upper bound on `s*`.
    y: DVector<f64>,
    s: f64,
    s_upper: f64,
    /// The primal iterate to warm-start phase 2 (none when the barrier found the point).
    warm: Option<ipm::Primal>,
    solver: &'static str,
    iterations: usize,
}

/// Phase 1: `max s` s.t. `s Π ⪯ L(w) ⪯ Π` to a relative gap of ½ (or an upper bound below
/// `floor`), the barrier method rescuing a stalled solve.
fn phase1(space: &StressSpace, floor: f64) -> Result<Phase1, DesignError> {
    let m = space.z.ncols();
    let p1 = ipm::Problem::new(space, &Mode::Condition);
    let mut y0 = DVector::zeros(m + 1);
    y0[m] = -1.0;
    let phase1_done = |lo: f64, up: f64| (lo > floor && up - lo <= 0.5 * lo) || up < floor;
    let out1 = ipm::solve(&p1, y0.clone(), None, |_, b| {
        b.pinf <= PINF && phase1_done(b.dobj, b.upper)
    })
    .ok_or(DesignError::Solver {
        status: SolverStatus::NumericalBreakdown,
        iterations: 0,
    })?;
    let mut iterations = out1.iterations;
    let mut s_upper = if out1.bounds.pinf <= PINF {
        out1.bounds.upper
    } else {
        f64::INFINITY
    };
    let (mut y1, mut s1, mut warm) = (out1.y, out1.bounds.dobj, Some(out1.primal));
    let mut solver = "primal-dual";
    if !(s1 > floor || s_upper < floor) {
        let fb = barrier_condition(space, &y1, &y0, barrier::RESCUE_STEPS, phase1_done);
        if let Some((y, s, upper, steps)) = fb {
            iterations += steps;
            s_upper = s_upper.min(upper);
            if s > s1 {
                (y1, s1, warm, solver) = (y, s, None, "barrier (fallback)");
            }
        }
    }
    Ok(Phase1 {
        y0,
        y: y1,
        s: s1,
        s_upper,
        warm,
        solver,
        iterations,
    })
}

/// Phase 2: `min t` s.t. `Π ⪯ L(w) ⪯ t Π` from phase 1's point scaled to `λ_min = 1`, to
/// `rel`; the barrier method polishes a solve that stalls far from it.
fn phase2(space: &StressSpace, rel: f64, p1: Phase1) -> Conditioned {
    let m = space.z.ncols();
    let Phase1 {
        y0,
        y: y1,
        s: s1,
        s_upper,
        warm,
        mut solver,
        mut iterations,
    } = p1;
    let p2 = ipm::Problem::ratio(space);
    let mut y2 = &y1 / s1;
    y2[m] = 1.0 / s1;
    let warm = warm.map(|p| {
        let scale = 1.0 / p.x[1].trace();
        ipm::Primal {
            x: p.x.iter().map(|x| x * scale).collect(),
            xl: p.xl * scale,
        }
    });
    let mut t_lo = (1.0 / s_upper).max(1.0);
    let (mut best_y, mut best_t) = (y2.clone(), 1.0 / s1);
    if let Some(out2) = ipm::solve(&p2, y2, warm, |_, b| {
        b.pinf <= PINF && b.upper - b.dobj <= rel * (-b.upper).max(1.0)
    }) {
        iterations += out2.iterations;
        if out2.bounds.pinf <= PINF {
            t_lo = t_lo.max(-out2.bounds.upper);
        }
        if -out2.bounds.dobj < best_t {
            (best_y, best_t) = (out2.y, -out2.bounds.dobj);
            solver = "primal-dual";
        }
    }
    if best_t - t_lo > 1e-3 * t_lo {
        // Phase 2 stalled far from the tolerance: the barrier method on the s-form from the best
        // point. (Closer than 1e-3 the barrier does no better: its own round-off floor.)
        let mut y = &best_y / best_t;
        y[m] = 1.0 / best_t;
        let accept = |lo: f64, up: f64| lo > 0.0 && up - lo <= rel * lo;
        let polish = barrier_condition(space, &y, &y0, barrier::POLISH_STEPS, accept);
        if let Some((yb, s, upper, steps)) = polish {
            iterations += steps;
            t_lo = t_lo.max(1.0 / upper);
            if 1.0 / s < best_t {
                best_t = 1.0 / s;
                best_y = &yb / s;
                best_y[m] = best_t;
                solver = "barrier (fallback)";
            }
        }
    }
    Conditioned {
        w: &space.z * best_y.rows(0, m),
        ratio: best_t,
        iterations,
        solver,
        gap: ((best_t - t_lo) / t_lo).max(0.0),
    }
}

/// The barrier method on the s-form `max s` s.t. `s Π ⪯ L(w) ⪯ Π`, from `start` (or `fallback`
/// if the barrier's own feasibility test puts `start` on the boundary), stopped by
/// `accept(s, s̄)` or after `budget` Newton steps. Returns its last iterate, `s`, the certified upper bound `s̄` and the
/// Newton steps.
fn barrier_condition(
    space: &StressSpace,
    start: &DVector<f64>,
    fallback: &DVector<f64>,
    budget: usize,
    accept: impl Fn(f64, f64) -> bool,
) -> Option<(DVector<f64>, f64, f64, usize)> {
    let m = space.z.ncols();
    let bp = barrier::Problem::new(space, Mode::Condition);
    let stop = |x: &DVector<f64>, gap: f64| accept(x[m], x[m] + gap);
    let out = barrier::solve(&bp, start.clone(), budget, stop)
        .or_else(|| barrier::solve(&bp, fallback.clone(), budget, stop))?;
    let s = out.x[m];
    Some((out.x, s, -out.lower_bound, out.newton_steps))
}

/// [`best_conditioned`], with the closed-form optimum on complete graphs.
pub(crate) fn conditioned(
    flat: &[f64],
    dim: usize,
    links: &[(usize, usize)],
    space: &StressSpace,
    expected_rank: usize,
    solver: SdpSolver,
    rel_tol: f64,
) -> Result<Conditioned, DesignError> {
    let n = flat.len() / dim;
    if links.len() == n * (n - 1) / 2 {
        Ok(Conditioned {
            w: complete_graph_optimum(flat, dim, links),
            ratio: 1.0,
            iterations: 0,
            solver: "closed form",
            gap: 0.0,
        })
    } else {
        best_conditioned(space, expected_rank, solver, rel_tol)
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
    let n = candidate.config.len();
    let complete = links.len() == n * (n - 1) / 2;
    // A complete graph under the conditioning objective has its optimum in closed form: no
    // stress basis (its L × m matrix is large: 499 500 × 497 503 for N = 1000).
    let space = if complete && options.objective == SdpObjective::Conditioning {
        StressSpace::without_stresses(&flat, candidate.dim, &links)?
    } else {
        StressSpace::new(&flat, candidate.dim, &links)?
    };
    let expected_rank = candidate.config.len() - candidate.dim - 1;
    match options.objective {
        SdpObjective::Conditioning => {
            let best = conditioned(
                &flat,
                candidate.dim,
                &links,
                &space,
                expected_rank,
                options.solver,
                options.rel_tol,
            )?;
            let f = sdp_finish(true, best.iterations, best.solver, best.gap);
            finish(candidate, &links, best.w.as_slice(), &space, f)
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
            let floor = lambda_bar.min(weight_bound) / max_condition(candidate.config.len());
            let gap = solve_gap(&space, lambda_bar, weight_bound, floor, options)?;
            certified(gap.lower, gap.upper, floor, gap.iterations, |_| {
                DesignError::NotUniversallyRigid(format!(
                    "no positive semidefinite stress of rank N − D − 1 = {expected_rank} exists on this graph"
                ))
            })?;
            let w = &space.z * gap.y.rows(0, space.z.ncols());
            let rel_gap = ((gap.upper - gap.lower) / gap.lower).max(0.0);
            let f = sdp_finish(false, gap.iterations, gap.solver, rel_gap);
            finish(candidate, &links, w.as_slice(), &space, f)
        }
    }
}

/// How an SDP design is finished: links below 1e-10 of the largest weight dropped (they change
/// L by less than the checks' tolerance), named "sdp".
fn sdp_finish(normalise: bool, newton_steps: usize, solver: &'static str, gap: f64) -> Finish {
    Finish {
        drop_rel: 1e-10,
        normalise,
        method: "sdp",
        newton_steps,
        solver,
        gap,
    }
}

/// The thesis SDP (3.5) solved: its solution `(c, s)`, the bounds on the optimal `λ` and the
/// solver's iterations and name.
struct GapSolution {
    y: DVector<f64>,
    lower: f64,
    upper: f64,
    iterations: usize,
    solver: &'static str,
}

/// Solves the thesis SDP (3.5) (`max s` with `λ̄ ≥ s`, `|w_l| ≤ w̄`) on `space`, stopping at the
/// relative tolerance or once the upper bound falls below `floor` (no stress).
fn solve_gap(
    space: &StressSpace,
    lambda_bar: f64,
    weight_bound: f64,
    floor: f64,
    options: &SdpOptions,
) -> Result<GapSolution, DesignError> {
    let mode = Mode::Gap {
        lambda_bar,
        wmax: weight_bound,
    };
    let m = space.z.ncols();
    let rel = options.rel_tol;
    match options.solver {
        SdpSolver::Ipm => {
            let mut y0 = DVector::zeros(m + 1);
            y0[m] = -lambda_bar.min(1.0);
            let out = ipm::solve_robust(space, mode, y0, |lo, up| {
                (lo > 0.0 && up - lo <= rel * lo) || up < floor
            })?;
            Ok(GapSolution {
                y: out.y,
                lower: out.lower,
                upper: out.upper,
                iterations: out.iterations,
                solver: out.solver,
            })
        }
        #[cfg(feature = "clarabel")]
        SdpSolver::Clarabel => {
            // Clarabel's gap is relative to max(1, |λ|), i.e. absolute for λ < 1: at most
            // rel_tol (1e-6), and never coarser than the acceptance floor allows.
            let tol = rel.min(CLARABEL_GAP.max(1e-2 * floor));
            let out = conic::solve(space, &mode, tol)?;
            let s = out.x[m];
            Ok(GapSolution {
                y: out.x,
                lower: s,
                upper: s + out.gap,
                iterations: out.iterations,
                solver: "clarabel",
            })
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
        let best = best_conditioned(&space, 4, SdpSolver::Ipm, 1e-6).unwrap();
        let (w_ipm, ratio) = (best.w, best.ratio);
        assert!(best.iterations > 0);
        // Optimal ratio 1; the solver stops at relative gap 1e-6 on s = 1/ratio.
        assert!((ratio - 1.0).abs() < 1e-5, "{ratio}");
        // Same weights as the projector, up to the scale and the solver accuracy.
        let w_exact = complete_graph_optimum(&flat, 2, &c.links);
        let scale = w_exact.dot(&w_ipm) / w_ipm.norm_squared();
        assert!((&w_ipm * scale - &w_exact).amax() < 1e-4 * w_exact.amax());
    }
}
