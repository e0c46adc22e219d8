"""Frames from Python and Rerun recordings (`Result.frames`, `Result.to_rerun`).

The recording is checked by Rerun's own command-line program (`rerun rrd verify`, `rerun rrd
print`, from the rerun-sdk wheel). Without rerun-sdk these tests skip, unless
EDGEKF_REQUIRE_RERUN=1 (CI sets it: there a missing package is a failure, not a skip).
"""

import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import edgekf
from edgekf import _rerun

ROOT = Path(__file__).resolve().parents[2]


def _need_rerun():
    if os.environ.get("EDGEKF_REQUIRE_RERUN") == "1":
        import rerun  # noqa: F401  (an ImportError fails the test)
    else:
        pytest.importorskip("rerun")


def _rerun_cli(*args):
    exe = Path(sys.executable).parent / "rerun"
    env = dict(os.environ, CI="1")  # no analytics prompt
    out = subprocess.run(
        [str(exe), *args], capture_output=True, text=True, env=env, timeout=120, check=True
    )
    return out.stdout + out.stderr


@pytest.fixture(scope="module")
def fig12():
    # Li & Rajan S3 (an agent departs at 15 s) with GA-RKF and the RKF: links are lost and an
    # agent leaves within the recorded frames.
    return edgekf.run(ROOT / "scenarios" / "garkf-fig12.toml", runs=3, seed=5)


def test_frames_match_the_paths_and_are_covariances(fig12):
    steps = fig12.frame_steps
    assert len(steps) >= 24 and steps[0] == 1 and steps[-1] == fig12.steps[-1]
    edges = fig12.edges
    for est in fig12.estimators:
        runs = fig12.frames(est)
        assert [r["run"] for r in runs] == [0, 1, 2]
        fr = runs[0]
        f, n, d = fr["positions"].shape
        assert fr["estimates"].shape == (f, len(edges), d)
        assert fr["covariances"].shape == (f, len(edges), d, d)
        # Run 0 is the paths run: its positions at the frames are paths() at those steps.
        at = np.searchsorted(fig12.steps, steps[:f])
        np.testing.assert_array_equal(fr["positions"], fig12.paths(est)[at])
        cov = fr["covariances"]
        has = np.isfinite(cov).all(axis=(2, 3))
        np.testing.assert_array_equal(cov[has], np.swapaxes(cov, 2, 3)[has])
        assert (np.linalg.eigvalsh(cov[has]) > -1e-12).all()
    # The departure and the lost links are in the frames.
    g = fig12.frames("GA-RKF")[0]
    assert g["present"][0].all() and not g["present"][-1].all()
    assert not g["observed"].all()


def test_ellipse_loops_lie_on_the_one_sigma_contour():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 2, 2))
    covs = a @ np.swapaxes(a, 1, 2) + 0.01 * np.eye(2)
    centers = rng.normal(size=(5, 2))
    loops = _rerun.ellipse_loops(centers, covs)
    x = loops - centers[:, None, :]
    q = np.einsum("kpd,kde,kpe->kp", x, np.linalg.inv(covs), x)
    np.testing.assert_allclose(q, 1.0, atol=1e-10)


def test_ellipsoids_rebuild_the_covariance():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(6, 3, 3))
    covs = a @ np.swapaxes(a, 1, 2)
    sizes, quats = _rerun.ellipsoids(covs)
    for p, h, (x, y, z, w) in zip(covs, sizes, quats):
        r = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        np.testing.assert_allclose(r @ np.diag(h**2) @ r.T, p, atol=1e-10)


def _rows(printout):
    """Rows per entity path in `rerun rrd print` output."""
    rows = Counter()
    for m in re.finditer(r"with (\d+) rows \([^)]*\) - (/(?:\\.|\S)+)", printout):
        rows[m.group(2)] += int(m.group(1))
    return rows


def test_recording_verifies_and_holds_every_frame_and_metric(fig12, tmp_path):
    _need_rerun()
    path = tmp_path / "fig12.rrd"
    fig12.to_rerun(path)
    assert "1 file verified without error" in _rerun_cli("rrd", "verify", str(path))
    rows = _rows(_rerun_cli("rrd", "print", str(path)))
    frames = len(fig12.frame_steps)
    from rerun import escape_entity_path_part as part_of

    for label in fig12.estimators:
        est = part_of(label)
        for run_ in (0, 1, 2):
            f = next(r for r in fig12.frames(label) if r["run"] == run_)["positions"].shape[0]
            for part in ("agents", "links", "lost_links", "estimates", "uncertainty"):
                assert rows[f"/runs/{run_}/{est}/{part}"] == f, (est, run_, part)
        t, mean, _ = fig12.metric(label, "tracking_error")
        assert rows[f"/metrics/tracking_error/{est}"] == np.isfinite(mean).sum()
    assert rows["/target"] == frames
    # Lost links and the departed agent: a lost link is drawn in some frame of GA-RKF's run.
    out = _rerun_cli("rrd", "print", "-vvv", str(path))
    assert "/runs/0/GA-RKF/lost_links" in out


def test_selection_and_errors(fig12, tmp_path):
    _need_rerun()
    path = tmp_path / "one.rrd"
    fig12.to_rerun(path, estimators=["GA-RKF"], runs=[1])
    rows = _rows(_rerun_cli("rrd", "print", str(path)))
    assert rows["/runs/1/GA-RKF/agents"] > 0
    assert not any(p.startswith("/runs/0/") or "/RKF/" in p for p in rows)
    with pytest.raises(ValueError, match="unknown estimator 'bogus'"):
        fig12.to_rerun(tmp_path / "bad.rrd", estimators=["bogus"])
    with pytest.raises(ValueError, match="not recorded"):
        fig12.to_rerun(tmp_path / "bad.rrd", runs=[7])
    assert not (tmp_path / "bad.rrd").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["one.rrd"]


def test_without_rerun_sdk_the_error_says_what_to_install(fig12, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)
    with pytest.raises(ImportError, match=r"pip install 'edgekf\[rerun\]'"):
        fig12.to_rerun(tmp_path / "x.rrd")
