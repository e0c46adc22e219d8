//! Formation design (issues 4 and 11): every design passes every check on the hexagon, a 3-D
//! framework, a random 50-agent configuration and Zhao's 7-agent example (leaders not linked);
//! the designed loops converge to the affine image; flexible and non-generic inputs are rejected
//! with the right reason; leaders are chosen by λ_min(L_ff).

use edgekf::design::{
    self, generators, leaders, sdp, sparse, yang, Candidate, CheckReport, DesignError, LeaderMode,
    Method,
};
use edgekf::framework::Framework;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

const METHODS: [Method; 3] = [Method::Sdp, Method::Yang, Method::Sparse];

fn candidates() -> Vec<Candidate> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2024);
    vec![
        generators::hexagon_candidate(),
        generators::hexagon3d_candidate(),
        generators::random50(generators::Density::Sparse, &mut rng),
    ]
}

/// Noiseless closed loop `z_{k+1} = z_k − Δt (L ⊗ I) z_k` from a random start, with
/// `Δt = 1 / λ_max` (stable for `Δt < 2 / λ_max`). Returns the final positions and the start.
fn simulate(f: &Framework, rng: &mut impl Rng) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = f.agents();
    let dim = f.dim();
    let l = f.laplacian();
    let dt = 1.0 / f.eigenvalues()[n - 1];
    let z0 = DMatrix::from_fn(n, dim, |_, _| rng.random_range(-5.0..5.0));
    let mut z = z0.clone();
    // Contraction per step 1 − Δt λ_gap = 1 − 1/κ; 40 κ steps shrink the non-affine part by
    // e^-40 ≈ 4e-18, below round-off.
    let steps = (40.0 * f.eigenvalues()[n - 1] / f.stress_gap()).ceil() as usize;
    for _ in 0..steps {
        z = &z - (l * &z) * dt;
    }
    (z, z0)
}

fn affine_basis(f: &Framework) -> DMatrix<f64> {
    DMatrix::from_fn(f.agents(), f.dim() + 1, |i, c| {
        if c == 0 {
            1.0
        } else {
            f.point(i)[c - 1]
        }
    })
}

#[test]
fn every_design_passes_every_check_and_converges() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    for c in candidates() {
        for m in METHODS {
            let d = design::design(&c, m).unwrap_or_else(|e| panic!("{} {m:?}: {e}", c.name));
            let f = &d.framework;
            let report = CheckReport::from_framework(f);
            assert!(report.passed(), "{} {m:?}:\n{report}", c.name);
            assert!(report.universally_rigid());
            assert!(report.connected() && report.generic() && report.equilibrium() && report.psd());
            assert_eq!(report.rank, f.agents() - f.dim() - 1);
            // Every design is normalised to smallest nonzero eigenvalue 1 (to round-off).
            assert!(
                (report.stress_gap() - 1.0).abs() < 1e-9,
                "{}",
                report.stress_gap()
            );
            // The leaders are carried through (the stress does not depend on them).
            assert_eq!(f.leaders(), &c.leaders[..]);

            let (z, z0) = simulate(f, &mut rng);
            // The limit is the orthogonal projection of z0 onto span[1 P] (L is symmetric and
            // its null space is exactly that span): an affine image of the configuration.
            let a = affine_basis(f);
            let proj = &a * (a.transpose() * &a).try_inverse().unwrap() * a.transpose();
            let limit = &proj * &z0;
            let err = (&z - &limit).amax();
            assert!(
                err < 1e-8 * z0.amax(),
                "{} {m:?}: distance to affine image {err:e}",
                c.name
            );
        }
    }
}

