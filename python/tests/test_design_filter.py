"""edgekf.design, edgekf.check and edgekf.EdgeFilter."""

import numpy as np
import pytest

import edgekf

# The hexagon of the EUSIPCO paper: 6 outer + 4 inner... use a simple generic 2-D framework.
CONFIG = np.array([[0.0, 0.0], [2.0, 0.1], [1.1, 1.9], [-0.9, 1.6], [0.8, -1.7], [2.6, 1.5]])
EDGES = [[i, j] for i in range(6) for j in range(i + 1, 6)]  # complete graph


def test_design_then_check():
    doc = edgekf.design(CONFIG, EDGES, method="sdp")
    assert doc["schema"] == "edgekf.framework/1"
    assert doc["dim"] == 2 and len(doc["weights"]) == len(doc["edges"])
    rep = edgekf.check(doc["config"], doc["edges"], doc["weights"])
    assert rep["passed"] and rep["verdict"] == "passed"
    assert rep["rank"] == rep["expected_rank"] == 6 - 2 - 1
    assert rep["psd"] and rep["universally_rigid"]
    ev = np.array(rep["eigenvalues"])
    assert np.all(ev > -1e-9)
    auto = edgekf.design(CONFIG, EDGES, leaders="auto")
    assert len(auto["leaders"]) == 3


def test_check_flags_a_wrong_sign():
    doc = edgekf.design(CONFIG, EDGES)
    w = -np.array(doc["weights"])
    rep = edgekf.check(doc["config"], doc["edges"], w)
    assert not rep["passed"] and rep["verdict"] != "passed"


def test_design_bad_input():
    with pytest.raises(ValueError, match="unknown design method"):
        edgekf.design(CONFIG, EDGES, method="magic")
    with pytest.raises(ValueError):
        edgekf.design(CONFIG, [[0, 1], [1, 2]])  # a path is not universally rigid
    with pytest.raises(ValueError, match="weights"):
        edgekf.check(CONFIG, EDGES, [1.0])
    with pytest.raises(ValueError, match="edges"):
        edgekf.design(CONFIG, [[0, 1, 2]])


def numpy_rkf(x, P, Q, R, du, y):
    """The same filter (EUSIPCO eq. (5)) in NumPy, vectorised over the batch."""
    x = x + du
    P = P + Q
    S = P + R
    K = P @ np.linalg.inv(S)
    x = x + np.einsum("bij,bj->bi", K, y - x)
    A = np.eye(x.shape[1]) - K
    P = A @ P @ A.transpose(0, 2, 1) + K @ R @ K.transpose(0, 2, 1)
    P = 0.5 * (P + P.transpose(0, 2, 1))
    return x, P


def test_single_filter_matches_numpy():
    rng = np.random.default_rng(1)
    Q = np.eye(2) * 2e-6
    R = np.array([[1e-3, 3e-4], [3e-4, 1e-3]])
    f = edgekf.EdgeFilter("rkf", R=R, Q=Q, x0=np.zeros(2), P0=2 * np.eye(2))
    x, P = np.zeros((1, 2)), 2 * np.eye(2)[None]
    z = np.array([1.0, -0.5])
    for _ in range(200):
        du = rng.normal(size=2) * 1e-3
        z = z + du
        y = z + rng.multivariate_normal(np.zeros(2), R)
        xr, Pr = f.step(du, y)
        x, P = numpy_rkf(x, P, Q[None], R[None], du[None], y[None])
        np.testing.assert_allclose(xr, x[0], rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(Pr, P[0], rtol=1e-10, atol=1e-15)
    assert xr.shape == (2,) and Pr.shape == (2, 2)
    assert np.linalg.norm(xr - z) < 0.05
    xp, Pp = f.predict([0.0, 0.0])
    np.testing.assert_allclose(Pp, Pr + Q)
    xu, Pu = f.update(z)
    assert np.trace(Pu) < np.trace(Pp)


@pytest.mark.parametrize("d,B", [(1, 50), (2, 50), (3, 50), (2, 10_001), (3, 9_000)])
def test_batched_filter_matches_numpy(d, B):
    """Small batches run serially, large ones in parallel chunks: both equal NumPy."""
    rng = np.random.default_rng(d)
    A = rng.normal(size=(B, d, d))
    R = A @ A.transpose(0, 2, 1) * 1e-3 + np.eye(d) * 1e-4
    Q = np.eye(d) * 1e-6
    f = edgekf.EdgeFilter(R=R, Q=Q, x0=np.zeros((B, d)), P0=np.eye(d))
    x, P = np.zeros((B, d)), np.broadcast_to(np.eye(d), (B, d, d)).copy()
    for _ in range(20):
        du = rng.normal(size=(B, d)) * 1e-2
        y = rng.normal(size=(B, d))
        xr, Pr = f.step(du, y)
        x, P = numpy_rkf(x, P, Q[None], R, du, y)
    assert xr.shape == (B, d) and Pr.shape == (B, d, d)
    np.testing.assert_allclose(xr, x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Pr, P, rtol=1e-9, atol=1e-14)


def test_filter_bad_input_leaves_state():
    f = edgekf.EdgeFilter(R=np.eye(2), Q=0.0, x0=np.zeros((3, 2)), P0=np.eye(2))
    with pytest.raises(ValueError, match="shape"):
        f.step(np.zeros((2, 2)), np.zeros((3, 2)))
    x0, P0 = f.x.copy(), f.P.copy()
    # An R no filter can use is refused when the filter is built, naming it (and the edge of a
    # batch), not at the first step.
    with pytest.raises(ValueError, match="R: must be symmetric positive definite"):
        edgekf.EdgeFilter(R=-3 * np.eye(2), Q=0.0, x0=np.zeros((3, 2)), P0=np.eye(2))
    R = np.broadcast_to(np.eye(2), (9000, 2, 2)).copy()
    R[7777] = -3 * np.eye(2)
    with pytest.raises(ValueError, match="R of edge 7777"):
        edgekf.EdgeFilter(R=R, Q=0.0, x0=np.zeros((9000, 2)), P0=np.eye(2))
    np.testing.assert_array_equal(f.x, x0)
    with pytest.raises(ValueError, match="not finite"):
        f.update(np.full((3, 2), np.nan))
    with pytest.raises(ValueError, match="kind"):
        edgekf.EdgeFilter("ukf", R=1.0, Q=1.0, x0=[0.0], P0=1.0)
    with pytest.raises(ValueError, match="D must be"):
        edgekf.EdgeFilter(R=1.0, Q=1.0, x0=np.zeros(4), P0=1.0)
