"""Batched EdgeFilter.step over many edges vs the same filter (EUSIPCO eq. (5)) in NumPy.

    python bench/filter_speed.py [EDGES] [STEPS]

Prints the time per step of each and the speed-up. The NumPy version is vectorised over the
batch (np.linalg.inv and matmul on (B, D, D) stacks), the fair comparison; a Python loop over
the edges is timed on a subset and scaled, for reference.
"""

import sys
import time

import numpy as np

import edgekf


def numpy_rkf(x, P, Q, R, du, y):
    x = x + du
    P = P + Q
    K = P @ np.linalg.inv(P + R)
    x = x + np.einsum("bij,bj->bi", K, y - x)
    A = np.eye(x.shape[1]) - K
    P = A @ P @ A.transpose(0, 2, 1) + K @ R @ K.transpose(0, 2, 1)
    return x, 0.5 * (P + P.transpose(0, 2, 1))


def main():
    B = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 200
    d = 2
    rng = np.random.default_rng(0)
    # One R per edge (they differ in practice); one Q for all, broadcast by both implementations.
    R = np.array([[1e-3, 3e-4], [3e-4, 1e-3]]) * rng.uniform(0.5, 2.0, size=(B, 1, 1))
    Q = np.eye(d) * 2e-6
    dus = rng.normal(size=(steps, B, d)) * 1e-3
    ys = rng.normal(size=(steps, B, d))

    f = edgekf.EdgeFilter(R=R, Q=Q, x0=np.zeros((B, d)), P0=2 * np.eye(d))
    t = time.perf_counter()
    for k in range(steps):
        xr, Pr = f.step(dus[k], ys[k])
    rust = (time.perf_counter() - t) / steps

    x, P = np.zeros((B, d)), np.broadcast_to(2 * np.eye(d), (B, d, d)).copy()
    t = time.perf_counter()
    for k in range(steps):
        x, P = numpy_rkf(x, P, Q, R, dus[k], ys[k])
    vec = (time.perf_counter() - t) / steps
    assert np.allclose(xr, x, rtol=1e-9, atol=1e-12), "the two filters disagree"

    sub = min(B, 500)
    x1, P1 = np.zeros((1, d)), 2 * np.eye(d)[None]
    t = time.perf_counter()
    for k in range(5):
        for e in range(sub):
            numpy_rkf(x1, P1, Q, R[e : e + 1], dus[k, e : e + 1], ys[k, e : e + 1])
    loop = (time.perf_counter() - t) / 5 * B / sub

    print(f"{B} edges, D = {d}, {steps} steps")
    print(f"  edgekf.EdgeFilter.step (batched): {rust * 1e3:8.3f} ms/step")
    print(f"  NumPy, vectorised over the batch: {vec * 1e3:8.3f} ms/step  -> {vec / rust:6.1f}x")
    print(f"  NumPy, Python loop over edges:    {loop * 1e3:8.3f} ms/step  -> {loop / rust:6.0f}x")


if __name__ == "__main__":
    main()
