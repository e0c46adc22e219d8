//! The cost of a study, estimated before it runs: a run that cannot fit in memory is refused
//! with the estimate named, and a long one is announced (or refused past a limit) instead of
//! running silently for hours.
//!
//! Memory counts what grows with the study: the per-run values of every metric at every
//! reported step (twice: the chunks' and the assembled copy), the recorded paths, and every
//! chunk's state. Time is a rough model calibrated on this project's measurements (≈ 1 ns per
//! normal draw, ≈ 0.25 ns per floating-point operation of the loops, and the measured time of
//! the CA filters' kernels; 2 cores); it is meant to tell seconds from hours, not to be precise:
//! measured, it is 0.8–2.4× the actual time for studies of 0.2 s or more and 0.5–4.4× for
//! shorter ones. `edgekf bench --cost` sets it beside the measured time of every shipped
//! scenario's estimators.

use super::fork;
use super::sweep::resolved_key;
use super::world::Factor;
use crate::scenario::Scenario;

/// What a study will cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudyCost {
    /// Bytes of memory at the peak.
    pub bytes: f64,
    /// Estimated wall time in seconds on `threads` threads.
    pub seconds: f64,
    /// The part of `seconds` spent in computations shared by all runs (covariances, gains).
    pub shared_seconds: f64,
}

/// Nanoseconds per normal draw and per floating-point operation (measured on this project's
/// machine; see the user guide's Speed chapter).
const NS_PER_NORMAL: f64 = 1.0;
const NS_PER_FLOP: f64 = 0.25;

/// A cost measured in nanoseconds, in the model's operations (for kernels whose time is
/// measured rather than counted).
pub(crate) fn ops_of_ns(ns: f64) -> f64 {
    ns / NS_PER_FLOP
}
/// Nanoseconds per output row written (a `metrics.csv` row, or one agent's `paths.csv` row, and
/// its share of the figures): measured ≈ 1 µs on this project's machine, where a study that
/// reports every step spends more time writing its outputs than simulating.
const NS_PER_OUTPUT_ROW: f64 = 1000.0;

/// Estimates the cost of running `runs` of the scenario's runs on `threads` threads; a sweep
/// runs the scenario once per value, and itself (without the sweep) unless one of the values
/// is that scenario ([`super::sweep`]); each of those counts, the steps that values share
/// (`sim::fork`) once.
pub fn cost(sc: &Scenario, runs: usize, threads: usize) -> StudyCost {
    let mut c = cost_one(sc, runs, threads);
    let Some(points) = sc.sweep().and(sc.sweep_points().ok()) else {
        // No sweep; or an invalid point, which fails before anything runs.
        return c;
    };
    let key = resolved_key(sc);
    if points.iter().any(|p| resolved_key(&p.scenario) == key) {
        // Its results are kept twice (as the base and as the point), but computed once.
        c.seconds = 0.0;
        c.shared_seconds = 0.0;
    }
    // Values that share their first steps (`sim::fork`): all but the first of a group
    // simulate only the steps from the departures on.
    let scs: Vec<&Scenario> = points.iter().map(|p| &p.scenario).collect();
    let mut own = vec![1.0; scs.len()];
    for (members, at) in fork::groups(&scs) {
        for &k in &members[1..] {
            own[k] = 1.0 - (at - 1) as f64 / scs[k].steps() as f64;
        }
    }
    for (p, own) in scs.iter().zip(own) {
        let q = cost_one(p, runs, threads);
        c.bytes += q.bytes;
        c.seconds += own * q.seconds;
        c.shared_seconds += own * q.shared_seconds;
    }
    c
}

/// [`cost`] of the scenario alone (without its sweep points).
fn cost_one(sc: &Scenario, runs: usize, threads: usize) -> StudyCost {
    let model = sc.model();
    let d = model.dim() as f64;
    let n = model.agents() as f64;
    let m = model.num_edges() as f64;
    let (nd, md) = (n * d, m * d);
    let reports = sc.report_count() as f64;
    let runs_f = runs as f64;
    let threads = threads.clamp(1, runs.max(1)) as f64;
    let chunks = threads;
    let steps = sc.steps() as f64;
    // Memory.
    let mut bytes = 0.0;
    let mut per_run_flops = 0.0;
    let mut shared_flops = 0.0;
    let mut output_rows = 0.0;
    let q = Factor::of(model.q(), model.dim());
    let draws = md + nd;
    let world_flops = match q {
        Factor::Zero => 0.0,
        Factor::Diagonal(_) => nd,
        Factor::Kron { n, d, .. } => (n * n) as f64 * d as f64,
        Factor::Dense { n, .. } => (n * n) as f64,
    };
    for e in sc.estimators() {
        let metrics = sc.metrics_of(e).len() as f64;
        bytes += 2.0 * metrics * reports * runs_f * 8.0;
        output_rows += reports * (metrics + n);
        bytes += 2.0 * 2.0 * reports * nd * 8.0;
        let c = e.config().cost(model);
        bytes += runs_f * (c.bytes_per_run + (4.0 * nd + 4.0 * md) * 8.0);
        bytes += chunks * c.bytes_shared;
        per_run_flops += c.flops_per_run_step + 8.0 * md + 6.0 * nd;
        shared_flops += c.flops_shared_step;
    }
    let per_run_ns = draws * NS_PER_NORMAL + (world_flops + per_run_flops) * NS_PER_FLOP;
    let seconds_runs = runs_f * steps * per_run_ns * 1e-9 / threads;
    let shared_seconds = steps * shared_flops * NS_PER_FLOP * 1e-9;
    let output_seconds = output_rows * NS_PER_OUTPUT_ROW * 1e-9;
    StudyCost {
        bytes,
        seconds: seconds_runs + shared_seconds + output_seconds,
        shared_seconds,
    }
}

/// `1.2 GB`-style sizes.
pub fn human_bytes(b: f64) -> String {
    const UNITS: [&str; 5] = ["B", "kB", "MB", "GB", "TB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < UNITS.len() {
        v /= 1000.0;
        u += 1;
    }
    format!("{v:.1} {}", UNITS[u])
}

/// `3.2 h`-style durations.
pub fn human_seconds(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.1} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else if s < 48.0 * 3600.0 {
        format!("{:.1} h", s / 3600.0)
    } else {
        format!("{:.1} days", s / 86400.0)
    }
}
