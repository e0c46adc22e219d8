//! Frameworks: a nominal configuration, a sensing graph, Laplacian (stress) weights and leaders,
//! checked once when built.
//!
//! A framework `(G, p)` with a generalized Laplacian `L = B diag(w) Bᵀ` (thesis eq. 3.4) drives the
//! followers to an affine image of `p` when `L` is positive semidefinite with rank `N − D − 1` and
//! `(L ⊗ I_D) p = 0` (thesis Theorems 3.1–3.2). [`Framework::new`] verifies exactly that, and checks
//! the leaders (none or `D + 1` distinct agents; thesis §3.5, Theorem 3.3); the distance-based leader law also needs them to
//! form a complete subgraph ([`Framework::check_leader_clique`]).
//!
//! The weight design problem itself (thesis SDP (3.5) and others) is a separate concern.

use nalgebra::{DMatrix, DVector};

use crate::graph::{Graph, GraphError};

/// Errors building a [`Framework`]; each names the offending quantity.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameworkError {
    /// The graph is invalid.
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// Unsupported dimension.
    #[error("dimension must be 1, 2 or 3, got {0}")]
    Dimension(usize),
    /// A configuration point has the wrong number of coordinates.
    #[error("config[{agent}] has {got} coordinates, expected dim = {expected}")]
    ConfigDimension {
        /// Agent index.
        agent: usize,
        /// Expected D.
        expected: usize,
        /// Coordinates given.
        got: usize,
    },
    /// A number is NaN or infinite.
    #[error("{what} is not finite")]
    NotFinite {
        /// What was not finite.
        what: String,
    },
    /// Wrong number of weights.
    #[error("{got} weights given for {expected} links")]
    WeightCount {
        /// Number of links.
        expected: usize,
        /// Number of weights.
        got: usize,
    },
    /// A link carries zero weight (it should then not be a link).
    #[error("link ({i}, {j}) has zero weight")]
    ZeroWeight {
        /// First endpoint.
        i: usize,
        /// Second endpoint.
        j: usize,
    },
    /// The configuration does not affinely span R^D.
    #[error("the configuration is degenerate: its affine span has dimension {rank} < {dim}")]
    Degenerate {
        /// Dimension of the affine span.
        rank: usize,
        /// D.
        dim: usize,
    },
    /// The Laplacian has a negative eigenvalue.
    #[error("the Laplacian is not positive semidefinite: smallest eigenvalue {min_eig:.3e}")]
    NotPsd {
        /// Smallest eigenvalue.
        min_eig: f64,
    },
    /// The Laplacian has the wrong rank.
    #[error("the Laplacian has rank {rank}, but N − D − 1 = {expected} is needed (Theorem 3.2)")]
    WrongRank {
        /// Numerical rank.
        rank: usize,
        /// N − D − 1.
        expected: usize,
    },
    /// The configuration is not an equilibrium: `(L ⊗ I) p ≠ 0`.
    #[error(
        "the configuration is not in the Laplacian's null space: max |(L ⊗ I) p| = {residual:.3e}"
    )]
    NotEquilibrium {
        /// Largest residual entry.
        residual: f64,
    },
    /// A leader index is out of range.
    #[error("leader {leader} is not an agent (agents are 0..{n})")]
    LeaderOutOfRange {
        /// The leader.
        leader: usize,
        /// N.
        n: usize,
    },
    /// Wrong number of leaders.
    #[error("{got} leaders given; rigid formations need none or exactly D + 1 = {expected}")]
    LeaderCount {
        /// Number given.
        got: usize,
        /// D + 1.
        expected: usize,
    },
    /// Leaders repeated.
    #[error("leader {0} is listed twice")]
    DuplicateLeader(usize),
    /// Leaders are not mutually linked.
    #[error("leaders {i} and {j} are not linked: the distance-based leader law needs the leaders to form a complete subgraph")]
    LeadersNotComplete {
        /// First leader.
        i: usize,
        /// Second leader.
        j: usize,
    },
}

