//! A seeded, structure-aware mutation engine for the project's input files: TOML scenario files,
//! resolved `scenario.json` files and framework files.
//!
//! A valid input (a *seed*) is parsed into a value tree; one to three mutations are applied to
//! the tree (extreme numbers, wrong types, dropped, unknown, renamed or duplicated keys, resized
//! arrays, swapped container kinds, sections taken from other inputs, options of another
//! estimator kind, out-of-range indices, huge covariance entries); the tree is written back in the
//! seed's format; and sometimes the text itself is mutated too (truncated, a line duplicated or
//! dropped, a TOML table header swapped between `[x]` and `[[x]]`, a number replaced by `nan`,
//! `inf`, `1e999` or 2⁶³). Every case is a pure function of `(seed list, case number)`, so a
//! failure reproduces from its number alone.
//!
//! Shared by the parser fuzz (crate `edgekf`: `tests/fuzz_parse.rs`, `benches/fuzz_parse.rs`) and
//! the whole-program fuzz (crate `edgekf-cli`: `tests/fuzz_cli.rs`, `benches/fuzz_cli.rs`), which
//! include this file by path. It depends only on `rand`, `rand_xoshiro`, `serde_json` and `toml`.

#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde_json::{Map, Value};

/// The text format of an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A TOML scenario file.
    Toml,
    /// A JSON file (resolved scenario or framework file).
    Json,
}

/// A valid input to mutate.
#[derive(Debug, Clone)]
pub struct Seed {
    /// A name for reports (`eusipco.toml`, `eusipco.json`, `framework:hexagon`, …).
    pub name: String,
    /// Its format.
    pub format: Format,
    /// The original text.
    pub text: String,
    /// Its value tree.
    pub tree: Value,
}

impl Seed {
    /// Parses `text`; `None` when it is not valid in `format`.
    pub fn new(name: &str, format: Format, text: &str) -> Option<Self> {
        let tree = match format {
            Format::Toml => toml::from_str::<Value>(text).ok()?,
            Format::Json => serde_json::from_str::<Value>(text).ok()?,
        };
        Some(Self {
            name: name.to_string(),
            format,
            text: text.to_string(),
            tree,
        })
    }
}

/// One mutated input.
#[derive(Debug, Clone)]
pub struct Case {
    /// Case number (with the engine's seed, all it takes to reproduce it).
    pub number: u64,
    /// Index of the seed it came from.
    pub seed: usize,
    /// The mutated text.
    pub text: String,
    /// What was done, for the report.
    pub ops: Vec<String>,
    /// Whether a mutation touched `steps` or `every` (the whole-program fuzz then keeps the
    /// file's own size instead of overriding `--steps`).
    pub touches_size: bool,
}

/// Marker of a raw token: the string `"@@RAW@@tok@@"` is written as `tok` verbatim, so a mutation
/// can place tokens a value tree cannot hold (`nan`, `inf`, `1e999`, integers beyond i64).
const RAW: &str = "@@RAW@@";

fn raw(tok: &str) -> Value {
    Value::String(format!("{RAW}{tok}@@"))
}

/// Replaces every raw marker (quoted in either TOML style) by its token.
pub fn unraw(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    loop {
        let Some(at) = rest.find(RAW) else {
            out.push_str(rest);
            return out;
        };
        // The marker is preceded by its opening quote.
        let (head, tail) = rest.split_at(at);
        let quoted = head.ends_with('"') || head.ends_with('\'');
        out.push_str(if quoted {
            &head[..head.len() - 1]
        } else {
            head
        });
        let body = &tail[RAW.len()..];
        let end = body.find("@@").unwrap_or(body.len());
        out.push_str(&body[..end]);
        let mut after = &body[(end + 2).min(body.len())..];
        if quoted && (after.starts_with('"') || after.starts_with('\'')) {
            after = &after[1..];
        }
        rest = after;
    }
}

