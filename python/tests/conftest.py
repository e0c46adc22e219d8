"""Shared fixtures: the repository root, a small scenario, and the CLI binary for comparisons."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

SMALL = """
name = "small"
estimators = ["none", "mle", "rkf", "jrkf", "crkf"]

[framework]
preset = "hexagon"

[sim]
dt = 0.001
steps = 300
runs = 6
seed = 7
samples_per_step = 10
every = 10

[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
"""


@pytest.fixture
def small(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


@pytest.fixture(scope="session")
def cli():
    """The `edgekf` binary: $EDGEKF_CLI, else target/release/edgekf (built by
    `cargo build --release -p edgekf-cli`), else built here."""
    env = os.environ.get("EDGEKF_CLI")
    if env:
        return env
    exe = ROOT / "target" / "release" / "edgekf"
    if not exe.exists():
        subprocess.run(
            ["cargo", "build", "--release", "-q", "-p", "edgekf-cli"], cwd=ROOT, check=True
        )
    return str(exe)
