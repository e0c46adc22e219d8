//! The check report: every condition of thesis Theorems 3.1–3.2 on one framework, each with the
//! number it was decided on.
//!
//! A framework `(G, p)` with stress (generalized Laplacian) `L = B diag(w) Bᵀ` drives the
//! followers of `u_i = −Σ_j l_ij z_ij` to an affine image of `p` iff
//! 1. `G` is connected;
//! 2. `p` is generic: its affine span is all of `R^D` (thesis §3.4: then `q_1, …, q_D, 1` are
//!    independent);
//! 3. `p` is an equilibrium: `Σ_j l_ij (p_i − p_j) = 0` for every agent, i.e. `(L ⊗ I) p = 0`;
//! 4. `L ⪰ 0` with rank `N − D − 1`, which certifies universal rigidity (Theorem 3.2).
//!
//! The report adds the D-trilateration test (a sufficient graph condition for generic universal
//! rigidity, thesis §2.5) and the smallest nonzero eigenvalue of `L`, the convergence rate of the
//! closed loop. The tolerances are those of [`Framework::new`](crate::framework::Framework::new),
//! so a framework passes this report iff it can be built.

use std::fmt;

use nalgebra::DMatrix;

use super::DesignError;
use crate::framework::Framework;

/// Outcome of the D-trilateration test.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Trilateration {
    /// A D-trilateration ordering exists; the seed clique of D + 1 agents is given.
    Yes {
        /// The initial complete subgraph.
        seed: Vec<usize>,
    },
    /// No ordering exists.
    No,
    /// The search was cut off (more than [`MAX_SEEDS`] seed cliques tried).
    Undecided,
}

/// Seed cliques tried by the trilateration test before it gives up.
pub const MAX_SEEDS: usize = 20_000;

/// Everything checked on one framework.
#[derive(Debug, Clone)]
pub struct CheckReport {
    /// N.
    pub agents: usize,
    /// D.
    pub dim: usize,
    /// Number of undirected links with nonzero weight.
    pub links: usize,
    /// An agent not reachable from agent 0, if any.
    pub unreached: Option<usize>,
    /// Dimension of the affine span of the configuration.
    pub affine_span: usize,
    /// Smallest over largest singular value of the centred configuration (1 = isotropic,
    /// 0 = degenerate).
    pub span_ratio: f64,
    /// Largest entry of `|(L ⊗ I) p|`.
    pub equilibrium_residual: f64,
    /// Tolerance the residual was compared with.
    pub equilibrium_tolerance: f64,
    /// Eigenvalues of `L`, ascending.
    pub eigenvalues: Vec<f64>,
    /// Tolerance below which an eigenvalue counts as zero.
    pub eigen_tolerance: f64,
    /// Numerical rank of `L`.
    pub rank: usize,
    /// `N − D − 1`.
    pub expected_rank: usize,
    /// The trilateration test.
    pub trilateration: Trilateration,
    /// Leaders (none, or D + 1 agents).
    pub leaders: Vec<usize>,
    /// A pair of leaders that is not linked, if any (the distance-based leader law of thesis
    /// §3.5 needs the leaders mutually linked; target tracking does not).
    pub unlinked_leaders: Option<(usize, usize)>,
    /// `λ_min(L_ff)`, the smallest eigenvalue of the followers' block of `L` (leaders' rows and
    /// columns removed): the followers' convergence rate with the leaders held, time constant
    /// `1/λ_min(L_ff)`. `None` without leaders.
    pub follower_min_eigenvalue: Option<f64>,
}

impl CheckReport {
    /// Graph connected.
    pub fn connected(&self) -> bool {
        self.unreached.is_none()
    }
    /// Affine span is all of `R^D`.
    pub fn generic(&self) -> bool {
        self.affine_span == self.dim
    }
    /// `(L ⊗ I) p = 0` within tolerance.
    pub fn equilibrium(&self) -> bool {
        self.equilibrium_residual <= self.equilibrium_tolerance
    }
    /// `L ⪰ 0` within tolerance.
    pub fn psd(&self) -> bool {
        self.eigenvalues
            .first()
            .is_some_and(|&v| v >= -self.eigen_tolerance)
    }
    /// PSD with rank `N − D − 1` (and generic): universally rigid by Theorem 3.2.
    pub fn universally_rigid(&self) -> bool {
        self.generic() && self.psd() && self.rank == self.expected_rank
    }
    /// Smallest nonzero eigenvalue of `L` (the `D + 2`-th smallest): the convergence rate.
    pub fn stress_gap(&self) -> f64 {
        self.eigenvalues
            .get(self.dim + 1)
            .copied()
            .unwrap_or(f64::NAN)
    }
    /// Largest eigenvalue of `L` (bounds the step: `Δt < 2 / λ_max`).
    pub fn max_eigenvalue(&self) -> f64 {
        self.eigenvalues.last().copied().unwrap_or(f64::NAN)
    }
    /// Every condition holds.
    pub fn passed(&self) -> bool {
        self.verdict().is_ok()
    }

