//! Agents as a distributed system: N [`edgekf::agent::Agent`]s and their world stepped in
//! lockstep reproduce `edgekf run --runs 1` bit for bit — every decentralised estimator kind,
//! on every shipped scenario (faults, departures, maneuvers, link failures, T > 1, correlated
//! process noise, every control law the scenarios use) — and the centralised kinds are refused.

use edgekf::agent::{lockstep, Agent, AgentError, LockstepError};
use edgekf::estimate::Registry;
use edgekf::scenario::{EstimatorEntry, Scenario, ScenarioSpec};
use edgekf::sim::{self, Quiet, Results};
use edgekf_io::reproductions::ENTRIES;

/// The kinds no single agent can run.
const CENTRAL: &[&str] = &["crkf", "oracle"];

fn label_kind(e: &EstimatorEntry) -> String {
    e.0.get("kind")
        .and_then(|v| v.as_str())
        .unwrap_or_default()
        .to_string()
}

/// A shipped scenario at one run and `steps` steps, its decentralised estimators only.
fn shipped(file: &str, text: &str, steps: usize) -> Option<Scenario> {
    let mut spec = edgekf_io::spec_from_toml(text).ok()?;
    let fw = edgekf_io::reproductions::framework_of(file, &spec).expect("framework");
    spec.estimators
        .retain(|e| !CENTRAL.contains(&label_kind(e).as_str()));
    if spec.estimators.is_empty() {
        return None;
    }
    spec.plots.clear();
    spec.sweep = None;
    spec.sim.runs = 1;
    spec.sim.steps = steps.min(spec.sim.steps);
    spec.sim.every = 7;
    Some(Scenario::from_spec(&spec, fw.as_ref()).expect("valid"))
}

fn assert_same(a: &Results, b: &Results, what: &str) {
    assert_eq!(a.steps, b.steps, "{what}: reported steps");
    for (x, y) in a.estimators.iter().zip(&b.estimators) {
        assert_eq!(x.label, y.label);
        assert_eq!(x.outcome, y.outcome, "{what}: {} outcome", x.label);
        assert_eq!(x.metrics, y.metrics, "{what}: {} metrics", x.label);
        for (m, (u, v)) in x.metrics.iter().zip(x.values.iter().zip(&y.values)) {
            for (k, (p, q)) in u.iter().zip(v).enumerate() {
                assert!(
                    p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()),
                    "{what}: {} `{m}` at report {k}: engine {p:e}, agents {q:e}",
                    x.label
                );
            }
        }
        assert_eq!(x.paths, y.paths, "{what}: {} paths", x.label);
    }
}

/// Every shipped filter scenario, run by the engine and by its agents.
#[test]
fn agents_in_lockstep_reproduce_the_engine_on_every_shipped_scenario() {
    let mut kinds = std::collections::BTreeSet::new();
    let mut files = std::collections::BTreeSet::new();
    for e in ENTRIES.iter().filter(|e| !e.is_slam()) {
        for (file, text) in std::iter::once((e.file, e.text)).chain(e.companions.iter().copied()) {
            if !files.insert(file) {
                continue;
            }
            let steps = if file.starts_with("garkf-fig13") {
                120
            } else {
                400
            };
            let Some(sc) = shipped(file, text, steps) else {
                continue;
            };
            for def in sc.estimators() {
                kinds.insert(def.kind().to_string());
            }
            let engine = sim::run(&sc, &Quiet).expect("engine");
            let agents = lockstep(&sc, &Quiet).expect("agents");
            assert_same(&engine, &agents, file);
        }
    }
    // The shipped scenarios run these; the next test runs every decentralised kind.
    assert!(kinds.len() >= 10, "{kinds:?}");
}

/// The kinds the shipped scenarios do not run, on the hexagon with faults of every sort.
#[test]
fn every_decentralised_kind_in_lockstep_with_faults() {
    for kind in Registry::builtin().names() {
        if CENTRAL.contains(&kind) {
            continue;
        }
        let entry = if kind == "mmse" {
            "{ kind = \"mmse\", prior_var = 1e-3 }".to_string()
        } else {
            format!("\"{kind}\"")
        };
        let text = format!(
            "name = \"k\"\nestimators = [{entry}]\n[framework]\npreset = \"hexagon\"\n\
             [sim]\nsteps = 300\nruns = 1\nevery = 5\n[noise]\nsigma_v = 0.1\nsigma_w = 0.001\n\
             [comm]\np_fail = 0.3\nar = {{ coeffs = [[0.97, 0.98]], noise_var = [0.01, 0.01] }}\n\
             [faults]\navailability = 0.7\ndepartures = [{{ agent = 5, at = 0.1 }}]\n"
        );
        let spec = edgekf_io::spec_from_toml(&text).expect("TOML");
        let sc = match Scenario::from_spec(&spec, None) {
            Ok(sc) => sc,
            Err(e) => panic!("{kind}: {e}"),
        };
        let engine = sim::run(&sc, &Quiet).expect("engine");
        let agents = lockstep(&sc, &Quiet).expect("agents");
        assert_same(&engine, &agents, kind);
    }
}

#[test]
fn centralised_kinds_and_bad_ids_are_refused_by_name() {
    let mut spec = ScenarioSpec::minimal("c", &["rkf", "crkf"]);
    spec.sim.runs = 1;
    let sc = Scenario::from_spec(&spec, None).expect("valid");
    let err = Agent::new(&sc, 0, false).err().expect("refused");
    assert!(
        matches!(&err, AgentError::NotDistributed { kind, .. } if kind == "crkf"),
        "{err}"
    );
    assert!(err.to_string().contains("centralised"), "{err}");
    assert!(matches!(
        lockstep(&sc, &Quiet),
        Err(LockstepError::Agent(_))
    ));
    let spec = ScenarioSpec::minimal("c", &["rkf"]);
    let sc = Scenario::from_spec(&spec, None).expect("valid");
    let err = Agent::new(&sc, 10, false).err().expect("refused");
    assert_eq!(
        err.to_string(),
        "agent id 10 is out of range: the scenario has agents 0..10"
    );
}
