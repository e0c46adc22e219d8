//! Robustness sweep of the stress design (issue 11): on generated families of sparse candidate
//! graphs just above the rigidity threshold — D-trilateration backbones (`D + 1` earlier
//! neighbours per agent) plus `k ∈ {0, 2, 4}` nearest neighbours, N ∈ {10, 20, 50, 100}, 2-D and
//! 3-D, four box shapes — every instance either designs a stress that passes every check or is
//! refused with the failed condition named (`NotUniversallyRigid`, `NonGeneric`); no design
//! stops on a solver failure.
//!
//! The test in the normal run is a reduced version (51 instances, mostly N ≤ 20). The full
//! sweep (288 instances × `sdp` and `sparse`) is `#[ignore]`d here and also printed with counts
//! and times by `cargo run --release -p edgekf --example design_sweep`.

use edgekf::design::generators::{self, Extent};
use edgekf::design::{self, Candidate, CheckReport, DesignError, Method};

/// How one design ended.
#[derive(Debug, Clone, PartialEq)]
enum Outcome {
    /// Designed and every check passed; the relative optimality gap.
    Designed { gap: f64 },
    /// Refused with a named condition.
    Refused(String),
}

fn run(c: &Candidate, method: Method) -> Outcome {
    match design::design(c, method) {
        Ok(d) => {
            let r = CheckReport::from_framework(&d.framework);
            assert!(r.passed(), "{} {method:?}: designed but\n{r}", c.name);
            // Normalised to smallest nonzero eigenvalue 1 (to round-off relative to λ_max).
            let tol = 1e-9 * r.max_eigenvalue().max(1.0);
            assert!(
                (r.stress_gap() - 1.0).abs() <= tol,
                "{} {method:?}: gap {}",
                c.name,
                r.stress_gap()
            );
            assert!(
                d.gap.is_finite() && d.gap >= 0.0,
                "{}: gap {}",
                c.name,
                d.gap
            );
            Outcome::Designed { gap: d.gap }
        }
        Err(e @ (DesignError::NotUniversallyRigid(_) | DesignError::NonGeneric(_))) => {
            Outcome::Refused(e.to_string())
        }
        Err(e) => panic!("{} {method:?}: stopped without a verdict: {e}", c.name),
    }
}

/// Designs every instance with `sdp` and `sparse`; returns (designed, refused, designed with a
/// gap above 1e-6). Both methods start from the same conditioning SDP, so they must agree on
/// whether an instance is refused.
fn sweep(instances: &[Candidate]) -> (usize, usize, usize) {
    let (mut designed, mut refused, mut loose) = (0, 0, 0);
    for c in instances {
        let mut verdicts = Vec::new();
        for method in [Method::Sdp, Method::Sparse] {
            let outcome = run(c, method);
            match &outcome {
                Outcome::Designed { gap } => {
                    designed += 1;
                    if *gap > 1e-6 {
                        loose += 1;
                    }
                }
                Outcome::Refused(reason) => {
                    eprintln!("{} {method:?}: refused — {reason}", c.name);
                    refused += 1;
                }
            }
            verdicts.push(matches!(outcome, Outcome::Designed { .. }));
        }
        assert_eq!(
            verdicts[0], verdicts[1],
            "{}: sdp and sparse disagree",
            c.name
        );
    }
    (designed, refused, loose)
}

#[test]
fn reduced_sweep_designs_or_refuses_every_instance() {
    let mut instances = generators::family(&[10, 20], &[2, 3], &[0, 2, 4], &Extent::ALL, 0..1);
    instances.extend(generators::family(
        &[50],
        &[2],
        &[0, 2, 4],
        &[Extent::Unit],
        0..1,
    ));
    assert_eq!(instances.len(), 51);
    let (designed, refused, loose) = sweep(&instances);
    eprintln!("reduced sweep: {designed} designed ({loose} with gap > 1e-6), {refused} refused");
    assert_eq!(designed + refused, 2 * instances.len());
    // The backbones are universally rigid (generic D-trilateration graphs); a refusal is the
    // numerical limit λ_max/λ_min > 1e8/N, which sparse 3-D backbones (agents far outside the
    // simplex of their D + 1 references) do reach. Measured: 2 of 51 instances (both 3-D).
    assert!(refused <= 2 * 4, "{refused} refusals");
}

#[test]
#[ignore = "full sweep, ≈ 10 min; run with --ignored or the design_sweep example"]
fn full_sweep_designs_or_refuses_every_instance() {
    let instances = generators::family(&[10, 20, 50, 100], &[2, 3], &[0, 2, 4], &Extent::ALL, 0..3);
    assert_eq!(instances.len(), 288);
    let (designed, refused, loose) = sweep(&instances);
    eprintln!("full sweep: {designed} designed ({loose} with gap > 1e-6), {refused} refused");
    assert_eq!(designed + refused, 2 * instances.len());
}

#[test]
fn flexible_backbones_are_refused_with_the_reason() {
    // Cut every link of agent 7 but two: in 2-D it can flip across the line through its two
    // neighbours, so the framework is not globally (hence not universally) rigid.
    for seed in 0..3 {
        let mut c =
            generators::family(&[20], &[2], &[0], &[Extent::Unit], seed..seed + 1).remove(0);
        let mut kept = 0;
        c.links.retain(|&(i, j)| {
            if i != 7 && j != 7 {
                return true;
            }
            kept += 1;
            kept <= 2
        });
        for method in [Method::Sdp, Method::Sparse] {
            match run(&c, method) {
                Outcome::Refused(reason) => assert!(
                    reason.contains("not universally rigid"),
                    "{}: {reason}",
                    c.name
                ),
                other => panic!("{}: {other:?}", c.name),
            }
        }
    }
}
