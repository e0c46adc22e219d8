#!/usr/bin/env python3
"""Check that every host-only dependency compiles unoptimised in `dev` and `test`.

Proc macros, build scripts and the crates only they use (syn, quote, darling, serde_derive,
cc, …) run at compile time. Cargo's own default compiles them at opt-level 0
(`build-override`), but the root `Cargo.toml` optimises every dependency in `dev` and `test`
(`[profile.dev.package."*"] opt-level = 2`, for the engine's speed), and a `"*"` override
takes precedence over `build-override`. So each host-only crate is named in the root
`Cargo.toml` with `opt-level = 0`: CI's clippy build took 5 min 41 s with them optimised and
2 min 50 s without (docs/build-times.md). This script finds the host-only crates of every CI
build with `cargo tree` (all crates, less those compiled for the target) and names any that
`Cargo.toml` does not list (exit 1); `--print` prints their block to paste instead.
"""
import re
import subprocess
import sys

# Every package and opt-in feature CI builds (.ci/run's clippy command).
ARGS = ["--workspace", "--features", "edgekf/clarabel,edgekf-cli/swarm"]


def names(edges):
    cmd = ["cargo", "tree", "-q", "--locked", "-e", edges, "--prefix", "none", "-f", "{p}", *ARGS]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"error: `{' '.join(cmd)}` failed:\n{run.stderr}")
    return {line.split()[0] for line in run.stdout.splitlines() if line.strip()}


def host_only():
    """Crates reached only through build scripts and proc macros (by name: a crate with a
    version on each side, as `strsim`, is left optimised)."""
    return sorted(names("normal,build,dev") - names("normal,dev,no-proc-macro"))


def listed():
    text = open("Cargo.toml").read()
    return set(re.findall(r'^\[profile\.dev\.package\.([A-Za-z0-9_-]+)\]\nopt-level = 0$', text, re.M))


def main():
    crates = host_only()
    missing = [c for c in crates if c not in listed()]
    if "--print" in sys.argv:
        for c in missing:
            print(f"[profile.dev.package.{c}]\nopt-level = 0")
        return 0
    if missing:
        print("error: these host-only crates (proc macros, build scripts and their dependencies)"
              " compile optimised in dev and test; add each to the root Cargo.toml with"
              " `opt-level = 0` (`python3 scripts/check_host_crates.py --print` prints the"
              " block to paste):", *(f"  {c}" for c in missing), sep="\n", file=sys.stderr)
        return 1
    print(f"host-only crates: all {len(crates)} compile unoptimised in dev and test")
    return 0


if __name__ == "__main__":
    sys.exit(main())