/// Hexagon weights per link in sorted link order (see [`Framework::hexagon`]).
#[allow(clippy::excessive_precision)]
const HEXAGON_WEIGHTS: [f64; 30] = [
    6.868790779120246,
    6.868790779327488,
    12.23772544841831,
    6.034294411056413,
    13.559416231153289,
    -3.6080463663082836,
    -9.642340777468307,
    6.868790779262154,
    12.237725448494787,
    -9.642340777589128,
    6.03429441132903,
    13.559416230890145,
    -3.6080463663310516,
    12.237725448351897,
    -3.6080463663699076,
    -9.642340777696052,
    6.034294411358811,
    13.559416230844272,
    -3.615041139028913,
    3.4778627508550084,
    -3.6150411393082638,
    3.4778627511175983,
    -3.61504113932975,
    3.477862750909701,
    -0.6152300888425334,
    4.205940299870623,
    4.205940299952029,
    -0.6152300888666229,
    4.205940299981399,
    -0.6152300888635317,
];

/// A checked framework.
#[derive(Debug, Clone)]
pub struct Framework {
    name: String,
    dim: usize,
    config: Vec<f64>,
    graph: Graph,
    weights: Vec<f64>,
    leaders: Vec<usize>,
    laplacian: DMatrix<f64>,
    eigenvalues: Vec<f64>,
}

impl Framework {
    /// Builds and checks a framework.
    ///
    /// `config` holds one point per agent; `links` the undirected links (any orientation; they
    /// are sorted as in [`Graph::links`]) and `weights` one weight per entry of `links`, in the
    /// order given.
    ///
    /// # Errors
    /// [`FrameworkError`] naming the failed condition: graph, dimensions, finiteness, weights,
    /// degenerate configuration, Laplacian not PSD, wrong rank, configuration not an equilibrium,
    /// leaders.
    pub fn new(
        name: impl Into<String>,
        dim: usize,
        config: &[Vec<f64>],
        links: &[(usize, usize)],
        weights: &[f64],
        leaders: &[usize],
    ) -> Result<Self, FrameworkError> {
        if !(1..=3).contains(&dim) {
            return Err(FrameworkError::Dimension(dim));
        }
        let n = config.len();
        let mut flat = Vec::with_capacity(n * dim);
        for (agent, p) in config.iter().enumerate() {
            if p.len() != dim {
                return Err(FrameworkError::ConfigDimension {
                    agent,
                    expected: dim,
                    got: p.len(),
                });
            }
            if p.iter().any(|v| !v.is_finite()) {
                return Err(FrameworkError::NotFinite {
                    what: format!("config[{agent}]"),
                });
            }
            flat.extend_from_slice(p);
        }
        let graph = Graph::new(n, links)?;
        if weights.len() != links.len() {
            return Err(FrameworkError::WeightCount {
                expected: links.len(),
                got: weights.len(),
            });
        }
        let mut sorted_w = vec![0.0; links.len()];
        for (&(i, j), &w) in links.iter().zip(weights) {
            if !w.is_finite() {
                return Err(FrameworkError::NotFinite {
                    what: format!("weight of link ({i}, {j})"),
                });
            }
            if w == 0.0 {
                return Err(FrameworkError::ZeroWeight {
                    i: i.min(j),
                    j: i.max(j),
                });
            }
            let l = graph
                .links()
                .binary_search(&(i.min(j), i.max(j)))
                .expect("graph holds every link");
            sorted_w[l] = w;
        }
        let span = affine_rank(&flat, n, dim);
        if span < dim {
            return Err(FrameworkError::Degenerate { rank: span, dim });
        }
        let laplacian = graph.laplacian(&sorted_w);
        let spec = StressSpectrum::of(&laplacian, &flat, dim);
        if spec.eigenvalues[0] < -spec.eigen_tolerance {
            return Err(FrameworkError::NotPsd {
                min_eig: spec.eigenvalues[0],
            });
        }
        let expected = n.saturating_sub(dim + 1);
        if spec.rank != expected {
            return Err(FrameworkError::WrongRank {
                rank: spec.rank,
                expected,
            });
        }
        if spec.equilibrium_residual > spec.equilibrium_tolerance {
            return Err(FrameworkError::NotEquilibrium {
                residual: spec.equilibrium_residual,
            });
        }
        let eigenvalues = spec.eigenvalues;
        check_leaders(&graph, dim, leaders)?;
        Ok(Self {
            name: name.into(),
            dim,
            config: flat,
            graph,
            weights: sorted_w,
            leaders: leaders.to_vec(),
            laplacian,
            eigenvalues,
        })
    }

