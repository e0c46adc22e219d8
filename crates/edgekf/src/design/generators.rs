//! Configurations and candidate graphs to design on: random generic configurations,
//! D-trilateration graphs, complete graphs, the thesis hexagon and a 3-D counterpart, and the
//! 50-agent random configuration of Li & Rajan, Fig. 13a.
//!
//! A [`Candidate`] is the input of a design: configuration, candidate links (the design may give
//! some of them zero weight) and leaders. Random generators take `&mut impl Rng` so that a seed
//! fixes the result.

use rand::Rng;

use crate::framework::Framework;

/// The input of a design: a configuration, candidate links and leaders (`edgekf.framework/1`
/// without weights).
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Name carried into the framework.
    pub name: String,
    /// D.
    pub dim: usize,
    /// One point per agent.
    pub config: Vec<Vec<f64>>,
    /// Candidate undirected links.
    pub links: Vec<(usize, usize)>,
    /// Leaders: none, or D + 1 mutually linked agents.
    pub leaders: Vec<usize>,
}

impl Candidate {
    /// Average degree `2 L / N` of the candidate graph.
    pub fn average_degree(&self) -> f64 {
        2.0 * self.links.len() as f64 / self.config.len() as f64
    }
}

/// `n` points drawn uniformly in the cube `[0, extent]^dim`. Such a configuration is generic
/// with probability one (no algebraic relation among its coordinates).
pub fn random_config(n: usize, dim: usize, extent: f64, rng: &mut impl Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| (0..dim).map(|_| rng.random_range(0.0..extent)).collect())
        .collect()
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// D-trilateration links on a configuration, in its agent order: the first `D + 1` agents form a
/// complete graph and every later agent links to its `k ≥ D + 1` nearest earlier agents (thesis
/// §2.5). On a generic configuration the result is universally rigid.
///
/// # Panics
/// If `k < dim + 1` or the configuration has fewer than `dim + 1` points.
pub fn trilateration_links(config: &[Vec<f64>], dim: usize, k: usize) -> Vec<(usize, usize)> {
    assert!(
        k > dim,
        "a D-trilateration graph needs k ≥ D + 1 earlier neighbours"
    );
    assert!(config.len() > dim, "need at least D + 1 agents");
    let mut links = Vec::new();
    for i in 0..=dim {
        for j in i + 1..=dim {
            links.push((i, j));
        }
    }
    for a in dim + 1..config.len() {
        let mut earlier: Vec<usize> = (0..a).collect();
        earlier.sort_by(|&x, &y| {
            dist2(&config[a], &config[x]).total_cmp(&dist2(&config[a], &config[y]))
        });
        for &b in earlier.iter().take(k) {
            links.push((b, a));
        }
    }
    links.sort_unstable();
    links
}

/// Links of every agent to its `k` nearest agents (symmetrised), united with `extra`.
pub fn nearest_neighbour_links(
    config: &[Vec<f64>],
    k: usize,
    extra: &[(usize, usize)],
) -> Vec<(usize, usize)> {
    let n = config.len();
    let mut links: Vec<(usize, usize)> = extra.iter().map(|&(i, j)| (i.min(j), i.max(j))).collect();
    for a in 0..n {
        let mut others: Vec<usize> = (0..n).filter(|&b| b != a).collect();
        others.sort_by(|&x, &y| {
            dist2(&config[a], &config[x]).total_cmp(&dist2(&config[a], &config[y]))
        });
        for &b in others.iter().take(k) {
            links.push((a.min(b), a.max(b)));
        }
    }
    links.sort_unstable();
    links.dedup();
    links
}

