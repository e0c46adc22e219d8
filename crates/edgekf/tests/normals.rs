//! The multi-lane normal generator (`edgekf::rng`) against the normal distribution: moments, a
//! Kolmogorov–Smirnov test, tail frequencies, and independence between lanes and between
//! successive draws. Each bound is a number of standard errors chosen so that a correct
//! generator fails with probability below 1e-6 per check (5 SE for moments and correlations;
//! the KS bound at α = 1e-6).

use edgekf::rng::Streams;

/// `rows × runs` normals from seeds 7, 8, …: 8 runs, so two vectors of four lanes.
fn draws(rows: usize) -> (Vec<f64>, usize) {
    let runs = 8;
    let mut s = Streams::new((0..runs as u64).map(|r| 7 + r));
    let mut buf = vec![0.0; rows * runs];
    s.fill_normals(&mut buf);
    (buf, runs)
}

/// `erfc` (Numerical Recipes' Chebyshev fit, relative error < 1.2e-7): far below what the
/// tests below resolve (their bounds are 1e-3 and coarser).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

fn phi(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

#[test]
fn moments_are_the_normals() {
    let (x, _) = draws(500_000);
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let m = |p: i32| x.iter().map(|v| (v - mean).powi(p)).sum::<f64>() / n;
    let (var, m3, m4) = (m(2), m(3), m(4));
    let skew = m3 / var.powf(1.5);
    let kurt = m4 / (var * var) - 3.0;
    for (what, value, se) in [
        ("mean", mean, (1.0 / n).sqrt()),
        ("variance − 1", var - 1.0, (2.0 / n).sqrt()),
        ("skewness", skew, (6.0 / n).sqrt()),
        ("excess kurtosis", kurt, (24.0 / n).sqrt()),
    ] {
        assert!(
            value.abs() < 5.0 * se,
            "{what} {value:e} (SE {se:e}, n = {n})"
        );
    }
}

#[test]
fn kolmogorov_smirnov_against_phi() {
    let (mut x, _) = draws(125_000);
    x.sort_by(f64::total_cmp);
    let n = x.len() as f64;
    let d = x
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let f = phi(v);
            (f - i as f64 / n).abs().max(((i + 1) as f64 / n - f).abs())
        })
        .fold(0.0, f64::max);
    // P(D > c) ≤ 2 exp(−2 n c²) (Dvoretzky–Kiefer–Wolfowitz–Massart): c at 1e-6.
    let c = ((2.0f64 / 1e-6).ln() / (2.0 * n)).sqrt();
    assert!(d < c, "KS distance {d:e} ≥ {c:e} (n = {n})");
}

#[test]
fn tail_frequencies_to_five_sigma() {
    // 4e7 draws: |x| > 4 is expected 2,532 times, > 5 about 23 times.
    let (x, _) = draws(5_000_000);
    let n = x.len() as f64;
    for k in [1.0, 2.0, 3.0, 4.0, 5.0] {
        let p = erfc(k / std::f64::consts::SQRT_2);
        let count = x.iter().filter(|v| v.abs() > k).count() as f64;
        let se = (n * p * (1.0 - p)).sqrt();
        assert!(
            (count - n * p).abs() < 5.0 * se + 1.0,
            "|x| > {k}: {count} of {n}, expected {:.1} ± {se:.1}",
            n * p
        );
    }
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - ma) * (y - mb))
        .sum::<f64>()
        / n;
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum::<f64>() / n;
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum::<f64>() / n;
    cov / (va * vb).sqrt()
}

#[test]
fn lanes_and_successive_draws_are_uncorrelated() {
    let rows = 500_000;
    let (x, runs) = draws(rows);
    let run = |r: usize| -> Vec<f64> { (0..rows).map(|k| x[k * runs + r]).collect() };
    let se = 1.0 / (rows as f64).sqrt();
    // Lanes of one vector (0–1, 0–3), across vectors (3–4), and squares (a dependence in
    // magnitude that a linear correlation would miss).
    for (a, b) in [(0, 1), (0, 3), (3, 4), (2, 7)] {
        let (xa, xb) = (run(a), run(b));
        let rho = correlation(&xa, &xb);
        assert!(rho.abs() < 5.0 * se, "runs {a} and {b}: ρ = {rho:e}");
        let sq = |v: &[f64]| v.iter().map(|x| x * x).collect::<Vec<_>>();
        let rho2 = correlation(&sq(&xa), &sq(&xb));
        assert!(
            rho2.abs() < 5.0 * se,
            "runs {a} and {b}, squares: ρ = {rho2:e}"
        );
    }
    // Successive draws of one stream.
    let r0 = run(0);
    let rho = correlation(&r0[..rows - 1], &r0[1..]);
    assert!(rho.abs() < 5.0 * se, "lag 1: ρ = {rho:e}");
}
