#!/usr/bin/env python3
"""Vectorised NumPy reference for the EUSIPCO 2022 / thesis ch. 5 closed loop (edgekf).

Reads a resolved ``scenario.json`` (schema ``edgekf.scenario/1``, written by ``edgekf run``) and
simulates, each in its own closed loop, the estimators ``none`` (one raw sample), ``mle`` (mean of
T samples), ``rkf`` (one KF per directed edge), ``jrkf`` (one joint KF per agent) and ``crkf``
(centralised, node-relative form).  All estimators share the draws: initial positions, process
noise ``w = chol(Q) xi`` and the measurement-mean noise ``chol(R_ij / T) eta`` (the T-sample mean
is drawn directly, DESIGN.md).  Writes ``metrics.csv`` in the edgekf format
(``estimator,step,time,metric,mean,std``; metrics est_error, est_error_sq, cov_trace, procrustes).

Conventions (DESIGN.md; thesis Algorithms 5-7): directed edge e = (i, j) in incidence order,
``z_ij = z_i - z_j``; one step k: predict with ``u_{k-1}``, measure ``ybar_k`` at ``z_k``, update to
``xhat_{k|k}``, report, compute ``u_k``, move ``z_{k+1} = z_k + dt u_k + w_k``.  Control
(edgekf ``control.rs``): followers ``u_i = -c sum_j l_ij zhat_ij``; leaders the distance law
``u_i = -k sum_{j leader} (|zhat_ij|^2 - d_ij^2) zhat_ij`` on their leader-leader edges only.

Layout: every batch is ``(lanes, rows, runs)``: one lane per estimator, one row per state
component (edge-major ``e * D + a``; agent-major ``i * D + a`` for positions), the runs innermost,
so the closed-loop parts shared by all estimators (measurements, control, motion) are one NumPy
call for all lanes and runs, and each filter works on its own contiguous lane.  Each
filter's gain depends only on the model, so it is computed once per step (and frozen, like the
Rust engine, once the covariance has converged to rounding level) and applied to all runs with one
(batched) matmul.

Usage:
    python eusipco.py SCENARIO.json --out DIR [--runs R] [--steps K] [--estimators rkf,...]
                      [--seed S] [--block B] [--quiet]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

EPS = np.finfo(float).eps
METRICS = ("est_error", "est_error_sq", "cov_trace", "procrustes")


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------
class Model:
    """Everything the simulation needs, from a resolved scenario.json."""

    def __init__(self, sc: dict, runs: int | None = None, steps: int | None = None):
        self.sc = sc
        self.D = D = int(sc["dim"])
        self.N = N = int(sc["agents"])
        self.P = np.array(sc["config"], dtype=float)  # nominal configuration (N, D)
        self.edges = [tuple(e) for e in sc["edges"]]
        self.M = M = len(self.edges)
        self.I = np.array([e[0] for e in self.edges])
        self.J = np.array([e[1] for e in self.edges])
        self.l = np.array(sc["weights"], dtype=float)
        self.leaders = list(sc.get("leaders", []))
        self.dt = float(sc["dt"])
        self.steps = int(steps if steps is not None else sc["steps"])
        self.runs = int(runs if runs is not None else sc["runs"])
        self.every = int(sc.get("every", 10))
        self.init_mean = np.array(sc["init_mean"], dtype=float)
        self.init_cov = np.array(sc["init_cov"], dtype=float)
        self.Q = np.array(sc["process_cov"], dtype=float)  # (ND, ND)
        self.R = np.array(sc["meas_cov"], dtype=float)  # (M, D, D)
        self.c = float(sc.get("follower_gain", 1.0))
        self.k = float(sc.get("leader_gain", 1.0))
        T0 = int(sc.get("samples_per_step", 1))
        specs = sc.get("estimator_specs")
        if specs is None:
            specs = [{"kind": e, "label": e} for e in sc["estimators"]]
        self.specs = []
        for s in specs:
            kind = s["kind"]
            T = int(s.get("samples", 1 if kind == "none" else T0))
            self.specs.append((s.get("label", kind), kind, T))
        # Edge incidence: x = BT z with x (MD rows), z (ND rows).
        BT = np.zeros((M * D, N * D))
        for e, (i, j) in enumerate(self.edges):
            for a in range(D):
                BT[e * D + a, i * D + a] = 1.0
                BT[e * D + a, j * D + a] = -1.0
        self.BT = BT
        self.edges_of = [np.flatnonzero(self.I == i) for i in range(N)]
        # Edge-space process and initial covariances: B^T Q B (thesis 4.26 / 5.9) and
        # B^T B (x) P (thesis 4.28 / 5.7).
        self.Qx = BT @ self.Q @ BT.T
        self.P0x = BT @ np.kron(np.eye(N), self.init_cov) @ BT.T

    def report_steps(self) -> list[int]:
        """Step 1, every `every`-th step, and the last (edgekf Scenario::report_steps)."""
        v = [1] + [m * self.every for m in range(1, self.steps // self.every + 1) if m * self.every > 1]
        if v[-1] != self.steps:
            v.append(self.steps)
        return v

    def edge_blocks(self, A: np.ndarray) -> np.ndarray:
        """The M diagonal D x D blocks of an MD x MD matrix, shape (M, D, D)."""
        D, M = self.D, self.M
        return np.stack([A[e * D:(e + 1) * D, e * D:(e + 1) * D] for e in range(M)])


def converged(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """edgekf linalg::converged per leading index: no entry moves by more than 8 eps max|old|."""
    axes = tuple(range(1, new.ndim))
    tol = 8.0 * EPS * np.abs(old).max(axis=axes)
    return (np.abs(new - old).max(axis=axes) <= tol)


# ----------------------------------------------------------------------------------------------
# Estimators.  Each owns a column block `cols` of the shared batches (its lane); `step` turns
# the prior estimate into x_{k|k} in place.
# ----------------------------------------------------------------------------------------------
class Mle:
    """`none` (T = 1) and `mle`: thesis (4.16)-(4.17): xhat = ybar, cov R_ij / T."""

    def __init__(self, m: Model, T: int, runs_cols: int):
        self.trace = float(np.trace(m.R, axis1=1, axis2=2).sum() / T)

    def cov_step(self):
        pass

    def step(self, xh, y, du, ud, x):
        np.copyto(xh, y)


class Rkf:
    """EUSIPCO (5a)-(5g) = thesis (4.27)-(4.33): one KF per directed edge.

    Sigma_{0|0} = 2P; prior Sigma + Q_ij (Q_ij = Bbar_ij^T Q Bbar_ij); K = prior (prior + W)^-1,
    W = R_ij / T; posterior in Joseph form (I-K) prior (I-K)^T + K W K^T.  Gains: one (M, D, D)
    stack per step, applied to all runs with one batched matmul; an edge freezes once converged.
    """

    def __init__(self, m: Model, T: int, runs_cols: int):
        D, M = m.D, m.M
        self.D, self.M = D, M
        self.Qe = m.edge_blocks(m.Qx)
        self.W = m.R / T
        self.sigma = m.edge_blocks(m.P0x).copy()  # 2P per edge
        self.K = np.zeros((M, D, D))
        self.frozen = np.zeros(M, dtype=bool)
        self.all_frozen = False
        self.eye = np.eye(D)
        self.inn = np.empty((M * D, runs_cols))
        self.tmp = np.empty((M * D, runs_cols))
        self.trace = float(np.trace(self.sigma, axis1=1, axis2=2).sum())

    def cov_step(self):
        if self.all_frozen:
            return
        prior = self.sigma + self.Qe  # (5d)
        S = prior + self.W
        K = prior @ np.linalg.inv(S)  # (5e); S symmetric => K = prior S^-1
        A = self.eye - K
        post = A @ prior @ A.transpose(0, 2, 1) + K @ self.W @ K.transpose(0, 2, 1)  # (5g) Joseph
        post = 0.5 * (post + post.transpose(0, 2, 1))
        conv = converged(post, self.sigma)
        live = ~self.frozen
        self.sigma[live] = post[live]
        self.K[live] = K[live]
        self.frozen |= conv
        self.all_frozen = bool(self.frozen.all())
        self.trace = float(np.trace(self.sigma, axis1=1, axis2=2).sum())

    def step(self, xh, y, du, ud, x):
        D, M = self.D, self.M
        cols = xh.shape[1]
        xh += du  # (5c) prediction with the communicated inputs
        np.subtract(y, xh, out=self.inn)  # innovation
        np.matmul(self.K, self.inn.reshape(M, D, cols), out=self.tmp.reshape(M, D, cols))
        xh += self.tmp  # (5f)


class Jrkf:
    """EUSIPCO (14a)-(14g) = thesis (5.19)-(5.25): one joint KF per agent over its edges.

    Sigma^i_{0|0} = B_i^T B_i (x) P; prior + Bbar_i^T Q Bbar_i; Joseph posterior.  The edges of an
    agent are contiguous rows (incidence order), so consecutive agents with equally many edges form
    one (agents, n, n) stack and their gains are applied with one batched matmul.
    """

    def __init__(self, m: Model, T: int, runs_cols: int):
        D = m.D
        W = np.zeros((m.M * D, m.M * D))
        for e in range(m.M):
            W[e * D:(e + 1) * D, e * D:(e + 1) * D] = m.R[e] / T
        # groups of consecutive agents with the same block size: (row0, count, n)
        groups = []
        for i in range(m.N):
            idx = m.edges_of[i]
            r0, n = idx[0] * D, len(idx) * D
            assert np.all(np.diff(idx) == 1)
            if groups and groups[-1][2] == n and groups[-1][0] + groups[-1][1] * n == r0:
                groups[-1][1] += 1
            else:
                groups.append([r0, 1, n])
        self.groups = []
        for r0, cnt, n in groups:
            sl = [slice(r0 + a * n, r0 + (a + 1) * n) for a in range(cnt)]
            g = dict(
                r0=r0, r1=r0 + cnt * n, cnt=cnt, n=n,
                Q=np.stack([m.Qx[s, s] for s in sl]),
                W=np.stack([W[s, s] for s in sl]),
                sigma=np.stack([m.P0x[s, s] for s in sl]),
                K=np.zeros((cnt, n, n)), frozen=False, eye=np.eye(n),
            )
            self.groups.append(g)
        self.inn = np.empty((m.M * D, runs_cols))
        self.tmp = np.empty((m.M * D, runs_cols))
        self.trace = self._trace()

    def _trace(self):
        return float(sum(np.trace(g["sigma"], axis1=1, axis2=2).sum() for g in self.groups))

    def cov_step(self):
        changed = False
        for g in self.groups:
            if g["frozen"]:
                continue
            prior = g["sigma"] + g["Q"]  # (14d)
            S = prior + g["W"]
            Kt = np.linalg.solve(S, prior)  # K^T = S^-1 prior (both symmetric)   (14e)
            K = Kt.transpose(0, 2, 1)
            A = g["eye"] - K
            post = A @ prior @ A.transpose(0, 2, 1) + K @ g["W"] @ Kt  # (14g) Joseph
            post = 0.5 * (post + post.transpose(0, 2, 1))
            g["frozen"] = bool(converged(post, g["sigma"]).all())
            g["sigma"] = post
            g["K"] = np.ascontiguousarray(K)
            changed = True
        if changed:
            self.trace = self._trace()

    def step(self, xh, y, du, ud, x):
        cols = xh.shape[1]
        xh += du  # (14c)
        np.subtract(y, xh, out=self.inn)
        for g in self.groups:
            r0, r1, cnt, n = g["r0"], g["r1"], g["cnt"], g["n"]
            np.matmul(g["K"], self.inn[r0:r1].reshape(cnt, n, cols),
                      out=self.tmp[r0:r1].reshape(cnt, n, cols))
        xh += self.tmp  # (14f)


class Crkf:
    """EUSIPCO (9a)-(9g) = thesis (5.6)-(5.12), in the exact node-relative form of edgekf.

    zeta_n = z_n - z_0 (n = 1..N-1), x = G zeta with G = B^T without agent 0's columns.
    Sigma_{0|0} = (I + 11^T) (x) P, Q_zeta = S Q S^T, information-form update
    Sigma_{k|k} = (Sigma_{k|k-1}^-1 + G^T W^-1 G)^-1, gain K = Sigma_{k|k} G^T W^-1 (nz x MD),
    zeta += K (ybar - G zeta);  xhat = G zeta;  tr Sigma^x = tr(Sigma G^T G).
    """

    def __init__(self, m: Model, T: int, runs_cols: int):
        D, N = m.D, m.N
        nz = (N - 1) * D
        self.G = np.ascontiguousarray(m.BT[:, D:])  # (MD, nz)
        S = np.zeros((nz, N * D))
        for n in range(1, N):
            for a in range(D):
                S[(n - 1) * D + a, n * D + a] = 1.0
                S[(n - 1) * D + a, a] = -1.0
        self.S = S
        self.Qz = S @ m.Q @ S.T
        self.sigma = S @ np.kron(np.eye(N), m.init_cov) @ S.T
        Winv = np.zeros((m.M * D, m.M * D))
        for e in range(m.M):
            Winv[e * D:(e + 1) * D, e * D:(e + 1) * D] = np.linalg.inv(m.R[e] / T)
        self.GtWinv = self.G.T @ Winv  # (nz, MD)
        self.Jinfo = self.GtWinv @ self.G
        self.GtG = self.G.T @ self.G
        self.K = np.zeros((nz, m.M * D))
        self.frozen = False
        self.zeta = np.zeros((nz, runs_cols))
        self.dz = np.empty((nz, runs_cols))
        self.inn = np.empty((m.M * D, runs_cols))
        self.trace = float(np.sum(self.sigma * self.GtG))

    def cov_step(self):
        if self.frozen:
            return
        prior = self.sigma + self.Qz  # (9d)
        info = np.linalg.inv(prior) + self.Jinfo  # (9e)-(9g), information form
        post = np.linalg.inv(info)
        post = 0.5 * (post + post.T)
        self.frozen = bool(converged(post[None], self.sigma[None])[0])
        self.sigma = post
        self.K = post @ self.GtWinv
        self.trace = float(np.sum(post * self.GtG))

    def step(self, xh, y, du, ud, x):
        np.matmul(self.S, ud, out=self.dz)  # (9c): zeta_n += dt (u_n - u_0)
        self.zeta += self.dz
        np.matmul(self.G, self.zeta, out=self.inn)
        np.subtract(y, self.inn, out=self.inn)
        np.matmul(self.K, self.inn, out=self.dz)
        self.zeta += self.dz  # (9f)
        np.matmul(self.G, self.zeta, out=xh)  # xhat = G zeta


KINDS = {"none": Mle, "mle": Mle, "rkf": Rkf, "jrkf": Jrkf, "crkf": Crkf}


# ----------------------------------------------------------------------------------------------
# Control
# ----------------------------------------------------------------------------------------------
class Controller:
    """dt * u from the edge estimates, for every lane and run at once (edgekf control.rs).

    Followers: u_i = -c sum_{e in edges(i)} l_e xhat_e.  Leaders: u_i = -k sum over their
    leader-leader edges of (|xhat_e|^2 - d_e^2) xhat_e.  Both are written as one matmul
    ``dt*u = C [xhat; s*xhat_LL]`` per lane, where the bottom rows hold the leader products.
    """

    def __init__(self, m: Model, lanes: int, runs: int):
        D, N, M = m.D, m.N, m.M
        lead = set(m.leaders)
        ll = [e for e, (i, j) in enumerate(m.edges) if i in lead and j in lead]
        self.ll = np.array(ll, dtype=int)
        self.nll = len(ll)
        self.d2 = np.array([np.sum((m.P[m.I[e]] - m.P[m.J[e]]) ** 2) for e in ll]).reshape(-1, 1)
        C = np.zeros((N * D, M * D + self.nll * D))
        for e, (i, j) in enumerate(m.edges):
            if i not in lead:
                for a in range(D):
                    C[i * D + a, e * D + a] = -m.dt * m.c * m.l[e]
        for q, e in enumerate(ll):
            i = m.I[e]
            for a in range(D):
                C[i * D + a, M * D + q * D + a] = -m.dt * m.k
        self.C = C
        self.M, self.D = M, D
        # [xhat; leader products] live in one buffer per lane so the law is one matmul.
        self.buf = np.zeros((lanes, M * D + self.nll * D, runs))
        self.xh = self.buf[:, :M * D]
        self.prod = self.buf[:, M * D:].reshape(lanes, self.nll, D, runs)
        self.s = np.empty((lanes, self.nll, runs))
        self.xl = np.empty((lanes, self.nll, D, runs))

    def apply(self, ud: np.ndarray):
        if self.nll:
            L, R = self.buf.shape[0], self.buf.shape[2]
            np.take(self.xh.reshape(L, self.M, self.D, R), self.ll, axis=1, out=self.xl)
            np.einsum("lqar,lqar->lqr", self.xl, self.xl, out=self.s)
            self.s -= self.d2
            np.multiply(self.xl, self.s[:, :, None, :], out=self.prod)
        np.matmul(self.C, self.buf, out=ud)


# ----------------------------------------------------------------------------------------------
# Metrics
# ----------------------------------------------------------------------------------------------
def procrustes(z: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Thesis Def. 2.9 for a batch: z (N, D, B) -> min_{t, Omega^T Omega = I} |Z Omega + 1t^T - P|_F / N.

    Centre both, Omega = U V^T from the SVD of Zc^T Pc (reflections allowed), as edgekf metrics.rs.
    """
    N = z.shape[0]
    zc = z - z.mean(axis=0, keepdims=True)
    pc = P - P.mean(axis=0, keepdims=True)
    Mab = np.einsum("iab,ic->bac", zc, pc)  # (B, D, D): sum_i zc_ia pc_ic
    U, _, Vt = np.linalg.svd(Mab)
    Om = U @ Vt
    res = np.einsum("iab,bac->bic", zc, Om) - pc[None]
    return np.sqrt(np.sum(res * res, axis=(1, 2))) / N


