//! Engine speed against a minimal structure-of-arrays loop of the same closed loop.
//!
//! `cargo bench -p edgekf --bench engine [-- RUNS STEPS REPS]` (one thread, release; each timing the
//! fastest of REPS = 3): the EUSIPCO
//! scenario (hexagon, N = 10, M = 60, T = 10, σ_w = 0.001 with the thesis kernel, σ_v = 0.1),
//! 50 runs × 30 000 steps by default. It prints ns per agent-step of
//! - the minimal loop: per step the same draws (M·D measurement-mean and N·D process normals per
//!   run), `w = C_Q ξ` with the Kronecker factor, the shared RKF gains (Joseph 2 × 2 per edge,
//!   frozen once converged), the mean updates, the leaders' distance law and the followers'
//!   affine law, the move, and ε² at the reported steps — nothing else;
//! - the draws alone (the floor of any implementation that draws the same normals);
//! - the engine running `rkf` alone, and the whole Fig. 4a estimator set.
//!
//! The target: the engine's RKF within 1.5× of the minimal loop.

use std::time::Instant;

use edgekf::estimate::batch::{joseph_step, settled, Mat};
use edgekf::rng::Streams;
use edgekf::scenario::{EstimatorEntry, Scenario};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

const EUSIPCO: &str = include_str!("../../../scenarios/eusipco.toml");

fn scenario(estimators: &[&str], runs: usize, steps: usize) -> Scenario {
    let mut spec = edgekf_io::spec_from_toml(EUSIPCO).expect("shipped scenario");
    spec.plots.clear();
    spec.estimators = estimators.iter().map(|k| EstimatorEntry::kind(k)).collect();
    spec.sim.runs = runs;
    spec.sim.steps = steps;
    // The shipped AR(1) input model and P_fail = 0.25 for `rkf-ar` (thesis Fig. 6.2).
    spec.comm.p_fail = 0.25;
    spec.comm.ar = Some(edgekf::estimate::ArModel {
        coeffs: vec![vec![0.975, 0.979]],
        noise_var: vec![0.0115, 0.0119],
    });
    Scenario::from_spec(&spec, None).expect("valid")
}

fn lower_rm(m: &DMatrix<f64>) -> Vec<f64> {
    let c = m.clone().cholesky().expect("positive definite").unpack();
    let n = c.nrows();
    (0..n * n).map(|k| c[(k / n, k % n)]).collect()
}

