//! Invariants over the whole registry: every kind of [`Registry::builtin`], with no list of
//! names here, so a new estimator is covered without editing this file (STYLE 11).
//!
//! On three scenarios of the thesis hexagon — white process noise without faults (every gain
//! shared by the runs), correlated process noise without measurement faults but with every
//! input lost (`p_fail = 1`: the AR filters' shared path with inflation), and faults
//! (availability 0.8, a departure and a rejoin, `p_fail = 0.3` with the AR model of `[comm]`, a
//! metric edge: the per-run paths) — every kind, built with its
//! [`EstimatorKind::example_options`](edgekf::estimate::EstimatorKind::example_options), must
//! 1. give bit-identical [`Results`] on 1, 2 and 3 threads (a run is a pure function of
//!    (scenario, seed, run index));
//! 2. allocate nothing in the step loop: on the two-thread run, each chunk's thread makes no
//!    heap allocation from the report at step 100 to the last one at step 300 (after a warm-up
//!    of 100 steps; reports and metrics included);
//! 3. keep every covariance it holds ([`Estimator::covariances`]) symmetric positive
//!    semidefinite at every reported step and run, and expose them whenever its `cov_trace` is
//!    not zero;
//! 4. finish without a breakdown.
//!
//! Then, on the two fault-free scenarios with 120 runs, every kind that declares itself
//! [`Consistency::Exact`] must have a mean squared error equal to its mean `cov_trace`
//! (tolerance derived in [`consistency`]); the others are printed with their reason, not
//! checked.
//!
//! The allocation counter is this test binary's global allocator, counting per thread (so the
//! test harness, rayon's scheduler and other threads do not blur the count); everything runs in
//! one `#[test]`, one check after the other.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::fmt::Write as _;
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use edgekf::estimate::{Consistency, Estimator, EstimatorKind, Registry};
use edgekf::noise::Kernel;
use edgekf::scenario::{CommSpec, DepartureSpec, EstimatorEntry, Scenario, ScenarioSpec};
use edgekf::sim::{Observer, Outcome, Quiet, Results};
use nalgebra::DMatrix;

/// The system allocator, counting the allocations (and reallocations) of each thread.
struct Counting;

thread_local! {
    /// Allocations made by this thread so far (a `const` cell without destructor: safe to use
    /// from inside the allocator, also while the thread exits).
    static THREAD_ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn count_allocation() {
    let _ = THREAD_ALLOCS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_allocation();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_allocation();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_allocation();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The scenarios, each with the thesis hexagon, Δt = 1 ms, σ_w = 0.001, σ_v = 0.1, T = 10 and
/// the AR(1) model shipped with the chapter 6 scenarios.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Case {
    /// White process noise, no faults, `p_fail = 0`.
    White,
    /// Correlated process noise (the default exponential kernel), no measurement faults,
    /// `p_fail = 1`.
    Correlated,
    /// Availability 0.8, agent 6 leaves at 0.08 s and rejoins at 0.16 s, `p_fail = 0.3`, a
    /// metric edge (the CA filters' PCRB).
    Faults,
}

const CASES: [Case; 3] = [Case::White, Case::Correlated, Case::Faults];

impl Case {
    fn spec(self, steps: usize, runs: usize, every: usize) -> ScenarioSpec {
        let mut s = common::spec(0.001, 0.1, steps, runs, every, Vec::new());
        s.name = format!("{self:?}").to_lowercase();
        s.noise.kernel = match self {
            Case::White => Kernel::White,
            Case::Correlated | Case::Faults => Kernel::default(),
        };
        s.comm = CommSpec {
            p_fail: match self {
                Case::White => 0.0,
                Case::Correlated => 1.0,
                Case::Faults => 0.3,
            },
            ar: Some(common::ar()),
        };
        if self == Case::Faults {
            s.faults.availability = 0.8;
            s.faults.departures = vec![DepartureSpec {
                agent: 6,
                at: 0.08,
                rejoin: Some(0.16),
            }];
            s.metrics.edge = Some([1, 0]);
        }
        s
    }
}

/// The entry of `kind` with its example options.
fn entry(kind: &dyn EstimatorKind) -> EstimatorEntry {
    let mut e = EstimatorEntry::kind(kind.name());
    for (k, v) in kind.example_options() {
        e = e.with(&k, v);
    }
    e
}

/// `spec` with the estimators `entries`, checked.
fn scenario(spec: &ScenarioSpec, entries: Vec<EstimatorEntry>) -> Scenario {
    let mut s = spec.clone();
    s.estimators = entries;
    Scenario::from_spec(&s, None).unwrap_or_else(|e| {
        panic!(
            "{}: every kind configures with its example options: {e}",
            s.name
        )
    })
}

fn run_on(threads: usize, sc: &Scenario, obs: &dyn Observer) -> Results {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| edgekf::sim::run(sc, obs).expect("not cancelled"))
}

