//! Formation design: rigidity checks, stress (Laplacian weight) design and framework generators.
//!
//! Affine formation control converges only for a universally rigid framework with a positive
//! semidefinite stress matrix `L` of rank `N − D − 1` whose null space holds the configuration
//! (thesis §2.4–2.5, §3.3–3.4, Theorems 3.1–3.2). This module
//!
//! - checks any framework and explains what holds and what fails ([`checks`]);
//! - designs the weights three ways: the thesis SDP (3.5) ([`sdp`]), the Yang et al. 2019
//!   construction that designs the graph too ([`yang`]), and an ℓ1-penalised sparse design in the
//!   spirit of Li, Leus & Rajan, EUSIPCO 2025 ([`sparse`]); the SDPs are solved by a primal–dual
//!   interior-point method with a barrier-method fallback (private modules `ipm`, `barrier`);
//! - chooses leaders for a designed framework by `λ_min(L_ff)` ([`leaders`]) — the design itself
//!   does not depend on who leads, and leaders need not be linked;
//! - generates configurations and candidate graphs ([`generators`]);
//! - estimates the memory and time of a design before it runs ([`cost`]).
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

mod barrier;
pub mod checks;
#[cfg(feature = "clarabel")]
mod conic;
pub mod cost;
mod dense;
pub mod generators;
mod ipm;
pub mod leaders;
pub mod sdp;
pub mod sparse;
pub mod yang;

use nalgebra::{DMatrix, DVector};

use crate::framework::{Framework, FrameworkError};
use crate::graph::GraphError;

/// Which stress SDP to solve (shared by the interior-point method [`ipm`] and the barrier
/// method [`barrier`]).
#[derive(Debug, Clone)]
pub(crate) enum Mode {
    /// `max s` s.t. `s Π ⪯ L(w) ⪯ Π`.
    Condition,
    /// `max s` s.t. `s Π ⪯ L(w)`, `s ≤ lambda_bar`, `|w_l| ≤ wmax`.
    Gap { lambda_bar: f64, wmax: f64 },
    /// `min Σ p` s.t. `Π ⪯ L(w) ⪯ kappa Π`, `|w_l| ≤ p_l` where `penalised[l]`.
    L1 { kappa: f64, penalised: Vec<bool> },
}

pub use checks::{check, CheckReport};
pub use generators::Candidate;
pub use leaders::{choose_leaders, LeaderChoice, LeaderMode};
pub use sdp::{SdpObjective, SdpOptions, SdpSolver};
pub use sparse::SparseOptions;

/// Why a solver stopped without an answer.
#[derive(Debug, Clone, Copy, PartialEq)]
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
    /// Both interior-point methods stalled with the optimum `s*` of the conditioning SDP
    /// bracketed by `lower ≤ s* ≤ upper` around the acceptance threshold `1e-8`: neither a usable
    /// stress nor a certificate that none exists.
    Stalled {
        /// Best `s` reached.
        lower: f64,
        /// Certified upper bound on `s*`.
        upper: f64,
    },
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
            SolverStatus::Stalled { lower, upper } => {
                return write!(
                    f,
                    "stalled with the optimum bracketed in [{lower:.2e}, {upper:.2e}]"
                )
            }
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
    /// Iterations of the interior-point solvers (primal–dual iterations plus fallback Newton
    /// steps, summed over the solves of a design; Clarabel: its iterations; 0 for closed-form
    /// designs).
    pub newton_steps: usize,
    /// Candidate links offered to the design (the Yang construction ignores them and designs
    /// its own graph).
    pub candidate_links: usize,
    /// The solver behind the weights: `primal-dual` (default), `barrier (fallback)`,
    /// `clarabel`, `closed form` (complete graphs) or `construction` (Yang).
    pub solver: &'static str,
    /// Relative optimality gap of the final SDP, `(s̄ − s)/s` for the certified bound `s̄` on the
    /// optimum (`≤ 1e-6` when the solver converged; 0 for closed forms and constructions).
    pub gap: f64,
    /// How [`design`] adapted the method to the size of the input, when it did (e.g. an SDP on
    /// the nearest-neighbour subgraph of a candidate set too large for the interior-point
    /// method).
    pub note: Option<String>,
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

