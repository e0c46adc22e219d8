//! The user guide's numbers tables (What is reproduced; thesis chapter 6) with their Monte Carlo standard errors, from the shipped
//! scenarios at their own seeds (50 runs): `cargo run --release -p edgekf-claims --example
//! readme_numbers`. Each number is the mean over runs of the per-run window mean (± its standard
//! error over runs); a covariance trace that is the same in every run is exact.

use edgekf::sim::Quiet;
use edgekf_claims::statistic::{Statistic, Window, FIRST};
use edgekf_claims::study::study;
use edgekf_claims::{Data, Size};

fn show(e: Result<(edgekf_claims::Estimate, Option<String>), String>) -> String {
    match e {
        Ok((e, _)) if e.se == 0.0 => format!("{:.5e} (exact)", e.value),
        Ok((e, _)) => format!("{:.4e} ± {:.1e}", e.value, e.se),
        Err(why) => why,
    }
}

fn mean(d: &Data, label: &'static str, metric: &'static str, window: Window) -> String {
    show(
        Statistic::Mean {
            label,
            metric,
            window,
        }
        .eval(d),
    )
}

fn consistency(d: &Data, label: &'static str, window: Window) -> String {
    show(
        Statistic::MetricRatio {
            label,
            num: "est_error_sq",
            den: "cov_trace",
            window,
        }
        .eval(d),
    )
}

fn run(id: &str) -> Data {
    study(id)
        .expect("a study")
        .run(Size::Full, Some(1), &Quiet)
        .expect("runs")
}

fn main() {
    let steady = (15.0, 30.0);
    let floor = (25.0, 30.0);
    let d = run("eusipco");
    println!("## eusipco (seed 2022, 50 runs): cov_trace 15–30 s | ε²/cov 15–30 s | procrustes 25–30 s | ε 15–30 s");
    for l in ["none", "mle", "rkf", "jrkf", "crkf"] {
        println!(
            "{l}: {} | {} | {} | {}",
            mean(&d, l, "cov_trace", steady),
            consistency(&d, l, steady),
            mean(&d, l, "procrustes", floor),
            mean(&d, l, "est_error", steady)
        );
    }
    let d = run("fig4.5");
    println!("## fig4.5: procrustes 25–30 s | ε²/cov 15–30 s");
    for l in ["noiseless", "none", "mle-T10", "mle-T100"] {
        println!(
            "{l}: {} | {}",
            mean(&d, l, "procrustes", floor),
            consistency(&d, l, steady)
        );
    }
    let d = run("fig4.8");
    println!("## fig4.8: cov_trace at 30 s | ε²/cov 15–30 s | procrustes 25–30 s");
    for l in ["none", "mle", "mmse", "rkf"] {
        println!(
            "{l}: {} | {} | {}",
            mean(&d, l, "cov_trace", (30.0, 30.0)),
            consistency(&d, l, steady),
            mean(&d, l, "procrustes", floor)
        );
    }
    let d = run("fig3.3");
    println!("## fig3.3: procrustes at start | 25–30 s | at 30 s");
    println!(
        "{} | {} | {}",
        mean(&d, "noiseless", "procrustes", FIRST),
        mean(&d, "noiseless", "procrustes", floor),
        mean(&d, "noiseless", "procrustes", (30.0, 30.0))
    );
    let early = (0.5, 4.0);
    let transient = (0.1, 1.0);
    println!("## chapter 6: ε 0.5–4 s | ε 15–30 s | ε²/cov 0.1–1 s | ε²/cov 15–30 s");
    let d = run("fig6.2");
    for l in [
        "P_fail=0",
        "P_fail=0.25",
        "P_fail=0.5",
        "P_fail=0.75",
        "P_fail=1",
        "u=0 baseline",
    ] {
        println!(
            "{l}: {} | {} | {} | {}",
            mean(&d, l, "est_error", early),
            mean(&d, l, "est_error", steady),
            consistency(&d, l, transient),
            consistency(&d, l, steady)
        );
    }
    let d = run("fig6.3");
    for l in ["clairvoyant", "u=0 baseline", "commless"] {
        println!(
            "{l}: {} | {} | {} | {}",
            mean(&d, l, "est_error", early),
            mean(&d, l, "est_error", steady),
            consistency(&d, l, transient),
            consistency(&d, l, steady)
        );
    }
}