    /// The thesis hexagon (thesis §3.6, Fig. 3.2; EUSIPCO Fig. 2a): N = 10 agents in 2-D,
    /// 30 links (60 directed edges), a 2-trilateration graph whose first three agents form a
    /// triangle and are the leaders.
    ///
    /// Coordinates (the papers print none; these are ours): leaders 0, 1, 2 on the unit circle at
    /// 90°, 210°, 330°; agent 3 at the centre; agents 4–9 on a hexagon of radius 2 at 30°, 90°,
    /// 150°, 210°, 270°, 330°. Agent k ≥ 3 links to the earlier agents
    /// 3: {0, 1, 2}; 4: {0, 2, 3}; 5: {0, 1, 3, 4}; 6: {0, 1, 3, 5}; 7: {1, 2, 3, 6};
    /// 8: {1, 2, 3, 7}; 9: {0, 2, 3, 4, 8}.
    ///
    /// Weights: the best-conditioned stress, `min t` s.t. `I ⪯ Q L Qᵀ ⪯ t I` with
    /// `L = B diag(w) Bᵀ` and `w` in the null space of the equilibrium map `L [P 1] = 0` (thesis
    /// (3.5) with the smallest nonzero eigenvalue fixed at 1 and the largest minimised), solved
    /// offline; the spectrum is {0 (×3), 1 (×3), 15.7, 51.6 (×3)}, so `Δt λ_max ≈ 0.05` at
    /// Δt = 1 ms. [`Framework::new`] re-verifies PSD, rank 7 and the null space at build.
    pub fn hexagon() -> Self {
        let s3 = 3f64.sqrt();
        let config = vec![
            vec![0.0, 1.0],
            vec![-s3 / 2.0, -0.5],
            vec![s3 / 2.0, -0.5],
            vec![0.0, 0.0],
            vec![s3, 1.0],
            vec![0.0, 2.0],
            vec![-s3, 1.0],
            vec![-s3, -1.0],
            vec![0.0, -2.0],
            vec![s3, -1.0],
        ];
        let attach: &[(usize, &[usize])] = &[
            (1, &[0]),
            (2, &[0, 1]),
            (3, &[0, 1, 2]),
            (4, &[0, 2, 3]),
            (5, &[0, 1, 3, 4]),
            (6, &[0, 1, 3, 5]),
            (7, &[1, 2, 3, 6]),
            (8, &[1, 2, 3, 7]),
            (9, &[0, 2, 3, 4, 8]),
        ];
        let mut links: Vec<(usize, usize)> = attach
            .iter()
            .flat_map(|&(k, nb)| nb.iter().map(move |&j| (j, k)))
            .collect();
        links.sort_unstable();
        Self::new("hexagon", 2, &config, &links, &HEXAGON_WEIGHTS, &[0, 1, 2])
            .expect("hexagon framework is valid")
    }

    /// Name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Dimension D.
    pub fn dim(&self) -> usize {
        self.dim
    }
    /// Number of agents N.
    pub fn agents(&self) -> usize {
        self.graph.agents()
    }
    /// Configuration, agent-major (`i * D + d`).
    pub fn config(&self) -> &[f64] {
        &self.config
    }
    /// Point of agent `i`.
    pub fn point(&self, i: usize) -> &[f64] {
        &self.config[i * self.dim..(i + 1) * self.dim]
    }
    /// The sensing graph.
    pub fn graph(&self) -> &Graph {
        &self.graph
    }
    /// One weight per undirected link, in [`Graph::links`] order.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
    /// `l_ij` per directed edge, in incidence order.
    pub fn edge_weights(&self) -> Vec<f64> {
        (0..self.graph.num_edges())
            .map(|e| self.weights[self.graph.link_of(e)])
            .collect()
    }
    /// Leaders (empty: a purely affine formation).
    pub fn leaders(&self) -> &[usize] {
        &self.leaders
    }
    /// The generalized Laplacian.
    pub fn laplacian(&self) -> &DMatrix<f64> {
        &self.laplacian
    }
    /// Eigenvalues of the Laplacian, ascending.
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }
    /// Smallest nonzero eigenvalue of `L` (the `D + 2`-th smallest): the affine convergence rate.
    pub fn stress_gap(&self) -> f64 {
        self.eigenvalues[self.dim + 1]
    }

    /// Checks that the leaders are mutually linked: the thesis's distance-based leader law
    /// (thesis §3.5) steers the leaders on their own edges to a congruent simplex, so it needs
    /// them to form a complete subgraph. A stress does not depend on who leads, so
    /// [`Framework::new`] does not ask for it; a scenario that uses the distance law does.
    ///
    /// # Errors
    /// [`FrameworkError::LeadersNotComplete`] naming the first unlinked pair.
    pub fn check_leader_clique(&self) -> Result<(), FrameworkError> {
        for (k, &a) in self.leaders.iter().enumerate() {
            for &b in &self.leaders[k + 1..] {
                if !self.graph.has_link(a, b) {
                    return Err(FrameworkError::LeadersNotComplete {
                        i: a.min(b),
                        j: a.max(b),
                    });
                }
            }
        }
        Ok(())
    }
}

