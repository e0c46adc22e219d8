"""Result.save writes exactly the CLI's files (figures and provenance too), sweeps run from
Python as from the CLI, and the constant-acceleration EdgeFilter (Li & Rajan eqs. 5–7)."""

import io
import json
import subprocess

import numpy as np
import pytest

import edgekf
from conftest import ROOT


def _files(d):
    return sorted(p.name for p in d.iterdir())


def test_save_writes_the_cli_files_figures_and_provenance(tmp_path, cli):
    sc = ROOT / "scenarios" / "thesis-fig4.5.toml"
    res = edgekf.run(sc, runs=3, steps=200, seed=4, threads=1)
    py_dir, cli_dir = tmp_path / "py", tmp_path / "cli"
    res.save(py_dir)
    subprocess.run(
        [cli, "run", str(sc), "--out", str(cli_dir), "--runs", "3", "--steps", "200",
         "--seed", "4", "--threads", "1"],
        check=True, capture_output=True,
    )
    assert _files(py_dir) == _files(cli_dir)
    pngs = [n for n in _files(cli_dir) if n.endswith(".png")]
    assert pngs, "the scenario has figures"
    # The same plotting code on the same numbers: the same image, byte for byte.
    for name in _files(cli_dir):
        if name != "provenance.json":
            assert (py_dir / name).read_bytes() == (cli_dir / name).read_bytes(), name
    prov_py = json.loads((py_dir / "provenance.json").read_text())
    prov_cli = json.loads((cli_dir / "provenance.json").read_text())
    for key in ("schema", "version"):
        assert prov_py[key] == prov_cli[key]
    assert "edgekf.run(" in prov_py["command"][-1] and "runs=3" in prov_py["command"][-1]
    # Without figures: the tables only.
    tables = tmp_path / "tables"
    res.save(tables, figures=False)
    assert not [n for n in _files(tables) if n.endswith(".png")]
    # The report page of a Python-written directory.
    subprocess.run([cli, "report", str(py_dir)], check=True, capture_output=True)
    assert (py_dir / "report.html").stat().st_size > 0


def test_a_sweep_runs_from_python_as_from_the_cli(tmp_path, cli):
    sc = ROOT / "scenarios" / "garkf-fig11.toml"
    args = dict(runs=2, steps=150, seed=3)
    res = edgekf.run(sc, threads=1, **args)
    assert res.sweep_parameter is not None
    summ = res.sweep_summary()
    assert len(summ["mean"]) == len(summ["estimator"]) > 0
    py_dir, cli_dir = tmp_path / "py", tmp_path / "cli"
    res.save(py_dir)
    subprocess.run(
        [cli, "run", str(sc), "--out", str(cli_dir), "--runs", "2", "--steps", "150",
         "--seed", "3", "--threads", "1"],
        check=True, capture_output=True,
    )
    assert _files(py_dir) == _files(cli_dir)
    for name in ("summary.csv", "sweep_metrics.csv", "metrics.csv"):
        assert (py_dir / name).read_bytes() == (cli_dir / name).read_bytes(), name
    # A scenario without a sweep has no summary.
    plain = edgekf.reproduce("eusipco-fig4b", runs=2, steps=50, threads=1)
    assert plain.sweep_parameter is None and plain.sweep_summary() is None


def test_to_pandas_leaves_out_undefined_values_like_metrics_csv():
    pd = pytest.importorskip("pandas")
    # GA-RKF's ψ is undefined until a geometric observation exists: NaN in metric(), no row
    # in metrics.csv, and none in the frame.
    res = edgekf.run(ROOT / "scenarios" / "garkf-fig9.toml", runs=2, steps=120, threads=1)
    df = res.to_pandas()
    ref = pd.read_csv(io.StringIO(res.metrics_csv()))
    assert len(df) == len(ref)
    assert not df["mean"].isna().any()
    np.testing.assert_array_equal(df["mean"].to_numpy(), ref["mean"].to_numpy())
    np.testing.assert_array_equal(df["step"].to_numpy(), ref["step"].to_numpy())


# --- kind "rkf-ca": Li & Rajan eqs. (5)–(7), intermittent observations --------------------


def _ca_numpy(dt, sigma_w, d):
    f = np.array([[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]])
    q = np.array([dt * dt / 2, dt, 1.0])
    F = np.kron(f, np.eye(d))
    Q = sigma_w**2 * np.kron(np.outer(q, q), np.eye(d))
    G = np.kron(np.array([[1.0, 0, 0]]), np.eye(d))
    return F, Q, G


