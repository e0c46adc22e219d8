//! Long runs at full size (issue 9 point 6): every filter's covariance stays symmetric positive
//! semidefinite over 10⁷ steps (`LONG_STEPS`), with and without faults (availability 0.5),
//! checked every 1000 steps (`LONG_EVERY`). Prints what was seen; exits non-zero on a failure.
//!
//! `nice -n 10 cargo bench -p edgekf --bench long_run_psd`

#[path = "../tests/long_run/mod.rs"]
mod long_run;

use std::time::Instant;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let steps = env("LONG_STEPS", 10_000_000);
    let every = env("LONG_EVERY", 1000);
    let mut failed = false;
    for faults in [false, true] {
        let t = Instant::now();
        let lr = long_run::long_run(steps, 1, every, faults);
        let (report, failures) = long_run::judge(&lr, steps);
        println!(
            "{steps} steps, {}: {:.1?}",
            if faults {
                "availability 0.5"
            } else {
                "no faults"
            },
            t.elapsed()
        );
        print!("{report}");
        for f in &failures {
            println!("FAILED {f}");
        }
        failed |= !failures.is_empty();
    }
    if failed {
        std::process::exit(1);
    }
}
