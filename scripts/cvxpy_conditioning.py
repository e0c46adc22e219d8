"""The conditioning SDP of `edgekf design --method sdp` in CVXPY, for timing against it:
min t s.t. I ⪯ Qᵀ L(w) Q ⪯ t I over equilibrium stresses L(w) [P 1] = 0 (Q: an orthonormal
basis of the complement of [P 1]); t* is the design's λ_max/λ_min.

    pip install cvxpy
    edgekf design --generate trilateration --agents 100 --seed 1 --method sdp --out d100
    python scripts/cvxpy_conditioning.py d100/framework.json SCS CLARABEL

Reads the framework file's configuration and edges (for `sdp`, every candidate link is kept, so
they are the candidates). Not part of the tests: CVXPY is an optional reference.
"""
import json, sys, time
import numpy as np, cvxpy as cp

d = json.load(open(sys.argv[1]))
P = np.array(d["config"]); n, dim = P.shape
E = [tuple(e) for e in d["edges"]]
A = np.hstack([P, np.ones((n, 1))])
u, s, vt = np.linalg.svd(A, full_matrices=True)
Q = u[:, dim + 1:]
t = cp.Variable()
B = np.zeros((n, len(E)))
for k, (i, j) in enumerate(E):
    B[i, k], B[j, k] = 1, -1
# Equilibrium stresses w = Z c (Z: null space of w ↦ L(w) [P 1]), so no redundant equalities.
R = np.zeros((n * (dim + 1), len(E)))
for k, (i, j) in enumerate(E):
    blk = np.zeros((n, dim + 1)); blk[i] = A[i] - A[j]; blk[j] = A[j] - A[i]
    R[:, k] = blk.ravel()
_, sv, vt2 = np.linalg.svd(R, full_matrices=True)
rank = int((sv > 1e-9 * sv[0]).sum())
Z = vt2[rank:].T
c = cp.Variable(Z.shape[1])
w = Z @ c
L = B @ cp.diag(w) @ B.T
M = Q.T @ L @ Q
M = (M + M.T) / 2
m = n - dim - 1
cons = [M >> np.eye(m), M << t * np.eye(m)]
prob = cp.Problem(cp.Minimize(t), cons)
for solver in sys.argv[2:]:
    t0 = time.perf_counter()
    try:
        prob.solve(solver=solver)
        print(f"{d['name']}: N={n}, {len(E)} links, CVXPY+{solver}: {time.perf_counter() - t0:.2f} s, status {prob.status}, t* = {t.value:.6f}")
    except Exception as e:
        print(f"{d['name']}: CVXPY+{solver} failed after {time.perf_counter() - t0:.2f} s: {e}")