#[test]
fn zhao_example_with_unlinked_leaders_designs_and_verifies() {
    let c = generators::zhao7_candidate();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    let mut spectra = Vec::new();
    for m in [Method::Sdp, Method::Sparse] {
        let d = design::design(&c, m).unwrap_or_else(|e| panic!("{m:?}: {e}"));
        let f = &d.framework;
        let r = CheckReport::from_framework(f);
        assert!(r.passed(), "{m:?}:\n{r}");
        assert_eq!(f.leaders(), &[0, 1, 2]);
        // Leaders 1 and 2 are not linked: named in the report and by the distance law's check,
        // which is no part of the design.
        assert_eq!(r.unlinked_leaders, Some((1, 2)));
        assert!(f.check_leader_clique().is_err());
        let text = r.to_string();
        assert!(text.contains("leaders 1 and 2 are not linked"), "{text}");
        // The leaders pin the followers: λ_min(L_ff) > 0 with its time constant printed.
        let lam = r.follower_min_eigenvalue.unwrap();
        assert!(lam > 1e-3 && lam <= r.stress_gap() * (1.0 + 1e-9), "{lam}");
        assert!(text.contains("time constant"), "{text}");
        // All twelve links stay: the stress space is one-dimensional, so both methods return the
        // same (unique up to scale) stress.
        assert_eq!(f.graph().links().len(), 12);
        spectra.push(f.eigenvalues().to_vec());
        let (z, z0) = simulate(f, &mut rng);
        let a = affine_basis(f);
        let proj = &a * (a.transpose() * &a).try_inverse().unwrap() * a.transpose();
        assert!((&z - &proj * &z0).amax() < 1e-8 * z0.amax());
    }
    // Same normalised spectrum from both methods (solver accuracy 1e-6 does not enter: the
    // stress is fixed by the graph, the solvers only choose its scale).
    for (a, b) in spectra[0].iter().zip(&spectra[1]) {
        assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{spectra:?}");
    }
}

#[test]
fn leaders_do_not_change_the_stress() {
    let mut c = generators::hexagon_candidate();
    let with = sdp::design(&c, &sdp::SdpOptions::default()).unwrap();
    c.leaders = vec![];
    let without = sdp::design(&c, &sdp::SdpOptions::default()).unwrap();
    c.leaders = vec![4, 7, 9];
    let other = sdp::design(&c, &sdp::SdpOptions::default()).unwrap();
    for d in [&without, &other] {
        for (a, b) in d.framework.weights().iter().zip(with.framework.weights()) {
            assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0));
        }
    }
    assert_eq!(other.framework.leaders(), &[4, 7, 9]);
    assert!(without.framework.leaders().is_empty());
    let r = CheckReport::from_framework(&without.framework);
    assert!(r.follower_min_eigenvalue.is_none());
    assert!(r.to_string().contains("no leaders"), "{r}");
}

#[test]
fn chosen_leaders_beat_the_default_ones() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2024);
    let c = generators::random50(generators::Density::Sparse, &mut rng);
    let d = sparse::design(&c, &sparse::SparseOptions::default()).unwrap();
    let f = &d.framework;
    let given = leaders::follower_min_eigenvalue(f.laplacian(), &[0, 1, 2]);
    let clique = design::choose_leaders(f, LeaderMode::Clique).unwrap();
    // A clique of the designed graph, at least as good as the leaders the framework has (they
    // are always on the shortlist when they qualify).
    for (k, &a) in clique.leaders.iter().enumerate() {
        for &b in &clique.leaders[k + 1..] {
            assert!(f.graph().has_link(a, b), "{:?}", clique.leaders);
        }
    }
    assert!(
        clique.follower_min_eigenvalue >= given,
        "{clique:?} vs {given}"
    );
    let affine = design::choose_leaders(f, LeaderMode::Affine).unwrap();
    assert!(affine.follower_min_eigenvalue >= given);
    eprintln!(
        "random50 sparse: λ_min(L_ff) given [0, 1, 2] {given:.4}, clique {:?} {:.4}, affine {:?} {:.4}",
        clique.leaders, clique.follower_min_eigenvalue, affine.leaders, affine.follower_min_eigenvalue
    );
    // The reported value is λ_min(L_ff) of the chosen set, and the report prints it.
    let g = f.clone().with_leaders(&affine.leaders).unwrap();
    let r = CheckReport::from_framework(&g);
    let lam = r.follower_min_eigenvalue.unwrap();
    assert!((lam - affine.follower_min_eigenvalue).abs() <= 1e-9 * lam);
}

#[test]
fn leader_choice_against_exhaustive_search_on_the_hexagon() {
    let f = Framework::hexagon();
    let n = f.agents();
    let mut best = 0.0_f64;
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                best = best.max(leaders::follower_min_eigenvalue(f.laplacian(), &[a, b, c]));
            }
        }
    }
    let chosen = design::choose_leaders(&f, LeaderMode::Affine).unwrap();
    eprintln!(
        "hexagon: chosen {:?} λ_min(L_ff) {:.4}, exhaustive best {best:.4}",
        chosen.leaders, chosen.follower_min_eigenvalue
    );
    assert!(chosen.follower_min_eigenvalue >= 0.9 * best);
}

