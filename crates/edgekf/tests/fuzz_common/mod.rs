//! The parser/checker fuzz of issue 9 point 6: mutated scenario files, resolved scenarios and
//! framework files through the library's parse and check path, with an oracle.
//!
//! - **Seeds**: every shipped `scenarios/*.toml` of the filter engine; the resolved
//!   `scenario.json` of each (`Scenario::to_resolved`); framework files (`edgekf.framework/1`) of
//!   the hexagon preset and of the stress designs `edgekf design --generate hexagon --method sdp`
//!   and `--generate hexagon3d --method sdp` would write, each read through a small scenario
//!   that names it in `framework.file`.
//! - **Path**: `edgekf_io::spec_from_toml` → `Scenario::from_spec`;
//!   `Resolved::from_json` → `Scenario::from_resolved`; a framework file is parsed
//!   as the CLI parses it (schema checked) and handed to `Scenario::from_spec`.
//! - **Oracle**: no panic; a refusal is an error whose key or field is named (a
//!   [`ScenarioError`] whose key is a key of that input, or a parse error naming a field in
//!   backticks or pointing at a line and column of the text); an accepted scenario passes cheap
//!   invariants (report steps, a finite cost estimate, a `to_resolved` round trip that parses
//!   back to an equal resolved form and is accepted again, the `--runs 2 --steps 30` overrides);
//!   and no case takes longer than [`SLOW`].
//!
//! Shared by `tests/fuzz_parse.rs` (10⁴ cases in `cargo test`) and `benches/fuzz_parse.rs`
//! (10⁶ cases, `cargo bench -p edgekf --bench fuzz_parse`).

#![allow(dead_code)]

pub mod mutate;

use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::panic::{self, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Once;
use std::time::{Duration, Instant};

use edgekf::design::{self, generators, Method};
use edgekf::framework::Framework;
use edgekf::scenario::{Resolved, Scenario, ScenarioError};
use edgekf_io::framework::FrameworkFile;
use mutate::{Format, Mutator, Seed};

/// A case slower than this plus [`SLOW_PER_BYTE`] per byte of input is a defect: parsing and
/// checking must stay cheap and about linear in the input (a mutation can grow an input to
/// megabytes, whose parsing alone takes a second).
pub const SLOW: Duration = Duration::from_secs(2);
/// The time allowed per byte of input on top of [`SLOW`].
pub const SLOW_PER_BYTE: Duration = Duration::from_micros(1);

/// What a seed is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A TOML scenario file.
    Toml,
    /// A resolved `scenario.json`.
    Resolved,
    /// A framework file, read through [`FRAMEWORK_SCENARIO`].
    Framework,
}

/// The scenario that reads a fuzzed framework file.
pub const FRAMEWORK_SCENARIO: &str = r#"
name = "framework-file"
estimators = ["mle", "rkf", "jrkf", "crkf"]
[framework]
file = "framework.json"
[sim]
steps = 30
runs = 2
"#;

/// The repository's `scenarios/` directory.
pub fn scenarios_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

