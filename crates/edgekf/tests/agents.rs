//! Agents as a distributed system: N [`edgekf::agent::Agent`]s and their world stepped in
//! lockstep reproduce `edgekf run --runs 1` bit for bit — every decentralised estimator kind,
//! on every shipped scenario (faults, departures, maneuvers, link failures, T > 1, correlated
//! process noise, every control law the scenarios use) — and the centralised kinds are refused.

use edgekf::agent::{lockstep, Agent, AgentError, Exchange, LockstepError, Output, World};
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

/// Run 0 of `sc` in lockstep with a live world (presence tracked, as `edgekf swarm --live`)
/// whose agent `gone` stops at step `from`: no output or exchange from it after step
/// `from − 1`, and the world departs it before sensing step `from` — a process that ended.
fn lockstep_with_an_ended_agent(sc: &Scenario, gone: usize, from: usize) -> Results {
    let n = sc.framework().agents();
    let mut world = World::live(sc);
    let mut agents: Vec<Agent> = (0..n)
        .map(|i| Agent::new(sc, i, true).expect("agent"))
        .collect();
    let mut last: Vec<Option<Output>> = vec![None; n];
    for k in 1..=sc.steps() {
        if k == from {
            world.depart(gone);
        }
        let ended = |i: usize| i == gone && k >= from;
        let sensing = world.sense();
        let mut exchanges: Vec<Option<Exchange>> = Vec::with_capacity(n);
        for (i, (a, s)) in agents.iter_mut().zip(&sensing).enumerate() {
            let x = if ended(i) {
                None
            } else {
                a.begin(s, |j| last[j].as_ref()).expect("begin")
            };
            exchanges.push(x);
        }
        let outputs: Vec<Option<Output>> = (0..n)
            .map(|i| (!ended(i)).then(|| agents[i].finish(|j| exchanges[j].as_ref())))
            .collect();
        world.act(&outputs.iter().map(Option::as_ref).collect::<Vec<_>>());
        last = outputs;
    }
    world.results()
}

/// An agent whose process ends (the world departs it and it sends nothing more) is absent
/// exactly as a departure of `[faults]` at the same step makes it, bit for bit, for every
/// decentralised kind: its neighbours read its input as zero once it has gone (the engine's
/// controller sets an absent agent's input to zero; predicting it by the AR model instead
/// made `rkf-ar` 15 times worse by the end), and the metrics leave out its last report (its
/// part of `cov_trace` and its per-agent quantities).
#[test]
fn an_agent_whose_process_ends_is_a_departure() {
    let kinds: Vec<String> = Registry::builtin()
        .names()
        .into_iter()
        .filter(|k| !CENTRAL.contains(k))
        .map(|k| match k {
            "mmse" => "{ kind = \"mmse\", prior_var = 1e-3 }".to_string(),
            _ => format!("\"{k}\""),
        })
        .collect();
    let base = format!(
        "name = \"k\"\nestimators = [{}]\n[framework]\npreset = \"hexagon\"\n\
         [sim]\ndt = 0.01\nsteps = 300\nruns = 1\nevery = 1\n\
         [comm.ar]\ncoeffs = [[0.97, 0.98]]\nnoise_var = [0.01, 0.01]\n",
        kinds.join(", ")
    );
    let load = |text: &str| {
        let spec = edgekf_io::spec_from_toml(text).expect("TOML");
        Scenario::from_spec(&spec, None).expect("valid")
    };
    let departed = load(&format!(
        "{base}[faults]\ndepartures = [{{ agent = 6, at = 1.01 }}]\n"
    ));
    let engine = sim::run(&departed, &Quiet).expect("engine");
    let agents = lockstep_with_an_ended_agent(&load(&base), 6, 101);
    assert_same(&engine, &agents, "agent 6 ended at step 101");
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
