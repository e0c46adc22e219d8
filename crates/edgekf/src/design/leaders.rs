//! Choosing the D + 1 leaders of a designed framework.
//!
//! With leaders `ℓ` held still, the followers of `u_i = −Σ_j l_ij z_ij` (thesis eq. 3.2) obey
//! `ż_f = −L_ff z_f − L_fℓ z_ℓ`: their error decays like `exp(−λ_min(L_ff) t)`, with the time
//! constant `1/λ_min(L_ff)`. `L_ff ≻ 0` iff the leaders are affinely independent (for a stress
//! of rank `N − D − 1`, thesis Theorem 3.3), and by interlacing `λ_min(L_ff) ≤ λ_gap`, the
//! smallest nonzero eigenvalue of `L`. A stress does not depend on who leads, so the leaders are
//! chosen after the design, to make `λ_min(L_ff)` large.
//!
//! # The proxy
//! Let `V` (N × (D + 1)) be an orthonormal basis of `span{1, q_1, …, q_D}` (the affine images of
//! the configuration) and `V_ℓ` its leader rows. For `x` with `x_ℓ = 0` write `x = a + q`, `a`
//! affine and `q ⊥ a`: then `a_ℓ = −q_ℓ`, so `‖a‖ ≤ ‖q‖ / σ` with `σ = σ_min(V_ℓ)`, and
//! `xᵀ L x = qᵀ L q ≥ λ_gap ‖q‖² ≥ λ_gap ‖x‖² σ² / (1 + σ)²`. Conversely the affine `a` with
//! `‖a_ℓ‖ = σ ‖a‖`, zeroed at the leaders, gives `λ_min(L_ff) ≤ λ_max(L_ℓℓ) σ² / (1 − σ²)`.
//! So, up to the factors `λ_gap` and `λ_max(L_ℓℓ)`,
//! ```text
//! λ_gap σ² / (1 + σ)²  ≤  λ_min(L_ff)  ≤  λ_max(L_ℓℓ) σ² / (1 − σ²),   σ = σ_min(V_ℓ),
//! ```
//! and `σ_min(V_ℓ)` — how well the leaders' simplex pins the affine images, a purely geometric
//! quantity costing one (D + 1)-square SVD — is the proxy. [`choose_leaders`] ranks candidate
//! sets by it, evaluates `λ_min(L_ff)` exactly for the best six (and for the framework's own
//! leaders, so the choice is never worse than those), and returns the best of those.
//!
//! # Modes
//! - [`LeaderMode::Clique`]: the leaders must be mutually linked, as the distance-based leader
//!   law of thesis §3.5 needs; every (D + 1)-clique of the graph is a candidate.
//! - [`LeaderMode::Affine`]: any D + 1 affinely independent agents (leaders that track a target
//!   need no links among them); candidates are the local optima of `σ_min(V_ℓ)` under single
//!   exchanges, from greedy maximum-volume starts.

use nalgebra::{DMatrix, DVector};

use super::DesignError;
use crate::framework::Framework;

/// Which leader sets are allowed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeaderMode {
    /// D + 1 mutually linked agents (for the distance-based leader law).
    Clique,
    /// Any D + 1 affinely independent agents (for target tracking).
    Affine,
}

impl std::str::FromStr for LeaderMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "clique" => Ok(LeaderMode::Clique),
            "affine" => Ok(LeaderMode::Affine),
            other => Err(format!("unknown leader mode {other:?} (clique, affine)")),
        }
    }
}

/// The chosen leaders and the numbers they were chosen on.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaderChoice {
    /// The leaders, ascending.
    pub leaders: Vec<usize>,
    /// `λ_min(L_ff)` for them.
    pub follower_min_eigenvalue: f64,
    /// The proxy `σ_min(V_ℓ)` for them.
    pub proxy: f64,
    /// Candidate sets ranked by the proxy.
    pub candidates: usize,
    /// Candidate sets whose `λ_min(L_ff)` was evaluated exactly.
    pub evaluated: usize,
}

/// Candidate sets evaluated exactly (the best by the proxy).
const SHORTLIST: usize = 6;
/// Cliques enumerated at most.
const MAX_CLIQUES: usize = 200_000;

/// `V`: an orthonormal basis of `span{1, q_1, …, q_D}` (modified Gram–Schmidt, twice).
pub(crate) fn affine_basis(config: &[f64], dim: usize) -> DMatrix<f64> {
    let n = config.len() / dim;
    let mut v = DMatrix::from_fn(n, dim + 1, |i, c| {
        if c == 0 {
            1.0
        } else {
            config[i * dim + c - 1]
        }
    });
    for c in 0..=dim {
        for _ in 0..2 {
            for p in 0..c {
                let dot = v.column(p).dot(&v.column(c));
                let col_p = v.column(p).into_owned();
                v.column_mut(c).axpy(-dot, &col_p, 1.0);
            }
        }
        let norm = v.column(c).norm();
        if norm > 0.0 {
            v.column_mut(c).scale_mut(1.0 / norm);
        }
    }
    v
}

