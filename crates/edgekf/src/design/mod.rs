//! Formation design: rigidity checks, stress (Laplacian weight) design and framework generators.
//!
//! Affine formation control converges only for a universally rigid framework with a positive
//! semidefinite stress matrix `L` of rank `N − D − 1` whose null space holds the configuration
//! (thesis §2.4–2.5, §3.3–3.4, Theorems 3.1–3.2). This module
//!
//! - checks any framework and explains what holds and what fails ([`checks`]);
//! - designs the weights three ways: the thesis SDP (3.5) ([`sdp`]), the Yang et al. 2019
//!   construction that designs the graph too ([`yang`]), and an ℓ1-penalised sparse design in the
//!   spirit of Li, Leus & Rajan, EUSIPCO 2025 ([`sparse`]);
//! - generates configurations and candidate graphs ([`generators`]).
//!
//! All designs share one parametrisation: a stress is a weight vector `w` (one per link) with
//! `L(w) [P 1] = 0`. These `w` form the null space of the *equilibrium map*
//! `w ↦ L(w) P` (the transpose of the rigidity matrix); we compute an orthonormal basis `Z` of it
//! once and design `w = Z c`, so every design is an exact equilibrium stress up to round-off and
//! the semidefinite programs have no (linearly dependent) equality rows. The positive
//! semidefiniteness and rank conditions then only concern `Q L Qᵀ`, where the rows of `Q` are an
//! orthonormal basis of the complement of `span{1, q_1, …, q_D}` (thesis §3.4).
//!
//! # References
//! - van der Marel, *Edge State Kalman Filtering for Distributed Formation Control Systems*, MSc
//!   thesis, TU Delft 2021, §2.4–2.5, §3.3–3.4 (SDP (3.5)).
//! - Z. Li, R. T. Rajan, *Geometry-Aware Edge-State Tracking for Robust Affine Formation
//!   Control*, IEEE OJCSYS 2026, Fig. 13 (50 random agents, sparse and dense designs).
//! - Z. Li, G. Leus, R. T. Rajan, "Fast multiagent formation stabilization with sparse
//!   universally rigid frameworks", EUSIPCO 2025.
//! - Q. Yang et al., "Constructing universally rigid tensegrity frameworks with application in
//!   multiagent formation control", IEEE TAC 2019.

pub mod checks;
#[cfg(feature = "clarabel")]
mod conic;
pub mod generators;
mod ipm;
pub mod sdp;
pub mod sparse;
pub mod yang;

use nalgebra::DMatrix;

use crate::framework::{Framework, FrameworkError};
use crate::graph::GraphError;

pub use checks::{check, CheckReport};
pub use generators::Candidate;
pub use sdp::{SdpObjective, SdpOptions, SdpSolver};
pub use sparse::SparseOptions;

/// Why a solver stopped without an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverStatus {
    /// Clarabel (feature `clarabel`) stopped with this status (its name, e.g.
    /// `InsufficientProgress`, `MaxIterations`, `NumericalError`) instead of `Solved`.
    Clarabel(&'static str),
    /// The Newton system was not positive definite (numerical breakdown).
    NumericalBreakdown,
    /// The iteration limit was reached before the requested accuracy.
    MaxIterations,
    /// The line search could not make progress.
    LineSearchFailure,
}

impl std::fmt::Display for SolverStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SolverStatus::Clarabel(status) => return write!(f, "Clarabel status {status}"),
            SolverStatus::NumericalBreakdown => {
                "numerical breakdown (Newton system not positive definite)"
            }
            SolverStatus::MaxIterations => "iteration limit reached",
            SolverStatus::LineSearchFailure => "line search failed",
        })
    }
}