/// The seeds: shipped TOML scenarios (filter engine only), their resolved forms, and framework
/// files. Returns the mutation engine and the role of each seed.
pub fn corpus(base: u64) -> (Mutator, Vec<Role>) {
    let mut seeds = Vec::new();
    let mut roles = Vec::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(scenarios_dir())
        .expect("scenarios directory")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    for p in &files {
        let text = std::fs::read_to_string(p).expect("readable scenario");
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let Ok(spec) = edgekf_io::spec_from_toml(&text) else {
            // SLAM scenarios (`kind = "slam"`) belong to edgekf-slam.
            assert!(text.contains("kind = \"slam\""), "{name} does not parse");
            continue;
        };
        // A scenario that names a framework file (the GA-RKF ones): the file is read here, and
        // only its resolved form is a seed (a mutated TOML of it would be checked without the
        // file; the resolved form carries the framework inline).
        let file = spec.framework.file.as_ref().map(|f| {
            let text = std::fs::read_to_string(scenarios_dir().join(f)).expect("framework file");
            edgekf_io::framework::spec_from_json(&text).expect("framework file")
        });
        let sc = Scenario::from_spec(&spec, file.as_ref()).expect("shipped scenarios are valid");
        if file.is_none() {
            seeds.push(Seed::new(&name, Format::Toml, &text).expect("TOML seed"));
            roles.push(Role::Toml);
        }
        let json = serde_json::to_string_pretty(&sc.to_resolved()).expect("serialisable");
        seeds.push(
            Seed::new(&name.replace(".toml", ".json"), Format::Json, &json).expect("JSON seed"),
        );
        roles.push(Role::Resolved);
    }
    for (name, fw) in frameworks() {
        let json = serde_json::to_string_pretty(&FrameworkFile::from_framework(&fw))
            .expect("serialisable");
        seeds.push(Seed::new(&name, Format::Json, &json).expect("framework seed"));
        roles.push(Role::Framework);
    }
    (Mutator::new(seeds, base), roles)
}

/// Framework files: the hexagon preset, and what `edgekf design --generate hexagon|hexagon3d
/// --method sdp` writes.
pub fn frameworks() -> Vec<(String, Framework)> {
    let mut out = vec![("framework:hexagon-preset".to_string(), Framework::hexagon())];
    for (name, c) in [
        ("framework:hexagon-sdp", generators::hexagon_candidate()),
        ("framework:hexagon3d-sdp", generators::hexagon3d_candidate()),
    ] {
        let d = design::design(&c, Method::Sdp).expect("the generators' designs succeed");
        out.push((name.to_string(), d.framework));
    }
    out
}

/// How a case ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Parsed, checked and every invariant held.
    Accepted,
    /// Refused with a message that names the key: by the parser or by the checks.
    Refused {
        /// `parse` or `check`.
        stage: &'static str,
        /// The message.
        message: String,
    },
    /// A defect: what kind, and the detail.
    Defect {
        /// Kind (`panic`, `unnamed refusal`, `invariant`, `slow`).
        kind: String,
        /// Detail.
        detail: String,
    },
}

fn defect(kind: &str, detail: impl Into<String>) -> Verdict {
    Verdict::Defect {
        kind: kind.into(),
        detail: detail.into(),
    }
}

/// Top-level keys of a TOML scenario (the roots a refusal may name).
const TOML_ROOTS: &[&str] = &[
    "name",
    "description",
    "framework",
    "sim",
    "init",
    "noise",
    "control",
    "comm",
    "faults",
    "maneuver",
    "metrics",
    "sweep",
    "estimators",
    "plots",
];

/// Top-level keys of a resolved scenario.
const RESOLVED_ROOTS: &[&str] = &[
    "schema",
    "name",
    "dim",
    "agents",
    "config",
    "edges",
    "weights",
    "leaders",
    "dt",
    "steps",
    "runs",
    "seed",
    "samples_per_step",
    "init_mean",
    "init_cov",
    "process_cov",
    "meas_cov",
    "estimators",
    "estimator_specs",
    "description",
    "every",
    "reports_per_decade",
    "paths_per_decade",
    "paths_run",
    "follower_gain",
    "leader_gain",
    "control",
    "comm",
    "faults",
    "maneuver",
    "metrics",
    "sweep",
    "allow_divergence",
    "plots",
];

/// Flags the overrides are named by.
const FLAG_ROOTS: &[&str] = &["--steps", "--runs", "--every", "sim"];

fn key_root(key: &str) -> &str {
    let end = key.find(['.', '[', ':', '/', ' ']).unwrap_or(key.len());
    &key[..end]
}

/// Whether a scenario error names a key of the input it came from.
fn names_key(e: &ScenarioError, roots: &[&str]) -> bool {
    !e.key.is_empty() && !e.message.trim().is_empty() && roots.contains(&key_root(&e.key))
}