/// A path into a value tree.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn path_string(p: &[Seg]) -> String {
    let mut s = String::new();
    for seg in p {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn collect(v: &Value, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    out.push(path.clone());
    match v {
        Value::Object(m) => {
            for (k, c) in m {
                path.push(Seg::Key(k.clone()));
                collect(c, path, out);
                path.pop();
            }
        }
        Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                path.push(Seg::Index(i));
                collect(c, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn get<'a>(v: &'a Value, path: &[Seg]) -> Option<&'a Value> {
    let mut cur = v;
    for seg in path {
        cur = match (seg, cur) {
            (Seg::Key(k), Value::Object(m)) => m.get(k)?,
            (Seg::Index(i), Value::Array(a)) => a.get(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

fn get_mut<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut cur = v;
    for seg in path {
        cur = match (seg, cur) {
            (Seg::Key(k), Value::Object(m)) => m.get_mut(k)?,
            (Seg::Index(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

fn last_key(path: &[Seg]) -> Option<&str> {
    path.iter().rev().find_map(|s| match s {
        Seg::Key(k) => Some(k.as_str()),
        Seg::Index(_) => None,
    })
}

/// Estimator kinds (and two that do not exist) for kind mutations.
pub const KINDS: &[&str] = &[
    "none",
    "mle",
    "mmse",
    "rkf",
    "jrkf",
    "crkf",
    "oracle",
    "rkf-ar",
    "rkf-zero",
    "rkf-commless",
    "jrkf-ar",
    "garkf",
    "RKF",
];

/// Sections that exercise the engine's features, inserted whole into TOML seeds (and, under
/// their resolved names, into resolved seeds).
const EXTRAS: &str = r#"
[faults]
availability = 0.5

[faults_lost]
lost = [[0, 1], [5, 3]]

[faults_departures]
departures = [{ agent = 5, at = 0.005, rejoin = 0.02 }, { agent = 7, at = 0.01 }]

[faults_random]
random_departures = { share = 0.5, at = 0.01 }

[comm]
p_fail = 0.5
ar = { coeffs = [[0.975, 0.979]], noise_var = [0.0115, 0.0119] }

[comm_ar2]
ar = { coeffs = [[0.5, 0.5], [0.3, 0.3]], noise_var = [0.01, 0.01] }

[control]
follower_gain = 2.0
leader_gain = 0.5
law = { kind = "pi", alpha = 1.0, eta = 0.001 }
leaders = "target"
feedback = "truth"

[control_vv]
law = "varying-velocity"

[maneuver]
keyframes = "garkf-fig7b"

[maneuver_list]
keyframes = [{ t = 0.0 }, { t = 0.01, translation = [1.0, 0.0], rotation = 45.0, scale = [1.5, 0.5], shear = 0.3 }]

[metrics]
edge = [0, 1]

[init]
mean = [1.0, -1.0]
cov = [[2.0, 0.5], [0.5, 1.0]]

[noise]
kernel = { kind = "squared_exponential", length = 1.0 }
normalise = false
meas_cov = [[0.01, 0.0], [0.0, 0.01]]

[noise_white]
kernel = "white"
sigma_w = 0.01

[plot_metric]
plots = [{ file = "m", kind = "metric", metric = "cov_trace", log_y = true, log_x = true }]

[plot_paths]
plots = [{ file = "p", kind = "paths", title = "paths" }]

[plot_inputs]
plots = [{ file = "i", kind = "inputs", agent = 5 }]

[estimators_all]
estimators = ["none", "mle", { kind = "mmse", prior_var = 1e-3 }, "rkf", "jrkf", "crkf", "oracle", "rkf-zero"]

[estimators_ar]
estimators = [{ kind = "rkf-ar", p_fail = 0.5 }, "rkf-commless", { kind = "jrkf-ar", p_fail = 0.25 }]
"#;

/// Options of every kind (and of none), with values to try.
const OPTIONS: &[(&str, &[f64])] = &[
    ("prior_var", &[1e-3, 0.0, -1.0, 1e300, 1e-300]),
    ("p_fail", &[0.5, 0.0, 1.0, 1.5, -0.1]),
    ("samples", &[1.0, 0.0, 100.0, 1e6, 9.3e18]),
    ("alpha", &[1.0]),
    ("sigma_w", &[1.0]),
];

/// The mutation engine: its seeds, what it learned from them, and the base seed of its cases.
pub struct Mutator {
    seeds: Vec<Seed>,
    base: u64,
    /// Every (key, value) seen in any seed or extra section, for crossover.
    pool: Vec<(String, Value)>,
    /// Every key seen.
    keys: Vec<String>,
    /// Whole sections to insert: (key, value).
    extras: Vec<(String, Value)>,
}

impl Mutator {
    /// A mutation engine over `seeds`, whose case `n` is drawn from the stream of `base ⊕ n`.
    pub fn new(seeds: Vec<Seed>, base: u64) -> Self {
        let mut pool = Vec::new();
        let mut keys: Vec<String> = Vec::new();
        let extra_tree: Value = toml::from_str(EXTRAS).expect("valid extra sections");
        let mut extras = Vec::new();
        if let Value::Object(m) = &extra_tree {
            for (name, sec) in m {
                // `faults_lost` → key `faults` holding that table, etc.; list sections hold one
                // top-level key (`plots`, `estimators`).
                let key = name.split('_').next().unwrap_or(name).to_string();
                match key.as_str() {
                    "plot" | "estimators" => {
                        if let Value::Object(inner) = sec {
                            for (k, v) in inner {
                                extras.push((k.clone(), v.clone()));
                            }
                        }
                    }
                    _ => extras.push((key, sec.clone())),
                }
            }
        }
        for v in seeds
            .iter()
            .map(|s| &s.tree)
            .chain(std::iter::once(&extra_tree))
        {
            let mut paths = Vec::new();
            collect(v, &mut Vec::new(), &mut paths);
            for p in paths {
                if let Some(k) = last_key(&p) {
                    if !keys.iter().any(|x| x == k) {
                        keys.push(k.to_string());
                    }
                    if matches!(p.last(), Some(Seg::Key(_))) {
                        if let Some(val) = get(v, &p) {
                            // Keep the pool small: skip huge values (the resolved matrices).
                            if serde_json::to_string(val).map_or(0, |s| s.len()) < 4000 {
                                pool.push((k.to_string(), val.clone()));
                            }
                        }
                    }
                }
            }
        }
        Self {
            seeds,
            base,
            pool,
            keys,
            extras,
        }
    }

    /// The seeds.
    pub fn seeds(&self) -> &[Seed] {
        &self.seeds
    }

    /// Case `n`.
    pub fn case(&self, n: u64) -> Case {
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(self.base ^ n.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let s = rng.random_range(0..self.seeds.len());
        let seed = &self.seeds[s];
        let mut tree = seed.tree.clone();
        let mut ops = Vec::new();
        let mut touches_size = false;
        let count = match rng.random_range(0..100) {
            0..=59 => 1,
            60..=84 => 2,
            _ => 3,
        };
        for _ in 0..count {
            if let Some(op) = self.mutate_tree(&mut rng, &mut tree, seed.format) {
                if op.contains("steps") || op.contains("every") || op.contains("sim") {
                    touches_size = true;
                }
                ops.push(op);
            }
        }
        let mut text = match seed.format {
            Format::Toml => toml::to_string(&tree).ok(),
            Format::Json => serde_json::to_string_pretty(&tree).ok(),
        }
        .map(|t| unraw(&t))
        .unwrap_or_else(|| {
            ops.push("(tree not writable: original text)".into());
            seed.text.clone()
        });
        if rng.random_range(0..100) < 25 {
            let op = text_mutation(&mut rng, &mut text, seed.format);
            if op.contains("steps") || op.contains("every") {
                touches_size = true;
            }
            ops.push(op);
        }
        Case {
            number: n,
            seed: s,
            text,
            ops,
            touches_size,
        }
    }

    fn mutate_tree(
        &self,
        rng: &mut Xoshiro256PlusPlus,
        tree: &mut Value,
        fmt: Format,
    ) -> Option<String> {
        let mut paths = Vec::new();
        collect(tree, &mut Vec::new(), &mut paths);
        let agents = agents_of(tree);
        match rng.random_range(0..100) {
            // An extreme or wrongly typed value anywhere (mostly at leaves).
            0..=29 => {
                let leaves: Vec<&Vec<Seg>> = paths
                    .iter()
                    .filter(|p| !p.is_empty())
                    .filter(|p| get(tree, p).is_some_and(|v| !v.is_object() && !v.is_array()))
                    .collect();
                let pick = if rng.random_range(0..10) < 8 && !leaves.is_empty() {
                    leaves[rng.random_range(0..leaves.len())].clone()
                } else {
                    paths[rng.random_range(1..paths.len().max(2)).min(paths.len() - 1)].clone()
                };
                let node = get_mut(tree, &pick)?;
                let new = extreme(rng, node);
                let desc = format!("set {} = {}", path_string(&pick), short(&new));
                *node = new;
                Some(desc)
            }
            // Drop a key.
            30..=39 => {
                let objs: Vec<&Vec<Seg>> = paths
                    .iter()
                    .filter(|p| matches!(p.last(), Some(Seg::Key(_))))
                    .collect();
                let p = objs.get(rng.random_range(0..objs.len().max(1)))?;
                let (parent, key) = p.split_at(p.len() - 1);
                let Seg::Key(k) = &key[0] else { return None };
                if let Some(Value::Object(m)) = get_mut(tree, parent) {
                    m.shift_remove(k);
                }
                Some(format!("drop {}", path_string(p)))
            }
            // An unknown key, or a known key in the wrong place.
            40..=46 => {
                let objs: Vec<Vec<Seg>> = paths
                    .iter()
                    .filter(|p| get(tree, p).is_some_and(|v| v.is_object()))
                    .cloned()
                    .collect();
                let p = objs.get(rng.random_range(0..objs.len().max(1)))?.clone();
                let k = if rng.random_bool(0.3) {
                    "bogus".to_string()
                } else {
                    self.keys[rng.random_range(0..self.keys.len())].clone()
                };
                let v = self.pool_value(rng, &k).unwrap_or(Value::from(1));
                if let Some(Value::Object(m)) = get_mut(tree, &p) {
                    m.insert(k.clone(), v);
                }
                Some(format!("add {}.{k}", path_string(&p)))
            }
            // Rename a key.
            47..=51 => {
                let objs: Vec<&Vec<Seg>> = paths
                    .iter()
                    .filter(|p| matches!(p.last(), Some(Seg::Key(_))))
                    .collect();
                let p = objs.get(rng.random_range(0..objs.len().max(1)))?;
                let (parent, key) = p.split_at(p.len() - 1);
                let Seg::Key(k) = &key[0] else { return None };
                let new = self.keys[rng.random_range(0..self.keys.len())].clone();
                if let Some(Value::Object(m)) = get_mut(tree, parent) {
                    if let Some(v) = m.shift_remove(k) {
                        m.insert(new.clone(), v);
                    }
                }
                Some(format!("rename {} → {new}", path_string(p)))
            }
            // Resize an array.
            52..=61 => {
                let arrs: Vec<Vec<Seg>> = paths
                    .iter()
                    .filter(|p| get(tree, p).is_some_and(|v| v.is_array()))
                    .cloned()
                    .collect();
                let p = arrs.get(rng.random_range(0..arrs.len().max(1)))?.clone();
                let Some(Value::Array(a)) = get_mut(tree, &p) else {
                    return None;
                };
                let what = match rng.random_range(0..6) {
                    0 => {
                        a.clear();
                        "empty".to_string()
                    }
                    1 if !a.is_empty() => {
                        let i = rng.random_range(0..a.len());
                        a.remove(i);
                        format!("remove [{i}]")
                    }
                    2 if !a.is_empty() => {
                        let i = rng.random_range(0..a.len());
                        let v = a[i].clone();
                        a.insert(i, v);
                        format!("duplicate [{i}]")
                    }
                    3 if !a.is_empty() => {
                        let v = a[a.len() - 1].clone();
                        a.push(v);
                        "append".to_string()
                    }
                    4 if !a.is_empty() => {
                        let n = [100, 500, 2000][rng.random_range(0..3)];
                        let v = a[rng.random_range(0..a.len())].clone();
                        while a.len() < n {
                            a.push(v.clone());
                        }
                        format!("grow to {n}")
                    }
                    _ => {
                        a.truncate(a.len() / 2);
                        "halve".to_string()
                    }
                };
                Some(format!("array {}: {what}", path_string(&p)))
            }
            // Swap the kind of a container (table ↔ array, scalar → array).
            62..=66 => {
                let p = paths[rng.random_range(1..paths.len().max(2)).min(paths.len() - 1)].clone();
                let node = get_mut(tree, &p)?;
                let new = match node.take() {
                    Value::Object(m) => Value::Array(m.into_iter().map(|(_, v)| v).collect()),
                    Value::Array(a) if a.len() == 1 && rng.random_bool(0.5) => {
                        a.into_iter().next().unwrap_or(Value::Null)
                    }
                    Value::Array(a) => Value::Object(
                        a.into_iter()
                            .enumerate()
                            .map(|(i, v)| (i.to_string(), v))
                            .collect(),
                    ),
                    other => Value::Array(vec![other]),
                };
                *node = new;
                Some(format!("swap kind of {}", path_string(&p)))
            }
            // Crossover: a value seen under the same key elsewhere, or a whole extra section.
            67..=76 => {
                if rng.random_bool(0.5) {
                    let (k, v) = &self.extras[rng.random_range(0..self.extras.len())];
                    let (k, v) = match fmt {
                        Format::Json => resolved_extra(k, v),
                        Format::Toml => (k.clone(), v.clone()),
                    };
                    if let Value::Object(m) = tree {
                        m.insert(k.clone(), v);
                    }
                    Some(format!("insert section {k}"))
                } else {
                    let keyed: Vec<&Vec<Seg>> = paths
                        .iter()
                        .filter(|p| matches!(p.last(), Some(Seg::Key(_))))
                        .collect();
                    let p = keyed.get(rng.random_range(0..keyed.len().max(1)))?;
                    let k = last_key(p)?.to_string();
                    let v = self.pool_value(rng, &k)?;
                    let node = get_mut(tree, p)?;
                    *node = v;
                    Some(format!("crossover {}", path_string(p)))
                }
            }
            // Estimator entries: another kind, options of another kind, labels.
            77..=86 => estimator_mutation(rng, tree),
            // Indices out of range.
            87..=94 => {
                let idx: Vec<&Vec<Seg>> = paths
                    .iter()
                    .filter(|p| {
                        p.iter().any(|s| {
                            matches!(s, Seg::Key(k) if matches!(k.as_str(),
                                "leaders" | "edges" | "lost" | "edge" | "agent" | "paths_run" | "departures"))
                        })
                    })
                    .filter(|p| get(tree, p).is_some_and(|v| v.is_u64()))
                    .collect();
                let p = idx.get(rng.random_range(0..idx.len().max(1)))?;
                let node = get_mut(tree, p)?;
                let new = match rng.random_range(0..6) {
                    0 => Value::from(agents.saturating_sub(1)),
                    1 => Value::from(agents),
                    2 => Value::from(agents + 1),
                    3 => Value::from(1u64 << 32),
                    4 => Value::from(u64::MAX),
                    _ => raw("9223372036854775808"),
                };
                let desc = format!("index {} = {}", path_string(p), short(&new));
                *node = new;
                Some(desc)
            }
            // A covariance entry: huge on the diagonal (still PSD), or asymmetric.
            _ => {
                let cov_keys = [
                    "process_cov",
                    "meas_cov",
                    "init_cov",
                    "cov",
                    "sigma_w",
                    "sigma_v",
                    "dt",
                    "noise_var",
                ];
                let cands: Vec<&Vec<Seg>> = paths
                    .iter()
                    .filter(|p| {
                        p.iter()
                            .any(|s| matches!(s, Seg::Key(k) if cov_keys.contains(&k.as_str())))
                    })
                    .filter(|p| get(tree, p).is_some_and(|v| v.is_number()))
                    .collect();
                let p = cands.get(rng.random_range(0..cands.len().max(1)))?;
                let node = get_mut(tree, p)?;
                let x = node.as_f64().unwrap_or(1.0);
                let new = match rng.random_range(0..8) {
                    0 => Value::from(1e300),
                    1 => Value::from(9_223_372_036_854_775_808.0),
                    2 => Value::from(1e150),
                    3 => Value::from(1e75),
                    4 => num(x * 1e9),
                    5 => num(x * 1e12),
                    6 => num(-x),
                    _ => Value::from(1e-300),
                };
                let desc = format!("cov {} = {}", path_string(p), short(&new));
                *node = new;
                Some(desc)
            }
        }
    }

    fn pool_value(&self, rng: &mut Xoshiro256PlusPlus, key: &str) -> Option<Value> {
        let same: Vec<&Value> = self
            .pool
            .iter()
            .filter(|(k, _)| k == key)
            .map(|(_, v)| v)
            .collect();
        if same.is_empty() {
            return None;
        }
        Some(same[rng.random_range(0..same.len())].clone())
    }
}

fn num(x: f64) -> Value {
    if x.is_finite() {
        Value::from(x)
    } else {
        raw(if x.is_nan() {
            "nan"
        } else if x > 0.0 {
            "inf"
        } else {
            "-inf"
        })
    }
}

/// The number of agents of a seed (resolved `agents`, inline `config`, else the hexagon's 10).
fn agents_of(tree: &Value) -> usize {
    if let Some(n) = tree.get("agents").and_then(Value::as_u64) {
        return n as usize;
    }
    if let Some(c) = tree.get("config").and_then(Value::as_array) {
        return c.len();
    }
    if let Some(c) = tree
        .get("framework")
        .and_then(|f| f.get("config"))
        .and_then(Value::as_array)
    {
        return c.len();
    }
    10
}

/// An extra section under the resolved scenario's names.
fn resolved_extra(k: &str, v: &Value) -> (String, Value) {
    match k {
        "init" => {
            let mean = v.get("mean").cloned().unwrap_or(Value::Null);
            ("init_mean".into(), mean)
        }
        "noise" => ("process_cov".into(), Value::Array(vec![])),
        "estimators" => {
            // Resolved inputs list specs under `estimator_specs`; labels are the kind names.
            ("estimators".into(), v.clone())
        }
        other => (other.to_string(), v.clone()),
    }
}

/// An extreme or wrongly typed replacement for `node`.
fn extreme(rng: &mut Xoshiro256PlusPlus, node: &Value) -> Value {
    let x = node.as_f64();
    if let (Some(x), true) = (x, rng.random_range(0..10) < 8) {
        return match rng.random_range(0..26) {
            0 => Value::from(0),
            1 => Value::from(-1),
            2 => Value::from(1),
            3 => Value::from(2),
            4 => Value::from(0.5),
            5 => Value::from(1e300),
            6 => Value::from(-1e300),
            7 => Value::from(1e-300),
            8 => Value::from(5e-324),
            9 => raw("9223372036854775808"),
            10 => Value::from(i64::MAX),
            11 => Value::from(i64::MIN),
            12 => Value::from(u64::MAX),
            13 => raw("nan"),
            14 => raw("inf"),
            15 => raw("-inf"),
            16 => raw("1e999"),
            17 => num(x * 1e9),
            18 => num(x * 1e-9),
            19 => num(-x),
            20 => num(x + 1.0),
            21 => Value::from(9_223_372_036_854_775_808.0),
            22 => Value::from(-0.0),
            23 => Value::from(1e19),
            24 => Value::from(4_294_967_296u64),
            _ => num(x * 1e300),
        };
    }
    match rng.random_range(0..14) {
        0 => Value::from("NaN"),
        1 => Value::from("nan"),
        2 => Value::from("inf"),
        3 => Value::from(""),
        4 => Value::from("x"),
        5 => Value::from(true),
        6 => Value::Array(vec![]),
        7 => Value::Object(Map::new()),
        8 => Value::Array(vec![Value::from(0)]),
        9 => Value::from(0),
        10 => Value::from(-1),
        11 => Value::from(1e300),
        12 => Value::from("rkf"),
        _ => Value::from("a,b\"c\n"),
    }
}

fn estimator_mutation(rng: &mut Xoshiro256PlusPlus, tree: &mut Value) -> Option<String> {
    let key = if tree.get("estimator_specs").is_some() && rng.random_bool(0.8) {
        "estimator_specs"
    } else {
        "estimators"
    };
    let labels_too = key == "estimator_specs";
    let list = tree.get_mut(key)?.as_array_mut()?;
    if list.is_empty() {
        list.push(Value::from("rkf"));
        return Some(format!("{key}: add rkf"));
    }
    let i = rng.random_range(0..list.len());
    let desc = match rng.random_range(0..7) {
        0 => {
            let k = KINDS[rng.random_range(0..KINDS.len())];
            match &mut list[i] {
                Value::Object(m) => {
                    m.insert("kind".into(), Value::from(k));
                }
                other => *other = Value::from(k),
            }
            format!("{key}[{i}].kind = {k}")
        }
        1 | 2 => {
            let (opt, vals) = OPTIONS[rng.random_range(0..OPTIONS.len())];
            let v = vals[rng.random_range(0..vals.len())];
            let v = if opt == "samples" && v.fract() == 0.0 && v < 1e18 {
                Value::from(v as u64)
            } else {
                Value::from(v)
            };
            let entry = &mut list[i];
            if let Value::String(s) = entry {
                let mut m = Map::new();
                m.insert("kind".into(), Value::from(s.clone()));
                *entry = Value::Object(m);
            }
            if let Value::Object(m) = entry {
                m.insert(opt.into(), v.clone());
            }
            format!("{key}[{i}].{opt} = {}", short(&v))
        }
        3 => {
            let l = ["dup", "", "a,b", "x\"y", "rkf"][rng.random_range(0..5)];
            let entry = &mut list[i];
            if let Value::String(s) = entry {
                let mut m = Map::new();
                m.insert("kind".into(), Value::from(s.clone()));
                *entry = Value::Object(m);
            }
            if let Value::Object(m) = entry {
                m.insert("label".into(), Value::from(l));
            }
            format!("{key}[{i}].label = {l:?}")
        }
        4 => {
            let v = list[i].clone();
            list.push(v);
            format!("{key}: duplicate [{i}]")
        }
        5 => {
            list.remove(i);
            format!("{key}: remove [{i}]")
        }
        _ => {
            if let Value::Object(m) = &mut list[i] {
                m.shift_remove("kind");
            } else {
                list[i] = Value::from(42);
            }
            format!("{key}[{i}]: drop kind")
        }
    };
    if labels_too && rng.random_bool(0.5) {
        // Keep `estimators` (the labels) in step, so the mutation reaches the kind's checks.
        let labels: Vec<Value> = tree["estimator_specs"]
            .as_array()?
            .iter()
            .map(|e| {
                e.get("label")
                    .cloned()
                    .or_else(|| e.get("kind").cloned())
                    .unwrap_or(Value::from("?"))
            })
            .collect();
        tree["estimators"] = Value::Array(labels);
    }
    Some(desc)
}

fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.len() > 60 {
        format!(
            "{}…",
            &s[..s.char_indices().nth(60).map_or(s.len(), |(i, _)| i)]
        )
    } else {
        s
    }
}

/// A mutation of the text itself.
fn text_mutation(rng: &mut Xoshiro256PlusPlus, text: &mut String, fmt: Format) -> String {
    let lines: Vec<&str> = text.lines().collect();
    match rng.random_range(0..6) {
        0 => {
            let cut = rng.random_range(0..text.len().max(1));
            let cut = (0..=cut)
                .rev()
                .find(|&c| text.is_char_boundary(c))
                .unwrap_or(0);
            text.truncate(cut);
            format!("truncate at byte {cut}")
        }
        1 if !lines.is_empty() => {
            let i = rng.random_range(0..lines.len());
            let line = lines[i].to_string();
            let mut out: Vec<&str> = lines.clone();
            out.insert(i, &line);
            let joined = out.join("\n");
            *text = joined;
            format!("duplicate line {}: {}", i + 1, line.trim())
        }
        2 if !lines.is_empty() => {
            let i = rng.random_range(0..lines.len());
            let line = lines[i].trim().to_string();
            let mut out: Vec<&str> = lines.clone();
            out.remove(i);
            *text = out.join("\n");
            format!("delete line {}: {line}", i + 1)
        }
        3 if fmt == Format::Toml => {
            let headers: Vec<usize> = lines
                .iter()
                .enumerate()
                .filter(|(_, l)| l.trim_start().starts_with('['))
                .map(|(i, _)| i)
                .collect();
            if headers.is_empty() {
                return "no table header to swap".into();
            }
            let i = headers[rng.random_range(0..headers.len())];
            let l = lines[i].trim().to_string();
            let new = if l.starts_with("[[") {
                l.trim_start_matches('[').trim_end_matches(']').to_string()
            } else {
                format!("[{l}]")
            };
            let new = if new.starts_with('[') {
                new
            } else {
                format!("[{new}]")
            };
            let mut out: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
            out[i] = new.clone();
            *text = out.join("\n");
            format!("swap table header {l} → {new}")
        }
        4 => {
            // Replace a number token by a token no tree holds.
            let starts: Vec<usize> = text
                .char_indices()
                .filter(|&(i, c)| {
                    c.is_ascii_digit()
                        && (i == 0 || !text.as_bytes()[i - 1].is_ascii_alphanumeric())
                        && !text[..i].ends_with('.')
                })
                .map(|(i, _)| i)
                .collect();
            if starts.is_empty() {
                return "no number to replace".into();
            }
            let s = starts[rng.random_range(0..starts.len())];
            let e = text[s..]
                .find(|c: char| {
                    !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '+' || c == '_')
                })
                .map_or(text.len(), |k| s + k);
            let tok = [
                "nan",
                "inf",
                "-inf",
                "1e999",
                "NaN",
                "9223372036854775808",
                "-0",
                "0x10",
                "1_000",
                "18446744073709551616",
            ][rng.random_range(0..10)];
            let old = text[s..e].to_string();
            text.replace_range(s..e, tok);
            format!("number {old} → {tok}")
        }
        _ => {
            let at = rng.random_range(0..text.len().max(1));
            let at = (0..=at)
                .rev()
                .find(|&c| text.is_char_boundary(c))
                .unwrap_or(0);
            let ins = ["\"", "{", "]", "\0", "é", "\n[x]\n", ",", "=", "#"][rng.random_range(0..9)];
            text.insert_str(at, ins);
            format!("insert {ins:?} at byte {at}")
        }
    }
}
