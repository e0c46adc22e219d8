//! The batched constant-acceleration Kalman kernels of [`edgekf::ca`] (GA-RKF issue, point 3):
//! time per edge-run-step of predict + Joseph correction (+ mean update) for D = 2, at
//! λ = 1 (every run corrected), λ = 0.4 (RKF-CA-like masks) and λ = 0 (prediction only), for
//! 64 and 1024 runs. Masks, R̃ and measurements are drawn once outside the timed part (fixed
//! seed) and cycled through 64 prepared steps. Throughput is reported in edge-run-steps, so
//! criterion's "elem/s" inverted is the ns per edge-run-step.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use edgekf::estimate::ca::{CaBatch, CaModel};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::time::Duration;

const PREPARED: usize = 64;

struct Inputs {
    r_tilde: Vec<Vec<f64>>,
    mask: Vec<Vec<bool>>,
    y: Vec<Vec<f64>>,
}

fn inputs(runs: usize, lambda: f64, seed: u64) -> Inputs {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut out = Inputs {
        r_tilde: Vec::new(),
        mask: Vec::new(),
        y: Vec::new(),
    };
    for _ in 0..PREPARED {
        let mut rt = vec![0.0; 3 * runs];
        let mut m = vec![false; runs];
        let mut y = vec![0.0; 2 * runs];
        for r in 0..runs {
            let direct = rng.random_bool(lambda);
            m[r] = direct;
            let s = if direct {
                1.0
            } else {
                rng.random_range(0.2..5.0)
            };
            rt[r] = 0.01 * s;
            rt[runs + r] = 0.003 * s;
            rt[2 * runs + r] = 0.01 * s;
            y[r] = rng.random_range(-1.0..1.0);
            y[runs + r] = rng.random_range(-1.0..1.0);
        }
        out.r_tilde.push(rt);
        out.mask.push(m);
        out.y.push(y);
    }
    out
}

fn bench_ca(c: &mut Criterion) {
    let model = CaModel::<2>::new(0.01, 1.0).expect("valid model");
    let mut group = c.benchmark_group("ca_kernel");
    group.sample_size(20);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(3));
    for runs in [64usize, 1024] {
        for (label, lambda) in [("lambda1", 1.0), ("lambda0.4", 0.4), ("lambda0", 0.0)] {
            let inp = inputs(runs, lambda, 7);
            group.throughput(Throughput::Elements((runs * PREPARED) as u64));
            group.bench_with_input(
                BenchmarkId::new(format!("cov_d2_{label}"), runs),
                &inp,
                |b, inp| {
                    let mut batch =
                        CaBatch::<2>::new(runs, &DMatrix::identity(6, 6), &[0.0; 6]).unwrap();
                    b.iter(|| {
                        for k in 0..PREPARED {
                            batch.predict_cov(&model);
                            batch.correct_cov(&inp.r_tilde[k], &inp.mask[k]);
                        }
                    })
                },
            );
            group.bench_with_input(
                BenchmarkId::new(format!("full_d2_{label}"), runs),
                &inp,
                |b, inp| {
                    let mut batch =
                        CaBatch::<2>::new(runs, &DMatrix::identity(6, 6), &[0.0; 6]).unwrap();
                    b.iter(|| {
                        for k in 0..PREPARED {
                            batch.step(&model, &inp.r_tilde[k], &inp.mask[k], &inp.y[k]);
                        }
                    })
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench_ca);
criterion_main!(benches);
