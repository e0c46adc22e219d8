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
    /// Leaders: none, or D + 1 agents (they need not be linked; the distance-based leader law
    /// of thesis §3.5, which needs them linked, is checked where it is used).
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

/// `n` points drawn uniformly in the box `[0, extents[0]] × … × [0, extents[D−1]]` (`D` =
/// `extents.len()`); generic with probability one.
pub fn random_config_box(n: usize, extents: &[f64], rng: &mut impl Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| extents.iter().map(|&e| rng.random_range(0.0..e)).collect())
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

/// A D-trilateration backbone plus nearest neighbours: `n` uniform points in the box with the
/// given `extents` (one per dimension, `D = extents.len()`), every agent after the first `D + 1`
/// linked to its `D + 1` nearest earlier agents (the sparsest D-trilateration graph, universally
/// rigid on a generic configuration, thesis §2.5), united with the links of every agent to its
/// `k` nearest agents. Leaders: the first `D + 1` agents. These are the families of the
/// robustness sweep (issue 11): sparse candidate graphs just above the rigidity threshold.
///
/// # Panics
/// If `n < D + 1` or `D` is not 1, 2 or 3.
pub fn backbone(n: usize, extents: &[f64], k: usize, rng: &mut impl Rng) -> Candidate {
    let dim = extents.len();
    assert!((1..=3).contains(&dim), "1, 2 or 3 extents");
    let config = random_config_box(n, extents, rng);
    let tri = trilateration_links(&config, dim, dim + 1);
    let links = nearest_neighbour_links(&config, k, &tri);
    let box_text: Vec<String> = extents.iter().map(|e| format!("{e}")).collect();
    Candidate {
        name: format!("backbone-{dim}d-n{n}-k{k}-{}", box_text.join("x")),
        dim,
        config,
        links,
        leaders: (0..=dim).collect(),
    }
}

/// Box shapes of the robustness families ([`family`]); each keeps one agent per unit volume at
/// scale 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    /// A cube of side `N^(1/D)`.
    Unit,
    /// The same cube scaled by 1e-3.
    Tiny,
    /// The same cube scaled by 1e3.
    Huge,
    /// A box with aspect ratio 10 : 1 (: 1) and the volume of the unit cube.
    Elongated,
}

impl Extent {
    /// All shapes.
    pub const ALL: [Extent; 4] = [Extent::Unit, Extent::Tiny, Extent::Huge, Extent::Elongated];

    /// The side lengths for `n` agents in `dim` dimensions.
    pub fn sides(self, n: usize, dim: usize) -> Vec<f64> {
        let side = (n as f64).powf(1.0 / dim as f64);
        match self {
            Extent::Unit => vec![side; dim],
            Extent::Tiny => vec![1e-3 * side; dim],
            Extent::Huge => vec![1e3 * side; dim],
            Extent::Elongated => {
                let short = side * 10f64.powf(-1.0 / dim as f64);
                let mut v = vec![short; dim];
                v[0] = short * 10.0;
                v
            }
        }
    }

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Extent::Unit => "unit",
            Extent::Tiny => "tiny",
            Extent::Huge => "huge",
            Extent::Elongated => "elongated",
        }
    }
}

/// The robustness families of issue 11: one [`backbone`] candidate per combination of `n` in
/// `sizes`, `D` in `dims`, `k` in `neighbours`, shape in `extents` and seed in `seeds`, each
/// drawn with its own generator seeded from the combination (so any subset reproduces the same
/// instances).
pub fn family(
    sizes: &[usize],
    dims: &[usize],
    neighbours: &[usize],
    extents: &[Extent],
    seeds: std::ops::Range<u64>,
) -> Vec<Candidate> {
    use rand::SeedableRng;
    let mut out = Vec::new();
    for &n in sizes {
        for &dim in dims {
            for &k in neighbours {
                for &shape in extents {
                    for seed in seeds.clone() {
                        let key = (n as u64) << 40
                            ^ (dim as u64) << 36
                            ^ (k as u64) << 30
                            ^ (shape as u64) << 26
                            ^ seed;
                        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(key);
                        let mut c = backbone(n, &shape.sides(n, dim), k, &mut rng);
                        c.name = format!("backbone-{dim}d-n{n}-k{k}-{}-s{seed}", shape.name());
                        out.push(c);
                    }
                }
            }
        }
    }
    out
}

/// The 7-agent example of S. Zhao, "Affine formation maneuver control of multiagent systems",
/// IEEE TAC 63(12), 2018, §VII (simulation; the nominal configuration and stress of its Fig. 3):
/// a hexagon-like configuration `(2, 0), (1, 1), (1, −1), (0, 1), (0, −1), (−1, 1), (−1, −1)`,
/// twelve links, leaders 0, 1, 2 (Zhao's agents 1–3). Leaders 1 and 2 are **not** linked, and
/// agents 1, 3, 5 (and 2, 4, 6) are collinear, so the configuration is not in general position;
/// its stress space is one-dimensional (12 links, rigidity rank 2·7 − 3 = 11) and the unique
/// stress is positive semidefinite with rank `N − D − 1 = 4`.
///
/// Source: we could not read the paper itself here; configuration and links are transcribed from
/// the public MATLAB reproduction of that simulation, `star2dust/paper-simulation`,
/// `Zhao2018Affine/affine_formation.m` (incidence matrix `D`, 7 × 12; configuration `r`), whose
/// comment states that the stress it computes is the one of the paper's Fig. 3. Indices are
/// 0-based here (Zhao's agent i is our i − 1).
pub fn zhao7_candidate() -> Candidate {
    let config = vec![
        vec![2.0, 0.0],
        vec![1.0, 1.0],
        vec![1.0, -1.0],
        vec![0.0, 1.0],
        vec![0.0, -1.0],
        vec![-1.0, 1.0],
        vec![-1.0, -1.0],
    ];
    // Columns of Zhao's incidence matrix, 1-based: 1–2, 1–3, 3–5, 5–7, 6–7, 4–6, 2–4, 2–7, 3–6,
    // 1–4, 4–5, 1–5.
    let mut links = vec![
        (0, 1),
        (0, 2),
        (2, 4),
        (4, 6),
        (5, 6),
        (3, 5),
        (1, 3),
        (1, 6),
        (2, 5),
        (0, 3),
        (3, 4),
        (0, 4),
    ];
    links.sort_unstable();
    Candidate {
        name: "zhao7".into(),
        dim: 2,
        config,
        links,
        leaders: vec![0, 1, 2],
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
        // Backbone: D + 1 earlier neighbours per agent, then nearest neighbours on top.
        let b0 = backbone(
            30,
            &[5.0, 5.0],
            0,
            &mut Xoshiro256PlusPlus::seed_from_u64(3),
        );
        assert_eq!(b0.links.len(), 3 + 3 * 27);
        let b4 = backbone(
            30,
            &[5.0, 5.0],
            4,
            &mut Xoshiro256PlusPlus::seed_from_u64(3),
        );
        assert!(b4.links.len() > b0.links.len());
        assert!(b0.links.iter().all(|l| b4.links.contains(l)));
        let z = zhao7_candidate();
        assert_eq!(z.links.len(), 12);
        assert!(
            !z.links.contains(&(1, 2)),
            "Zhao's leaders 2 and 3 are not linked"
        );
    }
}
