//! Long runs, reduced size (issue 9 point 6): every filter's covariance stays symmetric positive
//! semidefinite over 10⁵ steps, with and without faults (availability 0.5), checked every 100
//! steps through the filters' public covariance accessors. `cargo bench -p edgekf --bench
//! long_run_psd` runs 10⁷ steps.

mod long_run;

use long_run::{judge, long_run};

const STEPS: usize = 100_000;

#[test]
fn covariances_stay_symmetric_psd_over_1e5_steps() {
    let lr = long_run(STEPS, 1, 100, false);
    let (report, failures) = judge(&lr, STEPS);
    println!("{report}");
    assert!(failures.is_empty(), "{failures:?}\n{report}");
}

#[test]
fn covariances_stay_symmetric_psd_over_1e5_steps_with_faults() {
    let lr = long_run(STEPS, 1, 100, true);
    let (report, failures) = judge(&lr, STEPS);
    println!("{report}");
    assert!(failures.is_empty(), "{failures:?}\n{report}");
}
