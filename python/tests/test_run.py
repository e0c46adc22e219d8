"""edgekf.run, Result, save: the numbers and files of the CLI."""

import json
import subprocess

import numpy as np
import pytest

import edgekf
from conftest import ROOT, SMALL


def test_run_result_api(small):
    res = edgekf.run(small, runs=4, steps=200, seed=3, threads=2)
    assert res.estimators == ["none", "mle", "rkf", "jrkf", "crkf"]
    assert "est_error" in res.metrics and "cov_trace" in res.metrics
    assert res.runs == 4
    sc = res.scenario
    assert sc["schema"] == "edgekf.scenario/1"
    assert (sc["runs"], sc["steps"], sc["seed"]) == (4, 200, 3)
    t, mean, std = res.metric("rkf", "est_error")
    for a in (t, mean, std):
        assert isinstance(a, np.ndarray) and a.dtype == np.float64
    assert len(t) == len(mean) == len(std) == len(res.steps)
    np.testing.assert_allclose(t, res.steps * res.dt, rtol=0, atol=1e-12)
    assert np.all(std >= 0) and np.all(np.isfinite(mean))
    # The RKF beats the raw measurement at the end (EUSIPCO Fig. 4b).
    assert mean[-1] < res.metric("none", "est_error")[1][-1]
    p = res.paths("rkf")
    n, d = len(sc["config"]), sc["dim"]
    assert p.ndim == 3 and p.shape[1:] == (n, d) and p.shape[0] >= 1
    assert res.status("rkf")["status"] == "completed"


def test_same_seed_same_bits_and_threads_do_not_matter(small):
    a = edgekf.run(small, runs=3, steps=100, seed=11, threads=1)
    b = edgekf.run(small, runs=3, steps=100, seed=11, threads=2)
    c = edgekf.run(small, runs=3, steps=100, seed=12, threads=2)
    assert a.metrics_csv() == b.metrics_csv()
    assert a.metrics_csv() != c.metrics_csv()


def test_dict_equals_file(small):
    import tomllib

    spec = tomllib.loads(SMALL)
    a = edgekf.run(spec, runs=2, steps=50)
    b = edgekf.run(small, runs=2, steps=50)
    assert a.metrics_csv() == b.metrics_csv()
    # A resolved scenario as a dict reproduces too (the round trip of docs/formats.md).
    c = edgekf.run(b.scenario)
    assert c.metrics_csv() == b.metrics_csv()


def test_save_is_byte_identical_to_cli(small, tmp_path, cli):
    res = edgekf.run(small, runs=5, steps=250, seed=9, threads=2)
    py_dir = tmp_path / "py"
    res.save(py_dir)
    cli_dir = tmp_path / "cli"
    subprocess.run(
        [cli, "run", str(small), "--out", str(cli_dir), "--runs", "5", "--steps", "250",
         "--seed", "9", "--threads", "1"],
        check=True, capture_output=True,
    )
    for name in ("metrics.csv", "scenario.json", "status.csv", "paths.csv"):
        assert (py_dir / name).read_bytes() == (cli_dir / name).read_bytes(), name
    # And the CLI accepts the Python-written resolved scenario, giving the same metrics.
    again = tmp_path / "again"
    subprocess.run([cli, "run", str(py_dir / "scenario.json"), "--out", str(again)],
                   check=True, capture_output=True)
    assert (again / "metrics.csv").read_bytes() == (py_dir / "metrics.csv").read_bytes()


def test_to_pandas_matches_csv(small):
    pd = pytest.importorskip("pandas")
    import io

    res = edgekf.run(small, runs=3, steps=100)
    df = res.to_pandas()
    ref = pd.read_csv(io.StringIO(res.metrics_csv()))
    assert list(df.columns) == list(ref.columns)
    assert len(df) == len(ref)
    np.testing.assert_array_equal(df["mean"].to_numpy(), ref["mean"].to_numpy())