/// Above this many candidate links [`design`] with [`Method::Sdp`] does not hand the whole set
/// to the interior-point method (its time grows like `L² m`; measured on 2 cores with
/// trilateration candidates: 3 990 links at N = 1 000 in 62 s, 5 990 at N = 1 500 in 303 s, so
/// 15 000 would take hours) — unless the graph is complete, which has a closed form.
pub const AUTO_LINKS: usize = 6_000;

/// Designs weights for `candidate` with `method` and default options, choosing what works at
/// the size given: with [`Method::Sdp`], a candidate set of more than [`AUTO_LINKS`] links (not
/// a complete graph) is designed on the subgraph of each agent's `k` nearest candidate
/// neighbours — `k = D + 2` first, two more while the subgraph is not universally rigid (or not
/// connected) and stays within [`AUTO_LINKS`] — and, if no such subgraph is universally rigid, by the Yang
/// construction. A stress of a subgraph is a stress of the candidate graph (the other links
/// weigh zero); [`Design::note`] says what was done. `sdp::design` runs the SDP on any set up
/// to [`MAX_LINKS`].
///
/// # Errors
/// See [`sdp::design`], [`yang::design`], [`sparse::design`].
pub fn design(candidate: &Candidate, method: Method) -> Result<Design, DesignError> {
    match method {
        Method::Sdp => {
            let n = candidate.config.len();
            let links = crate::graph::Graph::new(n, &candidate.links)?.links().len();
            if links <= AUTO_LINKS || links == n * n.saturating_sub(1) / 2 {
                return sdp::design(candidate, &SdpOptions::default());
            }
            sdp_on_nearest(candidate, links)
        }
        Method::Yang => yang::design(candidate),
        Method::Sparse => sparse::design(candidate, &SparseOptions::default()),
    }
}

/// The links of `candidate` between each agent and its `k` nearest candidate neighbours
/// (undirected, sorted, each once).
pub fn nearest_candidate_links(candidate: &Candidate, k: usize) -> Vec<(usize, usize)> {
    let n = candidate.config.len();
    let mut nbrs: Vec<Vec<usize>> = vec![Vec::new(); n];
    for &(i, j) in &candidate.links {
        if i != j && i < n && j < n {
            nbrs[i].push(j);
            nbrs[j].push(i);
        }
    }
    let dist2 = |a: usize, b: usize| -> f64 {
        candidate.config[a]
            .iter()
            .zip(&candidate.config[b])
            .map(|(x, y)| (x - y) * (x - y))
            .sum()
    };
    let mut out = std::collections::BTreeSet::new();
    for (i, nb) in nbrs.iter_mut().enumerate() {
        nb.sort_unstable();
        nb.dedup();
        nb.sort_by(|&a, &b| dist2(i, a).total_cmp(&dist2(i, b)).then(a.cmp(&b)));
        for &j in nb.iter().take(k) {
            out.insert((i.min(j), i.max(j)));
        }
    }
    out.into_iter().collect()
}

