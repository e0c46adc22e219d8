"""What the package is given is checked where it is given, with the CLI's standards, and the
errors name the argument: the filter's covariances at construction, counts and seeds by name,
NumPy scalars taken where Python numbers are, files and folders as OSError subclasses, and
output folders that never mix two studies."""

import json

import numpy as np
import pytest

import edgekf
from conftest import SMALL


def test_the_filter_refuses_what_no_filter_can_use_at_construction():
    I = np.eye(2)
    ok = dict(R=1e-2 * I, Q=1e-4 * I, x0=np.zeros(2), P0=I)

    def build(**kw):
        return edgekf.EdgeFilter("rkf", **{**ok, **kw})

    build()
    # The cases: Q = -I gave P = 0 after a step; P0 = -0.001 I kept P negative; a
    # non-symmetric P0 or R = -I failed only at step() as "P + R is not positive definite".
    with pytest.raises(ValueError, match=r"^Q: must be symmetric positive semidefinite.*-1"):
        build(Q=-I)
    with pytest.raises(ValueError, match=r"^P0: must be symmetric positive semidefinite"):
        build(P0=-0.001 * I)
    with pytest.raises(ValueError, match=r"^P0: must be symmetric, but entry \(1, 0\)"):
        build(P0=np.array([[1.0, 0.5], [0.0, 1.0]]))
    with pytest.raises(ValueError, match=r"^R: must be symmetric positive definite"):
        build(R=-I)
    # R singular: the update would invert P + R with P → 0; refused (PD is needed).
    with pytest.raises(ValueError, match=r"^R: must be symmetric positive definite"):
        build(R=np.zeros((2, 2)))
    # Q = 0 and P0 = 0 are valid (no process noise; a known start).
    build(Q=0.0, P0=0.0)
    with pytest.raises(ValueError, match=r"^Q: entry 3 is not finite"):
        build(Q=np.array([[1.0, 0.0], [0.0, np.nan]]))
    with pytest.raises(ValueError, match=r"^R: expected shape \(2, 2\)"):
        build(R=np.eye(3))
    # In a batch, the edge is named.
    Q = np.broadcast_to(I, (50, 2, 2)).copy()
    Q[17] = [[1.0, 2.0], [2.0, 1.0]]  # symmetric, eigenvalues 3 and -1
    with pytest.raises(ValueError, match=r"^Q of edge 17: must be symmetric positive semidefinite"):
        edgekf.EdgeFilter("rkf", R=I, Q=Q, x0=np.zeros((50, 2)), P0=I)
    # The CA filter too.
    with pytest.raises(ValueError, match=r"^P0: must be symmetric, but"):
        P0 = np.eye(6)
        P0[0, 5] = 0.3
        edgekf.EdgeFilter("rkf-ca", R=1e-3, x0=np.zeros((3, 2)), P0=P0, dt=0.01)


def test_the_filter_takes_numpy_scalars_and_still_steps():
    f = edgekf.EdgeFilter(
        "rkf", R=np.float64(0.01), Q=np.float32(1e-4), x0=np.zeros(2), P0=np.int64(1)
    )
    x, P = f.step(np.zeros(2), np.ones(2))
    assert np.all(np.linalg.eigvalsh(P) > 0) and x.shape == (2,)
    ca = edgekf.EdgeFilter(
        "rkf-ca", R=np.float64(1e-3), x0=np.zeros((3, 2)), P0=np.eye(6), dt=np.float64(0.01),
        sigma_w=np.float32(0.1),
    )
    ca.step(None, np.ones(2))


def test_counts_and_seeds_are_checked_by_name(small):
    for name in ("runs", "steps", "every", "threads"):
        with pytest.raises(ValueError, match=rf"^{name}: must be a whole number in 1\.\.="):
            edgekf.run(small, **{name: -1})
        with pytest.raises(ValueError, match=rf"^{name}: "):
            edgekf.run(small, **{name: 0})
        with pytest.raises(TypeError, match=rf"^{name}: expected a whole number"):
            edgekf.run(small, **{name: 2.5})
    with pytest.raises(ValueError, match=r"^seed: must be a whole number in 0\.\.=2\^64 - 1, got -1"):
        edgekf.run(small, seed=-1)
    with pytest.raises(ValueError, match=r"^seed: "):
        edgekf.run(small, seed=2**64)
    with pytest.raises(ValueError, match=r"^runs: "):
        edgekf.reproduce("eusipco-fig4b", runs=-1)
    # NumPy integers are whole numbers.
    a = edgekf.run(small, runs=np.int64(2), steps=np.int32(50), seed=np.uint64(3))
    b = edgekf.run(small, runs=2, steps=50, seed=3)
    assert a.metrics_csv() == b.metrics_csv()