# ----------------------------------------------------------------------------------------------
# Simulation
# ----------------------------------------------------------------------------------------------
def simulate(m: Model, labels: list[str] | None = None, seed: int = 12345, block: int = 200,
             progress: bool = True, windows=((15.0, 30.0), (25.0, 30.0))):
    """Runs the closed loop of every selected estimator.

    Returns (labels, report steps, stats, per-run steady-state averages, info).
    """
    D, N, M, R = m.D, m.N, m.M, m.runs
    ND, MD = N * D, M * D
    specs = [s for s in m.specs if (labels is None or s[0] in labels)]
    # Lanes grouped by T so that each group's measurement noise is one broadcast add.
    Ts = sorted({T for _, _, T in specs})
    order = sorted(range(len(specs)), key=lambda q: Ts.index(specs[q][2]))
    specs = [specs[q] for q in order]
    L = len(specs)
    est = [KINDS[kind](m, T, R) for _, kind, T in specs]
    groups = []  # (T index, first lane, one past the last lane)
    for ti, T in enumerate(Ts):
        lanes = [q for q in range(L) if specs[q][2] == T]
        groups.append((ti, lanes[0], lanes[-1] + 1))

    rng = np.random.Generator(np.random.SFC64(seed))
    # Noise factors: C_Q (ND x ND) and chol(R_e / T) per edge and distinct T.
    CQ = psd_factor(m.Q)
    CR = [np.stack([psd_factor(m.R[e] / T) for e in range(M)])[None] for T in Ts]  # (1, M, D, D)
    CP = psd_factor(m.init_cov)

    # Every batch is (lanes, rows, runs).  Initial positions z_1 = mu + C_P xi, shared.
    z0 = m.init_mean[None, :, None] + np.einsum("ab,nbr->nar", CP, rng.standard_normal((N, D, R)))
    z = np.empty((L, ND, R))
    z[...] = z0.reshape(1, ND, R)
    ctrl = Controller(m, L, R)
    xh = ctrl.xh  # (L, MD, R): the estimates live in the controller's buffer
    x = np.matmul(m.BT, z)  # true edges x_1 = Bbar^T z_1
    y = np.empty((L, MD, R))
    du = np.zeros((L, MD, R))  # dt Bbar^T u_{k-1}; u_0 = 0
    ud = np.zeros((L, ND, R))  # dt u

    # Draw buffers for a block of steps.
    B = max(1, min(block, m.steps))
    eta = np.empty((B, M, D, R))
    xi = np.empty((B, ND, R))
    w = np.empty((B, ND, R))
    bw = np.empty((B, MD, R))  # Bbar^T w: the process noise on the edges
    vbar = [np.empty((B, MD, R)) for _ in Ts]

    report = m.report_steps()
    nr = len(report)
    err_sq = np.empty((L, nr, R))
    proc = np.empty((L, nr, R))
    trace = np.empty((L, nr))
    ri = 0
    t0, c0 = time.perf_counter(), time.process_time()
    t_cov = 0.0
    for k0 in range(1, m.steps + 1, B):
        nb = min(B, m.steps + 1 - k0)
        # Draws of this block: measurement-mean normals, then process normals.
        rng.standard_normal(out=eta)
        rng.standard_normal(out=xi)
        np.matmul(CQ, xi, out=w)  # w = C_Q xi
        np.matmul(m.BT, w, out=bw)
        for ti in range(len(Ts)):  # vbar = chol(R_e / T) eta, per edge
            np.matmul(CR[ti], eta, out=vbar[ti].reshape(B, M, D, R))
        for s in range(nb):
            k = k0 + s
            # Covariances and gains: once per step, for all runs.
            tc = time.perf_counter()
            for f in est:
                f.cov_step()
            t_cov += time.perf_counter() - tc
            # Measurement means at the true edges x_k.
            for ti, q0, q1 in groups:
                np.add(x[q0:q1], vbar[ti][s], out=y[q0:q1])
            for q, f in enumerate(est):
                f.step(xh[q], y[q], du[q], ud[q], x[q])
            if ri < nr and report[ri] == k:
                d = x - xh
                err_sq[:, ri, :] = np.einsum("lar,lar->lr", d, d)
                zb = z.reshape(L, N, D, R).transpose(1, 2, 0, 3).reshape(N, D, L * R)
                proc[:, ri, :] = procrustes(zb, m.P).reshape(L, R)
                trace[:, ri] = [f.trace for f in est]
                ri += 1
            ctrl.apply(ud)  # dt u_k
            # Motion: z_{k+1} = z_k + dt u_k + w_k, and on the edges (EUSIPCO eq. 4)
            # x_{k+1} = x_k + dt Bbar^T u_k + Bbar^T w_k, where dt Bbar^T u_k is also the next
            # step's prediction increment du = dt (u^i_k - u^j_k) of the edge filters.
            z += ud
            z += w[s]
            np.matmul(m.BT, ud, out=du)
            x += du
            x += bw[s]
        if progress and (k0 // B) % 25 == 0:
            el = time.perf_counter() - t0
            print(f"  step {k0 + nb - 1}/{m.steps}  {el:.1f} s", file=sys.stderr)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    # Per-lane statistics, in the scenario's estimator order.
    times = np.array(report) * m.dt
    stats, steady = {}, {}
    for q, (lab, _, _) in enumerate(specs):
        nrm = np.sqrt(err_sq[q])
        stats[lab] = {
            "est_error": (nrm.mean(axis=1), nrm.std(axis=1, ddof=1)),
            "est_error_sq": (err_sq[q].mean(axis=1), err_sq[q].std(axis=1, ddof=1)),
            "cov_trace": (trace[q], np.zeros(nr)),
            "procrustes": (proc[q].mean(axis=1), proc[q].std(axis=1, ddof=1)),
        }
        # Per-run time averages over the steady-state windows: their spread across the
        # independent runs gives an honest standard error of the windowed means.
        steady[lab] = {}
        for (w0, w1) in windows:
            sel = (times >= w0) & (times <= w1)
            if not sel.any():
                continue
            for met, arr in (("est_error_sq", err_sq[q]), ("est_error", nrm), ("procrustes", proc[q])):
                per_run = arr[sel].mean(axis=0)
                steady[lab][f"{met}@{w0:g}-{w1:g}"] = (
                    float(per_run.mean()), float(per_run.std(ddof=1) / np.sqrt(R)))
    order_labels = [s[0] for s in m.specs if s[0] in stats]
    info = dict(wall=wall, cpu=cpu, cov_time=t_cov, lanes=L, runs=R, steps=m.steps, agents=N)
    return order_labels, report, stats, steady, info


def psd_factor(A: np.ndarray) -> np.ndarray:
    """C with C C^T = A: Cholesky, or V sqrt(Lambda) when A is only semidefinite."""
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        lam, V = np.linalg.eigh(A)
        return V * np.sqrt(np.clip(lam, 0.0, None))


def write_metrics(path: str, labels, report, stats, dt):
    with open(path, "w") as f:
        f.write("estimator,step,time,metric,mean,std\n")
        for lab in labels:
            for met in METRICS:
                mu, sd = stats[lab][met]
                for q, k in enumerate(report):
                    f.write(f"{lab},{k},{k * dt!r},{met},{float(mu[q])!r},{float(sd[q])!r}\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario")
    ap.add_argument("--out", required=True)
    ap.add_argument("--runs", type=int)
    ap.add_argument("--steps", type=int)
    ap.add_argument("--estimators", help="comma-separated labels (default: all in the scenario)")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--block", type=int, default=200, help="steps of draws generated at once")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    with open(a.scenario) as f:
        sc = json.load(f)
    m = Model(sc, runs=a.runs, steps=a.steps)
    labels = a.estimators.split(",") if a.estimators else None
    labs, report, stats, steady, info = simulate(m, labels, seed=a.seed, block=a.block,
                                                 progress=not a.quiet)
    os.makedirs(a.out, exist_ok=True)
    write_metrics(os.path.join(a.out, "metrics.csv"), labs, report, stats, m.dt)
    with open(os.path.join(a.out, "steady.json"), "w") as f:
        json.dump(steady, f, indent=1)
    agent_steps = info["runs"] * info["agents"] * info["steps"]
    info.update(
        numpy=np.__version__, python=sys.version.split()[0], estimators=labs,
        ns_per_agent_step=info["wall"] / agent_steps * 1e9,
        ns_per_agent_step_per_estimator=info["wall"] / agent_steps / info["lanes"] * 1e9,
        cpu_ns_per_agent_step=info["cpu"] / agent_steps * 1e9,
        loadavg_after=os.getloadavg(),
        threads={v: os.environ.get(v) for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
    )
    with open(os.path.join(a.out, "timing.json"), "w") as f:
        json.dump(info, f, indent=1)
    print(json.dumps(info))


if __name__ == "__main__":
    main()
