//! Design at scale (issue 11, point 4): `cargo run --release -p edgekf --example design_scale
//! [-- N [K [SEEDS]]]` (defaults N = 1000, K = 4, SEEDS = 3).
//!
//! The family: N uniform points in 2-D at unit density, each agent linked to its K nearest
//! earlier agents (`generators::trilateration`; K = D + 2 = 4 is what `edgekf design --generate
//! trilateration` uses). For N it times one `sdp` design (the default method), the check report
//! of the designed framework and the automatic leader choice; for N = 100 it designs SEEDS
//! instances of the same family and prints their λ_max/λ_min, the reference for "within 10× of
//! what the SDP reaches at N = 100". With `yang` as a fourth argument it also times Yang's
//! construction at N.

use std::time::Instant;

use edgekf::design::{self, generators, CheckReport, LeaderMode, Method};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(1000, |s| s.parse().expect("N"));
    let k: usize = args.get(2).map_or(4, |s| s.parse().expect("K"));
    let seeds: u64 = args.get(3).map_or(3, |s| s.parse().expect("SEEDS"));
    let with_yang = args.get(4).is_some_and(|s| s == "yang");

    let mut reference = Vec::new();
    for seed in 1..=seeds {
        let c = generators::trilateration(100, 2, k, &mut Xoshiro256PlusPlus::seed_from_u64(seed));
        let t = Instant::now();
        let d = design::design(&c, Method::Sdp).expect("N = 100 design");
        let f = &d.framework;
        let ratio = f.eigenvalues()[f.agents() - 1] / f.stress_gap();
        println!(
            "N = 100, K = {k}, seed {seed}: sdp ratio {ratio:.1} ({} links, {} iterations, {:.2} s)",
            c.links.len(),
            d.newton_steps,
            t.elapsed().as_secs_f64()
        );
        reference.push(ratio);
    }
    reference.sort_by(f64::total_cmp);
    let median = reference[reference.len() / 2];

    let c = generators::trilateration(n, 2, k, &mut Xoshiro256PlusPlus::seed_from_u64(1));
    println!("N = {n}, K = {k}: {} candidate links", c.links.len());
    let t = Instant::now();
    let d = design::design(&c, Method::Sdp).expect("design");
    let t_design = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let report = CheckReport::from_framework(&d.framework);
    let t_report = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let choice = design::choose_leaders(&d.framework, LeaderMode::Clique).expect("leaders");
    let t_leaders = t.elapsed().as_secs_f64();
    let ratio = report.max_eigenvalue() / report.stress_gap();
    println!("{report}");
    println!(
        "sdp: {t_design:.1} s ({} iterations, solver {}, gap {:.1e}); check report {t_report:.2} s; \
         leader choice {t_leaders:.2} s ({:?}, λ_min(L_ff) = {:.3e}, given [0, 1, 2]: {:.3e})",
        d.newton_steps,
        d.solver,
        d.gap,
        choice.leaders,
        choice.follower_min_eigenvalue,
        report.follower_min_eigenvalue.unwrap_or(f64::NAN)
    );
    println!(
        "ratio λ_max/λ_min at N = {n}: {ratio:.1}; median at N = 100: {median:.1}; quotient {:.2}",
        ratio / median
    );
    if with_yang {
        let t = Instant::now();
        let y = design::design(&c, Method::Yang).expect("yang");
        let f = &y.framework;
        println!(
            "yang: {:.1} s, ratio {:.3e}",
            t.elapsed().as_secs_f64(),
            f.eigenvalues()[f.agents() - 1] / f.stress_gap()
        );
    }
}
