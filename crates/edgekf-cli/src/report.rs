//! `edgekf report DIR` and `edgekf reproduce … --report`: one self-contained HTML page per
//! simulation directory (`report.html`), and an `index.html` for a `reproduce` output root.
//!
//! A page holds, from the files in the directory alone:
//! - the figures, inlined as base64 PNG (grouped by the reproduction names that share the
//!   simulation);
//! - the steady-state table of every estimator ([`crate::summary`], recomputed from
//!   `metrics.csv`, whose means are exact), or the final errors of a SLAM run;
//! - the papers' claims checked on this study, from `DIR/claims.json` (written by
//!   `edgekf claims … --json`: an array of `{id, paper, where, claim, paper_value, value, se,
//!   verdict}`), or a note that there is none;
//! - the resolved scenario (`scenario.json`) as a readable table;
//! - provenance: the crate version and git commit of the program that ran the study and of the
//!   one that wrote the page, the seed, and the command line (`provenance.json`).
//!
//! Nothing is fetched at view time: no external style sheet, script, font or image. A small
//! inline script records script errors and images that failed to decode into the page
//! (`#selfcheck`), which the browser test reads back.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use edgekf::sim::Outcome;
use edgekf_io::reproductions as registry;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::summary;

pub use edgekf_io::{program, Provenance};