impl Framework {
    /// The same framework with other leaders (none, or `D + 1` distinct agents); the stress is
    /// not re-verified (it does not depend on who leads).
    ///
    /// # Errors
    /// [`FrameworkError::LeaderCount`], [`FrameworkError::LeaderOutOfRange`] or
    /// [`FrameworkError::DuplicateLeader`].
    pub fn with_leaders(mut self, leaders: &[usize]) -> Result<Self, FrameworkError> {
        check_leaders(&self.graph, self.dim, leaders)?;
        self.leaders = leaders.to_vec();
        Ok(self)
    }
}

fn check_leaders(graph: &Graph, dim: usize, leaders: &[usize]) -> Result<(), FrameworkError> {
    let n = graph.agents();
    if !(leaders.is_empty() || leaders.len() == dim + 1) {
        return Err(FrameworkError::LeaderCount {
            got: leaders.len(),
            expected: dim + 1,
        });
    }
    for (k, &a) in leaders.iter().enumerate() {
        if a >= n {
            return Err(FrameworkError::LeaderOutOfRange { leader: a, n });
        }
        if leaders[..k].contains(&a) {
            return Err(FrameworkError::DuplicateLeader(a));
        }
    }
    Ok(())
}

/// The spectral facts of a stress (generalized Laplacian) for a configuration, with the
/// tolerances every check in this crate uses: an eigenvalue counts as zero below
/// `1e-9 · max|λ| · N`, and the equilibrium `(L ⊗ I) p = 0` holds when its largest entry is below
/// `1e-9 · max|λ| · max(1, max|p|) · N` — far above the ≈ 1e-15 relative round-off of the
/// eigensolver, far below any stress that matters.
#[derive(Debug, Clone, PartialEq)]
pub struct StressSpectrum {
    /// Eigenvalues, ascending.
    pub eigenvalues: Vec<f64>,
    /// Zero threshold for eigenvalues.
    pub eigen_tolerance: f64,
    /// Numerical rank.
    pub rank: usize,
    /// Largest entry of `|(L ⊗ I) p|`.
    pub equilibrium_residual: f64,
    /// Threshold for the residual.
    pub equilibrium_tolerance: f64,
}

impl StressSpectrum {
    /// Computes the spectrum of `laplacian` (N × N) and the equilibrium residual of the
    /// agent-major configuration `flat` (N · D). Eigenvalues only (no eigenvectors: 0.6 s
    /// instead of 2.3 s for N = 1000).
    pub fn of(laplacian: &DMatrix<f64>, flat: &[f64], dim: usize) -> Self {
        let eigenvalues: Vec<f64> = laplacian.symmetric_eigenvalues().iter().copied().collect();
        Self::from_eigenvalues(eigenvalues, laplacian, flat, dim)
    }

    /// As [`StressSpectrum::of`], with the eigenvalues of `laplacian` already computed (in any
    /// order).
    pub fn from_eigenvalues(
        mut eigenvalues: Vec<f64>,
        laplacian: &DMatrix<f64>,
        flat: &[f64],
        dim: usize,
    ) -> Self {
        let n = laplacian.nrows();
        eigenvalues.sort_by(f64::total_cmp);
        let scale = eigenvalues
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        let eigen_tolerance = 1e-9 * scale * n as f64;
        let rank = eigenvalues.iter().filter(|&&v| v > eigen_tolerance).count();
        let pmax = flat.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1.0);
        let mut equilibrium_residual = 0.0_f64;
        for d in 0..dim {
            let q = DVector::from_iterator(n, (0..n).map(|i| flat[i * dim + d]));
            equilibrium_residual = equilibrium_residual.max((laplacian * q).amax());
        }
        Self {
            eigenvalues,
            eigen_tolerance,
            rank,
            equilibrium_residual,
            equilibrium_tolerance: 1e-9 * scale * pmax * n as f64,
        }
    }
}