/// The proxy `σ_min(V_ℓ)` (0 for affinely dependent leaders).
pub fn leader_proxy(affine: &DMatrix<f64>, leaders: &[usize]) -> f64 {
    let k = affine.ncols();
    if leaders.len() != k {
        return 0.0;
    }
    let sub = DMatrix::from_fn(k, k, |r, c| affine[(leaders[r], c)]);
    sub.singular_values().min()
}

/// `λ_min(L_ff)`: the smallest eigenvalue of `L` without the rows and columns of `leaders`
/// (dense eigenvalues up to 400 followers; above, Lanczos on `L_ff⁻¹` after one Cholesky
/// factorisation). Returns 0 (or a negative round-off value) when `L_ff` is singular.
pub fn follower_min_eigenvalue(laplacian: &DMatrix<f64>, leaders: &[usize]) -> f64 {
    let n = laplacian.nrows();
    let followers: Vec<usize> = (0..n).filter(|i| !leaders.contains(i)).collect();
    let nf = followers.len();
    if nf == 0 {
        return f64::INFINITY;
    }
    let lff = DMatrix::from_fn(nf, nf, |r, c| laplacian[(followers[r], followers[c])]);
    if nf <= 400 {
        return lff.symmetric_eigenvalues().min();
    }
    let Some(chol) = super::dense::cholesky(lff) else {
        return 0.0;
    };
    // Largest eigenvalue of L_ff⁻¹ = −(smallest of −L_ff⁻¹).
    let lam = super::dense::lanczos_min(nf, |v: &DVector<f64>| -chol.solve(v));
    -1.0 / lam
}

/// Chooses D + 1 leaders for `framework` maximising `λ_min(L_ff)` over a shortlist ranked by the
/// proxy `σ_min(V_ℓ)` (see the module docs).
///
/// # Errors
/// [`DesignError::Input`] in [`LeaderMode::Clique`] when the graph has no D + 1 mutually linked
/// agents (the message suggests [`LeaderMode::Affine`]).
pub fn choose_leaders(
    framework: &Framework,
    mode: LeaderMode,
) -> Result<LeaderChoice, DesignError> {
    let dim = framework.dim();
    let n = framework.agents();
    let affine = affine_basis(framework.config(), dim);
    let mut ranked: Vec<(f64, Vec<usize>)> = match mode {
        LeaderMode::Clique => {
            let adj: Vec<Vec<usize>> = (0..n)
                .map(|i| framework.graph().neighbours(i).collect())
                .collect();
            let cliques = cliques(&adj, dim + 1);
            if cliques.is_empty() {
                return Err(DesignError::Input(format!(
                    "no {} mutually linked agents in the designed graph: the distance-based \
                     leader law needs a leader clique (choose leaders for target tracking with \
                     the affine mode instead)",
                    dim + 1
                )));
            }
            cliques
                .into_iter()
                .map(|c| (leader_proxy(&affine, &c), c))
                .collect()
        }
        LeaderMode::Affine => affine_local_optima(&affine)
            .into_iter()
            .map(|c| (leader_proxy(&affine, &c), c))
            .collect(),
    };
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
    ranked.dedup_by(|a, b| a.1 == b.1);
    let candidates = ranked.len();
    let mut shortlist: Vec<(f64, Vec<usize>)> = ranked.into_iter().take(SHORTLIST).collect();
    // The framework's own leaders, when they qualify, are always evaluated: the choice is never
    // worse than what the user has.
    let mut current = framework.leaders().to_vec();
    current.sort_unstable();
    let qualifies = current.len() == dim + 1
        && (mode == LeaderMode::Affine
            || current.iter().enumerate().all(|(k, &a)| {
                current[k + 1..]
                    .iter()
                    .all(|&b| framework.graph().has_link(a, b))
            }));
    if qualifies && !shortlist.iter().any(|(_, s)| *s == current) {
        shortlist.push((leader_proxy(&affine, &current), current));
    }
    let mut best: Option<LeaderChoice> = None;
    let evaluated = shortlist.len();
    for (proxy, set) in shortlist {
        if proxy <= 0.0 {
            continue;
        }
        let lam = follower_min_eigenvalue(framework.laplacian(), &set);
        let better = match &best {
            None => true,
            Some(b) => lam > b.follower_min_eigenvalue,
        };
        if better {
            best = Some(LeaderChoice {
                leaders: set,
                follower_min_eigenvalue: lam,
                proxy,
                candidates,
                evaluated,
            });
        }
    }
    best.ok_or_else(|| {
        DesignError::NonGeneric(format!(
            "no {} affinely independent leader candidates",
            dim + 1
        ))
    })
}