/// Where two results differ bitwise (NaN included), if they do.
fn bit_difference(a: &Results, b: &Results) -> Option<String> {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    if a.steps != b.steps || a.runs != b.runs || a.estimators.len() != b.estimators.len() {
        return Some("reported steps, runs or estimators".into());
    }
    for (x, y) in a.estimators.iter().zip(&b.estimators) {
        if x.outcome != y.outcome || x.valid != y.valid || x.metrics != y.metrics {
            return Some(format!("{}: outcome or metrics", x.label));
        }
        for (m, (p, q)) in x.metrics.iter().zip(x.values.iter().zip(&y.values)) {
            if bits(p) != bits(q) {
                return Some(format!("{}: metric {m}", x.label));
            }
        }
        if bits(&x.paths) != bits(&y.paths) || bits(&x.inputs) != bits(&y.inputs) {
            return Some(format!("{}: paths or inputs", x.label));
        }
    }
    None
}

/// Checks every covariance of every estimator at every reported step: symmetric and positive
/// semidefinite to rounding. An n × n covariance computed in floating point is symmetric to
/// its last bits (Joseph form, symmetrised) and an eigenvalue is computed with an error of
/// order n ε ‖C‖; `16 n ε ‖C‖` allows that and nothing more (an indefinite covariance from a
/// wrong formula has a negative eigenvalue at the size of the entries).
///
/// It also reads every edge's covariance ([`Estimator::edge_covariance`], the one quantity every
/// kind exposes alike): each must be symmetric PSD, and their traces summed over the edges are
/// kept per (step, run), for [`check_kind`] to compare with `cov_trace`.
#[derive(Default)]
struct PsdCheck {
    /// Directed edges and dimension of the scenario.
    edges: usize,
    dim: usize,
    /// Per estimator index: matrices checked.
    checked: Mutex<Vec<usize>>,
    /// Σ_e tr(edge covariance) per (step, run), for a kind that exposes every edge's.
    edge_traces: Mutex<std::collections::BTreeMap<(usize, usize), f64>>,
    failures: Mutex<Vec<String>>,
}

impl PsdCheck {
    fn new(sc: &Scenario) -> Self {
        Self {
            edges: sc.framework().graph().num_edges(),
            dim: sc.framework().dim(),
            ..Self::default()
        }
    }

    /// Every edge's covariance of run `r`: PSD, and the sum of their traces (`None` when the
    /// kind exposes none).
    fn edge_covariances(&self, k: usize, run: usize, r: usize, est: &dyn Estimator) -> Option<f64> {
        let d = self.dim;
        let mut buf = vec![0.0; d * d];
        let mut sum = 0.0;
        for e in 0..self.edges {
            if !est.edge_covariance(e, r, &mut buf) {
                return None;
            }
            if let Some(why) = not_psd(&DMatrix::from_row_slice(d, d, &buf)) {
                self.failures
                    .lock()
                    .unwrap()
                    .push(format!("step {k}, run {run}, edge {e}'s covariance: {why}"));
            }
            sum += (0..d).map(|a| buf[a * d + a]).sum::<f64>();
        }
        Some(sum)
    }
}