def test_bad_input_messages(tmp_path, small, cli):
    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL.replace('sigma_v = 0.1', 'sigma_v = -0.1'))
    with pytest.raises(ValueError) as py_err:
        edgekf.run(bad)
    out = subprocess.run([cli, "run", str(bad), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True)
    assert out.returncode != 0
    cli_msg = out.stderr.strip().removeprefix("edgekf: error: ")
    assert str(py_err.value) == cli_msg
    assert "sigma_v" in str(py_err.value)

    typo = tmp_path / "typo.toml"
    typo.write_text(SMALL.replace("samples_per_step", "samples_per_stp"))
    with pytest.raises(ValueError, match="samples_per_stp"):
        edgekf.run(typo)
    with pytest.raises(ValueError, match="unknown field"):
        edgekf.run({"name": "x", "bogus": 1})
    with pytest.raises(FileNotFoundError, match="cannot read"):
        edgekf.run(tmp_path / "missing.toml")
    with pytest.raises(ValueError, match=r"^runs: must be a whole number in 1\.\."):
        edgekf.run(small, runs=0)
    with pytest.raises(TypeError):
        edgekf.run(42)
    with pytest.raises(ValueError, match="SLAM"):
        edgekf.run(ROOT / "scenarios" / "slam-fig3.toml")
    with pytest.raises(ValueError, match="SLAM"):
        edgekf.reproduce("slam-fig3")
    res = edgekf.run(small, runs=2, steps=20)
    with pytest.raises(ValueError, match="unknown estimator"):
        res.metric("kf", "est_error")
    with pytest.raises(ValueError, match="no metric"):
        res.metric("rkf", "nope")


def test_resolve_and_reproductions():
    names = [r["name"] for r in edgekf.list_reproductions()]
    assert "eusipco-fig4b" in names
    res = edgekf.reproduce("eusipco-fig4b", runs=2, steps=60, threads=1)
    assert res.scenario["name"] == "eusipco"
    t, m, s = res.metric("crkf", "cov_trace")
    assert len(t) > 0 and np.all(np.diff(t) > 0)
    with pytest.raises(ValueError, match="unknown figure"):
        edgekf.reproduce("nope-fig1")
    with pytest.raises(ValueError, match="unknown override"):
        edgekf.reproduce("eusipco-fig4b", run=2)
    sc = edgekf.resolve(ROOT / "scenarios" / "eusipco.toml")
    assert sc["runs"] == 50 and len(sc["edges"]) == 60


def test_ctrl_c_stops_a_long_run(small, tmp_path):
    """SIGINT during a long run raises KeyboardInterrupt promptly, in a child interpreter.

    No fixed sleep: the signal is sent once the run reports progress on stderr (so it lands in
    the simulation, not in the interpreter's start), and the child must end within 2 s of it.
    """
    import sys
    import time

    code = f"""
import edgekf, time, sys
t = time.time()
try:
    edgekf.run({str(small)!r}, runs=8, steps=5_000_000, every=5000, threads=1, progress=True)
except KeyboardInterrupt:
    print("interrupted", round(time.time() - t, 2))
    sys.exit(0)
print("finished")
"""
    p = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        # The progress line is "\rsmall:   0.1 %": wait for its first "%" (or the child's end).
        seen = ""
        deadline = time.monotonic() + 120
        while "%" not in seen:
            ch = p.stderr.read(1)
            assert ch, f"the child ended before reporting progress: {seen!r}"
            seen += ch
            assert time.monotonic() < deadline, seen
        sent = time.monotonic()
        p.send_signal(2)
        out, _ = p.communicate(timeout=30)
        assert time.monotonic() - sent < 2.0
    finally:
        p.kill()
    assert out.startswith("interrupted"), out


def test_gil_is_released_during_a_run(small):
    """Python threads keep running while a run is under way in another thread."""
    import threading
    import time

    box = {}

    def work():
        box["res"] = edgekf.run(small, runs=2, steps=40_000, every=1000, threads=1)

    t = threading.Thread(target=work)
    start = time.perf_counter()
    t.start()
    ticks = 0
    while t.is_alive():
        ticks += 1
        time.sleep(0.001)
    elapsed = time.perf_counter() - start
    assert elapsed > 0.2, "the run was too short to tell"
    # With the GIL held for the whole run the loop would tick once or twice.
    assert ticks > 50, (ticks, elapsed)
    assert box["res"].status("crkf")["status"] == "completed"


def test_progress_prints_to_stderr(small, capfd):
    edgekf.run(small, runs=2, steps=100, progress=True)
    err = capfd.readouterr().err
    assert "small" in err and "done" in err