/// Whether a parse error names a field in backticks or points at a line of `text`.
pub fn parse_error_named(msg: &str, text: &str) -> bool {
    if msg.trim().is_empty() {
        return false;
    }
    if msg.contains('`') {
        return true;
    }
    // TOML: "TOML parse error at line L, column C"; JSON: "… at line L column C" (the last
    // "line" followed by a number: a quoted value in the message may hold the word too).
    let line = msg
        .split("line ")
        .skip(1)
        .filter_map(|s| s.split(|c: char| !c.is_ascii_digit()).next())
        .filter_map(|s| s.parse::<usize>().ok())
        .last();
    match line {
        Some(l) => l >= 1 && l <= text.lines().count().max(1) + 1,
        None => false,
    }
}

thread_local! {
    static FUZZING: Cell<bool> = const { Cell::new(false) };
    static PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

static HOOK: Once = Once::new();

/// Installs a panic hook that records panics of fuzz cases (silently) and leaves every other
/// panic to the default hook.
pub fn install_hook() {
    HOOK.call_once(|| {
        let default = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if FUZZING.with(Cell::get) {
                let loc = info
                    .location()
                    .map(|l| format!(" at {}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                let msg = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                PANIC.with(|p| *p.borrow_mut() = Some(format!("{msg}{loc}")));
            } else {
                default(info);
            }
        }));
    });
}

/// Runs one input through parse + check + invariants, catching panics.
pub fn judge(role: Role, text: &str) -> Verdict {
    install_hook();
    FUZZING.with(|f| f.set(true));
    let start = Instant::now();
    let r = panic::catch_unwind(AssertUnwindSafe(|| check_input(role, text)));
    FUZZING.with(|f| f.set(false));
    let v = match r {
        Ok(v) => v,
        Err(_) => {
            let msg = PANIC.with(|p| p.borrow_mut().take()).unwrap_or_default();
            return defect("panic", msg);
        }
    };
    let t = start.elapsed();
    if t > SLOW + SLOW_PER_BYTE * text.len() as u32 {
        return defect(
            "slow",
            format!("{t:.2?} in parse and checks of {} bytes", text.len()),
        );
    }
    v
}

fn check_input(role: Role, text: &str) -> Verdict {
    match role {
        Role::Toml => {
            let spec = match edgekf_io::spec_from_toml(text) {
                Ok(s) => s,
                Err(e) => return parse_refusal(&e.to_string(), text),
            };
            if spec.framework.file.is_some() {
                // No file to read here: the check must name the key.
                return match Scenario::from_spec(&spec, None) {
                    Ok(_) => defect("invariant", "accepted an unread framework.file"),
                    Err(e) => check_refusal(&e, TOML_ROOTS),
                };
            }
            match Scenario::from_spec(&spec, None) {
                Ok(sc) => invariants(&sc),
                Err(e) => check_refusal(&e, TOML_ROOTS),
            }
        }
        Role::Resolved => {
            let r = match Resolved::from_json(text) {
                Ok(r) => r,
                Err(e) => return parse_refusal(&e.to_string(), text),
            };
            match Scenario::from_resolved(&r) {
                Ok(sc) => invariants(&sc),
                Err(e) => check_refusal(&e, RESOLVED_ROOTS),
            }
        }
        Role::Framework => {
            // Read as the CLI and the scenarios read it.
            let fs = match FrameworkFile::parse(text) {
                Ok(f) => f.to_spec(),
                Err(e) => return parse_refusal(&e.to_string(), text),
            };
            let spec =
                edgekf_io::spec_from_toml(FRAMEWORK_SCENARIO).expect("valid framework scenario");
            match Scenario::from_spec(&spec, Some(&fs)) {
                Ok(sc) => invariants(&sc),
                Err(e) => check_refusal(&e, TOML_ROOTS),
            }
        }
    }
}

fn parse_refusal(msg: &str, text: &str) -> Verdict {
    if parse_error_named(msg, text) {
        Verdict::Refused {
            stage: "parse",
            message: msg.to_string(),
        }
    } else {
        defect(
            "unnamed refusal",
            format!("parse error names no key: {msg}"),
        )
    }
}