impl Observer for PsdCheck {
    fn on_estimator(&self, k: usize, index: usize, runs: Range<usize>, est: &dyn Estimator) {
        let mut count = 0;
        for r in 0..runs.len() {
            for (c, m) in est.covariances(r).iter().enumerate() {
                count += 1;
                if let Some(why) = not_psd(m) {
                    self.failures.lock().unwrap().push(format!(
                        "step {k}, run {}, covariance {c}: {why}",
                        runs.start + r
                    ));
                }
            }
            if let Some(t) = self.edge_covariances(k, runs.start + r, r, est) {
                self.edge_traces
                    .lock()
                    .unwrap()
                    .insert((k, runs.start + r), t);
            }
        }
        let mut checked = self.checked.lock().unwrap();
        if checked.len() <= index {
            checked.resize(index + 1, 0);
        }
        checked[index] += count;
    }
}

fn not_psd(c: &DMatrix<f64>) -> Option<String> {
    let n = c.nrows();
    if n != c.ncols() || n == 0 {
        return Some(format!("shape {} × {}", c.nrows(), c.ncols()));
    }
    if c.iter().any(|v| !v.is_finite()) {
        return Some("a non-finite entry".into());
    }
    let scale = c.amax();
    let tol = 16.0 * n as f64 * f64::EPSILON * scale;
    let asym = (c - c.transpose()).amax();
    if asym > tol {
        return Some(format!("asymmetric by {asym:e} (entries up to {scale:e})"));
    }
    let min = c.clone().symmetric_eigen().eigenvalues.min();
    if min < -tol {
        return Some(format!("eigenvalue {min:e} (entries up to {scale:e})"));
    }
    None
}

/// Counts the heap allocations of each chunk's thread from reported step `from` to reported
/// step `to`: a chunk's runs step on one thread, which runs nothing else in between (the step
/// loop has no nested parallelism), so the count is the step loop's own. The observer itself
/// does not allocate.
struct AllocWindow {
    from: usize,
    to: usize,
    /// Per first run of a chunk: the thread's count at `from` and at `to` (`usize::MAX`: not
    /// reached).
    at_from: Vec<AtomicUsize>,
    at_to: Vec<AtomicUsize>,
}

impl AllocWindow {
    fn new(from: usize, to: usize, runs: usize) -> Self {
        let unset = || (0..runs).map(|_| AtomicUsize::new(usize::MAX)).collect();
        Self {
            from,
            to,
            at_from: unset(),
            at_to: unset(),
        }
    }

    /// Allocations per chunk (keyed by its first run) between the two reports.
    fn counts(&self) -> Vec<(usize, Option<usize>)> {
        let get = |v: &AtomicUsize| Some(v.load(Ordering::SeqCst)).filter(|&n| n != usize::MAX);
        self.at_from
            .iter()
            .zip(&self.at_to)
            .enumerate()
            .filter_map(|(r, (a, b))| {
                let a = get(a)?;
                Some((r, get(b).map(|b| b - a)))
            })
            .collect()
    }
}

impl Observer for AllocWindow {
    fn on_estimator(&self, k: usize, _index: usize, runs: Range<usize>, _est: &dyn Estimator) {
        let n = THREAD_ALLOCS.with(Cell::get);
        if k == self.from {
            self.at_from[runs.start].store(n, Ordering::SeqCst);
        } else if k == self.to {
            self.at_to[runs.start].store(n, Ordering::SeqCst);
        }
    }
}

/// Runs, steps and reporting interval of the determinism, allocation and covariance checks;
/// allocations are counted from the report at `ALLOC_FROM` (after a warm-up) to the last.
const RUNS: usize = 7;
const STEPS: usize = 300;
const EVERY: usize = 20;
const ALLOC_FROM: usize = 100;

