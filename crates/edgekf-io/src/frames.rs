//! `frames.json` (`edgekf.frames/1`): a few runs of a study frame by frame — every estimator's
//! true positions, edge estimates and their covariances, measured links and present agents —
//! what the report page's player animates (`docs/formats.md`, "frames.json").

use std::fmt::Write as _;

use edgekf::scenario::Scenario;
use edgekf::sim::{Options, Results, RunFrames};

/// The bytes `frames.json` may take (the report page embeds it): [`frame_options`] chooses the
/// runs and frames to stay within it.
pub const FRAMES_BUDGET: usize = 2_000_000;
/// At most this many runs are recorded …
pub const FRAME_RUNS: usize = 3;
/// … and this many frames.
pub const FRAME_LIMIT: usize = 100;
/// Fewer frames than this are no animation: one run is recorded instead of several, and if
/// even that does not fit, none.
pub const MIN_FRAMES: usize = 24;

/// Bytes per written number (four significant digits and a comma: 7.3 on average in the shipped
/// studies, so that the budget holds).
const BYTES_PER_VALUE: usize = 8;

/// The options that record frames of `sc` (`sim::Options::frame_runs`, `frame_limit`) within
/// [`FRAMES_BUDGET`]: [`FRAME_RUNS`] runs if at least [`MIN_FRAMES`] frames of each fit (or
/// every path report does), else one run, else none (the default options).
pub fn frame_options(sc: &Scenario) -> Options {
    let fw = sc.framework();
    let (n, m, d) = (fw.agents(), fw.graph().num_edges(), fw.dim());
    let values = n * d + m * d + m * d * (d + 1) / 2;
    let per_frame = BYTES_PER_VALUE * values + 2 * (n + m) + 16;
    let estimators = sc.estimators().len().max(1);
    let available = sc.path_reports().len().min(FRAME_LIMIT);
    for runs in [FRAME_RUNS.min(sc.runs()), 1] {
        let fit = FRAMES_BUDGET / (per_frame * runs * estimators);
        let frames = fit.min(available);
        if frames >= MIN_FRAMES.min(available) && frames > 0 {
            return Options {
                frame_runs: runs,
                frame_limit: frames,
                ..Options::default()
            };
        }
    }
    Options::default()
}

/// A number with four significant digits (what a viewer needs: 0.1 mm on a formation of metres;
/// the CSVs keep full precision), `null` when not finite.
fn num(s: &mut String, v: f64) {
    if !v.is_finite() {
        s.push_str("null");
        return;
    }
    let r: f64 = format!("{v:.3e}").parse().unwrap_or(v);
    if r != 0.0 && r.abs() < 1e-3 {
        let _ = write!(s, "{r:e}");
    } else {
        let _ = write!(s, "{r}");
    }
}

/// `[[…]; frames]`: `per` numbers per frame.
fn rows(s: &mut String, v: &[f64], per: usize) {
    per_frame(s, v, per, |s, row| {
        s.push('[');
        for (i, &x) in row.iter().enumerate() {
            if i > 0 {
                s.push(',');
            }
            num(s, x);
        }
        s.push(']');
    });
}

/// `["0101…"; frames]`: `per` flags per frame.
fn flags(s: &mut String, v: &[bool], per: usize) {
    per_frame(s, v, per, |s, row| {
        s.push('"');
        s.extend(row.iter().map(|&b| if b { '1' } else { '0' }));
        s.push('"');
    });
}

/// `[frame, frame, …]`: `v` cut into frames of `per` values, each written by `frame`.
fn per_frame<T>(s: &mut String, v: &[T], per: usize, frame: impl Fn(&mut String, &[T])) {
    s.push('[');
    for (f, row) in v.chunks(per.max(1)).enumerate() {
        if f > 0 {
            s.push(',');
        }
        frame(s, row);
    }
    s.push(']');
}

fn run_json(s: &mut String, rf: &RunFrames, (n, m, d): (usize, usize, usize)) {
    let t = d * (d + 1) / 2;
    let _ = write!(
        s,
        "{{\"run\":{},\"frames\":{},\"positions\":",
        rf.run, rf.frames
    );
    rows(s, &rf.positions, n * d);
    s.push_str(",\"estimates\":");
    rows(s, &rf.estimates, m * d);
    s.push_str(",\"covariances\":");
    rows(s, &rf.covariances, m * t);
    s.push_str(",\"observed\":");
    flags(s, &rf.observed, m);
    s.push_str(",\"present\":");
    flags(s, &rf.present, n);
    s.push('}');
}

/// `frames.json` of a study run with frames, `None` without any.
pub fn frames_json(sc: &Scenario, res: &Results) -> Option<String> {
    if res.frame_steps.is_empty() || res.estimators.iter().all(|e| e.frames.is_empty()) {
        return None;
    }
    let fw = sc.framework();
    let (n, m, d) = (fw.agents(), fw.graph().num_edges(), fw.dim());
    let mut s = String::new();
    let _ = write!(
        s,
        "{{\"schema\":\"edgekf.frames/1\",\"name\":{},\"dim\":{d},\"agents\":{n},\"edges\":[",
        serde_json::Value::from(sc.name())
    );
    for (e, (i, j)) in fw.graph().edges().iter().enumerate() {
        let _ = write!(s, "{}[{i},{j}]", if e > 0 { "," } else { "" });
    }
    let leaders: Vec<String> = fw.leaders().iter().map(|l| l.to_string()).collect();
    let _ = write!(s, "],\"leaders\":[{}],\"config\":", leaders.join(","));
    rows(&mut s, fw.config(), d);
    let steps: Vec<String> = res.frame_steps.iter().map(|k| k.to_string()).collect();
    let _ = write!(
        s,
        ",\"dt\":{},\"steps\":[{}],\"target\":",
        res.dt,
        steps.join(",")
    );
    if res.frame_targets.is_empty() {
        s.push_str("null");
    } else {
        rows(&mut s, &res.frame_targets, n * d);
    }
    s.push_str(",\"estimators\":[");
    for (k, e) in res.estimators.iter().enumerate() {
        let label = serde_json::Value::from(e.label.as_str());
        let kind = serde_json::Value::from(e.kind.as_str());
        let _ = write!(
            s,
            "{}{{\"label\":{label},\"kind\":{kind},\"runs\":[",
            if k > 0 { "," } else { "" }
        );
        for (r, rf) in e.frames.iter().enumerate() {
            if r > 0 {
                s.push(',');
            }
            run_json(&mut s, rf, (n, m, d));
        }
        s.push_str("]}");
    }
    s.push_str("]}\n");
    Some(s)
}
