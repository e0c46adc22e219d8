//! The instances on which the old barrier solver stopped on its iteration limit (issue 11):
//! `cargo run --release -p edgekf --example design_stalled [-- SEEDS]` (default 20 seeds).
//!
//! 50 agents uniform in a 10 × 10 square, a 2-trilateration backbone (every agent linked to its 3
//! nearest earlier agents) plus the `k` nearest neighbours of every agent, `k ∈ {5, 6, 7}`, kept
//! when the candidate graph has 200–226 links (the instance has 213). Each is designed by
//! `sdp` and `sparse`; the line gives the outcome, solver, iterations, certified relative gap,
//! λ_max/λ_min and the wall time.

use std::time::Instant;

use edgekf::design::{self, generators, Candidate, Method};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map_or(20, |s| s.parse().expect("SEEDS is a number"));
    let (mut designed, mut failed) = (0, 0);
    for seed in 0..seeds {
        for knn in [5usize, 6, 7] {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
            let config = generators::random_config(50, 2, 10.0, &mut rng);
            let tri = generators::trilateration_links(&config, 2, 3);
            let links = generators::nearest_neighbour_links(&config, knn, &tri);
            if !(200..=226).contains(&links.len()) {
                continue;
            }
            let c = Candidate {
                name: format!("seed{seed}-k{knn}"),
                dim: 2,
                config,
                links,
                leaders: vec![0, 1, 2],
            };
            for m in [Method::Sdp, Method::Sparse] {
                let t = Instant::now();
                match design::design(&c, m) {
                    Ok(d) => {
                        designed += 1;
                        let f = &d.framework;
                        println!(
                            "{} {m:?} L={} designed: {} {} iterations, gap {:.1e}, ratio {:.1}, {:.2} s",
                            c.name,
                            c.links.len(),
                            d.solver,
                            d.newton_steps,
                            d.gap,
                            f.eigenvalues()[f.agents() - 1] / f.stress_gap(),
                            t.elapsed().as_secs_f64()
                        );
                    }
                    Err(e) => {
                        failed += 1;
                        println!(
                            "{} {m:?} L={} ERROR {e} ({:.2} s)",
                            c.name,
                            c.links.len(),
                            t.elapsed().as_secs_f64()
                        );
                    }
                }
            }
        }
    }
    println!("{designed} designed, {failed} errors");
}