#[test]
fn sdp_reproduces_the_hexagon_preset_spectrum() {
    let d = sdp::design(
        &generators::hexagon_candidate(),
        &sdp::SdpOptions::default(),
    )
    .unwrap();
    let ours = d.framework.eigenvalues();
    let preset = Framework::hexagon();
    // Spectrum {0 ×3, 1 ×3, 15.7, 51.6 ×3}: the optimal ratio λ_max/λ_min is unique; we ask for
    // agreement to 1e-4 relative (solver stops at 1e-6 relative duality gap; the preset was
    // solved offline to similar accuracy).
    for (a, b) in ours.iter().zip(preset.eigenvalues()) {
        assert!(
            (a - b).abs() <= 1e-4 * b.abs().max(1.0),
            "{ours:?} vs {:?}",
            preset.eigenvalues()
        );
    }
    assert!((ours[9] - 51.6).abs() < 0.05 && (ours[6] - 15.7).abs() < 0.05);
}

#[test]
fn thesis_gap_variant_respects_its_bounds() {
    let opts = sdp::SdpOptions {
        objective: sdp::SdpObjective::ThesisGap {
            lambda_bar: 100.0,
            weight_bound: 1.0,
        },
        ..sdp::SdpOptions::default()
    };
    let d = sdp::design(&generators::hexagon_candidate(), &opts).unwrap();
    let r = CheckReport::from_framework(&d.framework);
    assert!(r.passed(), "{r}");
    // Unscaled: every |w| ≤ 1 (interior point, so strictly) and the gap positive.
    assert!(d.framework.weights().iter().all(|w| w.abs() <= 1.0));
    assert!(r.stress_gap() > 0.0);
    // The best-conditioned design scaled to max |w| = 1 is feasible for this problem, so the
    // optimum must reach at least its gap (up to the solver's 1e-6 relative accuracy).
    let cond = sdp::design(
        &generators::hexagon_candidate(),
        &sdp::SdpOptions::default(),
    )
    .unwrap();
    let wmax = cond
        .framework
        .weights()
        .iter()
        .fold(0.0_f64, |m, w| m.max(w.abs()));
    assert!(r.stress_gap() >= cond.framework.stress_gap() / wmax * (1.0 - 1e-6));
}

#[test]
fn three_d_trilateration_and_complete_graphs() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    let c = generators::trilateration(20, 3, 5, &mut rng);
    for m in METHODS {
        let d = design::design(&c, m).unwrap();
        assert!(CheckReport::from_framework(&d.framework).passed());
    }
    // Complete graph: the conditioning optimum is the projector, ratio 1.
    let cfg = generators::random_config(8, 2, 3.0, &mut rng);
    let d = sdp::design(
        &generators::complete("k8", 2, cfg),
        &sdp::SdpOptions::default(),
    )
    .unwrap();
    let ev = d.framework.eigenvalues();
    assert!(
        (ev[7] - 1.0).abs() < 1e-9 && (ev[3] - 1.0).abs() < 1e-9,
        "{ev:?}"
    );
}

#[test]
fn sparse_design_drops_links_and_stays_rigid() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2024);
    let c = generators::random50(generators::Density::Sparse, &mut rng);
    let d = sparse::design(&c, &sparse::SparseOptions::default()).unwrap();
    let kept = d.framework.graph().links().len();
    assert!(kept < c.links.len(), "{kept} of {}", c.links.len());
    assert_eq!(d.candidate_links, c.links.len());
    // Every kept link is a candidate.
    assert!(d
        .framework
        .graph()
        .links()
        .iter()
        .all(|l| c.links.contains(l)));
}

#[test]
fn yang_builds_a_banded_trilateration_graph() {
    let d = yang::design(&generators::hexagon_candidate()).unwrap();
    let r = CheckReport::from_framework(&d.framework);
    assert!(
        matches!(r.trilateration, design::checks::Trilateration::Yes { .. }),
        "{r}"
    );
    // Each agent after the first D + 1 links to at most D + 1 agents before it in the order:
    // (D + 1)(D + 2)/2 + (D + 1)(N − D − 2) links at most.
    assert!(d.framework.graph().links().len() <= 3 + 3 * 7);
}

fn hexagon_with(links: Vec<(usize, usize)>) -> Candidate {
    let mut c = generators::hexagon_candidate();
    c.links = links;
    c
}

