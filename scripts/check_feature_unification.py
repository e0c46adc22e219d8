#!/usr/bin/env python3
"""Check that CI's later test builds reuse what `cargo test` compiled.

Cargo unifies a dependency's features over the packages one command selects. The swarm's
and Clarabel's test commands and the Python extension's build select other packages and
features than `cargo test`, so a
dependency we share with Zenoh or Clarabel can get another feature set there, and then it and
everything above it (nalgebra, our crates) compile a second time. `crates/workspace-hack`
lists the union of those feature sets; this script compares, with `cargo tree`, the
(target-side) feature set of every shared dependency in each later build with the one in
`cargo test`'s, and names every difference (exit 1) so the list can be brought up to date.
"""
import subprocess
import sys

# The builds of .ci/run after `cargo test`, as `cargo tree` arguments.
LATER = {
    "swarm tests": ["-p", "edgekf-swarm", "-p", "edgekf-cli", "--features", "edgekf-cli/swarm"],
    "clarabel tests": ["-p", "edgekf", "--features", "clarabel"],
    "Python extension": ["-p", "edgekf-python", "--features", "workspace-hack"],
}


def features(args):
    """Package (name and version) -> its feature set, on the target side only (no build
    scripts' or proc-macros' dependencies: those compile for the host, apart)."""
    cmd = ["cargo", "tree", "-q", "--locked", "-e", "normal,dev,no-proc-macro", "--prefix", "none",
           "--no-dedupe", "-f", "{p}|{f}", *args]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"error: `{' '.join(cmd)}` failed:\n{run.stderr}")
    out = run.stdout
    seen = {}
    for line in out.splitlines():
        if "|" not in line:
            continue
        pkg, feats = line.split("|", 1)
        name, version = pkg.split()[:2]
        if " (" in pkg and "registry" not in pkg:  # a workspace member: compiles apart anyway
            continue
        seen.setdefault(f"{name} {version}", set()).add(feats.replace(" (*)", "").strip())
    return seen


def main():
    base = features([])
    stale = []
    for build, args in LATER.items():
        for pkg, sets in sorted(features(args).items()):
            if pkg in base and sets != base[pkg]:
                stale.append(f"  {pkg}: `cargo test` {sorted(base[pkg])}, {build} {sorted(sets)}")
    if stale:
        print("error: these dependencies compile twice in CI (crates/workspace-hack/Cargo.toml "
              "should list the union of their features):", *stale, sep="\n", file=sys.stderr)
        return 1
    print(f"feature unification: every shared dependency has one feature set ({len(base)} packages)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