/// Checks 1–4 for one kind on one scenario; the failures, if any.
fn check_kind(case: Case, kind: &dyn EstimatorKind) -> Vec<String> {
    let name = kind.name();
    let mut failures = Vec::new();
    let sc = scenario(&case.spec(STEPS, RUNS, EVERY), vec![entry(kind)]);
    assert_eq!(
        sc.model().measurement_faults(),
        case == Case::Faults,
        "{case:?}: the faults stage is active exactly in the fault scenario"
    );
    // 1, 2 and 3: covariances checked on one and three threads, allocations counted on two.
    let psd = PsdCheck::new(&sc);
    let window = AllocWindow::new(ALLOC_FROM, STEPS, RUNS);
    let one = run_on(1, &sc, &psd);
    let two = run_on(2, &sc, &window);
    let three = run_on(3, &sc, &psd);
    assert!(
        two.steps.contains(&ALLOC_FROM) && two.steps.contains(&STEPS),
        "the allocation window's ends are reported steps"
    );
    for (t, other) in [(2, &two), (3, &three)] {
        if let Some(d) = bit_difference(&one, other) {
            failures.push(format!("1 vs {t} threads differ: {d}"));
        }
    }
    failures.extend(edge_trace_failures(case, &one, name, &psd));
    failures.extend(psd.failures.into_inner().unwrap());
    let checked = psd
        .checked
        .into_inner()
        .unwrap()
        .first()
        .copied()
        .unwrap_or(0);
    let res = &one.estimators[0];
    if res.outcome != Outcome::Completed {
        failures.push(format!("did not complete: {:?}", res.outcome));
    }
    let ct = one.values(name, "cov_trace").expect("cov_trace");
    if checked == 0 && ct.iter().any(|&v| v != 0.0) {
        failures.push(
            "reports a covariance trace but exposes no covariance (Estimator::covariances)".into(),
        );
    }
    let chunks = window.counts();
    if chunks.len() != 2 {
        failures.push(format!(
            "two chunks expected on two threads, saw {chunks:?}"
        ));
    }
    for (first, n) in chunks {
        match n {
            Some(0) => {}
            Some(n) => failures.push(format!(
                "allocates in the step loop: {n} allocations in steps {}..={STEPS} of the \
                 chunk from run {first}",
                ALLOC_FROM + 1
            )),
            None => failures.push(format!("the chunk from run {first} missed step {STEPS}")),
        }
    }
    println!(
        "{case:?} {name}: {} gain, {checked} covariances checked",
        if sc.estimators()[0].config().shared_gain(sc.model()) {
            "shared"
        } else {
            "per-run"
        }
    );
    failures
}

