"""Shared fixtures: the repository root, a small scenario, and the CLI binary for comparisons."""

import os
import pathlib
import signal
import subprocess

import pytest

# The Ctrl-C tests send SIGINT to child interpreters, as a terminal does. A shell script that
# starts a job in the background (`… &` without job control, as a CI harness may) starts it with
# SIGINT *ignored*, and an ignored signal stays ignored across exec: every child would then ignore
# Ctrl-C and those tests would fail for the harness's sake. Give the children a terminal's
# disposition: a handler here is reset to the default in each child at exec.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

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