/// Errors of the design functions; each names the condition that failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// The input graph is invalid (out of range, duplicate, disconnected, ...).
    #[error("invalid graph: {0}")]
    Graph(#[from] GraphError),
    /// The designed framework failed its final verification.
    #[error("the designed framework failed verification: {0}")]
    Framework(#[from] FrameworkError),
    /// Unsupported dimension or inconsistent coordinates.
    #[error("invalid input: {0}")]
    Input(String),
    /// Too few agents for an affine formation in this dimension.
    #[error("{n} agents in {dim}-D: an affine formation needs at least D + 2 = {} agents", dim + 2)]
    TooFewAgents {
        /// N.
        n: usize,
        /// D.
        dim: usize,
    },
    /// The configuration is not generic.
    #[error("non-generic configuration: {0}")]
    NonGeneric(String),
    /// No positive semidefinite stress of rank N − D − 1 exists on the graph.
    #[error("not universally rigid: {0}")]
    NotUniversallyRigid(String),
    /// The solver stopped without an answer.
    #[error("solver failure: {status} after {iterations} iterations")]
    Solver {
        /// Why it stopped.
        status: SolverStatus,
        /// Newton steps taken.
        iterations: usize,
    },
}

/// A designed framework and how the design went.
#[derive(Debug, Clone)]
pub struct Design {
    /// The checked framework (links with nonzero weight only).
    pub framework: Framework,
    /// Method name (`sdp`, `yang`, `sparse`).
    pub method: &'static str,
    /// Newton steps of the interior-point solver (Clarabel: its iterations; 0 for closed-form
    /// designs).
    pub newton_steps: usize,
    /// Candidate links offered to the design (the Yang construction ignores them and designs
    /// its own graph).
    pub candidate_links: usize,
}

/// The design methods of the CLI.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Thesis SDP (3.5), see [`sdp`].
    Sdp,
    /// Yang et al. 2019 construction, see [`yang`].
    Yang,
    /// ℓ1-penalised sparse design, see [`sparse`].
    Sparse,
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "sdp" => Ok(Method::Sdp),
            "yang" => Ok(Method::Yang),
            "sparse" => Ok(Method::Sparse),
            other => Err(format!(
                "unknown design method {other:?} (sdp, yang, sparse)"
            )),
        }
    }
}

/// Designs weights for `candidate` with `method` and default options.
///
/// # Errors
/// See [`sdp::design`], [`yang::design`], [`sparse::design`].
pub fn design(candidate: &Candidate, method: Method) -> Result<Design, DesignError> {
    match method {
        Method::Sdp => sdp::design(candidate, &SdpOptions::default()),
        Method::Yang => yang::design(candidate),
        Method::Sparse => sparse::design(candidate, &SparseOptions::default()),
    }
}

/// Orthonormal basis (columns) of the orthogonal complement of the column space of `a`
/// (n × k). Returns the basis and the numerical rank of `a`.
///
/// Householder QR with column pivoting (Businger–Golub): at step j the remaining column of
/// largest norm is eliminated; the rank is the number of steps before that norm falls below
/// `1e-9 ‖a‖_max max(n, k)`, far above round-off (≈ 1e-16 ‖a‖ per operation) and far below the
/// pivots of any configuration we call generic. The last `n − r` columns of the full orthogonal
/// factor span the complement. (nalgebra's SVD was measured to reconstruct some symmetric
/// rigidity matrices only to 5e-6, too coarse for the equilibrium test; this QR is exact to
/// round-off.)
pub(crate) fn complement_basis(a: &DMatrix<f64>) -> (DMatrix<f64>, usize) {
    let n = a.nrows();
    let k = a.ncols();
    let mut work = a.clone();
    let col_norm2 = |w: &DMatrix<f64>, c: usize, from: usize| -> f64 {
        (from..n).map(|i| w[(i, c)] * w[(i, c)]).sum()
    };
    let amax = (0..k)
        .map(|c| col_norm2(&work, c, 0))
        .fold(0.0_f64, f64::max)
        .sqrt();
    let tol = 1e-9 * amax.max(f64::MIN_POSITIVE) * n.max(k) as f64;
    let mut reflectors: Vec<Vec<f64>> = Vec::new();
    for j in 0..n.min(k) {
        let (best, best_norm2) = (j..k)
            .map(|c| (c, col_norm2(&work, c, j)))
            .fold((j, -1.0), |acc, cur| if cur.1 > acc.1 { cur } else { acc });
        if best_norm2.sqrt() <= tol {
            break;
        }
        work.swap_columns(j, best);
        let x: Vec<f64> = (j..n).map(|i| work[(i, j)]).collect();
        let norm = best_norm2.sqrt();
        let alpha = if x[0] >= 0.0 { -norm } else { norm };
        let mut v = x;
        v[0] -= alpha;
        let vn = v.iter().map(|t| t * t).sum::<f64>().sqrt();
        v.iter_mut().for_each(|t| *t /= vn);
        for c in j..k {
            let dot: f64 = (j..n).map(|i| v[i - j] * work[(i, c)]).sum();
            for i in j..n {
                work[(i, c)] -= 2.0 * dot * v[i - j];
            }
        }
        reflectors.push(v);
    }
    let r = reflectors.len();
    let mut e = DMatrix::zeros(n, n - r);
    for c in 0..n - r {
        e[(r + c, c)] = 1.0;
    }
    for (j, v) in reflectors.iter().enumerate().rev() {
        for c in 0..n - r {
            let dot: f64 = (j..n).map(|i| v[i - j] * e[(i, c)]).sum();
            if dot != 0.0 {
                for i in j..n {
                    e[(i, c)] -= 2.0 * dot * v[i - j];
                }
            }
        }
    }
    (e, r)
}