/// [`design`]'s SDP on nearest-neighbour subgraphs of a large candidate set, then Yang.
fn sdp_on_nearest(candidate: &Candidate, links: usize) -> Result<Design, DesignError> {
    // D + 2 neighbours: what trilateration candidates give (K = 4 in 2-D at N = 1 000 designs
    // with λ_max/λ_min ≈ 2 250); two more per refusal.
    let step = 2;
    let mut k = candidate.dim + 2;
    let mut last_refusal = None;
    loop {
        let sub_links = nearest_candidate_links(candidate, k);
        if sub_links.len() > AUTO_LINKS {
            break;
        }
        let sub = Candidate {
            links: sub_links,
            ..candidate.clone()
        };
        match sdp::design(&sub, &SdpOptions::default()) {
            Ok(mut d) => {
                d.note = Some(format!(
                    "{links} candidate links are more than the interior-point design takes in \
                     reasonable time ({AUTO_LINKS}): designed on the {} links between each agent \
                     and its {k} nearest candidate neighbours",
                    sub.links.len()
                ));
                d.candidate_links = candidate.links.len();
                return Ok(d);
            }
            Err(DesignError::NotUniversallyRigid(why)) => {
                last_refusal = Some(why);
                k += step;
            }
            Err(DesignError::Graph(why)) => {
                last_refusal = Some(why.to_string());
                k += step;
            }
            Err(e) => return Err(e),
        }
    }
    let mut d = yang::design(candidate)?;
    d.note = Some(format!(
        "{links} candidate links are more than the interior-point design takes in reasonable \
         time ({AUTO_LINKS}), and no nearest-neighbour subgraph within that size is universally \
         rigid{}: designed by the Yang construction instead",
        last_refusal.map_or(String::new(), |w| format!(" (the last: {w})"))
    ));
    Ok(d)
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
    let (n, k) = a.shape();
    let mut work = a.clone();
    let norm2 = |col: &[f64]| col.iter().map(|v| v * v).sum::<f64>();
    let amax = (0..k)
        .map(|c| norm2(&work.as_slice()[c * n..(c + 1) * n]))
        .fold(0.0_f64, f64::max)
        .sqrt();
    let tol = 1e-9 * amax.max(f64::MIN_POSITIVE) * n.max(k) as f64;
    let mut reflectors: Vec<Vec<f64>> = Vec::new();
    for j in 0..n.min(k) {
        let data = work.as_slice();
        let (best, best_norm2) = (j..k)
            .map(|c| (c, norm2(&data[c * n + j..(c + 1) * n])))
            .fold((j, -1.0), |acc, cur| if cur.1 > acc.1 { cur } else { acc });
        if best_norm2.sqrt() <= tol {
            break;
        }
        work.swap_columns(j, best);
        let data = work.as_mut_slice();
        let mut v = data[j * n + j..(j + 1) * n].to_vec();
        let norm = best_norm2.sqrt();
        let alpha = if v[0] >= 0.0 { -norm } else { norm };
        v[0] -= alpha;
        let vn = norm2(&v).sqrt();
        v.iter_mut().for_each(|t| *t /= vn);
        for c in j..k {
            let col = &mut data[c * n + j..(c + 1) * n];
            let dot: f64 = v.iter().zip(col.iter()).map(|(a, b)| a * b).sum();
            col.iter_mut()
                .zip(&v)
                .for_each(|(x, vi)| *x -= 2.0 * dot * vi);
        }
        reflectors.push(v);
    }
    let r = reflectors.len();
    let mut e = DMatrix::zeros(n, n - r);
    for c in 0..n - r {
        e[(r + c, c)] = 1.0;
    }
    let data = e.as_mut_slice();
    for (j, v) in reflectors.iter().enumerate().rev() {
        // Columns c of e are zero above row r + c until reflector j ≤ r reaches them; the
        // reflector touches rows j.. only.
        for c in 0..n - r {
            let col = &mut data[c * n + j..(c + 1) * n];
            let dot: f64 = v.iter().zip(col.iter()).map(|(a, b)| a * b).sum();
            if dot != 0.0 {
                col.iter_mut()
                    .zip(v)
                    .for_each(|(x, vi)| *x -= 2.0 * dot * vi);
            }
        }
    }
    (e, r)
}

/// The stress space of a framework: `Z` (L × m, orthonormal columns spanning the weights `w`
/// with `L(w) [P 1] = 0`), the orthogonal projector `J` onto `span{1, q_1, …, q_D}` (so
/// `Q L Qᵀ` acts like `L` on the range of `Π = I − J`), and `Qᵀ` (N × n', `n' = N − D − 1`,
/// orthonormal columns spanning that range; `u_l = Q (e_i − e_j)`, see [`StressSpace::u`]).
#[derive(Debug, Clone)]
pub(crate) struct StressSpace {
    /// Basis of the equilibrium stresses, one row per link.
    pub z: DMatrix<f64>,
    /// The links `(i, j)`, in the order of the rows of `z`.
    pub links: Vec<(usize, usize)>,
    /// `J` (N × N).
    j: DMatrix<f64>,
    /// `V` (N × (D + 1)), orthonormal columns spanning `span{1, q_1, …, q_D}` (`J = V Vᵀ`).
    affine: DMatrix<f64>,
    /// `Qᵀ` (N × n').
    qt: DMatrix<f64>,
}