/// Where every edge is tracked (no measurement faults), the edges' covariance traces sum to
/// `cov_trace` at every reported step and run, to rounding (`1e-10` relative: the centralised
/// filter sums its node-space blocks in another order). A kind that reports a covariance trace
/// must expose its edges' covariances.
fn edge_trace_failures(case: Case, res: &Results, name: &str, psd: &PsdCheck) -> Vec<String> {
    let traces = psd.edge_traces.lock().unwrap();
    let ct = res.values(name, "cov_trace").expect("cov_trace");
    let runs = res.runs.len();
    if traces.is_empty() {
        return if ct.iter().any(|&v| v != 0.0) {
            vec![
                "reports a covariance trace but no edge covariance (Estimator::edge_covariance)"
                    .into(),
            ]
        } else {
            Vec::new()
        };
    }
    if case == Case::Faults {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (&(k, r), &sum) in traces.iter() {
        let Some(at) = res.steps.iter().position(|&s| s == k) else {
            continue;
        };
        let want = ct[at * runs + r];
        if (sum - want).abs() > 1e-10 * want.abs().max(1e-300) {
            out.push(format!(
                "step {k}, run {r}: the edges' covariance traces sum to {sum:e}, cov_trace is {want:e}"
            ));
        }
    }
    out.truncate(3);
    out
}

/// Runs of the consistency check (and its reports: steps 1, 30, …, 600).
const C_RUNS: usize = 120;
const C_STEPS: usize = 600;
const C_EVERY: usize = 30;

/// Mean squared error against covariance trace, for the kinds that declare
/// [`Consistency::Exact`] on the fault-free scenarios.
///
/// For an exact Kalman filter `E ε²_k = tr Σ_k` at every step k (its covariance is the error
/// covariance given the data, and the initial positions are drawn from its prior), so per run
/// `a_r = mean_k (ε²_{k,r} − c_{k,r}) / c̄_k` (c̄_k the mean covariance trace at report k: a
/// relative deviation, so the transient's large errors do not swamp the steady state) has
/// mean 0. The runs are independent, so `z = ā / (s_a / √R)` is ~N(0, 1); `|z| < 4.5` fails
/// with probability 7e-6 per check (< 2e-4 for the ≤ 20 checks here). The check must also be
/// able to fail: its resolution `4.5 s_a / √R` (the smallest relative bias it detects) is
/// asserted below 5 % (measured 0.6–1.1 %), so a filter whose covariance is 5 % off its error
/// fails.
fn consistency(case: Case) -> (Vec<String>, String) {
    let registry = Registry::builtin();
    let spec = case.spec(C_STEPS, C_RUNS, C_EVERY);
    let mut exact = Vec::new();
    let mut table = String::new();
    for kind in registry.kinds() {
        let sc = scenario(&spec, vec![entry(kind)]);
        match sc.estimators()[0].config().consistency(sc.model()) {
            Consistency::Exact => exact.push(entry(kind)),
            Consistency::Approximate(why) => {
                writeln!(
                    table,
                    "{case:?} {}: not checked (approximate: {why})",
                    kind.name()
                )
                .unwrap();
            }
            Consistency::Undeclared => {
                writeln!(table, "{case:?} {}: not checked (undeclared)", kind.name()).unwrap();
            }
        }
    }
    let sc = scenario(&spec, exact);
    let res = edgekf::sim::run(&sc, &Quiet).expect("not cancelled");
    let mut failures = Vec::new();
    for label in res.labels() {
        let (e2, ct) = (
            res.values(label, "est_error_sq").unwrap(),
            res.values(label, "cov_trace").unwrap(),
        );
        let reports = res.steps.len();
        let cbar: Vec<f64> = (0..reports)
            .map(|k| ct[k * C_RUNS..(k + 1) * C_RUNS].iter().sum::<f64>() / C_RUNS as f64)
            .collect();
        if cbar.iter().all(|&c| c == 0.0) {
            // The oracle: no error and no covariance.
            let ok = e2.iter().all(|&v| v == 0.0);
            writeln!(table, "{case:?} {label}: error and covariance 0: {ok}").unwrap();
            if !ok {
                failures.push(format!("{case:?} {label}: covariance 0 but an error"));
            }
            continue;
        }
        let a: Vec<f64> = (0..C_RUNS)
            .map(|r| {
                (0..reports)
                    .map(|k| (e2[k * C_RUNS + r] - ct[k * C_RUNS + r]) / cbar[k])
                    .sum::<f64>()
                    / reports as f64
            })
            .collect();
        let mean = a.iter().sum::<f64>() / C_RUNS as f64;
        let sd = (a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (C_RUNS - 1) as f64).sqrt();
        let se = sd / (C_RUNS as f64).sqrt();
        let z = mean / se;
        writeln!(
            table,
            "{case:?} {label}: relative bias {mean:+.4} (z = {z:+.2}, resolution {:.4})",
            4.5 * se
        )
        .unwrap();
        if z.abs() >= 4.5 {
            failures.push(format!(
                "{case:?} {label}: mean squared error off its covariance trace by {:+.2} % (z = {z:.2})",
                100.0 * mean
            ));
        }
        if 4.5 * se >= 0.05 {
            failures.push(format!(
                "{case:?} {label}: the check cannot resolve a 5 % bias (resolution {:.3})",
                4.5 * se
            ));
        }
    }
    (failures, table)
}

#[test]
fn every_registered_kind_keeps_the_invariants() {
    // The counter counts this thread's allocations (else check 2 would pass vacuously).
    let before = THREAD_ALLOCS.with(Cell::get);
    let v = std::hint::black_box(vec![0u8; 64]);
    assert!(
        THREAD_ALLOCS.with(Cell::get) > before,
        "the allocator counts"
    );
    drop(v);
    let registry = Registry::builtin();
    let mut failures = Vec::new();
    for case in CASES {
        for kind in registry.kinds() {
            for f in check_kind(case, kind) {
                failures.push(format!("{case:?} {}: {f}", kind.name()));
            }
        }
    }
    // The filters whose model is the simulated world must say so (a guard against declaring
    // a kind out of the check).
    for case in [Case::White, Case::Correlated] {
        for name in ["none", "mle", "rkf", "jrkf", "crkf"] {
            let kind = registry.find(name).expect("built in");
            let sc = scenario(&case.spec(10, 1, 1), vec![entry(kind)]);
            let c = sc.estimators()[0].config().consistency(sc.model());
            if c != Consistency::Exact {
                failures.push(format!("{case:?} {name}: declared {c:?}"));
            }
        }
        let (f, table) = consistency(case);
        print!("{table}");
        failures.extend(f);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