    /// The first failed condition as an error, in the order of the report.
    ///
    /// # Errors
    /// [`DesignError::Input`] for a disconnected graph, [`DesignError::NonGeneric`],
    /// [`DesignError::NotUniversallyRigid`] for a failed equilibrium, PSD or rank condition.
    pub fn verdict(&self) -> Result<(), DesignError> {
        if let Some(a) = self.unreached {
            return Err(DesignError::NotUniversallyRigid(format!(
                "the graph is not connected: agent {a} cannot be reached from agent 0"
            )));
        }
        if !self.generic() {
            return Err(DesignError::NonGeneric(format!(
                "the affine span of the configuration has dimension {} < D = {}",
                self.affine_span, self.dim
            )));
        }
        if !self.equilibrium() {
            return Err(DesignError::NotUniversallyRigid(format!(
                "the configuration is not an equilibrium of the stress: max |(L ⊗ I) p| = {:.3e} > {:.1e}",
                self.equilibrium_residual, self.equilibrium_tolerance
            )));
        }
        if !self.psd() {
            return Err(DesignError::NotUniversallyRigid(format!(
                "the Laplacian is not positive semidefinite: smallest eigenvalue {:.3e}",
                self.eigenvalues[0]
            )));
        }
        if self.rank != self.expected_rank {
            return Err(DesignError::NotUniversallyRigid(format!(
                "the Laplacian has rank {}, but N − D − 1 = {} is needed (Theorem 3.2)",
                self.rank, self.expected_rank
            )));
        }
        Ok(())
    }

    /// The report of a checked framework, with its leaders. Reuses the framework's eigenvalues
    /// (no second eigendecomposition).
    pub fn from_framework(f: &Framework) -> Self {
        let config: Vec<Vec<f64>> = (0..f.agents()).map(|i| f.point(i).to_vec()).collect();
        let links: Vec<(usize, usize, f64)> = f
            .graph()
            .links()
            .iter()
            .zip(f.weights())
            .map(|(&(i, j), &w)| (i, j, w))
            .collect();
        let spectrum = crate::framework::StressSpectrum::from_eigenvalues(
            f.eigenvalues().to_vec(),
            f.laplacian(),
            f.config(),
            f.dim(),
        );
        report(
            f.dim(),
            &config,
            &links,
            f.laplacian(),
            spectrum,
            f.leaders(),
        )
    }

    /// The time constant `1/λ_min(L_ff)` of the followers (unit gain), if there are leaders.
    pub fn follower_time_constant(&self) -> Option<f64> {
        self.follower_min_eigenvalue.map(|v| 1.0 / v)
    }
}

