//! Design time per method for N = 10, 50, 100 agents in 2-D (issues 4 and 11), and the
//! 50-agent backbone instance on which the old barrier solver stalled (issue 11).
//!
//! Candidates: random 2-trilateration graphs (uniform points, one agent per unit area, every
//! agent linked to its 6 nearest earlier agents: 2N-ish links more than needed, so the SDP and the
//! sparse design have a real choice), fixed seed; and the backbone instance (50 agents in a
//! 10 × 10 square, 2-trilateration backbone with 3 earlier neighbours plus the 6 nearest
//! neighbours of every agent, 222 candidate links, seed 16). Setup (generation) is outside the
//! timed part. N = 1000 is timed by `cargo run --release -p edgekf --example design_scale`
//! (one design takes tens of seconds; criterion would repeat it ten times).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use edgekf::design::{self, generators, Candidate, Method};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::time::Duration;

/// The stalled instance of issue 11, rebuilt from the generators.
fn backbone50() -> Candidate {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(16);
    let config = generators::random_config(50, 2, 10.0, &mut rng);
    let tri = generators::trilateration_links(&config, 2, 3);
    let links = generators::nearest_neighbour_links(&config, 6, &tri);
    Candidate {
        name: "backbone50".into(),
        dim: 2,
        config,
        links,
        leaders: vec![0, 1, 2],
    }
}

fn bench_design(c: &mut Criterion) {
    let mut group = c.benchmark_group("design");
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(5));
    for n in [10usize, 50, 100] {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(42);
        let candidate = generators::trilateration(n, 2, 6, &mut rng);
        for (name, method) in [
            ("sdp", Method::Sdp),
            ("yang", Method::Yang),
            ("sparse", Method::Sparse),
        ] {
            group.bench_with_input(
                BenchmarkId::new(name, format!("n{n}_d2")),
                &candidate,
                |b, cand| b.iter(|| design::design(cand, method).expect("design succeeds")),
            );
        }
    }
    let stalled = backbone50();
    for (name, method) in [("sdp", Method::Sdp), ("sparse", Method::Sparse)] {
        group.bench_with_input(
            BenchmarkId::new(name, "backbone50_l222"),
            &stalled,
            |b, cand| b.iter(|| design::design(cand, method).expect("design succeeds")),
        );
    }
    group.finish();
}

criterion_group!(benches, bench_design);
criterion_main!(benches);
