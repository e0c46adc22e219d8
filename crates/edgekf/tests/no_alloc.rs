//! The step loop allocates nothing: the number of heap allocations of a whole simulation does not
//! grow with the number of steps (same estimators, same number of reported steps).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use common::{hexagon, names, table, trilateration_kernel};

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// One test: the counter is the process's, so the checks run one after the other, with no
/// other test (nor the harness reporting one) allocating meanwhile.
#[test]
fn step_loops_allocate_nothing() {
    allocations_do_not_grow_with_steps();
    ca_filters_allocate_nothing_per_step();
    forked_sweep_values_allocate_nothing_per_step();
    a_large_run_on_two_threads_allocates_nothing_per_step();
}

/// A pool of `threads` threads, every worker started (a thread's start-up allocates) before
/// anything is counted.
fn started_pool(threads: usize) -> rayon::ThreadPool {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.broadcast(|_| ());
    pool
}

/// The allocations of a whole simulation of `sc` in `pool` (which reports 3 steps).
fn allocations(pool: &rayon::ThreadPool, sc: &edgekf::scenario::Scenario) -> usize {
    pool.install(|| {
        let before = ALLOCS.load(Ordering::SeqCst);
        let res = edgekf::sim::run(sc, &edgekf::sim::Quiet).unwrap();
        let after = ALLOCS.load(Ordering::SeqCst);
        assert_eq!(res.steps.len(), 3);
        // A loop that stops writes its cause once (an allocation): these studies must not.
        for e in &res.estimators {
            assert_eq!(
                e.outcome,
                edgekf::sim::Outcome::Completed,
                "{}: the study must run to its end",
                e.label
            );
        }
        after - before
    })
}

/// One run of 160 agents under the spatial kernel on two threads: the JRKF's recursions and
/// means in slices, the noise factor's rows in halves, each by `rayon` within the step.
fn a_large_run_on_two_threads_allocates_nothing_per_step() {
    let pool = started_pool(2);
    let count = |steps: usize| {
        let sc = trilateration_kernel(160, steps, steps / 2, names(&["jrkf", "rkf"]));
        allocations(&pool, &sc)
    };
    same_allocations("large run", (40, 400), count);
}

fn allocations_do_not_grow_with_steps() {
    let pool = started_pool(1);
    let mut estimators = names(&["none", "mle", "rkf", "jrkf", "crkf", "oracle"]);
    estimators.push(table("mmse", "mmse", None, Some(1e-3)));
    // The adaptive filters (issue 25): per-run covariances and sensitivities, sized once.
    for (kind, adaptive) in [("rkf", "both"), ("jrkf", "process")] {
        estimators.push(
            edgekf::scenario::EstimatorEntry::kind(kind)
                .with("label", format!("{kind}-adaptive"))
                .with("adaptive", adaptive),
        );
    }
    // Both report exactly steps {1, every, steps}: 3 reports.
    let count = |steps: usize| {
        let sc = hexagon(0.001, 0.1, steps, 3, steps / 2, estimators.clone());
        allocations(&pool, &sc)
    };
    same_allocations("every estimator", (200, 4000), count);
}

fn ca_filters_allocate_nothing_per_step() {
    // rkf-ca and garkf (decoupled axes, covariances shared by classes of runs that split at
    // lost links, and per run after a geometric observation) under random link losses, and
    // under departures, with the metric edge's PCRB.
    let pool = started_pool(1);
    for faults in [
        "availability = 0.6",
        "random_departures = { share = 0.25, at = 1.0 }",
    ] {
        ca_filters_allocate_nothing_per_step_with(&pool, faults);
    }
}

/// The CA filters' study on the thesis hexagon: `steps` steps reporting 3 of them, 5 runs, the
/// CA filters and `more` estimators, then the sections `tail` (faults, metrics, a sweep).
fn ca_scenario(steps: usize, more: &str, tail: &str) -> edgekf::scenario::Scenario {
    let text = format!(
        r#"
name = "ca-alloc"
estimators = ["none", "rkf-ca", "garkf", {{ kind = "garkf", label = "translation", ral = "translation" }},
  {{ kind = "rkf-ca", label = "rkf-ca-adaptive", adaptive = "both" }},
  {{ kind = "garkf", label = "garkf-adaptive", adaptive = true }}{more}]
[framework]
preset = "hexagon"
[sim]
dt = 0.01
steps = {steps}
runs = 5
every = {every}
# A seed whose departures keep the formation (a follower among 5, 7, 9 of the hexagon
# leaving breaks its stress's equilibrium, and the run diverges).
seed = 10
{tail}
"#,
        every = steps / 2
    );
    let spec = edgekf_io::spec_from_toml(&text).unwrap();
    edgekf::scenario::Scenario::from_spec(&spec, None).unwrap()
}

fn ca_filters_allocate_nothing_per_step_with(pool: &rayon::ThreadPool, faults: &str) {
    let tail = format!("[faults]\n{faults}\n[metrics]\nedge = [1, 0]");
    let count = |steps: usize| allocations(pool, &ca_scenario(steps, "", &tail));
    // A first run initialises a process-wide cache once (one allocation); not counted.
    count(200);
    same_allocations(faults, (200, 2000), count);
}

/// A sweep over the share of departing agents steps its values together until the departures
/// and each from a copy of the whole state after them (`sim::fork`): copying allocates once, the
/// copies' steps nothing (a copy must keep the room its buffers reserved).
fn forked_sweep_values_allocate_nothing_per_step() {
    let pool = started_pool(1);
    let tail = r#"[faults]
random_departures = { share = 0.25, at = 1.0 }
[metrics]
edge = [1, 0]
[sweep]
parameter = "faults.random_departures.share"
values = [0.0, 0.25]"#;
    let count = |steps: usize| {
        let sc = ca_scenario(steps, r#", "rkf", "jrkf", "mle""#, tail);
        pool.install(|| {
            let before = ALLOCS.load(Ordering::SeqCst);
            let res = edgekf::sim::sweep::run(&sc, &edgekf::sim::Quiet).unwrap();
            let after = ALLOCS.load(Ordering::SeqCst);
            for p in &res.points {
                for e in &p.results.estimators {
                    assert_eq!(e.outcome, edgekf::sim::Outcome::Completed, "{}", e.label);
                }
            }
            after - before
        })
    };
    count(200);
    same_allocations("forked sweep", (200, 2000), count);
}

/// Asserts that a study of `short` steps allocates as often as one of `long` steps (`count`
/// runs one of the given length and returns its allocations): nothing per step.
fn same_allocations(what: &str, (short, long): (usize, usize), count: impl Fn(usize) -> usize) {
    let (a, b) = (count(short), count(long));
    assert_eq!(
        a, b,
        "{what}: allocations: {a} for {short} steps, {b} for {long} steps"
    );
}