#[test]
fn flexible_frameworks_are_rejected_with_the_reason() {
    // A cycle carries no equilibrium stress at all.
    let cycle: Vec<(usize, usize)> = (0..10).map(|i| (i, (i + 1) % 10)).collect();
    for m in [Method::Sdp, Method::Sparse] {
        let err = design::design(&hexagon_with(cycle.clone()), m).unwrap_err();
        assert!(
            matches!(&err, DesignError::NotUniversallyRigid(s) if s.contains("no nonzero equilibrium stress")),
            "{err}"
        );
    }
    // The hexagon with agent 9 hanging on two links: the rest has stresses, but agent 9 can
    // swing out of the affine image, so no PSD stress of rank N − D − 1 exists.
    let c = generators::hexagon_candidate();
    let links: Vec<_> = c
        .links
        .iter()
        .copied()
        .filter(|&(i, j)| !(j == 9 && (i == 0 || i == 2 || i == 3)))
        .collect();
    assert_eq!(links.iter().filter(|l| l.1 == 9).count(), 2);
    for m in [Method::Sdp, Method::Sparse] {
        let err = design::design(&hexagon_with(links.clone()), m).unwrap_err();
        assert!(
            matches!(&err, DesignError::NotUniversallyRigid(s) if s.contains("no positive semidefinite stress of rank N − D − 1 = 7")),
            "{err}"
        );
    }
    // The check report names the failure too: the preset weights restricted to those links.
    let hex = Framework::hexagon();
    let w: Vec<f64> = hex
        .graph()
        .links()
        .iter()
        .zip(hex.weights())
        .filter(|(l, _)| links.contains(l))
        .map(|(_, &w)| w)
        .collect();
    let r = design::check(2, &c.config, &links, &w, &[]).unwrap();
    assert!(!r.passed());
    assert!(r.to_string().contains("verdict: FAILED"), "{r}");
}

#[test]
fn non_generic_configurations_are_rejected() {
    let mut c = generators::hexagon_candidate();
    c.config = (0..10).map(|i| vec![i as f64, 0.5 * i as f64]).collect();
    for m in METHODS {
        let err = design::design(&c, m).unwrap_err();
        assert!(matches!(err, DesignError::NonGeneric(_)), "{m:?}: {err}");
    }
    let mut small = generators::hexagon_candidate();
    small.config.truncate(3);
    small.links = vec![(0, 1), (0, 2), (1, 2)];
    assert!(matches!(
        design::design(&small, Method::Sdp),
        Err(DesignError::TooFewAgents { n: 3, dim: 2 })
    ));
}

#[test]
fn check_report_matches_framework_verification() {
    // A stress whose sign is flipped is an equilibrium but not PSD.
    let f = Framework::hexagon();
    let cfg: Vec<Vec<f64>> = (0..10).map(|i| f.point(i).to_vec()).collect();
    let neg: Vec<f64> = f.weights().iter().map(|v| -v).collect();
    let r = design::check(2, &cfg, f.graph().links(), &neg, &[]).unwrap();
    assert!(r.equilibrium() && !r.psd());
}

#[test]
fn malformed_input_is_an_input_error() {
    let mut c = generators::hexagon_candidate();
    c.leaders = vec![0];
    for m in METHODS {
        let err = design::design(&c, m).unwrap_err();
        assert!(matches!(err, DesignError::Input(_)), "{m:?}: {err}");
    }
    let mut c = generators::hexagon_candidate();
    c.config[4] = vec![1.0];
    assert!(matches!(
        design::design(&c, Method::Sdp),
        Err(DesignError::Input(_))
    ));
    let c = generators::hexagon_candidate();
    let err = design::check(2, &c.config, &c.links, &[1.0; 29], &[]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "invalid input: 29 weights given for 30 links"
    );
}

/// The opt-in Clarabel solver (feature `clarabel`) against the default interior-point method.
#[cfg(feature = "clarabel")]
mod clarabel {
    use super::*;
    use std::time::Instant;

    /// Eigenvalue ratio `λ_max / λ_min` of `Q L Qᵀ` (the conditioning SDP's optimal value).
    fn ratio(f: &Framework) -> f64 {
        f.eigenvalues()[f.agents() - 1] / f.stress_gap()
    }