/// The command line as a shell would take it back.
fn shell_line(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            if !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c))
            {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', "'\\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Standard base64 (RFC 4648, with padding). Twenty lines instead of a dependency.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (k, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if k <= c.len() {
                out.push(A[((n >> shift) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// HTML-escapes text.
fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            _ => o.push(c),
        }
    }
    o
}

/// Turns the figures' `_{…}`/`^{…}` markup into `<sub>`/`<sup>` (escaped otherwise).
fn markup(s: &str) -> String {
    let mut o = String::new();
    let mut rest = s;
    while let Some(p) = rest.find(['_', '^']) {
        let (head, tail) = rest.split_at(p);
        o.push_str(&esc(head));
        let tag = if tail.starts_with('_') { "sub" } else { "sup" };
        if tail[1..].starts_with('{') {
            if let Some(end) = tail.find('}') {
                let _ = write!(o, "<{tag}>{}</{tag}>", esc(&tail[2..end]));
                rest = &tail[end + 1..];
                continue;
            }
        }
        o.push_str(&esc(&tail[..1]));
        rest = &tail[1..];
    }
    o.push_str(&esc(rest));
    o
}

const STYLE: &str = "
:root { font-family: system-ui, -apple-system, 'Segoe UI', Roboto, 'DejaVu Sans', sans-serif; color: #1d1d1f; }
body { margin: 0 auto; max-width: 1180px; padding: 1.2rem 1.5rem 3rem; line-height: 1.45; }
h1 { font-size: 1.6rem; margin: 0.2rem 0; } h2 { font-size: 1.25rem; margin-top: 2.2rem; border-bottom: 1px solid #ddd; padding-bottom: 0.2rem; }
h3 { font-size: 1.05rem; margin: 1.4rem 0 0.4rem; }
nav { font-size: 0.92rem; margin: 0.6rem 0 1rem; } nav a { margin-right: 1rem; }
figure { margin: 0.6rem 0 1.4rem; } figure img { max-width: 100%; height: auto; border: 1px solid #e3e3e3; }
figcaption { font-size: 0.85rem; color: #555; }
table { border-collapse: collapse; font-size: 0.9rem; margin: 0.4rem 0 1rem; }
th, td { border: 1px solid #d6d6d6; padding: 0.25rem 0.55rem; text-align: left; vertical-align: top; }
th { background: #f3f4f6; } td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.agrees td.verdict { color: #0a6b2b; font-weight: 600; } tr.differs td.verdict { color: #a31515; font-weight: 600; }
tr.not-checkable td.verdict { color: #6b6b6b; }
code, .mono { font-family: 'DejaVu Sans Mono', Menlo, Consolas, monospace; font-size: 0.85rem; }
.note { color: #555; font-size: 0.9rem; } .muted { color: #777; }
dl { display: grid; grid-template-columns: max-content auto; gap: 0.2rem 1rem; } dt { font-weight: 600; } dd { margin: 0; }
";

/// Records script errors and undecodable images into `#selfcheck` (read by the browser test).
const SELFCHECK: &str = "
(function () {
  var errors = [];
  window.addEventListener('error', function (e) {
    errors.push(String(e.message || (e.target && (e.target.src || e.target.href)) || 'error'));
    publish();
  }, true);
  function publish() {
    var out = document.getElementById('selfcheck');
    if (!out) { return; }
    var broken = [];
    var imgs = document.images;
    for (var i = 0; i < imgs.length; i++) {
      if (!imgs[i].complete || imgs[i].naturalWidth === 0) { broken.push(imgs[i].alt || String(i)); }
    }
    var empty = [];
    var tables = document.querySelectorAll('table');
    for (var t = 0; t < tables.length; t++) {
      if (tables[t].querySelectorAll('tbody tr').length === 0) { empty.push(tables[t].id || String(t)); }
    }
    out.setAttribute('data-errors', String(errors.length));
    out.setAttribute('data-images', String(imgs.length));
    out.setAttribute('data-broken-images', String(broken.length));
    out.setAttribute('data-tables', String(tables.length));
    out.setAttribute('data-empty-tables', String(empty.length));
    out.setAttribute('data-status', errors.length + broken.length + empty.length === 0 ? 'ok' : 'fail');
    out.textContent = 'self-check: ' + imgs.length + ' images (' + broken.length + ' broken), ' +
      tables.length + ' tables (' + empty.length + ' empty), ' + errors.length + ' script errors' +
      (errors.length ? ': ' + errors.join('; ') : '') + (broken.length ? '; broken: ' + broken.join(', ') : '') +
      (empty.length ? '; empty: ' + empty.join(', ') : '');
  }
  window.addEventListener('load', publish);
})();
";

fn page_start(title: &str, out: &mut String) {
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n<script>{SELFCHECK}</script>\n</head>\n<body>\n",
        esc(title)
    );
}

fn page_end(out: &mut String) {
    let _ = write!(
        out,
        "<footer class=\"note\"><p>Written by {} — a self-contained page: every figure is inlined, \
         nothing is fetched.</p><p id=\"selfcheck\" class=\"muted\" data-status=\"pending\"></p>\
         </footer>\n</body>\n</html>\n",
        esc(&program())
    );
}

/// A table with a header row and body rows; `num` marks the numeric columns.
fn table(id: &str, head: &[String], rows: &[Vec<String>], num: &dyn Fn(usize) -> bool) -> String {
    let mut o = format!("<table id=\"{}\">\n<thead><tr>", esc(id));
    for h in head {
        let _ = write!(o, "<th>{}</th>", esc(h));
    }
    o.push_str("</tr></thead>\n<tbody>\n");
    for r in rows {
        o.push_str("<tr>");
        for (c, v) in r.iter().enumerate() {
            if num(c) {
                let _ = write!(o, "<td class=\"num\">{}</td>", esc(v));
            } else {
                let _ = write!(o, "<td>{}</td>", esc(v));
            }
        }
        o.push_str("</tr>\n");
    }
    o.push_str("</tbody></table>\n");
    o
}

/// One claim of `claims.json` (the interface agreed with `edgekf claims --json`).
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct Claim {
    /// Stable id.
    pub id: String,
    /// Which paper.
    pub paper: String,
    /// Where in it.
    #[serde(rename = "where")]
    pub location: String,
    /// The statement.
    pub claim: String,
    /// The paper's value or ordering.
    pub paper_value: Value,
    /// Ours.
    pub value: Value,
    /// Its standard error.
    pub se: Value,
    /// `agrees`, `differs` or `not checkable`.
    pub verdict: String,
}

/// Reads `dir/claims.json`, if present.
///
/// # Errors
/// When the file exists but is not an array of claims.
pub fn read_claims(dir: &Path) -> Result<Option<Vec<Claim>>> {
    let p = dir.join("claims.json");
    if !p.exists() {
        return Ok(None);
    }
    let text = fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
    let claims: Vec<Claim> = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not an array of claims {{id, paper, where, claim, paper_value, value, se, verdict}}",
            p.display()
        )
    })?;
    for c in &claims {
        if !["agrees", "differs", "not checkable"].contains(&c.verdict.as_str()) {
            bail!(
                "{}: claim `{}` has verdict `{}`; expected agrees, differs or not checkable",
                p.display(),
                c.id,
                c.verdict
            );
        }
    }
    Ok(Some(claims))
}

/// A JSON value as a table cell: numbers in the guide's form, strings bare, others compact.
fn cell(v: &Value) -> String {
    match v {
        Value::Null => "–".into(),
        Value::Number(n) => n.as_f64().map_or_else(|| n.to_string(), fmt_num),
        Value::String(s) => s.clone(),
        Value::Array(a) if a.iter().all(|x| x.is_number() || x.is_string()) => {
            a.iter().map(cell).collect::<Vec<_>>().join(", ")
        }
        other => other.to_string(),
    }
}

/// Numbers for tables: integers as they are, others to 5 significant digits.
fn fmt_num(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{v}")
    } else if (1e-3..1e5).contains(&v.abs()) {
        let d = (4 - v.abs().log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.d$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.4e}")
    }
}

fn claims_section(claims: Option<&[Claim]>, id: &str) -> String {
    let mut o = format!("<h2 id=\"{id}\">Claims of the papers checked on this study</h2>\n");
    match claims {
        None => o.push_str(
            "<p class=\"note\">No claims checked for this study (no <code>claims.json</code> \
             here). After <code>edgekf reproduce all --out ROOT</code>, \
             <code>edgekf claims --out ROOT</code> writes one per simulation and \
             <code>edgekf report ROOT</code> shows them.</p>\n",
        ),
        Some([]) => o.push_str(
            "<p class=\"note\">No claims checked for this study (claims.json is empty).</p>\n",
        ),
        Some(cs) => {
            let count = |v: &str| cs.iter().filter(|c| c.verdict == v).count();
            let _ = writeln!(
                o,
                "<p>{} claims: {} agree, {} differ, {} not checkable. Value ± standard error; the \
                 rule behind each verdict is in the claims registry.</p>",
                cs.len(),
                count("agrees"),
                count("differs"),
                count("not checkable")
            );
            o.push_str("<table id=\"claims\">\n<thead><tr><th>id</th><th>paper</th><th>where</th><th>claim</th><th>paper's value</th><th>ours</th><th>± SE</th><th>verdict</th></tr></thead>\n<tbody>\n");
            for c in cs {
                let _ = writeln!(
                    o,
                    "<tr class=\"{}\"><td class=\"mono\">{}</td><td>{}</td><td>{}</td><td>{}</td>\
                     <td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"verdict\">{}</td></tr>",
                    c.verdict.replace(' ', "-"),
                    esc(&c.id),
                    esc(&c.paper),
                    esc(&c.location),
                    esc(&c.claim),
                    esc(&cell(&c.paper_value)),
                    esc(&cell(&c.value)),
                    esc(&cell(&c.se)),
                    esc(&c.verdict)
                );
            }
            o.push_str("</tbody></table>\n");
        }
    }
    o
}

/// A matrix in a cell: small ones written out, large ones summarised.
fn matrix_cell(rows: &[Value]) -> String {
    let m: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            r.as_array()
                .map(|a| a.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default()
        })
        .collect();
    let n = m.len();
    if n <= 3 && m.iter().all(|r| r.len() <= 3) {
        return format!(
            "[{}]",
            m.iter()
                .map(|r| format!(
                    "[{}]",
                    r.iter().map(|v| fmt_num(*v)).collect::<Vec<_>>().join(", ")
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let cols = m.first().map_or(0, Vec::len);
    let diag: Vec<f64> = (0..n.min(cols)).map(|i| m[i][i]).collect();
    let (lo, hi) = diag
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let trace: f64 = diag.iter().sum();
    if diag.is_empty() {
        format!("{n} × {cols}")
    } else if m.iter().flatten().all(|v| *v == 0.0) {
        format!("{n} × {cols}, all zero")
    } else {
        format!(
            "{n} × {cols}; diagonal {}…{}, trace {}",
            fmt_num(lo),
            fmt_num(hi),
            fmt_num(trace)
        )
    }
}

/// A compact, truncated JSON text.
fn compact(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 400 {
        let t: String = s.chars().take(400).collect();
        format!("{t} …")
    } else {
        s
    }
}

/// The scalar keys of a resolved scenario with their meaning, in the order shown.
const SCALARS: &[(&str, &str)] = &[
    ("schema", "format"),
    ("name", "name"),
    ("description", "what it reproduces"),
    ("agents", "agents N"),
    ("dim", "dimension D"),
    ("leaders", "leaders"),
    ("dt", "time step Δt [s]"),
    ("steps", "steps"),
    ("runs", "Monte Carlo runs"),
    ("seed", "seed"),
    ("samples_per_step", "measurements per step T"),
    ("every", "report every … steps"),
    (
        "reports_per_decade",
        "extra log-spaced reports per decade (first interval)",
    ),
    ("paths_run", "run recorded in paths.csv"),
    (
        "paths_per_decade",
        "paths.csv: log-spaced reports per decade",
    ),
    ("follower_gain", "follower gain c"),
    ("leader_gain", "leader gain k"),
    ("allow_divergence", "divergence allowed"),
];

/// The keys with rows of their own (the [`SCALARS`] and those summarised); any other key is
/// shown as compact JSON at the end.
const SHOWN: &[&str] = &[
    "schema",
    "name",
    "description",
    "agents",
    "dim",
    "leaders",
    "dt",
    "steps",
    "runs",
    "seed",
    "samples_per_step",
    "every",
    "reports_per_decade",
    "paths_run",
    "paths_per_decade",
    "follower_gain",
    "leader_gain",
    "allow_divergence",
    "edges",
    "config",
    "weights",
    "init_mean",
    "init_cov",
    "process_cov",
    "meas_cov",
    "estimator_specs",
    "estimators",
    "plots",
];

type Object = serde_json::Map<String, Value>;

fn row(k: &str, what: &str, val: String) -> Vec<String> {
    vec![k.into(), what.into(), val]
}

/// The resolved scenario (`edgekf.scenario/1`) as rows of (key, meaning, value).
fn scenario_rows(v: &Value) -> Vec<Vec<String>> {
    let mut rows: Vec<Vec<String>> = Vec::new();
    let Some(o) = v.as_object() else {
        return rows;
    };
    for (k, what) in SCALARS {
        if let Some(x) = o.get(*k) {
            rows.push(row(k, what, cell(x)));
        }
    }
    if let (Some(s), Some(dt)) = (
        o.get("steps").and_then(Value::as_f64),
        o.get("dt").and_then(Value::as_f64),
    ) {
        rows.push(row("", "horizon [s]", fmt_num(s * dt)));
    }
    framework_rows(o, &mut rows);
    noise_rows(o, &mut rows);
    estimator_rows(o, &mut rows);
    for (k, x) in o {
        if !SHOWN.contains(&k.as_str()) {
            rows.push(vec![k.clone(), String::new(), compact(x)]);
        }
    }
    rows
}

/// `edges`, `config` and `weights`, summarised.
fn framework_rows(o: &Object, rows: &mut Vec<Vec<String>>) {
    if let Some(e) = o.get("edges").and_then(Value::as_array) {
        rows.push(row(
            "edges",
            "directed edges (incidence order)",
            format!("{} directed edges ({} links)", e.len(), e.len() / 2),
        ));
    }
    if let Some(c) = o.get("config").and_then(Value::as_array) {
        let pts: Vec<String> = c
            .iter()
            .map(|p| {
                p.as_array().map_or_else(String::new, |a| {
                    format!(
                        "({})",
                        a.iter()
                            .filter_map(Value::as_f64)
                            .map(fmt_num)
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
            })
            .collect();
        let text = if pts.len() <= 20 {
            pts.join(" ")
        } else {
            format!("{} … ({} agents)", pts[..20].join(" "), pts.len())
        };
        rows.push(row("config", "configuration p_i [m]", text));
    }
    if let Some(w) = o.get("weights").and_then(Value::as_array) {
        let ws: Vec<f64> = w.iter().filter_map(Value::as_f64).collect();
        let (lo, hi) = ws
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        rows.push(row(
            "weights",
            "stress weights l_ij per directed edge",
            format!(
                "{} values from {} to {}",
                ws.len(),
                fmt_num(lo),
                fmt_num(hi)
            ),
        ));
    }
}

/// The initial state's and the noises' covariances (matrices in full, `meas_cov` once when
/// every edge has the same).
fn noise_rows(o: &Object, rows: &mut Vec<Vec<String>>) {
    for (k, what) in [
        ("init_mean", "initial mean μ [m]"),
        ("init_cov", "initial covariance P [m²]"),
        ("process_cov", "process noise Q (agent-major) [m²]"),
    ] {
        if let Some(x) = o.get(k) {
            let val = match x.as_array() {
                Some(a) if a.iter().all(Value::is_array) => matrix_cell(a),
                _ => cell(x),
            };
            rows.push(row(k, what, val));
        }
    }
    if let Some(r) = o.get("meas_cov").and_then(Value::as_array) {
        let first = r.first().cloned().unwrap_or(Value::Null);
        let same = r.iter().all(|x| *x == first);
        let m = first
            .as_array()
            .map_or_else(String::new, |a| matrix_cell(a));
        rows.push(row(
            "meas_cov",
            "measurement noise R_ij [m²]",
            if same {
                format!("{m} on all {} edges", r.len())
            } else {
                format!("{} matrices, the first {m}", r.len())
            },
        ));
    }
}

/// The estimators (label: kind, options) and the figures.
fn estimator_rows(o: &Object, rows: &mut Vec<Vec<String>>) {
    if let Some(specs) = o.get("estimator_specs").and_then(Value::as_array) {
        let txt: Vec<String> = specs
            .iter()
            .map(|s| {
                let label = s.get("label").map(cell).unwrap_or_default();
                let rest: Vec<String> = s
                    .as_object()
                    .map(|o| {
                        o.iter()
                            .filter(|(k, _)| *k != "label")
                            .map(|(k, v)| format!("{k} = {}", cell(v)))
                            .collect()
                    })
                    .unwrap_or_default();
                format!("{label}: {}", rest.join(", "))
            })
            .collect();
        rows.push(row(
            "estimator_specs",
            "estimators (label: kind, options)",
            txt.join("; "),
        ));
    } else if let Some(e) = o.get("estimators") {
        rows.push(row("estimators", "estimators", compact(e)));
    }
    if let Some(p) = o.get("plots").and_then(Value::as_array) {
        let files: Vec<String> = p
            .iter()
            .filter_map(|x| x.get("file").and_then(Value::as_str).map(String::from))
            .collect();
        rows.push(row("plots", "figures", files.join(", ")));
    }
}

/// A SLAM scenario (`edgekf.slam/1`) as rows of (key, value).
fn slam_rows(v: &Value) -> Vec<Vec<String>> {
    v.as_object()
        .map(|o| {
            o.iter()
                .map(|(k, x)| vec![k.clone(), String::new(), compact(x)])
                .collect()
        })
        .unwrap_or_default()
}

/// `(step, mean)` at each report of one metric.
type Series = Vec<(usize, f64)>;

/// Reads `metrics.csv` and `status.csv` back into the summary's input.
fn summary_from_files(dir: &Path, sc: &Value) -> Result<summary::Summary> {
    let path = dir.join("metrics.csv");
    let mut rd =
        csv::Reader::from_path(&path).with_context(|| format!("cannot read {}", path.display()))?;
    // estimator → metric → (step, mean), in file order.
    let mut order: Vec<String> = Vec::new();
    let mut data: BTreeMap<String, Vec<(String, Series)>> = BTreeMap::new();
    for rec in rd.records() {
        let r = rec.with_context(|| format!("{}: bad row", path.display()))?;
        let (e, step, metric, mean) = (&r[0], &r[1], &r[3], &r[4]);
        let step: usize = step
            .parse()
            .with_context(|| format!("{}: bad step", path.display()))?;
        let mean: f64 = mean.parse().unwrap_or(f64::NAN);
        if !order.iter().any(|x| x == e) {
            order.push(e.to_string());
        }
        let ms = data.entry(e.to_string()).or_default();
        match ms.iter_mut().find(|(m, _)| m == metric) {
            Some((_, v)) => v.push((step, mean)),
            None => ms.push((metric.to_string(), vec![(step, mean)])),
        }
    }
    let mut steps: Vec<usize> = data
        .values()
        .flat_map(|ms| ms.iter().flat_map(|(_, v)| v.iter().map(|(s, _)| *s)))
        .collect();
    steps.sort_unstable();
    steps.dedup();
    let kind_of = |label: &str| {
        sc.get("estimator_specs")
            .and_then(Value::as_array)
            .and_then(|a| {
                a.iter()
                    .find(|s| s.get("label").and_then(Value::as_str) == Some(label))
            })
            .and_then(|s| s.get("kind").and_then(Value::as_str))
            .unwrap_or(label)
            .to_string()
    };
    let mut status: BTreeMap<String, Outcome> = BTreeMap::new();
    if let Ok(mut rd) = csv::Reader::from_path(dir.join("status.csv")) {
        for r in rd.records().flatten() {
            if &r[1] == "diverged" {
                status.insert(
                    r[0].to_string(),
                    Outcome::Diverged {
                        step: r[2].parse().unwrap_or(0),
                        run: r[4].parse().unwrap_or(0),
                        cause: r[5].to_string(),
                    },
                );
            }
        }
    }
    let means: Vec<summary::Means> = order
        .iter()
        .map(|label| summary::Means {
            label: label.clone(),
            kind: kind_of(label),
            outcome: status.get(label).cloned().unwrap_or(Outcome::Completed),
            metrics: data[label]
                .iter()
                .map(|(m, v)| (m.clone(), v.iter().map(|(_, x)| *x).collect()))
                .collect(),
        })
        .collect();
    let dt = sc.get("dt").and_then(Value::as_f64).unwrap_or(1.0);
    let runs = sc.get("runs").and_then(Value::as_u64).unwrap_or(0) as usize;
    let name = sc.get("name").and_then(Value::as_str).unwrap_or("");
    Ok(summary::summarise_means(name, &steps, dt, runs, &means))
}

/// The final errors of a SLAM run, from `team.csv` and `robots.csv`.
fn slam_summary(dir: &Path) -> Result<(Vec<String>, Vec<Vec<String>>)> {
    let path = dir.join("team.csv");
    let mut rd =
        csv::Reader::from_path(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut last: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    let mut peak = (0.0f64, 0.0f64);
    for r in rd.records() {
        let r = r?;
        let (t, q, v): (f64, &str, f64) = (
            r[0].parse().unwrap_or(f64::NAN),
            &r[1],
            r[2].parse().unwrap_or(f64::NAN),
        );
        if q == "est_err_total" && v > peak.1 {
            peak = (t, v);
        }
        last.insert(q.to_string(), (t, v));
    }
    let mut robots: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    if let Ok(mut rd) = csv::Reader::from_path(dir.join("robots.csv")) {
        for r in rd.records().flatten() {
            if &r[2] == "est_err" {
                let i: usize = r[1].parse().unwrap_or(0);
                robots.insert(
                    i,
                    (
                        r[0].parse().unwrap_or(f64::NAN),
                        r[3].parse().unwrap_or(f64::NAN),
                    ),
                );
            }
        }
    }
    let head = vec!["quantity".into(), "value [m]".into(), "at t [s]".into()];
    let mut rows = Vec::new();
    for q in ["est_err_total", "formation_err", "centroid_err"] {
        if let Some((t, v)) = last.get(q) {
            rows.push(vec![q.to_string(), summary::sci(*v), fmt_num(*t)]);
        }
    }
    rows.push(vec![
        "peak est_err_total".into(),
        summary::sci(peak.1),
        fmt_num(peak.0),
    ]);
    for (i, (t, v)) in robots {
        rows.push(vec![
            format!("robot {i}: ‖x̂_i − x‖"),
            summary::sci(v),
            fmt_num(t),
        ]);
    }
    Ok((head, rows))
}

/// What a page is of.
enum Study {
    Filters(Value),
    Slam(Value),
}

fn read_study(dir: &Path) -> Result<Study> {
    let p = dir.join("scenario.json");
    let text = fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
    let v: Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a resolved scenario", p.display()))?;
    match v.get("schema").and_then(Value::as_str) {
        Some("edgekf.scenario/1") => Ok(Study::Filters(v)),
        Some("edgekf.slam/1") => Ok(Study::Slam(v)),
        other => bail!(
            "{}: unknown schema {:?}; expected edgekf.scenario/1 or edgekf.slam/1",
            p.display(),
            other
        ),
    }
}

/// Whether `dir` holds a study's outputs.
pub fn is_study(dir: &Path) -> bool {
    dir.join("scenario.json").is_file()
        && (dir.join("metrics.csv").is_file() || dir.join("team.csv").is_file())
}

/// The files of the study in `dir`: those its `provenance.json` lists, and the files derived
/// from them later (`report.html`, `claims.json`); `None` when no provenance lists them (an
/// older edgekf), then every file is taken.
fn study_files(dir: &Path) -> Option<Vec<String>> {
    let p = edgekf_io::outdir::provenance(dir)?;
    if p.files.is_empty() {
        return None;
    }
    let mut v = p.files;
    v.extend(edgekf_io::outdir::DERIVED.iter().map(|s| s.to_string()));
    Some(v)
}

/// Whether `file` in `dir` is one of the study's files (see [`study_files`]) and exists.
fn of_study(dir: &Path, listed: Option<&[String]>, file: &str) -> bool {
    listed.is_none_or(|l| l.iter().any(|f| f == file)) && dir.join(file).is_file()
}

/// The reproduction names whose figures this simulation draws (by its scenario name and the
/// figures present), with their descriptions and figure stems.
fn reproductions_of(dir: &Path, name: &str) -> Vec<&'static registry::Entry> {
    let listed = study_files(dir);
    let sim = dir.file_name().and_then(|s| s.to_str()).unwrap_or("");
    registry::ENTRIES
        .iter()
        .filter(|e| {
            if e.is_slam() {
                e.name == sim
            } else {
                (e.simulation() == name || e.simulation() == sim)
                    && e.plots
                        .iter()
                        .all(|p| of_study(dir, listed.as_deref(), &format!("{p}.png")))
            }
        })
        .collect()
}

fn img(dir: &Path, file: &str, alt: &str) -> Result<String> {
    let p = dir.join(file);
    let bytes = fs::read(&p).with_context(|| format!("cannot read {}", p.display()))?;
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        bail!("{}: not a PNG file", p.display());
    }
    Ok(format!(
        "<figure><img src=\"data:image/png;base64,{}\" alt=\"{}\"><figcaption><code>{}</code></figcaption></figure>\n",
        base64(&bytes),
        esc(alt),
        esc(file)
    ))
}

/// Writes `dir/report.html` and returns its path.
///
/// # Errors
/// When the directory holds no study, or a file cannot be read or written.
pub fn write_page(dir: &Path) -> Result<PathBuf> {
    let study = read_study(dir)?;
    let (sc, slam) = match &study {
        Study::Filters(v) => (v, false),
        Study::Slam(v) => (v, true),
    };
    let name = sc.get("name").and_then(Value::as_str).unwrap_or("study");
    let reps = reproductions_of(dir, name);
    // Only the files the study wrote: a directory may hold others (written by hand, or by an
    // older edgekf into a reused directory); they are not this study's.
    let listed = study_files(dir);
    let mut o = String::new();
    page_start(&format!("edgekf — {name}"), &mut o);
    page_header(&mut o, name, sc, &reps);
    figures_section(&mut o, dir, &reps, slam, listed.as_deref())?;
    let frames = of_study(dir, listed.as_deref(), "frames.json");
    crate::player::section(&mut o, dir, frames)?;
    summary_section(&mut o, dir, sc, slam)?;
    let claims = read_claims(dir)?;
    o.push_str(&claims_section(claims.as_deref(), "claims"));
    scenario_section(&mut o, sc, slam);
    provenance_section(&mut o, dir, sc);
    files_section(&mut o, dir, listed.as_deref())?;
    page_end(&mut o);
    let out = dir.join("report.html");
    write_atomic(&out, o.as_bytes())?;
    Ok(out)
}

/// The page's title, description, reproductions and table of contents.
fn page_header(o: &mut String, name: &str, sc: &Value, reps: &[&registry::Entry]) {
    let _ = writeln!(o, "<header><h1>{}</h1>", esc(name));
    if let Some(d) = sc.get("description").and_then(Value::as_str) {
        let _ = writeln!(o, "<p>{}</p>", esc(d));
    }
    if !reps.is_empty() {
        let names: Vec<String> = reps
            .iter()
            .map(|e| format!("<a href=\"#{0}\"><code>{0}</code></a>", esc(e.name)))
            .collect();
        let _ = writeln!(
            o,
            "<p class=\"note\">One simulation, {} reproduction(s): {}.</p>",
            reps.len(),
            names.join(", ")
        );
    }
    o.push_str("<nav><a href=\"#figures\">Figures</a><a href=\"#watch\">Watch the run</a><a href=\"#summary\">Steady state</a><a href=\"#claims\">Claims</a><a href=\"#scenario\">Scenario</a><a href=\"#provenance\">Provenance</a><a href=\"#files\">Files</a></nav></header>\n");
}

/// The figures of each reproduction, then any other figure in the directory.
fn figures_section(
    o: &mut String,
    dir: &Path,
    reps: &[&registry::Entry],
    slam: bool,
    listed: Option<&[String]>,
) -> Result<()> {
    o.push_str("<h2 id=\"figures\">Figures</h2>\n");
    let mut drawn: Vec<String> = Vec::new();
    for e in reps {
        let _ = writeln!(
            o,
            "<h3 id=\"{}\"><code>{}</code> — {}</h3>",
            esc(e.name),
            esc(e.name),
            esc(e.description)
        );
        let files: Vec<String> = if slam {
            vec!["paths.png".into(), "errors.png".into()]
        } else {
            e.plots.iter().map(|p| format!("{p}.png")).collect()
        };
        for f in files {
            if of_study(dir, listed, &f) {
                o.push_str(&img(dir, &f, &format!("{} ({f})", e.name))?);
                drawn.push(f);
            }
        }
    }
    // Figures of a plain `run` (or not in the registry).
    let mut others: Vec<String> = fs::read_dir(dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|d| d.ok())
        .filter_map(|d| d.file_name().into_string().ok())
        .filter(|f| f.ends_with(".png") && !f.starts_with('.') && !drawn.contains(f))
        .filter(|f| of_study(dir, listed, f))
        .collect();
    others.sort();
    if !others.is_empty() && !reps.is_empty() {
        o.push_str("<h3>Other figures</h3>\n");
    }
    for f in &others {
        o.push_str(&img(dir, f, f)?);
    }
    if drawn.is_empty() && others.is_empty() {
        o.push_str("<p class=\"note\">No figures in this directory.</p>\n");
    }
    Ok(())
}

/// The steady-state table of the estimators (and their divergences), or a SLAM run's final
/// errors.
fn summary_section(o: &mut String, dir: &Path, sc: &Value, slam: bool) -> Result<()> {
    o.push_str("<h2 id=\"summary\">Steady state</h2>\n");
    if slam {
        let (head, rows) = slam_summary(dir)?;
        o.push_str(
            "<p>Final errors of the run (and the peak of the total estimation error).</p>\n",
        );
        o.push_str(&table("summary", &head, &rows, &|c| c > 0));
        return Ok(());
    }
    let s = summary_from_files(dir, sc)?;
    let rows = summary::cells(&s);
    let _ = writeln!(
        o,
        "<p>Per estimator: each metric's mean over the runs, averaged over the reports from \
         {} to {} s (the second half); mean ε² / cov_trace over the same window (1 for a \
         filter exact for its own model); the Procrustes error over the last sixth. {} run(s). \
         <code>edgekf run … --json</code> prints the same numbers.</p>",
        fmt_num(s.window[0]),
        fmt_num(s.window[1]),
        s.runs
    );
    if let Some(which) = swept_value(sc) {
        let _ = writeln!(
            o,
            "<p class=\"note\">This study is a sweep: the table is of the scenario as written, \
             {}. Every value's summary is in <code>summary.csv</code> and the sweep's figure.</p>",
            esc(&which)
        );
    }
    o.push_str(&table("summary", &rows[0], &rows[1..], &|c| c > 1));
    for l in &s.estimators {
        if let Some(d) = &l.diverged {
            let _ = writeln!(
                o,
                "<p class=\"note\">{} diverged at step {} (t = {} s, run {}): {}</p>",
                esc(&l.label),
                d.step,
                fmt_num(d.time),
                d.run,
                esc(&d.cause)
            );
        }
    }
    Ok(())
}

/// For a sweep, which value of its parameter the steady-state table shows (the scenario as
/// written, `sweep.parameter = value` when the resolved scenario has it at that path).
fn swept_value(sc: &Value) -> Option<String> {
    let parameter = sc.get("sweep")?.get("parameter")?.as_str()?;
    let mut v = sc;
    for part in parameter.split('.') {
        match v.get(part) {
            Some(next) => v = next,
            None => return Some(format!("whose `{parameter}` is in scenario.json")),
        }
    }
    Some(format!("`{parameter}` = {v}"))
}

/// The resolved scenario as a table.
fn scenario_section(o: &mut String, sc: &Value, slam: bool) {
    o.push_str("<h2 id=\"scenario\">Scenario (resolved)</h2>\n<p class=\"note\">From <code>scenario.json</code>; <code>edgekf run scenario.json --out DIR</code> re-runs it to the same bits.</p>\n");
    let rows = if slam {
        slam_rows(sc)
    } else {
        scenario_rows(sc)
    };
    o.push_str(&table(
        "scenario",
        &["key".into(), "meaning".into(), "value".into()],
        &rows,
        &|_| false,
    ));
}

/// What ran the study (`provenance.json`), its seed, and what wrote the page.
fn provenance_section(o: &mut String, dir: &Path, sc: &Value) {
    o.push_str("<h2 id=\"provenance\">Provenance</h2>\n<dl>\n");
    let prov: Option<Provenance> = fs::read_to_string(dir.join("provenance.json"))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    match &prov {
        Some(p) => {
            let commit = if p.commit.is_empty() {
                "unknown".to_string()
            } else {
                p.commit.clone()
            };
            let _ = writeln!(
                o,
                "<dt>produced by</dt><dd>edgekf {} (git {})</dd>\n<dt>command</dt><dd><code>{}</code></dd>",
                esc(&p.version),
                esc(&commit),
                esc(&shell_line(&p.command))
            );
        }
        None => o.push_str(
            "<dt>produced by</dt><dd class=\"muted\">not recorded (no provenance.json)</dd>\n",
        ),
    }
    if let Some(seed) = sc.get("seed") {
        let _ = writeln!(o, "<dt>seed</dt><dd>{}</dd>", esc(&cell(seed)));
    }
    let _ = writeln!(
        o,
        "<dt>page written by</dt><dd>{}</dd>\n<dt>page command</dt><dd><code>{}</code></dd>\n</dl>",
        esc(&program()),
        esc(&shell_line(&std::env::args().collect::<Vec<_>>()))
    );
}

/// The files beside the page, with their sizes (only the study's own when provenance lists them).
fn files_section(o: &mut String, dir: &Path, listed: Option<&[String]>) -> Result<()> {
    o.push_str("<h2 id=\"files\">Files</h2>\n<p class=\"note\">Beside this page (formats: docs/formats.md in the repository).</p>\n");
    if listed.is_none() {
        o.push_str("<p class=\"note\">provenance.json does not list the study's files (written by an older edgekf): every file of the directory is shown, and some may be of another study.</p>\n");
    }
    o.push_str("<ul>\n");
    let mut files: Vec<(String, u64)> = fs::read_dir(dir)?
        .filter_map(|d| d.ok())
        .filter_map(|d| {
            let n = d.file_name().into_string().ok()?;
            let len = d.metadata().ok()?.len();
            (!n.starts_with('.') && n != "report.html" && d.path().is_file()).then_some((n, len))
        })
        .filter(|(n, _)| listed.is_none_or(|l| l.contains(n)))
        .collect();
    files.sort();
    for (f, len) in &files {
        let _ = writeln!(
            o,
            "<li><a href=\"{0}\"><code>{0}</code></a> <span class=\"muted\">({1})</span></li>",
            esc(f),
            human(*len)
        );
    }
    o.push_str("</ul>\n");
    Ok(())
}

fn human(n: u64) -> String {
    let n = n as f64;
    if n >= 1e6 {
        format!("{:.1} MB", n / 1e6)
    } else if n >= 1e3 {
        format!("{:.0} kB", n / 1e3)
    } else {
        format!("{n} B")
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path.file_name().and_then(|s| s.to_str()).unwrap_or("out");
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

/// Writes `root/index.html` for a `reproduce` output root whose subdirectories have pages.
///
/// # Errors
/// When the index cannot be written.
pub fn write_index(root: &Path, pages: &[PathBuf]) -> Result<PathBuf> {
    let mut o = String::new();
    page_start("edgekf — reproductions", &mut o);
    o.push_str("<header><h1>edgekf — reproductions</h1>\n<p>One page per simulation; figures that share a simulation share its page and its data.</p></header>\n");
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut links: BTreeMap<String, String> = BTreeMap::new();
    for p in pages {
        let Some(dir) = p.parent() else { continue };
        let sim = dir.file_name().and_then(|s| s.to_str()).unwrap_or("");
        let rel = format!("{sim}/report.html");
        let name = read_study(dir)
            .ok()
            .and_then(|s| match s {
                Study::Filters(v) | Study::Slam(v) => {
                    v.get("name").and_then(Value::as_str).map(String::from)
                }
            })
            .unwrap_or_else(|| sim.to_string());
        let claims = read_claims(dir).ok().flatten();
        let verdicts = claims.map_or_else(
            || "–".to_string(),
            |c| {
                let n = |v: &str| c.iter().filter(|x| x.verdict == v).count();
                format!(
                    "{} agree, {} differ, {} not checkable",
                    n("agrees"),
                    n("differs"),
                    n("not checkable")
                )
            },
        );
        let reps = reproductions_of(dir, &name);
        for e in &reps {
            links.insert(e.name.to_string(), format!("{rel}#{}", e.name));
        }
        rows.push(vec![
            format!("<a href=\"{}\">{}</a>", esc(&rel), esc(sim)),
            reps.iter()
                .map(|e| {
                    format!(
                        "<a href=\"{}#{}\"><code>{}</code></a>",
                        esc(&rel),
                        esc(e.name),
                        esc(e.name)
                    )
                })
                .collect::<Vec<_>>()
                .join(" "),
            esc(&verdicts),
        ]);
    }
    o.push_str("<h2 id=\"pages\">Simulations</h2>\n<table id=\"pages-table\">\n<thead><tr><th>simulation (page)</th><th>reproductions</th><th>claims</th></tr></thead>\n<tbody>\n");
    for r in &rows {
        let _ = writeln!(
            o,
            "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
            r[0], r[1], r[2]
        );
    }
    o.push_str("</tbody></table>\n");
    if !links.is_empty() {
        o.push_str("<h2 id=\"figures\">Reproductions</h2>\n<table id=\"reproductions\">\n<thead><tr><th>name</th><th>what it shows</th></tr></thead>\n<tbody>\n");
        for e in registry::ENTRIES {
            if let Some(l) = links.get(e.name) {
                let _ = writeln!(
                    o,
                    "<tr><td><a href=\"{}\"><code>{}</code></a></td><td>{}</td></tr>",
                    esc(l),
                    esc(e.name),
                    markup(e.description)
                );
            }
        }
        o.push_str("</tbody></table>\n");
    }
    if let Some(c) = read_claims(root)? {
        o.push_str(&claims_section(Some(&c), "claims"));
    }
    page_end(&mut o);
    let out = root.join("index.html");
    write_atomic(&out, o.as_bytes())?;
    Ok(out)
}

/// `edgekf report DIR`: a page for a study directory, or pages and an index for a `reproduce`
/// output root. Returns the pages written (the index last).
///
/// # Errors
/// When `DIR` holds neither a study nor study subdirectories, or a page cannot be written.
pub fn run(dir: &Path) -> Result<Vec<PathBuf>> {
    let page = |d: &Path| crate::interrupt::critical(&d.join("report.html"), || write_page(d));
    if is_study(dir) {
        return Ok(vec![page(dir)?]);
    }
    let mut subs: Vec<PathBuf> = fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|d| d.ok().map(|d| d.path()))
        .filter(|p| p.is_dir() && is_study(p))
        .collect();
    subs.sort();
    if subs.is_empty() {
        bail!(
            "{}: no study here (a study directory has scenario.json and metrics.csv or team.csv; \
             a `reproduce` output root has such subdirectories)",
            dir.display()
        );
    }
    let mut pages = Vec::new();
    for s in &subs {
        pages.push(page(s)?);
    }
    let index = crate::interrupt::critical(&dir.join("index.html"), || write_index(dir, &pages))?;
    pages.push(index);
    Ok(pages)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn markup_and_escaping() {
        assert_eq!(
            markup("σ_{w} < 1 & P_{fail}"),
            "σ<sub>w</sub> &lt; 1 &amp; P<sub>fail</sub>"
        );
        assert_eq!(markup("u_x"), "u_x");
        assert_eq!(esc("<a href=\"x\">"), "&lt;a href=&quot;x&quot;&gt;");
        assert_eq!(
            shell_line(&["edgekf".into(), "run".into(), "my file.toml".into()]),
            "edgekf run 'my file.toml'"
        );
    }

    #[test]
    fn numbers_in_tables() {
        assert_eq!(fmt_num(30000.0), "30000");
        assert_eq!(fmt_num(0.001), "0.001");
        assert_eq!(fmt_num(0.12345678), "0.12346");
        assert_eq!(fmt_num(3.3397e-3), "0.0033397");
        assert_eq!(fmt_num(1.2e-7), "1.2000e-7");
    }
}
