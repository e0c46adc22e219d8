//! Whole-program fuzz at full size (issue 16 point 3): 10⁵ mutated inputs through the `edgekf`
//! binary (override with `FUZZ_CASES`; `FUZZ_WORKERS` concurrent binaries, default 4; the limit
//! per case `FUZZ_LIMIT_S`, default 10 s). Prints the counts; failing cases are kept with their
//! input, flags and stderr under `FUZZ_KEEP` (default `target/fuzz-cli-defects`). Exits non-zero
//! on a defect.
//!
//! `nice -n 10 cargo bench -p edgekf-cli --bench fuzz_cli`

#[path = "../tests/whole_program/mod.rs"]
mod whole_program;

use std::path::PathBuf;
use std::time::{Duration, Instant};

const BASE: u64 = 0x6564_6765_6b66;

fn env(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let cases = env("FUZZ_CASES", 100_000);
    let work = std::env::temp_dir().join(format!("edgekf-fuzz-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("scratch directory");
    let keep = std::env::var("FUZZ_KEEP")
        .map(PathBuf::from)
        .unwrap_or_else(|_| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fuzz-cli-defects")
        });
    let s = whole_program::Settings {
        limit: Duration::from_secs(env("FUZZ_LIMIT_S", 10)),
        max_hours: 1e-4,
        workers: env("FUZZ_WORKERS", 4) as usize,
        keep: keep.clone(),
        work: work.clone(),
    };
    let (m, roles) = whole_program::corpus(BASE, &work);
    println!(
        "whole-program fuzz: {} seeds, {cases} cases, {} workers, {:?} per case, binary {}",
        m.seeds().len(),
        s.workers,
        s.limit,
        whole_program::BIN
    );
    let t = Instant::now();
    let st = whole_program::run(&m, &roles, cases, &s);
    print!("{}", st.report());
    println!(
        "wall time {:.1?}; reproducers in {}",
        t.elapsed(),
        keep.display()
    );
    let _ = std::fs::remove_dir_all(&work);
    if st.defect_count() > 0 {
        std::process::exit(1);
    }
}