    fn opts(solver: sdp::SdpSolver) -> sdp::SdpOptions {
        sdp::SdpOptions {
            solver,
            ..sdp::SdpOptions::default()
        }
    }

    /// Both solvers approach the same optimum `κ*` from the feasible side and stop at a relative
    /// duality gap of 1e-6: the IPM on `s = 1/κ` (strictly feasible iterates), Clarabel on
    /// `t = κ` in the form `min t` s.t. `I ⪯ Q L Qᵀ ⪯ t I` (primal residual ≤ 1e-8, which moves
    /// the eigenvalues by ~1e-8 relative). So each ratio lies within ≈ 1e-6 κ* of `κ*` and the
    /// two within ≈ 2e-6 of each other; we assert 5e-6 relative (measured: ≤ 1e-7).
    const AGREE: f64 = 5e-6;

    /// Every shipped candidate but `random50-sparse`, and a 3-D trilateration. The 50-agent
    /// instances are the example's (`examples/clarabel_timing.rs`, times in the guide's design
    /// chapter): in the test profile Clarabel takes 63 s on `random50-sparse` (the default
    /// solver 0.15 s) and 26 s on the 6-neighbour backbone, more than the rest of its tests.
    #[test]
    fn clarabel_sdp_passes_every_check_and_agrees_with_the_ipm() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let mut cands: Vec<Candidate> = candidates()
            .into_iter()
            .filter(|c| c.name != "random50-sparse")
            .collect();
        cands.push(generators::trilateration(
            20,
            3,
            5,
            &mut Xoshiro256PlusPlus::seed_from_u64(11),
        ));
        for c in cands {
            let t = Instant::now();
            let ipm = sdp::design(&c, &opts(sdp::SdpSolver::Ipm)).unwrap();
            let t_ipm = t.elapsed();
            let t = Instant::now();
            let cl = sdp::design(&c, &opts(sdp::SdpSolver::Clarabel))
                .unwrap_or_else(|e| panic!("{}: {e}", c.name));
            let t_cl = t.elapsed();
            let f = &cl.framework;
            let report = CheckReport::from_framework(f);
            assert!(report.passed(), "{}:\n{report}", c.name);
            assert!(report.universally_rigid() && report.equilibrium() && report.psd());
            assert_eq!(report.rank, f.agents() - f.dim() - 1);
            assert!((report.stress_gap() - 1.0).abs() < 1e-9);
            let (z, z0) = simulate(f, &mut rng);
            let a = affine_basis(f);
            let proj = &a * (a.transpose() * &a).try_inverse().unwrap() * a.transpose();
            assert!((&z - &proj * &z0).amax() < 1e-8 * z0.amax(), "{}", c.name);

            let (ki, kc) = (ratio(&ipm.framework), ratio(f));
            let rel = (kc - ki).abs() / ki;
            eprintln!(
                "{}: ratio ipm {ki:.9} ({} steps, {t_ipm:.2?}), clarabel {kc:.9} ({} iterations, \
                 {t_cl:.2?}), relative difference {rel:.1e}",
                c.name, ipm.newton_steps, cl.newton_steps
            );
            assert!(rel < AGREE, "{}: {ki} vs {kc}", c.name);
        }
    }

    #[test]
    fn clarabel_thesis_gap_matches_the_ipm() {
        let mk = |solver| sdp::SdpOptions {
            objective: sdp::SdpObjective::ThesisGap {
                lambda_bar: 100.0,
                weight_bound: 1.0,
            },
            ..opts(solver)
        };
        let c = generators::hexagon_candidate();
        let ipm = sdp::design(&c, &mk(sdp::SdpSolver::Ipm)).unwrap();
        let cl = sdp::design(&c, &mk(sdp::SdpSolver::Clarabel)).unwrap();
        let r = CheckReport::from_framework(&cl.framework);
        assert!(r.passed(), "{r}");
        // Weight bound respected up to Clarabel's feasibility tolerance (1e-8).
        assert!(cl.framework.weights().iter().all(|w| w.abs() <= 1.0 + 1e-7));
        // Same optimal λ: IPM relative gap 1e-6, Clarabel gap 1e-6 relative to max(1, λ).
        let (gi, gc) = (ipm.framework.stress_gap(), r.stress_gap());
        eprintln!("thesis gap: ipm {gi:.9}, clarabel {gc:.9}");
        assert!((gi - gc).abs() <= 5e-6 * gi.max(1.0), "{gi} vs {gc}");
    }

    #[test]
    fn clarabel_sparse_design_passes_every_check() {
        // 15 agents, 2-trilateration links and 6 nearest neighbours (61 links): Clarabel's
        // sparse design in 50 ms. On random 16–30-agent candidates of this kind it stops at
        // `AlmostSolved`, and on the 50-agent ones it takes 1–3 minutes in the test profile
        // (the guide's design chapter, "Optional solver"; `examples/clarabel_timing.rs`).
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(2);
        let config = generators::random_config(15, 2, 15f64.sqrt(), &mut rng);
        let tri = generators::trilateration_links(&config, 2, 3);
        let links = generators::nearest_neighbour_links(&config, 6, &tri);
        let c = Candidate {
            name: "sparse15".into(),
            dim: 2,
            config,
            links,
            leaders: vec![0, 1, 2],
        };
        let t = Instant::now();
        let ipm = sparse::design(&c, &sparse::SparseOptions::default()).unwrap();
        let t_ipm = t.elapsed();
        let t = Instant::now();
        let cl = sparse::design(
            &c,
            &sparse::SparseOptions {
                solver: sdp::SdpSolver::Clarabel,
                ..sparse::SparseOptions::default()
            },
        )
        .unwrap();
        let t_cl = t.elapsed();
        let f = &cl.framework;
        let report = CheckReport::from_framework(f);
        assert!(report.passed(), "{report}");
        assert!((report.stress_gap() - 1.0).abs() < 1e-9);
        let kept = f.graph().links().len();
        assert!(kept < c.links.len(), "{kept} of {}", c.links.len());
        assert!(f.graph().links().iter().all(|l| c.links.contains(l)));
        let (ki, kc) = (ratio(&ipm.framework), ratio(f));
        let ni = ipm.framework.graph().links().len();
        eprintln!(
            "sparse15: ipm {ni} links, ratio {ki:.6} ({t_ipm:.2?}); clarabel {kept} links, \
             ratio {kc:.6} ({t_cl:.2?})"
        );
        // The ℓ1 optimum need not be unique, so the supports may differ; when they agree, the
        // polished designs are the same conditioning SDP on the same graph.
        if ipm.framework.graph().links() == f.graph().links() {
            assert!((kc - ki).abs() < AGREE * ki, "{ki} vs {kc}");
        }
    }

    /// The robustness families (issue 11) on a subset small enough for Clarabel: N = 10 and 20,
    /// 2-D and 3-D, k = 0, 2, 4 nearest neighbours, unit and elongated boxes (24 instances). Where the default solver
    /// certifies its optimum to 1e-6 relative (its `gap`), the two optimal ratios agree to 1e-6
    /// relative: the IPM's ratio lies in `[κ*, κ*(1 + gap)]` (a feasible design), Clarabel's
    /// within its relative gap (asked 1e-7) of `κ*` (up to its 1e-8 primal residual), so the
    /// difference is at most ≈ 1.1e-6 κ*; we assert 1e-6 (measured: ≤ 1e-7). Refusals must agree.
    #[test]
    fn clarabel_and_the_default_solver_agree_on_the_robustness_families() {
        use edgekf::design::generators::Extent;
        let cands = generators::family(
            &[10, 20],
            &[2, 3],
            &[0, 2, 4],
            &[Extent::Unit, Extent::Elongated],
            0..1,
        );
        let (mut compared, mut worst) = (0, 0.0_f64);
        for c in &cands {
            let ipm = sdp::design(c, &opts(sdp::SdpSolver::Ipm));
            let cl = sdp::design(c, &opts(sdp::SdpSolver::Clarabel));
            match (ipm, cl) {
                (Ok(a), Ok(b)) => {
                    assert!(
                        CheckReport::from_framework(&b.framework).passed(),
                        "{}",
                        c.name
                    );
                    let (ki, kc) = (ratio(&a.framework), ratio(&b.framework));
                    let rel = (ki - kc).abs() / kc;
                    eprintln!(
                        "{}: ratio ipm {ki:.9} (gap {:.1e}), clarabel {kc:.9} (gap {:.1e}): {rel:.1e}",
                        c.name, a.gap, b.gap
                    );
                    // Both at their tolerance: the IPM's 1e-6 and Clarabel's 1e-7 (it falls back
                    // to 1e-6 where it cannot reach 1e-7).
                    if a.gap <= 1e-6 && b.gap <= 1e-7 {
                        compared += 1;
                        worst = worst.max(rel);
                        assert!(rel <= 1e-6, "{}: {ki} vs {kc}", c.name);
                    }
                }
                // A refusal by the default solver (no stress with λ_max/λ_min ≤ 1e8/N) must not
                // be contradicted: Clarabel refuses as well, fails numerically on the
                // near-singular problem, or finds no better stress either.
                (Err(DesignError::NotUniversallyRigid(_)), other) => {
                    if let Ok(b) = &other {
                        let limit = sdp::max_condition(c.config.len());
                        assert!(ratio(&b.framework) > 0.5 * limit, "{}", c.name);
                    }
                    eprintln!("{}: refused; clarabel {:?}", c.name, other.map(|d| d.gap));
                }
                (a, b) => panic!(
                    "{}: {:?} vs {:?}",
                    c.name,
                    a.map(|d| d.gap),
                    b.map(|d| d.gap)
                ),
            }
        }
        eprintln!(
            "{compared} of {} compared, worst relative difference {worst:.1e}",
            cands.len()
        );
        assert!(compared >= cands.len() / 2);
    }

    #[test]
    fn clarabel_rejects_flexible_frameworks_with_the_reason() {
        let sdp_opts = opts(sdp::SdpSolver::Clarabel);
        let sparse_opts = sparse::SparseOptions {
            solver: sdp::SdpSolver::Clarabel,
            ..sparse::SparseOptions::default()
        };
        let run = |c: &Candidate| {
            [
                sdp::design(c, &sdp_opts).unwrap_err(),
                sparse::design(c, &sparse_opts).unwrap_err(),
            ]
        };
        let cycle: Vec<(usize, usize)> = (0..10).map(|i| (i, (i + 1) % 10)).collect();
        for err in run(&hexagon_with(cycle)) {
            assert!(
                matches!(&err, DesignError::NotUniversallyRigid(s) if s.contains("no nonzero equilibrium stress")),
                "{err}"
            );
        }
        let c = generators::hexagon_candidate();
        let links: Vec<_> = c
            .links
            .iter()
            .copied()
            .filter(|&(i, j)| !(j == 9 && (i == 0 || i == 2 || i == 3)))
            .collect();
        for err in run(&hexagon_with(links)) {
            assert!(
                matches!(&err, DesignError::NotUniversallyRigid(s) if s.contains("no positive semidefinite stress of rank N − D − 1 = 7")),
                "{err}"
            );
        }
    }
}