/// Candidate links the interior-point design accepts: it holds a few L × L matrices (three at
/// 15 000 links take 5.4 GB) and its time grows like `L² m` (m ≈ L − N D stresses).
pub const MAX_LINKS: usize = 15_000;

impl StressSpace {
    /// Builds the stress space for a configuration (agent-major, `dim` coordinates) and links.
    ///
    /// # Errors
    /// [`DesignError::NonGeneric`] for a degenerate configuration; [`DesignError::Input`] for
    /// more than [`MAX_LINKS`] links.
    pub fn new(config: &[f64], dim: usize, links: &[(usize, usize)]) -> Result<Self, DesignError> {
        if links.len() > MAX_LINKS {
            return Err(DesignError::Input(format!(
                "{} candidate links: the interior-point design is limited to {MAX_LINKS} (it holds \
                 L × L matrices and its time grows like L² m); thin the candidates, or use the \
                 Yang construction, which designs its own graph",
                links.len()
            )));
        }
        let mut space = Self::without_stresses(config, dim, links)?;
        space.z = equilibrium_basis(config, dim, links);
        Ok(space)
    }

    /// The same without the stress basis (`Z` with no columns), for closed-form designs.
    ///
    /// # Errors
    /// [`DesignError::NonGeneric`] for a degenerate configuration.
    pub fn without_stresses(
        config: &[f64],
        dim: usize,
        links: &[(usize, usize)],
    ) -> Result<Self, DesignError> {
        let n = config.len() / dim;
        let mut basis = DMatrix::zeros(n, dim + 1);
        for i in 0..n {
            basis[(i, 0)] = 1.0;
            for d in 0..dim {
                basis[(i, d + 1)] = config[i * dim + d];
            }
        }
        let (qt, rank) = complement_basis(&basis);
        if rank < dim + 1 {
            return Err(DesignError::NonGeneric(format!(
                "the affine span of the configuration has dimension {} < D = {dim}",
                rank.saturating_sub(1)
            )));
        }
        let affine = leaders::affine_basis(config, dim);
        let j = &affine * affine.transpose();
        Ok(Self {
            z: DMatrix::zeros(links.len(), 0),
            links: links.to_vec(),
            j,
            affine,
            qt,
        })
    }

    /// `U` (n' × L): column l is `u_l = Q (e_i − e_j)`.
    pub fn u(&self) -> DMatrix<f64> {
        let np = self.qt.ncols();
        let mut u = DMatrix::zeros(np, self.links.len());
        for (l, &(i, j)) in self.links.iter().enumerate() {
            for k in 0..np {
                u[(k, l)] = self.qt[(i, k)] - self.qt[(j, k)];
            }
        }
        u
    }

    /// N.
    pub fn agents(&self) -> usize {
        self.j.nrows()
    }

    /// `n' = N − D − 1`.
    pub fn np(&self) -> usize {
        self.qt.ncols()
    }

    /// `J`, the orthogonal projector onto `span{1, q_1, …, q_D}`.
    pub fn affine_projector(&self) -> &DMatrix<f64> {
        &self.j
    }

    /// `Π = I − J`.
    pub fn pi(&self) -> DMatrix<f64> {
        let n = self.agents();
        DMatrix::identity(n, n) - &self.j
    }

    /// The dense stress matrix `L(w) = Σ_l w_l (e_i − e_j)(e_i − e_j)ᵀ` (N × N).
    pub fn laplacian(&self, w: &[f64]) -> DMatrix<f64> {
        let n = self.agents();
        let mut l = DMatrix::zeros(n, n);
        for (&(i, j), &wl) in self.links.iter().zip(w) {
            l[(i, i)] += wl;
            l[(j, j)] += wl;
            l[(i, j)] -= wl;
            l[(j, i)] -= wl;
        }
        l
    }

