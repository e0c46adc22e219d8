//! Design time and agreement of the two SDP solvers (docs/clarabel.md):
//! `cargo run --release -p edgekf --features clarabel --example clarabel_timing`.
//!
//! Candidates as in `tests/design.rs`: the thesis hexagon, its 3-D counterpart and the random
//! 50-agent sparse candidate set (seed 2024). Each design is timed once (the solvers are
//! deterministic); the ratio is `λ_max / λ_min` of `Q L Qᵀ` of the designed framework.

use edgekf::design::{generators, sdp, sparse, Design};
use edgekf::framework::Framework;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::time::Instant;

fn ratio(f: &Framework) -> f64 {
    f.eigenvalues()[f.agents() - 1] / f.stress_gap()
}

fn timed(f: impl FnOnce() -> Design) -> (Design, f64) {
    let t = Instant::now();
    let d = f();
    (d, t.elapsed().as_secs_f64())
}

fn main() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2024);
    let cands = [
        generators::hexagon_candidate(),
        generators::hexagon3d_candidate(),
        generators::random50(generators::Density::Sparse, &mut rng),
    ];
    println!("candidate\tmethod\tsolver\tseconds\titerations\tlinks\tratio");
    for c in &cands {
        for solver in [sdp::SdpSolver::Ipm, sdp::SdpSolver::Clarabel] {
            let opts = sdp::SdpOptions {
                solver,
                ..sdp::SdpOptions::default()
            };
            let (d, secs) = timed(|| sdp::design(c, &opts).expect("sdp design"));
            print_row(&c.name, "sdp", solver, secs, &d);
        }
        if c.config.len() == 50 {
            for solver in [sdp::SdpSolver::Ipm, sdp::SdpSolver::Clarabel] {
                let opts = sparse::SparseOptions {
                    solver,
                    ..sparse::SparseOptions::default()
                };
                let (d, secs) = timed(|| sparse::design(c, &opts).expect("sparse design"));
                print_row(&c.name, "sparse", solver, secs, &d);
            }
        }
    }
}

fn print_row(name: &str, method: &str, solver: sdp::SdpSolver, secs: f64, d: &Design) {
    println!(
        "{name}\t{method}\t{solver:?}\t{secs:.3}\t{}\t{}\t{:.9}",
        d.newton_steps,
        d.framework.graph().links().len(),
        ratio(&d.framework)
    );
}
