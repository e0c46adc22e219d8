//! Claim 7c: without disturbances every robot's estimate of every robot and landmark — including landmarks it
//! never sees — converges to the truth, and the formation and centroid errors go to zero, at the rate the
//! spectral abscissa α of the error system (eq. 21) predicts.
mod common;

use edgekf_slam::simulate;

/// Non-normal transient allowance: `‖E(t)‖ ≤ C e^{αt}‖E(0)‖` with `C = 10`. The measured ratio
/// `‖E(10)‖ / (e^{10α}‖E(0)‖)` is 0.74; 10 is a generic allowance for a 48-dimensional non-normal system, not a fit.
const TRANSIENT: f64 = 10.0;

#[test]
fn every_estimate_converges_including_unseen_landmarks() {
    let sc = common::scenario(common::FIG3);
    let alpha = sc.theorem1().error_abscissa;
    let tr = simulate(&sc);
    let last = tr.times.len() - 1;
    assert!((tr.times[last] - 10.0).abs() < 1e-12);
    let e0 = tr.total_error(0);
    let bound = TRANSIENT * e0 * (alpha * tr.times[last]).exp();
    assert!(
        tr.total_error(last) < bound,
        "{} vs {bound}",
        tr.total_error(last)
    );
    let (n, m) = (sc.n(), sc.m());
    for i in 0..n {
        let e_init = tr.error(0, i);
        let e = tr.error(last, i);
        for l in 0..m {
            let k = 2 * (n + l);
            let init = (e_init[k].powi(2) + e_init[k + 1].powi(2)).sqrt();
            let fin = (e[k].powi(2) + e[k + 1].powi(2)).sqrt();
            // Every landmark error (seen or not) falls below the total-error bound, i.e. by > 10³ from its start.
            assert!(
                fin < bound && fin < 1e-3 * init,
                "robot {i} landmark {l}: {init} → {fin}"
            );
        }
    }
    // Robot 1 never sees landmarks 0 and 4, robot 2 never sees 0, 1, 2: they learn them through consensus.
    assert!(!sc.model().landmark_sets[1].contains(&0) && !sc.model().landmark_sets[2].contains(&0));
}

#[test]
fn decay_rate_matches_the_spectral_abscissa() {
    let sc = common::scenario(common::FIG3);
    let alpha = sc.theorem1().error_abscissa;
    let tr = simulate(&sc);
    // t = 6 s and 10 s (whatever the output grid): transients of the faster modes (≤ −0.98) have faded by ≥ e^{-0.09·6}
    let a = tr
        .times
        .iter()
        .position(|&t| t >= 6.0 - 1e-9)
        .expect("the horizon is 10 s");
    let b = tr.times.len() - 1;
    let dt = tr.times[b] - tr.times[a];
    let rate = |f: &dyn Fn(usize) -> f64| (f(a) / f(b)).ln() / dt;
    let est = rate(&|k| tr.total_error(k));
    let form = rate(&|k| sc.formation_error(&tr.x[k]));
    let cent = rate(&|k| sc.centroid_error(tr.times[k], &tr.x[k]));
    // The slowest mode dominates only asymptotically and the next ones sit at −0.98 and −1.0, so a finite-window
    // rate lies between |α| and about 1.1|α|; ±20% covers that without tuning.
    for (name, r) in [("estimate", est), ("formation", form), ("centroid", cent)] {
        assert!(
            (r / -alpha - 1.0).abs() < 0.2,
            "{name}: rate {r} vs |α| = {}",
            -alpha
        );
    }
    let last = tr.times.len() - 1;
    // Formation and centroid errors are driven only by E through k₂ D E: they end below the estimation bound.
    assert!(
        sc.formation_error(&tr.x[last]) < 1e-3
            && sc.centroid_error(tr.times[last], &tr.x[last]) < 1e-3
    );
}