/// The stress space of a framework: `Z` (L × m, orthonormal columns spanning the weights `w`
/// with `L(w) [P 1] = 0`) and `U` (n' × L, `u_l = Q (e_i − e_j)` with `n' = N − D − 1`).
#[derive(Debug, Clone)]
pub(crate) struct StressSpace {
    /// Basis of the equilibrium stresses, one row per link.
    pub z: DMatrix<f64>,
    /// Projected incidence vectors, one column per link.
    pub u: DMatrix<f64>,
}

impl StressSpace {
    /// Builds the stress space for a configuration (agent-major, `dim` coordinates) and links.
    pub fn new(config: &[f64], dim: usize, links: &[(usize, usize)]) -> Result<Self, DesignError> {
        let n = config.len() / dim;
        // Equilibrium map transposed = rigidity matrix R (L × N D): row l has p_i − p_j at agent
        // i's block and p_j − p_i at agent j's.
        let mut r = DMatrix::zeros(links.len(), n * dim);
        for (l, &(i, j)) in links.iter().enumerate() {
            for d in 0..dim {
                let diff = config[i * dim + d] - config[j * dim + d];
                r[(l, i * dim + d)] = diff;
                r[(l, j * dim + d)] = -diff;
            }
        }
        let (z, _) = complement_basis(&r);
        let mut basis = DMatrix::zeros(n, dim + 1);
        for i in 0..n {
            basis[(i, 0)] = 1.0;
            for d in 0..dim {
                basis[(i, d + 1)] = config[i * dim + d];
            }
        }
        let (q, rank) = complement_basis(&basis);
        if rank < dim + 1 {
            return Err(DesignError::NonGeneric(format!(
                "the affine span of the configuration has dimension {} < D = {dim}",
                rank.saturating_sub(1)
            )));
        }
        let np = q.ncols();
        let mut u = DMatrix::zeros(np, links.len());
        for (l, &(i, j)) in links.iter().enumerate() {
            for k in 0..np {
                u[(k, l)] = q[(i, k)] - q[(j, k)];
            }
        }
        Ok(Self { z, u })
    }

    /// `Q L(w) Qᵀ = U diag(w) Uᵀ`.
    pub fn projected(&self, w: &[f64]) -> DMatrix<f64> {
        let mut uw = self.u.clone();
        for (l, &wl) in w.iter().enumerate() {
            uw.column_mut(l).scale_mut(wl);
        }
        &uw * self.u.transpose()
    }
}