/// All `k`-cliques (ascending agent lists) of the graph given by ascending adjacency lists, at
/// most [`MAX_CLIQUES`].
fn cliques(adj: &[Vec<usize>], k: usize) -> Vec<Vec<usize>> {
    fn extend(
        adj: &[Vec<usize>],
        k: usize,
        clique: &mut Vec<usize>,
        cand: &[usize],
        out: &mut Vec<Vec<usize>>,
    ) {
        if out.len() >= MAX_CLIQUES {
            return;
        }
        if clique.len() == k {
            out.push(clique.clone());
            return;
        }
        for (p, &v) in cand.iter().enumerate() {
            // Candidates after v that are also neighbours of v (adjacency lists are sorted).
            let next: Vec<usize> = cand[p + 1..]
                .iter()
                .copied()
                .filter(|u| adj[v].binary_search(u).is_ok())
                .collect();
            clique.push(v);
            extend(adj, k, clique, &next, out);
            clique.pop();
        }
    }
    let mut out = Vec::new();
    let mut clique = Vec::with_capacity(k);
    for v in 0..adj.len() {
        let later: Vec<usize> = adj[v].iter().copied().filter(|&u| u > v).collect();
        clique.push(v);
        extend(adj, k, &mut clique, &later, &mut out);
        clique.pop();
    }
    out
}

/// Local optima of `σ_min(V_ℓ)` under single exchanges, from greedy maximum-volume starts (the
/// first leader the agent with the `s`-th largest row norm of `V`, `s = 0..5`; then the agent
/// that maximises the volume `det(V_S V_Sᵀ)` of the rows chosen so far).
fn affine_local_optima(affine: &DMatrix<f64>) -> Vec<Vec<usize>> {
    let n = affine.nrows();
    let k = affine.ncols();
    let gram_det = |set: &[usize]| -> f64 {
        let sub = DMatrix::from_fn(set.len(), k, |r, c| affine[(set[r], c)]);
        (&sub * sub.transpose()).determinant()
    };
    let mut by_norm: Vec<usize> = (0..n).collect();
    by_norm.sort_by(|&a, &b| {
        affine
            .row(b)
            .norm()
            .total_cmp(&affine.row(a).norm())
            .then(a.cmp(&b))
    });
    let mut optima = Vec::new();
    for &first in by_norm.iter().take(5.min(n)) {
        let mut set = vec![first];
        while set.len() < k {
            let next = (0..n)
                .filter(|a| !set.contains(a))
                .map(|a| {
                    let mut s = set.clone();
                    s.push(a);
                    (gram_det(&s), a)
                })
                .fold((f64::NEG_INFINITY, usize::MAX), |acc, cur| {
                    if cur.0 > acc.0 {
                        cur
                    } else {
                        acc
                    }
                })
                .1;
            set.push(next);
        }
        // Exchange passes: replace one leader by the agent that raises σ_min most.
        let mut value = leader_proxy(affine, &set);
        for _ in 0..50 {
            let mut improved = false;
            for pos in 0..k {
                for a in 0..n {
                    if set.contains(&a) {
                        continue;
                    }
                    let mut trial = set.clone();
                    trial[pos] = a;
                    let v = leader_proxy(affine, &trial);
                    if v > value * (1.0 + 1e-12) {
                        set = trial;
                        value = v;
                        improved = true;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        set.sort_unstable();
        optima.push(set);
    }
    optima
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proxy_bounds_hold_on_the_hexagon() {
        let f = Framework::hexagon();
        let v = affine_basis(f.config(), 2);
        // Orthonormal columns.
        assert!((v.transpose() * &v - DMatrix::<f64>::identity(3, 3)).amax() < 1e-12);
        let gap = f.stress_gap();
        for set in [[0, 1, 2], [4, 6, 8], [3, 5, 9], [0, 4, 7]] {
            let sigma = leader_proxy(&v, &set);
            let lam = follower_min_eigenvalue(f.laplacian(), &set);
            let lll = DMatrix::from_fn(3, 3, |r, c| f.laplacian()[(set[r], set[c])]);
            let upper = lll.symmetric_eigenvalues().max() * sigma * sigma / (1.0 - sigma * sigma);
            let lower = gap * (sigma / (1.0 + sigma)).powi(2);
            // The two bounds of the module docs (round-off 1e-12 relative).
            assert!(
                lam >= lower * (1.0 - 1e-12)
                    && lam <= upper * (1.0 + 1e-12)
                    && lam <= gap * (1.0 + 1e-12),
                "{set:?}: {lower} ≤ {lam} ≤ {upper}, gap {gap}"
            );
        }
        // Collinear leaders (5, 3, 8 on the y axis) pin no affine image: σ = 0 and L_ff singular.
        assert!(leader_proxy(&v, &[3, 5, 8]) < 1e-12);
        assert!(follower_min_eigenvalue(f.laplacian(), &[3, 5, 8]).abs() < 1e-9);
    }

    #[test]
    fn cliques_of_a_small_graph() {
        // Two triangles sharing an edge: 0-1-2 and 1-2-3.
        let adj = vec![vec![1, 2], vec![0, 2, 3], vec![0, 1, 3], vec![1, 2]];
        assert_eq!(cliques(&adj, 3), vec![vec![0, 1, 2], vec![1, 2, 3]]);
        assert_eq!(cliques(&adj, 4), Vec::<Vec<usize>>::new());
        assert_eq!(cliques(&adj, 2).len(), 5);
    }
}
