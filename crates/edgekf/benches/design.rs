//! Design time per method for N = 10, 50, 100 agents in 2-D (issue 4 point 6).
//!
//! Candidates: random 2-trilateration graphs (uniform points, one agent per unit area, every
//! agent linked to its 6 nearest earlier agents: 2N-ish links more than needed, so the SDP and the
//! sparse design have a real choice), fixed seed. Setup (generation) is outside the timed part.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use edgekf::design::{self, generators, Method};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::time::Duration;

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
    group.finish();
}

criterion_group!(benches, bench_design);
criterion_main!(benches);