def test_ca_filter_matches_a_numpy_kalman_filter_with_missing_observations():
    dt, sw, d, B = 0.01, 0.7, 2, 7
    rng = np.random.default_rng(3)
    F, Q, G = _ca_numpy(dt, sw, d)
    R = np.array([[2e-3, 5e-4], [5e-4, 1e-3]])
    x0 = rng.normal(size=(B, 3, d))
    P0 = np.eye(3 * d) * 0.5
    f = edgekf.EdgeFilter("rkf-ca", R=R, x0=x0, P0=P0, dt=dt, sigma_w=sw)
    xs = x0.reshape(B, 3 * d).copy()
    Ps = np.broadcast_to(P0, (B, 3 * d, 3 * d)).copy()
    for k in range(60):
        y = rng.normal(size=(B, d))
        obs = rng.random(B) < 0.6
        y[~obs] = np.nan  # a missing observation as a NaN row
        xr, Pr = f.step(None, y)
        for b in range(B):
            xs[b] = F @ xs[b]
            Ps[b] = F @ Ps[b] @ F.T + Q
            if obs[b]:
                S = G @ Ps[b] @ G.T + R
                K = Ps[b] @ G.T @ np.linalg.inv(S)
                xs[b] = xs[b] + K @ (y[b] - G @ xs[b])
                A = np.eye(3 * d) - K @ G
                Ps[b] = A @ Ps[b] @ A.T + K @ R @ K.T
        np.testing.assert_allclose(xr.reshape(B, 3 * d), xs, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(Pr, Ps, rtol=1e-9, atol=1e-13)
        assert np.allclose(Pr, Pr.transpose(0, 2, 1))
    # One edge: (3, D) in and out.
    one = edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=np.zeros((3, 1)), P0=1.0, dt=dt)
    x, P = one.step(None, np.array([0.3]))
    assert x.shape == (3, 1) and P.shape == (3, 3)
    x2, _ = one.predict()
    assert x2[0, 0] == pytest.approx(x[0, 0] + dt * x[1, 0] + dt * dt / 2 * x[2, 0])


def test_ca_filter_is_consistent_with_its_own_model():
    # Truths drawn from the CA model itself: the mean squared position error over the edges
    # equals the mean trace of the covariance's position block. The squared norm of a
    # Gaussian error e has variance 2 tr(P²) ≤ 2 tr(P)², so the ratio's relative SE over B
    # edges is at most sqrt(2 / B) (0.022 here); 4 SE. (Measured: 0.979.)
    dt, sw, d, B = 0.05, 2.0, 2, 4000
    rng = np.random.default_rng(8)
    F, Q, G = _ca_numpy(dt, sw, d)
    R = np.eye(d) * 1e-2
    P0 = np.eye(3 * d)
    truth = rng.multivariate_normal(np.zeros(3 * d), P0, size=B)
    f = edgekf.EdgeFilter("rkf-ca", R=R, x0=np.zeros((B, 3, d)), P0=P0, dt=dt, sigma_w=sw)
    Lq = np.linalg.cholesky(Q + 1e-18 * np.eye(3 * d))
    for k in range(40):
        truth = truth @ F.T + rng.normal(size=(B, 3 * d)) @ Lq.T
        obs = rng.random(B) < 0.5
        y = truth[:, :d] + rng.normal(size=(B, d)) * 0.1
        x, P = f.step(None, y, observed=obs)
    err2 = ((x.reshape(B, 3 * d)[:, :d] - truth[:, :d]) ** 2).sum(axis=1)
    tr = np.trace(P[:, :d, :d], axis1=1, axis2=2)
    ratio = err2.mean() / tr.mean()
    assert abs(ratio - 1) < 4 * np.sqrt(2 / B), ratio


def test_ca_filter_bad_input():
    x0 = np.zeros((4, 3, 2))
    with pytest.raises(ValueError, match="Q is set by dt and sigma_w"):
        edgekf.EdgeFilter("rkf-ca", R=1e-3, Q=1e-6, x0=x0, P0=1.0, dt=0.01)
    with pytest.raises(ValueError, match="dt .* is required"):
        edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=x0, P0=1.0)
    with pytest.raises(ValueError, match="sigma_w must be positive"):
        edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=x0, P0=1.0, dt=0.01, sigma_w=0.0)
    with pytest.raises(ValueError, match=r"x0: expected shape \(3, D\)"):
        edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=np.zeros((4, 2, 2)), P0=1.0, dt=0.01)
    with pytest.raises(ValueError, match="R: must be symmetric positive definite"):
        edgekf.EdgeFilter("rkf-ca", R=[[1.0, 0], [0, -1.0]], x0=x0, P0=1.0, dt=0.01)
    with pytest.raises(ValueError, match="P0: must be symmetric positive semidefinite"):
        edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=x0, P0=-np.eye(6), dt=0.01)
    with pytest.raises(ValueError, match="unknown kind"):
        edgekf.EdgeFilter("ekf", R=1e-3, x0=x0, P0=1.0)
    f = edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=x0, P0=1.0, dt=0.01)
    before = f.x, f.P
    y = np.ones((4, 2))
    y[2, 1] = np.inf
    with pytest.raises(ValueError, match="row 2 is observed but not finite"):
        f.step(None, y, observed=np.array([True, True, True, False]))
    # Refused before anything changed.
    np.testing.assert_array_equal(f.x, before[0])
    np.testing.assert_array_equal(f.P, before[1])
    with pytest.raises(ValueError, match="no input"):
        f.step(np.zeros((4, 2)), np.ones((4, 2)))
    with pytest.raises(ValueError, match="observed: expected booleans"):
        f.update(np.ones((4, 2)), observed=np.ones(4))
    rkf = edgekf.EdgeFilter(R=1e-3, Q=1e-6, x0=np.zeros(2), P0=1.0)
    with pytest.raises(ValueError, match="observes every edge"):
        rkf.update(np.ones(2), observed=True)