fn check_refusal(e: &ScenarioError, roots: &[&str]) -> Verdict {
    if names_key(e, roots) {
        Verdict::Refused {
            stage: "check",
            message: e.to_string(),
        }
    } else {
        defect(
            "unnamed refusal",
            format!("key `{}` is not a key of this input: {}", e.key, e.message),
        )
    }
}

/// Cheap invariants of an accepted scenario.
fn invariants(sc: &Scenario) -> Verdict {
    let held = report_steps_hold(sc)
        .and_then(|()| derived_values_hold(sc))
        .and_then(|()| round_trip_holds(sc))
        .and_then(|()| overrides_hold(sc));
    match held {
        Ok(()) => Verdict::Accepted,
        Err(v) => v,
    }
}

/// Report steps: 1, the multiples of `every`, and the last step, increasing.
fn report_steps_hold(sc: &Scenario) -> Result<(), Verdict> {
    let count = sc.report_count();
    if count == 0 {
        return Err(defect("invariant", "no reported step"));
    }
    if count > 1_000_000 {
        return Ok(());
    }
    let steps = sc.report_steps();
    if steps.len() != count {
        return Err(defect(
            "invariant",
            format!("report_count {count} but {} report steps", steps.len()),
        ));
    }
    if steps[0] != 1
        || *steps.last().unwrap() != sc.steps()
        || steps.windows(2).any(|w| w[0] >= w[1])
    {
        return Err(defect(
            "invariant",
            format!(
                "report steps not 1 < … < steps: {:?}…",
                &steps[..steps.len().min(5)]
            ),
        ));
    }
    Ok(())
}

/// The cost estimate is finite, the step bound a number, and there is a metric.
fn derived_values_hold(sc: &Scenario) -> Result<(), Verdict> {
    let c = edgekf::sim::cost(sc, sc.runs(), 2);
    if !(c.seconds.is_finite() && c.seconds >= 0.0 && c.bytes.is_finite() && c.bytes >= 0.0) {
        return Err(defect(
            "invariant",
            format!(
                "cost estimate not finite: {} s, {} bytes",
                c.seconds, c.bytes
            ),
        ));
    }
    if sc.step_bound().is_nan() {
        return Err(defect("invariant", "step bound is NaN"));
    }
    let _ = sc.divergence_hint();
    if sc.metric_names().is_empty() {
        return Err(defect("invariant", "no metric"));
    }
    Ok(())
}

/// Round trip through the resolved form: JSON and back, and scenario and back.
fn round_trip_holds(sc: &Scenario) -> Result<(), Verdict> {
    let r = sc.to_resolved();
    let json = serde_json::to_string(&r)
        .map_err(|e| defect("invariant", format!("resolved form not serialisable: {e}")))?;
    let back = Resolved::from_json(&json).map_err(|e| {
        defect(
            "invariant",
            format!("resolved form does not parse back: {e}"),
        )
    })?;
    if back != r {
        return Err(defect(
            "invariant",
            "resolved form parses back to a different value",
        ));
    }
    let again = Scenario::from_resolved(&back).map_err(|e| {
        defect(
            "invariant",
            format!("resolved form of an accepted scenario is refused: {e}"),
        )
    })?;
    if again.to_resolved() != r {
        return Err(defect(
            "invariant",
            "resolved → scenario → resolved differs",
        ));
    }
    Ok(())
}

/// The whole-program fuzz's size overrides refuse or accept, naming the flag.
fn overrides_hold(sc: &Scenario) -> Result<(), Verdict> {
    if let Err(e) = sc.clone().with_size(Some(2), Some(30), None) {
        if !names_key(&e, FLAG_ROOTS)
            && !names_key(&e, TOML_ROOTS)
            && !names_key(&e, RESOLVED_ROOTS)
        {
            return Err(defect(
                "unnamed refusal",
                format!("override refused without a key: {e}"),
            ));
        }
    }
    Ok(())
}