    /// Eigenvalues of `Q L(w) Qᵀ`, ascending: those of `L(w) + c J` without the `D + 1` copies
    /// of `c` (`c` above the spectrum of `L`), since `L(w) J = 0` for an equilibrium stress.
    pub fn spectrum(&self, w: &[f64]) -> Vec<f64> {
        let l = self.laplacian(w);
        let c = 2.0 * l.abs().column_sum().max() + 1.0;
        let mut ev: Vec<f64> = (l + &self.j * c)
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .collect();
        ev.sort_by(f64::total_cmp);
        ev.truncate(self.np());
        ev
    }

    /// `Y (σ L(w) + c Π)` for `Y` with `Y J = 0` up to round-off, in `O(N L + N² D)`: `L(w)` is
    /// sparse and `Y Π = Y − (Y V) Vᵀ`.
    pub fn mul_slack_step(&self, y: &DMatrix<f64>, sigma: f64, w: &[f64], c: f64) -> DMatrix<f64> {
        let n = self.agents();
        let mut out = if c == 0.0 {
            DMatrix::zeros(n, n)
        } else {
            (y - (y * &self.affine) * self.affine.transpose()) * c
        };
        let ys = y.as_slice();
        let os = out.as_mut_slice();
        let mut d = vec![0.0; n];
        for (&(i, j), &wl) in self.links.iter().zip(w) {
            let s = sigma * wl;
            if s == 0.0 {
                continue;
            }
            for r in 0..n {
                d[r] = s * (ys[i * n + r] - ys[j * n + r]);
            }
            for r in 0..n {
                os[i * n + r] += d[r];
                os[j * n + r] -= d[r];
            }
        }
        out
    }

    /// `b_lᵀ Y b_l` for every link (`b_l = e_i − e_j`).
    pub fn gather_diag(&self, y: &DMatrix<f64>) -> DVector<f64> {
        DVector::from_iterator(
            self.links.len(),
            self.links
                .iter()
                .map(|&(i, j)| y[(i, i)] - y[(i, j)] - y[(j, i)] + y[(j, j)]),
        )
    }

    /// `b_lᵀ X Y b_l` for every link, for symmetric `X` (`O(L N)`, without forming `X Y`).
    pub fn gather_diag_product(&self, x: &DMatrix<f64>, y: &DMatrix<f64>) -> DVector<f64> {
        let entry = |a: usize, b: usize| x.column(a).dot(&y.column(b));
        DVector::from_iterator(
            self.links.len(),
            self.links
                .iter()
                .map(|&(i, j)| entry(i, i) - entry(i, j) - entry(j, i) + entry(j, j)),
        )
    }

    /// `Σ_k (Bᵀ X_k B) ∘ (Bᵀ Y_k B)` (L × L) for symmetric pairs `(X_k, Y_k)`: entry `(l, l')`
    /// is `Σ_k (b_lᵀ X_k b_l')(b_lᵀ Y_k b_l')`, gathered from `d = X_k b_l` (one column
    /// difference) as `d_{i'} − d_{j'}`.
    pub fn hadamard_gram(&self, pairs: &[(&DMatrix<f64>, &DMatrix<f64>)]) -> DMatrix<f64> {
        let n = self.agents();
        let nl = self.links.len();
        let ends: Vec<(u32, u32)> = self
            .links
            .iter()
            .map(|&(i, j)| (i as u32, j as u32))
            .collect();
        let mut h = DMatrix::zeros(nl, nl);
        let fill = |l: usize, col: &mut [f64]| {
            let (i, j) = self.links[l];
            let mut dx = vec![0.0; n];
            let mut dy = vec![0.0; n];
            for &(x, y) in pairs {
                let (xs, ys) = (x.as_slice(), y.as_slice());
                for r in 0..n {
                    dx[r] = xs[i * n + r] - xs[j * n + r];
                    dy[r] = ys[i * n + r] - ys[j * n + r];
                }
                for (c, &(a, b)) in col.iter_mut().zip(&ends) {
                    let (a, b) = (a as usize, b as usize);
                    *c += (dx[a] - dx[b]) * (dy[a] - dy[b]);
                }
            }
        };
        dense::par_columns(&mut h, fill);
        h
    }
}