/// Validates a candidate's shape and returns the flat configuration.
pub(crate) fn validate(candidate: &Candidate) -> Result<Vec<f64>, DesignError> {
    let dim = candidate.dim;
    if !(1..=3).contains(&dim) {
        return Err(DesignError::Input(format!(
            "dimension must be 1, 2 or 3, got {dim}"
        )));
    }
    let n = candidate.config.len();
    if n < dim + 2 {
        return Err(DesignError::TooFewAgents { n, dim });
    }
    let mut flat = Vec::with_capacity(n * dim);
    for (i, p) in candidate.config.iter().enumerate() {
        if p.len() != dim {
            return Err(DesignError::Input(format!(
                "config[{i}] has {} coordinates, expected {dim}",
                p.len()
            )));
        }
        if p.iter().any(|v| !v.is_finite()) {
            return Err(DesignError::Input(format!("config[{i}] is not finite")));
        }
        flat.extend_from_slice(p);
    }
    let leaders = &candidate.leaders;
    if !(leaders.is_empty() || leaders.len() == dim + 1) {
        return Err(DesignError::Input(format!(
            "{} leaders given; rigid formations need none or exactly D + 1 = {}",
            leaders.len(),
            dim + 1
        )));
    }
    for (k, &a) in leaders.iter().enumerate() {
        if a >= n || leaders[..k].contains(&a) {
            return Err(DesignError::Input(format!(
                "leader {a} is out of range (agents are 0..{n}) or listed twice"
            )));
        }
    }
    Ok(flat)
}

/// How [`finish`] turns designed weights into a framework.
pub(crate) struct Finish {
    /// Links whose |weight| is at most this times the largest are dropped.
    pub drop_rel: f64,
    /// Scale so that the smallest nonzero eigenvalue of `L` is 1.
    pub normalise: bool,
    /// Method name.
    pub method: &'static str,
    /// Newton steps spent.
    pub newton_steps: usize,
}

/// Optionally scales `w` so that the smallest nonzero eigenvalue of `L(w)` is 1, drops links whose
/// weight is negligible, and builds the checked framework.
pub(crate) fn finish(
    candidate: &Candidate,
    links: &[(usize, usize)],
    w: &[f64],
    space: &StressSpace,
    how: Finish,
) -> Result<Design, DesignError> {
    let Finish {
        drop_rel,
        normalise,
        method,
        newton_steps,
    } = how;
    let m = space.projected(w);
    let eig = m.symmetric_eigen();
    let lmin = eig.eigenvalues.min();
    let lmax = eig.eigenvalues.max();
    if lmin <= 1e-9 * lmax.abs().max(f64::MIN_POSITIVE) {
        return Err(DesignError::NotUniversallyRigid(format!(
            "the designed stress has smallest nonzero eigenvalue {lmin:.3e} (largest {lmax:.3e})"
        )));
    }
    let wmax = w.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let mut kept_links = Vec::new();
    let mut kept_w = Vec::new();
    for (&link, &wl) in links.iter().zip(w) {
        if wl.abs() > drop_rel * wmax {
            kept_links.push(link);
            kept_w.push(if normalise { wl / lmin } else { wl });
        }
    }
    let framework = Framework::new(
        candidate.name.clone(),
        candidate.dim,
        &candidate.config,
        &kept_links,
        &kept_w,
        &candidate.leaders,
    )?;
    Ok(Design {
        framework,
        method,
        newton_steps,
        candidate_links: candidate.links.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn complement_is_orthonormal_and_orthogonal() {
        let a = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 1.0, 1.0, 1.0, 2.0, 1.0, 5.0]);
        let (c, r) = complement_basis(&a);
        assert_eq!(r, 2);
        assert_eq!(c.ncols(), 2);
        // Orthonormality to round-off (≈ 1e-15 for these O(1) numbers).
        assert!((c.transpose() * &c - DMatrix::identity(2, 2)).amax() < 1e-12);
        assert!((a.transpose() * &c).amax() < 1e-12);
    }
}
