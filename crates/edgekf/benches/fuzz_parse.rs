//! Parser/checker fuzz at full size (issue 9 point 6): 10⁶ mutated inputs (override with
//! `FUZZ_CASES`), on `FUZZ_THREADS` threads (default 2). Prints the counts; exits non-zero on a
//! defect.
//!
//! `nice -n 10 cargo bench -p edgekf --bench fuzz_parse`

#[path = "../tests/fuzz_common/mod.rs"]
mod fuzz_common;

use std::time::Instant;

const BASE: u64 = 0x6564_6765_6b66;

fn env(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else to parse.
    let cases = env("FUZZ_CASES", 1_000_000);
    let threads = env("FUZZ_THREADS", 2);
    let (m, roles) = fuzz_common::corpus(BASE);
    println!(
        "parser fuzz: {} seeds, {cases} cases on {threads} threads",
        m.seeds().len()
    );
    let t = Instant::now();
    let st = fuzz_common::run_parallel(&m, &roles, cases, threads);
    print!("{}", st.report());
    println!("wall time {:.1?}", t.elapsed());
    if st.defect_count() > 0 {
        std::process::exit(1);
    }
}