/// Orthonormal basis of the equilibrium stresses `{w : L(w) [P 1] = 0}` = the null space of the
/// transposed rigidity matrix `R` (L × N D): row l of `R` has `p_i − p_j` at agent i's block
/// and `p_j − p_i` at agent j's.
///
/// Small frameworks use the column-pivoted QR of [`complement_basis`] (exact to round-off,
/// `O(L (N D)²)` scalar work). Large ones project instead: for an infinitesimally rigid
/// framework `RᵀR + T` (`T` the projector onto the `D(D+1)/2` trivial motions) is positive
/// definite, `P = I − R (RᵀR + T)⁻¹ Rᵀ` is the projector onto the stresses, and `P E` for a
/// fixed pseudo-random `L × m` matrix `E` (`m = L − N D + D(D+1)/2`) spans them; two
/// projections and two Cholesky-QR passes make the basis exact and orthonormal to round-off,
/// all in matrix products. If `RᵀR + T` is numerically singular (an infinitesimally flexible
/// framework) or the result fails its check `‖Rᵀ Z‖ ≤ 1e-10 ‖R‖`, the QR is used after all.
fn equilibrium_basis(config: &[f64], dim: usize, links: &[(usize, usize)]) -> DMatrix<f64> {
    let n = config.len() / dim;
    let nd = n * dim;
    let nl = links.len();
    if (nl as f64) * (nd as f64) * (nd as f64) > 2e8 {
        if let Some(z) = projected_equilibrium_basis(config, dim, links) {
            return z;
        }
    }
    let mut r = DMatrix::zeros(nl, nd);
    for (l, &(i, j)) in links.iter().enumerate() {
        for d in 0..dim {
            let diff = config[i * dim + d] - config[j * dim + d];
            r[(l, i * dim + d)] = diff;
            r[(l, j * dim + d)] = -diff;
        }
    }
    complement_basis(&r).0
}

/// `Rᵀ E` (N D × m) for the rigidity matrix `R` of `links`.
fn rigidity_tr_mul(
    config: &[f64],
    dim: usize,
    links: &[(usize, usize)],
    e: &DMatrix<f64>,
) -> DMatrix<f64> {
    let nd = config.len();
    let mut out = DMatrix::zeros(nd, e.ncols());
    for c in 0..e.ncols() {
        let ec = e.column(c);
        let mut oc = out.column_mut(c);
        for (l, &(i, j)) in links.iter().enumerate() {
            let v = ec[l];
            for d in 0..dim {
                let diff = (config[i * dim + d] - config[j * dim + d]) * v;
                oc[i * dim + d] += diff;
                oc[j * dim + d] -= diff;
            }
        }
    }
    out
}

/// `R K` (L × m) for the rigidity matrix `R` of `links`.
fn rigidity_mul(
    config: &[f64],
    dim: usize,
    links: &[(usize, usize)],
    k: &DMatrix<f64>,
) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(links.len(), k.ncols());
    for c in 0..k.ncols() {
        let kc = k.column(c);
        let mut oc = out.column_mut(c);
        for (l, &(i, j)) in links.iter().enumerate() {
            let mut v = 0.0;
            for d in 0..dim {
                v += (config[i * dim + d] - config[j * dim + d])
                    * (kc[i * dim + d] - kc[j * dim + d]);
            }
            oc[l] = v;
        }
    }
    out
}