/// The default method picks what works at the size given (issue 11 point 4): a candidate set of
/// more than `AUTO_LINKS` links that is not a complete graph is designed on the subgraph of each
/// agent's nearest candidate neighbours, says so, and passes every check with links from the
/// candidates only.
#[test]
fn sdp_on_a_large_candidate_set_designs_on_its_nearest_neighbour_subgraph() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
    let cfg = generators::random_config(120, 2, 10.0, &mut rng);
    let mut c = generators::complete("k120-minus-one", 2, cfg);
    c.links.retain(|&l| l != (0, 1) && l != (1, 0));
    assert!(c.links.len() > design::AUTO_LINKS);
    let d = design::design(&c, Method::Sdp).unwrap();
    let note = d.note.as_deref().expect("a note says what was done");
    assert!(note.contains("nearest candidate neighbours"), "{note}");
    assert_eq!(d.candidate_links, c.links.len());
    let report = CheckReport::from_framework(&d.framework);
    assert!(report.passed(), "{report:?}");
    let kept = d.framework.graph().links();
    assert!(kept.len() <= 120 * 8, "{} links", kept.len());
    for &(i, j) in kept {
        assert!(c.links.contains(&(i, j)) || c.links.contains(&(j, i)));
    }
    // The subgraph: every agent keeps its k nearest candidate neighbours, nothing else.
    let sub = design::nearest_candidate_links(&c, 6);
    assert!(sub.len() >= 120 * 6 / 2 && sub.len() <= 120 * 6);
    let near0 = sub.iter().filter(|&&(i, j)| i == 0 || j == 0).count();
    assert!(near0 >= 6);
    // Small sets still get the SDP on every candidate, with no note.
    let small = generators::trilateration(30, 2, 4, &mut rng);
    assert!(design::design(&small, Method::Sdp).unwrap().note.is_none());
}