/// All links among `n` agents.
pub fn complete_links(n: usize) -> Vec<(usize, usize)> {
    (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .collect()
}

/// A random D-trilateration candidate: `n` uniform points in `[0, extent]^dim` (extent chosen
/// so that the density is one agent per unit volume), each later agent linked to its `k` nearest
/// earlier ones, the first `D + 1` agents the leaders.
pub fn trilateration(n: usize, dim: usize, k: usize, rng: &mut impl Rng) -> Candidate {
    let extent = (n as f64).powf(1.0 / dim as f64);
    let config = random_config(n, dim, extent, rng);
    let links = trilateration_links(&config, dim, k);
    Candidate {
        name: format!("trilateration-{dim}d-n{n}-k{k}"),
        dim,
        config,
        links,
        leaders: (0..=dim).collect(),
    }
}

/// The complete graph on a configuration (leaders: the first `D + 1` agents).
pub fn complete(name: &str, dim: usize, config: Vec<Vec<f64>>) -> Candidate {
    let links = complete_links(config.len());
    Candidate {
        name: name.into(),
        dim,
        config,
        links,
        leaders: (0..=dim).collect(),
    }
}

/// The thesis hexagon (see [`Framework::hexagon`]) as a design input: its configuration, its 30
/// links as candidates, leaders 0, 1, 2.
pub fn hexagon_candidate() -> Candidate {
    let f = Framework::hexagon();
    Candidate {
        name: "hexagon".into(),
        dim: 2,
        config: (0..f.agents()).map(|i| f.point(i).to_vec()).collect(),
        links: f.graph().links().to_vec(),
        leaders: f.leaders().to_vec(),
    }
}

/// A 3-D counterpart of the hexagon: N = 11 agents — a regular tetrahedron of leaders 0–3 on the
/// unit sphere, agent 4 at the centre, agents 5–10 spread over the sphere of radius 2 by the
/// Fibonacci lattice (`z = 1 − (2i + 1)/6`, azimuth `i` golden angles; no two antipodal, so no
/// three agents collinear and no four consecutive ones coplanar) — with the 3-trilateration
/// links of [`trilateration_links`] with `k = 5` (40 links; like the hexagon's agents, each
/// links to D + 1 or more earlier ones).
pub fn hexagon3d_candidate() -> Candidate {
    let r = 1.0 / 3f64.sqrt();
    let mut config = vec![
        vec![r, r, r],
        vec![r, -r, -r],
        vec![-r, r, -r],
        vec![-r, -r, r],
        vec![0.0, 0.0, 0.0],
    ];
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..6 {
        let z = 1.0 - (2 * i + 1) as f64 / 6.0;
        let rho = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        config.push(vec![2.0 * rho * phi.cos(), 2.0 * rho * phi.sin(), 2.0 * z]);
    }
    let links = trilateration_links(&config, 3, 5);
    Candidate {
        name: "hexagon3d".into(),
        dim: 3,
        config,
        links,
        leaders: vec![0, 1, 2, 3],
    }
}

/// Which 50-agent graph of Li & Rajan, Fig. 13a.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Density {
    /// Candidate links for the sparse design (Fig. 13a: average degree 7.5).
    Sparse,
    /// All links (Fig. 13a: average degree 47.8 of 49).
    Dense,
}

/// The 50-agent random configuration of Li & Rajan, Fig. 13a: 50 uniform points in a
/// 10 × 10 square. `Sparse`: the candidates are the 2-trilateration links with `k = 3` united with
/// the 12 nearest neighbours of every agent (the sparse design then keeps few of them);
/// `Dense`: the complete graph. Leaders 0, 1, 2.
pub fn random50(density: Density, rng: &mut impl Rng) -> Candidate {
    let config = random_config(50, 2, 10.0, rng);
    match density {
        Density::Sparse => {
            let tri = trilateration_links(&config, 2, 3);
            let links = nearest_neighbour_links(&config, 12, &tri);
            Candidate {
                name: "random50-sparse".into(),
                dim: 2,
                config,
                links,
                leaders: vec![0, 1, 2],
            }
        }
        Density::Dense => complete("random50-dense", 2, config),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn trilateration_counts() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        let c = trilateration(20, 2, 3, &mut rng);
        // 3 leader links + 3 per later agent.
        assert_eq!(c.links.len(), 3 + 3 * 17);
        let c3 = trilateration(20, 3, 4, &mut rng);
        assert_eq!(c3.links.len(), 6 + 4 * 16);
        assert_eq!(hexagon3d_candidate().links.len(), 6 + 4 + 5 * 6);
        let same = trilateration(20, 2, 3, &mut Xoshiro256PlusPlus::seed_from_u64(1));
        assert_eq!(same, c, "seeded generators are reproducible");
    }
}