/// Counts of a fuzz run.
#[derive(Debug, Default, Clone)]
pub struct Stats {
    /// Cases run.
    pub cases: u64,
    /// Accepted (and every invariant held).
    pub accepted: u64,
    /// Refused by the parser.
    pub refused_parse: u64,
    /// Refused by the checks.
    pub refused_check: u64,
    /// Defects by kind: count and the first three cases.
    pub defects: BTreeMap<String, (u64, Vec<String>)>,
    /// Per seed: cases and accepted.
    pub per_seed: BTreeMap<String, (u64, u64)>,
    /// The slowest case: time and number.
    pub slowest: (Duration, u64),
}

impl Stats {
    /// Total defects.
    pub fn defect_count(&self) -> u64 {
        self.defects.values().map(|(n, _)| n).sum()
    }

    /// Adds another run's counts.
    pub fn merge(&mut self, o: Stats) {
        self.cases += o.cases;
        self.accepted += o.accepted;
        self.refused_parse += o.refused_parse;
        self.refused_check += o.refused_check;
        for (k, (n, first)) in o.defects {
            let e = self.defects.entry(k).or_insert((0, Vec::new()));
            e.0 += n;
            for f in first {
                if e.1.len() < 3 {
                    e.1.push(f);
                }
            }
        }
        for (k, (a, b)) in o.per_seed {
            let e = self.per_seed.entry(k).or_insert((0, 0));
            e.0 += a;
            e.1 += b;
        }
        if o.slowest.0 > self.slowest.0 {
            self.slowest = o.slowest;
        }
    }

    /// A report, one line per count.
    pub fn report(&self) -> String {
        let mut s = format!(
            "cases {}\naccepted {}\nrefused {} (parse {}, check {})\ndefects {}\nslowest case {:.2?} (#{})\n",
            self.cases,
            self.accepted,
            self.refused_parse + self.refused_check,
            self.refused_parse,
            self.refused_check,
            self.defect_count(),
            self.slowest.0,
            self.slowest.1
        );
        for (k, (n, first)) in &self.defects {
            s.push_str(&format!("  defect {k}: {n}\n"));
            for f in first {
                s.push_str(&format!("    {f}\n"));
            }
        }
        for (k, (n, a)) in &self.per_seed {
            s.push_str(&format!("  seed {k}: {n} cases, {a} accepted\n"));
        }
        s
    }
}

/// Runs cases `range` of `m`, recording into fresh stats.
pub fn run(m: &Mutator, roles: &[Role], range: std::ops::Range<u64>) -> Stats {
    let mut st = Stats::default();
    for n in range {
        let case = m.case(n);
        let role = roles[case.seed];
        let t = Instant::now();
        let v = judge(role, &case.text);
        let dt = t.elapsed();
        if dt > st.slowest.0 {
            st.slowest = (dt, n);
        }
        st.cases += 1;
        let seed_name = m.seeds()[case.seed].name.clone();
        let e = st.per_seed.entry(seed_name.clone()).or_insert((0, 0));
        e.0 += 1;
        match v {
            Verdict::Accepted => {
                st.accepted += 1;
                e.1 += 1;
            }
            Verdict::Refused { stage, .. } => {
                if stage == "parse" {
                    st.refused_parse += 1;
                } else {
                    st.refused_check += 1;
                }
            }
            Verdict::Defect { kind, detail } => {
                let first = format!(
                    "case #{n} of {seed_name} ({}): {detail}",
                    case.ops.join("; ")
                );
                let e = st.defects.entry(kind).or_insert((0, Vec::new()));
                e.0 += 1;
                if e.1.len() < 3 {
                    e.1.push(first);
                }
            }
        }
    }
    st
}

/// Runs cases `0..cases` on `threads` threads.
pub fn run_parallel(m: &Mutator, roles: &[Role], cases: u64, threads: u64) -> Stats {
    let mut total = Stats::default();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let range = t * cases / threads..(t + 1) * cases / threads;
                s.spawn(move || run(m, roles, range))
            })
            .collect();
        for h in handles {
            total.merge(h.join().expect("fuzz thread"));
        }
    });
    total
}