/// Checks a framework given by its configuration, links, one weight per link and its leaders
/// (none, or D + 1 agents). Links with zero weight are ignored (they are not links of the
/// stress).
///
/// # Errors
/// [`DesignError::Input`] for malformed input only (wrong lengths, agents out of range,
/// non-finite numbers, a wrong number of leaders or repeated leaders); every failed *condition*
/// is reported in the [`CheckReport`].
pub fn check(
    dim: usize,
    config: &[Vec<f64>],
    links: &[(usize, usize)],
    weights: &[f64],
    leaders: &[usize],
) -> Result<CheckReport, DesignError> {
    let n = config.len();
    if !(1..=3).contains(&dim) {
        return Err(DesignError::Input(format!(
            "dimension must be 1, 2 or 3, got {dim}"
        )));
    }
    if weights.len() != links.len() {
        return Err(DesignError::Input(format!(
            "{} weights given for {} links",
            weights.len(),
            links.len()
        )));
    }
    for (i, p) in config.iter().enumerate() {
        if p.len() != dim || p.iter().any(|v| !v.is_finite()) {
            return Err(DesignError::Input(format!(
                "config[{i}] must hold {dim} finite coordinates"
            )));
        }
    }
    if !(leaders.is_empty() || leaders.len() == dim + 1) {
        return Err(DesignError::Input(format!(
            "{} leaders given; none or D + 1 = {} are needed",
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
    let mut active = Vec::new();
    for (&(i, j), &w) in links.iter().zip(weights) {
        if i >= n || j >= n || i == j {
            return Err(DesignError::Input(format!(
                "link ({i}, {j}) is not a link between two of the {n} agents"
            )));
        }
        if !w.is_finite() {
            return Err(DesignError::Input(format!(
                "weight of link ({i}, {j}) is not finite"
            )));
        }
        if w != 0.0 {
            active.push((i.min(j), i.max(j), w));
        }
    }
    // Laplacian, spectrum, equilibrium: the same tolerances as Framework::new (StressSpectrum).
    let mut l = DMatrix::<f64>::zeros(n, n);
    for &(i, j, w) in &active {
        l[(i, i)] += w;
        l[(j, j)] += w;
        l[(i, j)] -= w;
        l[(j, i)] -= w;
    }
    let flat: Vec<f64> = config.iter().flatten().copied().collect();
    let spectrum = crate::framework::StressSpectrum::of(&l, &flat, dim);
    Ok(report(dim, config, &active, &l, spectrum, leaders))
}

/// The report from the (validated) links with nonzero weight, the stress matrix and its spectrum.
fn report(
    dim: usize,
    config: &[Vec<f64>],
    active: &[(usize, usize, f64)],
    l: &DMatrix<f64>,
    spectrum: crate::framework::StressSpectrum,
    leaders: &[usize],
) -> CheckReport {
    let n = config.len();
    // Connectivity (adjacency lists, so that the report stays O(N + L) beyond the spectrum).
    let mut adj = vec![Vec::new(); n];
    for &(i, j, _) in active {
        adj[i].push(j);
        adj[j].push(i);
    }
    for a in &mut adj {
        a.sort_unstable();
    }
    let unreached = if n == 0 {
        None
    } else {
        let mut seen = vec![false; n];
        let mut stack = vec![0];
        seen[0] = true;
        while let Some(a) = stack.pop() {
            for &b in &adj[a] {
                if !seen[b] {
                    seen[b] = true;
                    stack.push(b);
                }
            }
        }
        seen.iter().position(|s| !s)
    };
    // Affine span.
    let mut centred = DMatrix::zeros(n, dim);
    for (i, p) in config.iter().enumerate() {
        for d in 0..dim {
            centred[(i, d)] = p[d] - config[0][d];
        }
    }
    let sv = centred.singular_values();
    let smax = sv.max().max(f64::MIN_POSITIVE);
    // Same threshold as Framework::new.
    let affine_span = sv.iter().filter(|&&s| s > 1e-9 * smax).count();
    let span_ratio = if affine_span == 0 {
        0.0
    } else {
        sv.min() / smax
    };
    let crate::framework::StressSpectrum {
        eigenvalues,
        eigen_tolerance,
        rank,
        equilibrium_residual,
        equilibrium_tolerance,
    } = spectrum;
    let trilateration = trilateration_lists(&adj, dim);
    let unlinked_leaders = leaders.iter().enumerate().find_map(|(k, &a)| {
        leaders[k + 1..]
            .iter()
            .find(|&&b| adj[a].binary_search(&b).is_err())
            .map(|&b| (a.min(b), a.max(b)))
    });
    let follower_min_eigenvalue =
        (!leaders.is_empty()).then(|| super::leaders::follower_min_eigenvalue(l, leaders));
    CheckReport {
        agents: n,
        dim,
        links: active.len(),
        unreached,
        affine_span,
        span_ratio,
        equilibrium_residual,
        equilibrium_tolerance,
        eigenvalues,
        eigen_tolerance,
        rank,
        expected_rank: n.saturating_sub(dim + 1),
        trilateration,
        leaders: leaders.to_vec(),
        unlinked_leaders,
        follower_min_eigenvalue,
    }
}

/// Whether the graph is a D-trilateration graph: some D + 1 agents form a complete subgraph and
/// the others can be ordered so that each links to at least D + 1 earlier ones (thesis §2.5).
/// For a fixed seed the greedy closure is exact (adding an agent never hurts), so we try every
/// seed clique (at most [`MAX_SEEDS`]).
pub fn trilateration_test(adj: &[Vec<bool>], dim: usize) -> Trilateration {
    let lists: Vec<Vec<usize>> = adj
        .iter()
        .map(|row| (0..row.len()).filter(|&b| row[b]).collect())
        .collect();
    trilateration_lists(&lists, dim)
}

/// [`trilateration_test`] on ascending adjacency lists: each seed costs `O(N + L)`.
fn trilateration_lists(adj: &[Vec<usize>], dim: usize) -> Trilateration {
    let n = adj.len();
    let k = dim + 1;
    if n < k {
        return Trilateration::No;
    }
    let mut tried = 0;
    let mut clique = Vec::with_capacity(k);
    let mut result = None;
    let mut count = vec![0usize; n];
    let mut inside = vec![false; n];
    for v in 0..n {
        let later: Vec<usize> = adj[v].iter().copied().filter(|&u| u > v).collect();
        clique.push(v);
        extend_clique(
            adj,
            k,
            &mut clique,
            &later,
            &mut tried,
            &mut result,
            &mut count,
            &mut inside,
        );
        clique.pop();
        if result.is_some() {
            break;
        }
    }
    match result {
        Some(Some(seed)) => Trilateration::Yes { seed },
        Some(None) => Trilateration::Undecided,
        None => Trilateration::No,
    }
}

/// Depth-first enumeration of k-cliques (candidates: common later neighbours); `result` becomes
/// `Some(Some(seed))` on success and `Some(None)` when the seed budget runs out.
#[allow(clippy::too_many_arguments)]
fn extend_clique(
    adj: &[Vec<usize>],
    k: usize,
    clique: &mut Vec<usize>,
    cand: &[usize],
    tried: &mut usize,
    result: &mut Option<Option<Vec<usize>>>,
    count: &mut [usize],
    inside: &mut [bool],
) {
    if result.is_some() {
        return;
    }
    if clique.len() == k {
        *tried += 1;
        if *tried > MAX_SEEDS {
            *result = Some(None);
        } else if closure_covers_all(adj, clique, k, count, inside) {
            *result = Some(Some(clique.clone()));
        }
        return;
    }
    for (p, &v) in cand.iter().enumerate() {
        let next: Vec<usize> = cand[p + 1..]
            .iter()
            .copied()
            .filter(|u| adj[v].binary_search(u).is_ok())
            .collect();
        clique.push(v);
        extend_clique(adj, k, clique, &next, tried, result, count, inside);
        clique.pop();
        if result.is_some() {
            return;
        }
    }
}

/// Whether the greedy closure of `seed` (add any agent with ≥ k neighbours inside) is everyone.
/// `count` and `inside` are scratch space, returned cleared.
fn closure_covers_all(
    adj: &[Vec<usize>],
    seed: &[usize],
    k: usize,
    count: &mut [usize],
    inside: &mut [bool],
) -> bool {
    let n = adj.len();
    let mut queue: Vec<usize> = seed.to_vec();
    let mut added = Vec::with_capacity(n);
    for &v in seed {
        inside[v] = true;
    }
    while let Some(v) = queue.pop() {
        added.push(v);
        for &u in &adj[v] {
            if !inside[u] {
                count[u] += 1;
                if count[u] == k {
                    inside[u] = true;
                    queue.push(u);
                }
            }
        }
    }
    let all = added.len() == n;
    for c in count.iter_mut() {
        *c = 0;
    }
    for v in inside.iter_mut() {
        *v = false;
    }
    all
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mark = |ok: bool| if ok { "[ok]  " } else { "[FAIL]" };
        writeln!(
            f,
            "framework: N = {} agents in {}-D, {} links",
            self.agents, self.dim, self.links
        )?;
        match self.unreached {
            None => writeln!(f, "  {} graph connected", mark(true))?,
            Some(a) => writeln!(
                f,
                "  {} graph connected: agent {a} is not reachable from agent 0",
                mark(false)
            )?,
        }
        writeln!(
            f,
            "  {} generic configuration: affine span {} of {} (σ_min/σ_max of the centred configuration = {:.3})",
            mark(self.generic()),
            self.affine_span,
            self.dim,
            self.span_ratio
        )?;
        writeln!(
            f,
            "  {} equilibrium: max |Σ_j l_ij (p_i − p_j)| = {:.2e} (tolerance {:.1e})",
            mark(self.equilibrium()),
            self.equilibrium_residual,
            self.equilibrium_tolerance
        )?;
        writeln!(
            f,
            "  {} Laplacian positive semidefinite: smallest eigenvalue {:.2e} (tolerance {:.1e})",
            mark(self.psd()),
            self.eigenvalues.first().copied().unwrap_or(f64::NAN),
            self.eigen_tolerance
        )?;
        writeln!(
            f,
            "  {} rank {} (N − D − 1 = {}){}",
            mark(self.rank == self.expected_rank),
            self.rank,
            self.expected_rank,
            if self.universally_rigid() {
                " ⇒ universally rigid (Theorem 3.2)"
            } else {
                ""
            }
        )?;
        match &self.trilateration {
            Trilateration::Yes { seed } => writeln!(
                f,
                "  [ok]   {}-trilateration graph (seed clique {:?})",
                self.dim, seed
            )?,
            Trilateration::No => writeln!(
                f,
                "  [--]   not a {}-trilateration graph (sufficient, not necessary)",
                self.dim
            )?,
            Trilateration::Undecided => writeln!(
                f,
                "  [--]   {}-trilateration test undecided after {MAX_SEEDS} seed cliques",
                self.dim
            )?,
        }
        let gap = self.stress_gap();
        let lmax = self.max_eigenvalue();
        writeln!(
            f,
            "  smallest nonzero eigenvalue (convergence rate) {gap:.4}, largest {lmax:.4}, ratio {:.2}",
            lmax / gap
        )?;
        match self.follower_min_eigenvalue {
            None => writeln!(f, "  no leaders (an affine formation only)")?,
            Some(lam) => {
                let rel = lam / gap.abs().max(f64::MIN_POSITIVE);
                if rel > 1e-9 {
                    writeln!(
                        f,
                        "  leaders {:?}: λ_min(L_ff) = {lam:.4} (followers' time constant \
                         1/λ_min(L_ff) = {:.4} at unit gain)",
                        self.leaders,
                        1.0 / lam
                    )?;
                } else {
                    writeln!(
                        f,
                        "  [!!]   leaders {:?} are affinely dependent: λ_min(L_ff) = {lam:.2e}, \
                         the followers are not pinned",
                        self.leaders
                    )?;
                }
                match self.unlinked_leaders {
                    None => writeln!(
                        f,
                        "         leaders mutually linked: the distance-based leader law (thesis \
                         §3.5) applies"
                    )?,
                    Some((a, b)) => writeln!(
                        f,
                        "         leaders {a} and {b} are not linked: fine for target tracking; \
                         the distance-based leader law (thesis §3.5) needs linked leaders"
                    )?,
                }
            }
        }
        match self.verdict() {
            Ok(()) => write!(f, "verdict: universally rigid with a valid stress"),
            Err(e) => write!(f, "verdict: FAILED — {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hexagon_passes_every_check() {
        let f = Framework::hexagon();
        let r = CheckReport::from_framework(&f);
        assert!(r.passed(), "{r}");
        assert!(matches!(r.trilateration, Trilateration::Yes { .. }));
        // The preset is normalised to gap 1 (to its solver accuracy, ≈ 1e-9).
        assert!((r.stress_gap() - 1.0).abs() < 1e-6);
        let text = r.to_string();
        assert!(text.contains("universally rigid (Theorem 3.2)"), "{text}");
        assert!(text.contains("verdict: universally rigid"), "{text}");
    }

    #[test]
    fn failures_are_named() {
        let f = Framework::hexagon();
        let cfg: Vec<Vec<f64>> = (0..10).map(|i| f.point(i).to_vec()).collect();
        let neg: Vec<f64> = f.weights().iter().map(|v| -v).collect();
        let r = check(2, &cfg, f.graph().links(), &neg, &[]).unwrap();
        assert!(!r.psd());
        assert!(r
            .verdict()
            .unwrap_err()
            .to_string()
            .contains("not positive semidefinite"));
        // Collinear points: not generic.
        let line: Vec<Vec<f64>> = (0..10).map(|i| vec![i as f64, 2.0 * i as f64]).collect();
        let r = check(2, &line, f.graph().links(), f.weights(), &[]).unwrap();
        assert!(matches!(r.verdict(), Err(DesignError::NonGeneric(_))));
        // A path is a tree: connected but not trilateration.
        let adj = vec![
            vec![false, true, false, false],
            vec![true, false, true, false],
            vec![false, true, false, true],
            vec![false, false, true, false],
        ];
        assert_eq!(trilateration_test(&adj, 2), Trilateration::No);
    }
}