def test_a_dict_scenario_takes_numpy_scalars_and_arrays():
    import tomllib

    spec = tomllib.loads(SMALL)
    plain = edgekf.run(spec, runs=2, steps=50)
    spec["sim"]["dt"] = np.float64(spec["sim"]["dt"])
    spec["sim"]["seed"] = np.int64(spec["sim"]["seed"])
    spec["noise"]["sigma_v"] = np.float64(0.1)
    spec["init"] = {"mean": np.zeros(2), "cov": np.eye(2)}
    numpyish = edgekf.run(spec, runs=2, steps=50)
    assert numpyish.metrics_csv() == plain.metrics_csv()


def test_missing_files_and_unwritable_folders_are_os_errors(tmp_path, small):
    with pytest.raises(FileNotFoundError, match="missing.toml"):
        edgekf.run(tmp_path / "missing.toml")
    with pytest.raises(FileNotFoundError):
        edgekf.resolve(tmp_path / "missing.toml")
    # A framework file that is not there: FileNotFoundError too, naming it.
    sc = tmp_path / "fw.toml"
    sc.write_text(SMALL.replace('preset = "hexagon"', 'file = "nowhere.json"'))
    with pytest.raises(FileNotFoundError, match="nowhere.json"):
        edgekf.run(sc)
    res = edgekf.run(small, runs=2, steps=30)
    # A folder under a file cannot be made (root can write anywhere else).
    (tmp_path / "plain.txt").write_text("x")
    with pytest.raises(OSError) as e:
        res.save(tmp_path / "plain.txt" / "out", figures=False)
    assert not isinstance(e.value, FileExistsError)


def test_save_never_mixes_two_studies(tmp_path, small):
    res = edgekf.run(small, runs=2, steps=30)
    out = tmp_path / "out"
    res.save(out, figures=False)
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["kind"] == "study" and prov["name"] == "small"
    assert sorted(p.name for p in out.iterdir()) == prov["files"]
    # The same study again: fine.
    res.save(out, figures=False)
    # Another study: refused by name; force=True replaces the folder's contents.
    other = tmp_path / "other.toml"
    other.write_text(SMALL.replace('name = "small"', 'name = "other"'))
    res2 = edgekf.run(other, runs=2, steps=30)
    with pytest.raises(FileExistsError, match="`small`.*`other`.*force=True"):
        res2.save(out, figures=False)
    res2.save(out, figures=False, force=True)
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["name"] == "other"
    assert sorted(p.name for p in out.iterdir()) == prov["files"]


def test_a_study_or_design_past_the_limits_is_refused_before_it_starts(small):
    import time

    t = time.monotonic()
    with pytest.raises(ValueError, match=r"^small: this study would take about .*max_hours, default 1 h"):
        edgekf.run(small, steps=4_000_000_000, every=4_000_000_000, runs=50)
    with pytest.raises(ValueError, match=r"max_hours"):
        edgekf.reproduce("eusipco-fig4b", steps=4_000_000_000, every=4_000_000_000)
    with pytest.raises(ValueError, match=r"^max_hours: must be a number of hours > 0"):
        edgekf.run(small, runs=2, steps=10, max_hours=0)
    # 3 000 agents: the dense checks alone (O(N³)) are past a tiny limit.
    n = 3000
    config = np.random.default_rng(1).random((n, 2)) * 50
    edges = np.array([(i, j) for i in range(n) for j in range(i + 1, min(n, i + 4))])
    with pytest.raises(ValueError, match=r"^the design of .*max_hours"):
        edgekf.design(config, edges, method="sparse", max_hours=1e-6)
    assert time.monotonic() - t < 10