/// The projection method of [`equilibrium_basis`]; `None` when it does not apply.
fn projected_equilibrium_basis(
    config: &[f64],
    dim: usize,
    links: &[(usize, usize)],
) -> Option<DMatrix<f64>> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let n = config.len() / dim;
    let nd = n * dim;
    let nl = links.len();
    let trivial = dim * (dim + 1) / 2;
    // RᵀR, then the trivial motions: translations and rotations about the centroid.
    let mut k = DMatrix::<f64>::zeros(nd, nd);
    let mut scale = 0.0_f64;
    for &(i, j) in links {
        let mut idx = [0usize; 6];
        let mut val = [0.0f64; 6];
        for d in 0..dim {
            let diff = config[i * dim + d] - config[j * dim + d];
            scale = scale.max(diff.abs());
            idx[d] = i * dim + d;
            val[d] = diff;
            idx[dim + d] = j * dim + d;
            val[dim + d] = -diff;
        }
        for a in 0..2 * dim {
            for b in 0..2 * dim {
                k[(idx[a], idx[b])] += val[a] * val[b];
            }
        }
    }
    let mut centroid = vec![0.0; dim];
    for i in 0..n {
        for d in 0..dim {
            centroid[d] += config[i * dim + d] / n as f64;
        }
    }
    let mut motions: Vec<DVector<f64>> = Vec::with_capacity(trivial);
    for d in 0..dim {
        motions.push(DVector::from_fn(nd, |r, _| f64::from(r % dim == d)));
    }
    for a in 0..dim {
        for b in a + 1..dim {
            let mut v = DVector::zeros(nd);
            for i in 0..n {
                v[i * dim + a] = -(config[i * dim + b] - centroid[b]);
                v[i * dim + b] = config[i * dim + a] - centroid[a];
            }
            motions.push(v);
        }
    }
    // Gram–Schmidt, twice; the eigenvalue on the motions is scale² (the size of RᵀR).
    for t in 0..motions.len() {
        for _ in 0..2 {
            for s in 0..t {
                let c = motions[s].dot(&motions[t]);
                let ms = motions[s].clone();
                motions[t].axpy(-c, &ms, 1.0);
            }
        }
        let norm = motions[t].norm();
        if norm == 0.0 {
            return None;
        }
        motions[t] /= norm;
    }
    let s2 = scale * scale;
    for v in &motions {
        k.ger(s2, v, v, 1.0);
    }
    let kmax = k.diagonal().amax();
    let chol = dense::cholesky(k)?;
    let fmin = chol.l_dirty().diagonal().min();
    // A pivot below 1e-6 of the largest (an eigenvalue below 1e-12 of it): numerically flexible.
    if fmin.is_nan() || fmin * fmin <= 1e-12 * kmax {
        return None;
    }
    let m = (nl + trivial).checked_sub(nd)?;
    if m == 0 {
        return Some(DMatrix::zeros(nl, 0));
    }
    let finv = dense::tri_inverse_lower(chol.l_dirty());
    let project = |e: DMatrix<f64>| -> DMatrix<f64> {
        let rte = rigidity_tr_mul(config, dim, links, &e);
        let kk = dense::par_mul_tr(&finv, &dense::par_mul(&finv, &rte));
        e - rigidity_mul(config, dim, links, &kk)
    };
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(0x5eed);
    let e = DMatrix::from_fn(nl, m, |_, _| StandardNormal.sample(&mut rng));
    let mut z = project(project(e));
    for _ in 0..2 {
        let g = dense::symmetrise(dense::par_mul_tr(&z, &z));
        let ch = dense::cholesky(g)?;
        z = dense::par_mul(&z, &dense::inv_factor_transpose(&ch));
    }
    let check = rigidity_tr_mul(config, dim, links, &z).amax();
    (check <= 1e-10 * scale.max(f64::MIN_POSITIVE)).then_some(z)
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
    /// Solver that produced the weights.
    pub solver: &'static str,
    /// Relative optimality gap of the final SDP (0 for closed forms).
    pub gap: f64,
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
        solver,
        gap,
    } = how;
    let eig = space.spectrum(w);
    let lmin = eig[0];
    let lmax = eig[eig.len() - 1];
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
        solver,
        gap,
        note: None,
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