/// Dimension of the affine span of the points (singular values of the configuration relative to
/// its first point above `1e-9` of the largest).
pub(crate) fn affine_rank(flat: &[f64], n: usize, dim: usize) -> usize {
    let mut m = DMatrix::zeros(n, dim);
    for i in 0..n {
        for d in 0..dim {
            m[(i, d)] = flat[i * dim + d] - flat[d];
        }
    }
    let sv = m.singular_values();
    let smax = sv.max().max(f64::MIN_POSITIVE);
    sv.iter().filter(|&&s| s > 1e-9 * smax).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hexagon_is_the_thesis_framework() {
        let f = Framework::hexagon();
        assert_eq!(f.agents(), 10);
        assert_eq!(f.graph().links().len(), 30);
        assert_eq!(f.graph().num_edges(), 60);
        assert_eq!(f.leaders(), &[0, 1, 2]);
        // PSD, rank N − D − 1 = 7, and the configuration and 1 in the null space.
        let ev = f.eigenvalues();
        let scale = ev[9];
        assert!(ev[0] > -1e-12 * scale);
        assert_eq!(ev.iter().filter(|&&v| v > 1e-9 * scale).count(), 7);
        // Designed spectrum: nonzero eigenvalues in [1, 51.6].
        assert!((f.stress_gap() - 1.0).abs() < 1e-6);
        assert!(scale < 52.0);
        let l = f.laplacian();
        let ones = DVector::from_element(10, 1.0);
        assert!((l * ones).amax() < 1e-12 * scale);
        for d in 0..2 {
            let q = DVector::from_iterator(10, (0..10).map(|i| f.point(i)[d]));
            assert!((l * q).amax() < 1e-10 * scale);
        }
        // 2-trilateration: agents after the first three have at least 3 earlier neighbours.
        for k in 3..10 {
            assert!(f.graph().neighbours(k).filter(|&j| j < k).count() >= 3);
        }
    }

    #[test]
    fn flexible_or_wrong_weights_are_rejected() {
        let f = Framework::hexagon();
        let cfg: Vec<Vec<f64>> = (0..10).map(|i| f.point(i).to_vec()).collect();
        let mut w = f.weights().to_vec();
        w[0] += 0.1;
        let err = Framework::new("x", 2, &cfg, f.graph().links(), &w, &[0, 1, 2]).unwrap_err();
        assert!(
            matches!(
                err,
                FrameworkError::NotEquilibrium { .. }
                    | FrameworkError::WrongRank { .. }
                    | FrameworkError::NotPsd { .. }
            ),
            "{err}"
        );
        let neg: Vec<f64> = f.weights().iter().map(|v| -v).collect();
        let err = Framework::new("x", 2, &cfg, f.graph().links(), &neg, &[0, 1, 2]).unwrap_err();
        assert!(matches!(err, FrameworkError::NotPsd { .. }), "{err}");
        let unlinked =
            Framework::new("x", 2, &cfg, f.graph().links(), f.weights(), &[0, 1, 9]).unwrap();
        assert_eq!(
            unlinked.check_leader_clique().unwrap_err().to_string(),
            "leaders 1 and 9 are not linked: the distance-based leader law needs the leaders to form a complete subgraph"
        );
        let err =
            Framework::new("x", 2, &cfg, f.graph().links(), f.weights(), &[0, 1, 12]).unwrap_err();
        assert!(matches!(
            err,
            FrameworkError::LeaderOutOfRange { leader: 12, .. }
        ));
        let err = Framework::new("x", 2, &cfg, f.graph().links(), &w[..29], &[]).unwrap_err();
        assert!(matches!(
            err,
            FrameworkError::WeightCount {
                expected: 30,
                got: 29
            }
        ));
    }
}