/// The minimal loop; returns a checksum so nothing is optimised away.
fn minimal(sc: &Scenario) -> f64 {
    const D: usize = 2;
    let m = sc.model();
    let fw = sc.framework();
    let (n, me, runs) = (m.agents(), m.num_edges(), sc.runs());
    let (nd, md) = (n * D, me * D);
    let dt = sc.dt();
    let t = sc.samples() as f64;
    // Q = Q_A ⊗ I: chol(Q_A), row-major lower.
    let qa = DMatrix::from_fn(n, n, |i, j| m.q()[(i * D, j * D)]);
    let ca = lower_rm(&qa);
    let cr: Vec<f64> = m.r().iter().flat_map(|r| lower_rm(&(r / t))).collect();
    let edges = &m.edges();
    let weights = fw.edge_weights();
    let leader = |i: usize| fw.leaders().contains(&i);
    let d2: Vec<f64> = edges
        .iter()
        .map(|&(i, j)| {
            (0..D)
                .map(|a| (fw.point(i)[a] - fw.point(j)[a]).powi(2))
                .sum()
        })
        .collect();
    let mut streams = Streams::new(0..runs as u64);
    let mut z = vec![0.0; nd * runs];
    streams.fill_normals(&mut z);
    let q: Vec<Mat<D>> = (0..me)
        .map(|e| Mat::<D>::from_fn(|a, b| m.edge_q(e, e)[(a, b)]))
        .collect();
    let w: Vec<Mat<D>> = m
        .r()
        .iter()
        .map(|r| Mat::<D>::from_fn(|a, b| r[(a, b)] / t))
        .collect();
    let mut sig: Vec<Mat<D>> = (0..me)
        .map(|e| Mat::<D>::from_fn(|a, b| m.edge_p0(e, e)[(a, b)]))
        .collect();
    let mut frozen = vec![false; me];
    let mut gain = vec![[0.0; 4]; me];
    let (mut eta, mut xi, mut wv) = (
        vec![0.0; md * runs],
        vec![0.0; nd * runs],
        vec![0.0; nd * runs],
    );
    let (mut xh, mut u) = (vec![0.0; md * runs], vec![0.0; nd * runs]);
    let mut y = vec![0.0; md * runs];
    let mut check = 0.0;
    for k in 1..=sc.steps() {
        streams.fill_normals(&mut eta);
        streams.fill_normals(&mut xi);
        wv.fill(0.0);
        for i in 0..n {
            for j in 0..=i {
                let c = ca[i * n + j];
                for d in 0..D {
                    let (o, s) = ((i * D + d) * runs, (j * D + d) * runs);
                    for r in 0..runs {
                        wv[o + r] += c * xi[s + r];
                    }
                }
            }
        }
        for e in 0..me {
            if !frozen[e] {
                let prior = sig[e] + q[e];
                let (post, kk) = joseph_step(&prior, &w[e]).expect("positive definite");
                frozen[e] = settled(&post, &sig[e]);
                sig[e] = post;
                gain[e] = [kk[(0, 0)], kk[(0, 1)], kk[(1, 0)], kk[(1, 1)]];
            }
            let (i, j) = edges[e];
            let c = &cr[e * 4..e * 4 + 4];
            let g = gain[e];
            let (r0, r1) = (e * D * runs, (e * D + 1) * runs);
            let (zi0, zi1) = (i * D * runs, (i * D + 1) * runs);
            let (zj0, zj1) = (j * D * runs, (j * D + 1) * runs);
            for r in 0..runs {
                let x0 = z[zi0 + r] - z[zj0 + r];
                let x1 = z[zi1 + r] - z[zj1 + r];
                let (e0, e1) = (eta[r0 + r], eta[r1 + r]);
                let y0 = x0 + c[0] * e0;
                let y1 = x1 + c[2] * e0 + c[3] * e1;
                y[r0 + r] = x0;
                y[r1 + r] = x1;
                let p0 = xh[r0 + r] + dt * (u[zi0 + r] - u[zj0 + r]);
                let p1 = xh[r1 + r] + dt * (u[zi1 + r] - u[zj1 + r]);
                let (v0, v1) = (y0 - p0, y1 - p1);
                xh[r0 + r] = p0 + g[0] * v0 + g[1] * v1;
                xh[r1 + r] = p1 + g[2] * v0 + g[3] * v1;
            }
        }
        if k % sc.every() == 0 {
            for (a, b) in y.iter().zip(&xh) {
                check += (a - b) * (a - b);
            }
        }
        u.fill(0.0);
        for (e, &(i, j)) in edges.iter().enumerate() {
            let (r0, r1) = (e * D * runs, (e * D + 1) * runs);
            let (u0, u1) = (i * D * runs, (i * D + 1) * runs);
            if leader(i) {
                if !leader(j) {
                    continue;
                }
                for r in 0..runs {
                    let s = xh[r0 + r] * xh[r0 + r] + xh[r1 + r] * xh[r1 + r] - d2[e];
                    u[u0 + r] -= s * xh[r0 + r];
                    u[u1 + r] -= s * xh[r1 + r];
                }
            } else {
                let l = weights[e];
                for r in 0..runs {
                    u[u0 + r] -= l * xh[r0 + r];
                    u[u1 + r] -= l * xh[r1 + r];
                }
            }
        }
        for ((zv, uv), wq) in z.iter_mut().zip(&u).zip(&wv) {
            *zv += dt * uv + wq;
        }
    }
    check
}

/// The draws alone: per step and run the minimal loop's M·D measurement-mean and N·D process
/// normals, each kept from being optimised away by `black_box` (no summing: a chain of
/// additions would cost more than the draws). Any implementation that draws the same
/// randomness with the same generator costs at least this per agent-step. `lanes`: the
/// engine's generator (`edgekf::rng`, four runs per vector); otherwise `rand_distr`'s ziggurat
/// on one Xoshiro256++ per run (the engine's generator before 2026-12-04).
fn draws_only(sc: &Scenario, lanes: bool) -> f64 {
    const D: usize = 2;
    let m = sc.model();
    let (n, runs) = (m.agents(), sc.runs());
    let per_run = (m.num_edges() + n) * D;
    let mut check = 0.0;
    if lanes {
        let mut streams = Streams::new(0..runs as u64);
        let mut buf = vec![0.0; per_run * runs];
        for _ in 0..sc.steps() {
            streams.fill_normals(&mut buf);
            std::hint::black_box(&mut buf);
        }
        return buf.iter().sum();
    }
    let mut rngs: Vec<Xoshiro256PlusPlus> = (0..runs)
        .map(|r| Xoshiro256PlusPlus::seed_from_u64(r as u64))
        .collect();
    for _ in 0..sc.steps() {
        for rng in &mut rngs {
            for _ in 0..per_run {
                let x: f64 = rng.sample(StandardNormal);
                check = std::hint::black_box(x);
            }
        }
    }
    check
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let runs = args.first().copied().unwrap_or(50);
    let steps = args.get(1).copied().unwrap_or(30_000);
    let reps = args.get(2).copied().unwrap_or(3).max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let per = |wall: f64, sc: &Scenario, est: usize| {
        wall / (sc.framework().agents() * sc.runs() * sc.steps() * est) as f64 * 1e9
    };
    // The fastest of `reps` timings: on a shared machine the others measure the neighbours.
    let fastest = |f: &dyn Fn() -> f64| -> (f64, f64) {
        let mut best = f64::INFINITY;
        let mut check = 0.0;
        for _ in 0..reps {
            let t = Instant::now();
            check = f();
            best = best.min(t.elapsed().as_secs_f64());
        }
        (best, check)
    };
    println!(
        "one thread, EUSIPCO scenario, {runs} runs × {steps} steps, fastest of {reps}; ns per agent-step (per estimator)"
    );
    let sc = scenario(&["rkf"], runs, steps);
    let (wall, c) = fastest(&|| minimal(&sc));
    let base = per(wall, &sc, 1);
    println!("minimal SoA loop (rkf)       {base:7.1}   (checksum {c:.3e})");
    let m = sc.model();
    let normals = (m.num_edges() + m.agents()) * 2 / m.agents();
    let (wall, c) = fastest(&|| draws_only(&sc, true));
    let draws = per(wall, &sc, 1);
    println!(
        "draws alone ({normals} normals)      {draws:7.1}   (checksum {c:.3e}; edgekf::rng, 4 lanes: the floor of any loop drawing them)"
    );
    let (wall, c) = fastest(&|| draws_only(&sc, false));
    let scalar = per(wall, &sc, 1);
    println!(
        "  the same, rand_distr       {scalar:7.1}   (checksum {c:.3e}; one Xoshiro256++ per run, the engine's before 2026-12-04)"
    );
    let mut rkf = f64::NAN;
    for set in [
        &["rkf"][..],
        &["oracle"],
        &["rkf-ar"],
        &["none", "mle", "rkf", "jrkf", "crkf"],
    ] {
        let sc = scenario(set, runs, steps);
        let (wall, _) = fastest(&|| {
            pool.install(|| edgekf::sim::run(&sc, &edgekf::sim::Quiet))
                .expect("not cancelled");
            0.0
        });
        let ns = per(wall, &sc, set.len());
        if set == ["rkf"] {
            rkf = ns;
        }
        println!(
            "engine {:<22} {ns:7.1}   ({:.2}× the minimal loop, {:.2}× rkf)",
            set.join(", "),
            ns / base,
            ns / rkf
        );
    }
}
