#!/usr/bin/env python3
"""Vectorised NumPy reference of GA-RKF (Li & Rajan, IEEE OJCSYS 2026) as edgekf issue 10 specifies.

Closed loop on the 10-agent hexagon framework of a resolved edgekf ``scenario.json`` (its
configuration P, directed edges in incidence order, weights l_ij, leaders): Delta t = 0.01 s,
leaders 0, 1, 2 set on the target each step, target Z*(t) = Theta*(t) P + t*(t) 1^T from the
issue's default 60 s maneuver, followers with the static law u_i = -c sum_j l_ij zhat_ij on their
estimates, single-integrator agents z_{k+1} = z_k + dt u_k (no process noise), measurements
y_ij = z_ij + v_ij with R = sigma_v^2 [[1, rho], [rho, 1]], one sample per step, each directed
edge available with probability lambda (independently per direction, step and run).  One draw
removes both the measurement and the message on that directed edge.

Estimators (each in its own closed loop; all share the draws):
- ``none``   the last available measurement of each edge is held (0 before the first one);
- ``rkf-ca`` constant-acceleration KF per directed edge (eqs. 5-7): predict every step, correct
             (Joseph form) only when the edge is observed;
- ``garkf``  Algorithm 1 with the issue's corrections: the missing prediction step; Joseph
             updates; an infeasible agent's RAL is unavailable (masked), not zero; psi (18)
             averages over feasible pairs only and holds its last value when undefined (before
             any value: no geometric update); consensus (16) with epsilon; R^ral (15) =
             (p_ij^T A_i^-1 p_ij) R with A_i = H_i H_i^T, R^geo = R^ral / N (17), composite
             covariance (10).  ``--infeasible literal`` feeds zeros instead (Alg. 1 lines 6-7).

Runs are vectorised: every batch has the runs as its last axis.  The CA filter's covariance
depends on each edge's availability history, so it is kept per (edge, run).  Because F, Q and the
observation matrix are Kronecker products with I_D and every observation covariance here is
a R' = a R + b I (measurement: a = 1, b = 0; geometric: a = c/N, b = psi), all of them are
diagonal in the eigenbasis V of R: in the rotated coordinates V^T z the D components of each edge
are independent 3-state filters with scalar observations.  This is an exact change of
coordinates (the covariance traces are invariant); ``riccati_check`` verifies the steady state
against the full 3D x 3D recursion in the original coordinates.

Usage:
    python garkf.py SCENARIO.json --out DIR [--lam 0.4] [--gain 5] [--runs 20] [--steps 6000]
                    [--estimators none,rkf-ca,garkf] [--infeasible masked|literal] [--seed S]
    python garkf.py SCENARIO.json --riccati [--lam L]   # Riccati fixed point; filter consistency
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

# ----------------------------------------------------------------------------------------------
# Maneuver (issue 10 default for Fig. 7b) and the target, eq. (2)
# ----------------------------------------------------------------------------------------------
# key frames: (t [s], translation t*, rotation a [deg], scale (s_x, s_y), shear sh); the
# parameters are interpolated with smoothstep between consecutive key frames and held after
# the last; Theta = R(a) [[s_x, sh], [0, s_y]].
KEYFRAMES = [
    (0.0, (0.0, 0.0), 0.0, (1.0, 1.0), 0.0),
    (10.0, (0.0, 0.0), 0.0, (1.0, 1.0), 0.0),  # hold 0-10 s
    (20.0, (3.0, 0.0), 0.0, (1.0, 1.0), 0.0),  # translate to (3, 0)
    (30.0, (5.0, 1.0), 45.0, (1.0, 1.0), 0.0),  # rotate 45 deg, move to (5, 1)
    (40.0, (7.0, 2.0), 45.0, (1.6, 0.6), 0.0),  # scale to (1.6, 0.6) at (7, 2)
    (50.0, (9.0, 2.0), 45.0, (1.6, 0.6), 0.4),  # add shear 0.4 at (9, 2)
    (60.0, (10.0, 0.0), 0.0, (1.0, 1.0), 0.0),  # back to Theta = I at (10, 0)
]


def smoothstep(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def maneuver(t: float):
    """(Theta*(t), t*(t)) of the key-framed maneuver."""
    par = [np.array([*kf[1], kf[2], *kf[3], kf[4]]) for kf in KEYFRAMES]
    times = [kf[0] for kf in KEYFRAMES]
    if t <= times[0]:
        p = par[0]
    elif t >= times[-1]:
        p = par[-1]
    else:
        q = np.searchsorted(times, t, side="right") - 1
        s = smoothstep((t - times[q]) / (times[q + 1] - times[q]))
        p = par[q] + (par[q + 1] - par[q]) * s
    tx, ty, a, sx, sy, sh = p
    a = np.deg2rad(a)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return rot @ np.array([[sx, sh], [0.0, sy]]), np.array([tx, ty])


def target(t: float, P: np.ndarray):
    """Eq. (2): Z*(t) = Theta*(t) P + t*(t) 1^T, returned agent-major (N, D), and Theta*."""
    th, tr = maneuver(t)
    return P @ th.T + tr[None, :], th


def tracking_error(z: np.ndarray, zs: np.ndarray) -> np.ndarray:
    """Eq. (4): delta_k = |Z_k - Z*_k|_F^2 / N, per lane and run; z (L, N, D, R), zs (N, D)."""
    d = z - zs[None, :, :, None]
    return np.einsum("lndr,lndr->lr", d, d) / z.shape[1]


# ----------------------------------------------------------------------------------------------
# Constant-acceleration edge model, eqs. (5)-(7), in the eigenbasis of R
# ----------------------------------------------------------------------------------------------
def ca_model(dt: float, sigma_w: float):
    """Eqs. (6)-(7) per coordinate: F3, Q3 (3 x 3); the full model is F3 (x) I_D, Q3 (x) I_D."""
    F3 = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    Q3 = sigma_w ** 2 * np.array([
        [dt ** 4 / 4, dt ** 3 / 2, dt ** 2 / 2],
        [dt ** 3 / 2, dt ** 2, dt],
        [dt ** 2 / 2, dt, 1.0]])
    return F3, Q3


def kf_predict(gamma, lam, F3, Q3):
    """Eq. (5a)/(21a) prediction, every step (the step missing from Alg. 1 lines 17-19).

    gamma (3, n) and lam (3, 3, n) hold n independent 3-state filters (coordinate, edge, run).
    gamma <- F gamma;  Lambda <- F Lambda F^T + Q.
    """
    n = gamma.shape[1]
    np.matmul(F3, gamma, out=gamma)
    t1 = (F3 @ lam.reshape(3, 3 * n)).reshape(3, 3, n)  # F Lambda
    # (F Lambda) F^T = (F (F Lambda)^T)^T; Lambda symmetric
    t2 = (F3 @ np.ascontiguousarray(t1.transpose(1, 0, 2)).reshape(3, 3 * n)).reshape(3, 3, n)
    np.add(t2.transpose(1, 0, 2), Q3[:, :, None], out=lam)


def kf_correct(gamma, lam, yobs, r, mask):
    """Alg. 1 lines 17-19 with observation (5b)/(8) and covariance (10), in Joseph form.

    Scalar observation G gamma = gamma[0] of each filter: S = Lambda_00 + r, K = Lambda[:, 0] / S,
    gamma += K (y - gamma_0), Lambda <- (I - K G) Lambda (I - K G)^T + r K K^T.  Where `mask` is
    False the gain is exactly 0, so gamma and Lambda are left bit-for-bit unchanged.
    """
    K = lam[:, 0, :] / (lam[0, 0] + r)  # Lambda G^T S^-1
    K *= mask
    gamma += K * (yobs - gamma[0])
    T = K[:, None, :] * lam[None, 0, :, :]
    np.subtract(lam, T, out=T)  # T = (I - K G) Lambda
    U = T[:, 0:1, :] * K[None, :, :]
    T -= U  # T (I - K G)^T
    np.multiply((r * K)[:, None, :], K[None, :, :], out=U)
    T += U  # + K r K^T
    np.add(T, T.transpose(1, 0, 2), out=lam)  # symmetrised
    lam *= 0.5


# ----------------------------------------------------------------------------------------------
# Geometry-aware estimators: RAL (12)-(15), consensus (16)-(17), convergence indicator (18)
# ----------------------------------------------------------------------------------------------
class Geometry:
    """Static geometry of the framework: p_ij per directed edge, who measures what."""

    def __init__(self, P, I, J, N):
        self.P, self.I, self.J, self.N = P, I, J, N
        self.M, self.D = len(I), P.shape[1]
        self.pe = P[I] - P[J]  # p_ij (M, D), eq. (11)
        self.pp = np.einsum("ea,eb->eab", self.pe, self.pe).reshape(self.M, -1)  # p p^T
        Sel = np.zeros((N, self.M))
        Sel[I, np.arange(self.M)] = 1.0  # Sel[i, e] = 1: agent i measures edge e (B_i's columns)
        self.Sel = Sel


def ral(geo: Geometry, beta, y, tol=1e-9):
    """Eqs. (12)-(14) and Definition 2 for every agent and run.

    H_{i,k} = P B_{i,k} (columns p_ij of the available edges), A_i = H_i H_i^T,
    Theta^ral_i = Y_i H_i^T A_i^-1 (= Y_i H_i^dagger).  Feasible (Def. 2): N_{i,k} >= D and H_i of
    full row rank (smallest eigenvalue of A_i > tol * largest).  Returns Theta^ral (N, R, D, D),
    zero where infeasible, A_i^-1 (identity where infeasible), feasibility and N_{i,k} (N, R).
    """
    N, M, D = geo.N, geo.M, geo.D
    R = beta.shape[1]
    A = (geo.Sel @ (beta[:, :, None] * geo.pp[:, None, :]).reshape(M, -1)).reshape(N, R, D, D)
    yb = y * beta[:, None, :]  # (M, D, R)
    YH = (geo.Sel @ np.einsum("edr,ef->erdf", yb, geo.pe).reshape(M, -1)).reshape(N, R, D, D)
    nobs = geo.Sel @ beta
    if D == 2:  # closed form: eigenvalues of the symmetric 2 x 2 A, and its inverse
        a, b, d = A[..., 0, 0], A[..., 0, 1], A[..., 1, 1]
        det = a * d - b * b
        half_tr = 0.5 * (a + d)
        disc = np.sqrt(np.maximum(half_tr * half_tr - det, 0.0))
        feas = (nobs >= D) & (half_tr - disc > tol * (half_tr + disc))
        inv_det = np.where(feas, 1.0 / np.where(feas, det, 1.0), 0.0)
        Ainv = np.empty_like(A)
        Ainv[..., 0, 0] = np.where(feas, d * inv_det, 1.0)
        Ainv[..., 1, 1] = np.where(feas, a * inv_det, 1.0)
        Ainv[..., 0, 1] = Ainv[..., 1, 0] = -b * inv_det
    else:
        ev = np.linalg.eigvalsh(A)
        feas = (nobs >= D) & (ev[..., 0] > tol * ev[..., -1])
        A[~feas] = np.eye(D)
        Ainv = np.linalg.inv(A)
    theta = YH @ Ainv
    theta[~feas] = 0.0
    return theta, Ainv, feas, nobs


def convergence_indicator(geo: Geometry, beta, theta_ral, feas, literal=False):
    """Eq. (18): psi_i = mean over j in N_{i,k} of |Theta^ral_i - Theta^ral_j|_F^2.

    Masked (default): only pairs with both i and j feasible count; undefined (NaN) when there is
    none.  Literal: every available neighbour counts, infeasible RAL being 0 (Alg. 1 line 7).
    """
    d = theta_ral[geo.I] - theta_ral[geo.J]
    d2 = np.einsum("erab,erab->er", d, d)
    wgt = beta if literal else beta * feas[geo.I] * feas[geo.J]
    num, den = geo.Sel @ (wgt * d2), geo.Sel @ wgt
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def consensus(geo: Geometry, beta, theta_hat, theta_ral, feas, eps, literal=False):
    """Eq. (16), as Alg. 1 line 11 uses it: from Theta_hat_{i,k-1} and Theta^ral_{j,k},

    Delta_i = sum_{j in N_ik} (That_j - That_i) + sum_{j in J_ik} (Theta^ral_j - That_i),
    J_ik = N_ik + {i}; masked: the second sum over feasible j only.  That_{i,k} = That + eps Delta.
    Also returns |J_i| (the RAL inputs counted), for the stability bound 2 / lambda_max.
    """
    N, R, D, _ = theta_hat.shape
    f = np.ones_like(feas, dtype=float) if literal else feas.astype(float)
    th_j = theta_hat[geo.J].reshape(geo.M, R, D * D)
    nb_sum = (geo.Sel @ (beta[:, :, None] * th_j).reshape(geo.M, -1)).reshape(N, R, D, D)
    deg = geo.Sel @ beta
    fj = beta * f[geo.J]
    ral_j = theta_ral[geo.J].reshape(geo.M, R, D * D)
    ral_sum = (geo.Sel @ (fj[:, :, None] * ral_j).reshape(geo.M, -1)).reshape(N, R, D, D)
    ral_sum += f[:, :, None, None] * theta_ral
    cnt = geo.Sel @ fj + f
    delta = nb_sum - deg[:, :, None, None] * theta_hat + ral_sum - cnt[:, :, None, None] * theta_hat
    return theta_hat + eps * delta, cnt


def consensus_bound(geo: Geometry, beta, cnt):
    """Spectral radius of the consensus iteration matrix I - eps (L_k + diag|J_i|), per run.

    Returns lambda_max-type numbers: the largest |mu| of M_k = L_k + diag|J_i| per run (the bound
    is eps < 2 / lambda_max for symmetric M_k; for the directed L_k we report max |mu| and check
    |1 - eps mu| < 1 directly in `stable_eps`).
    """
    N, R = geo.N, beta.shape[1]
    Mk = np.zeros((R, N, N))
    for e in range(geo.M):
        i, j = geo.I[e], geo.J[e]
        Mk[:, i, j] -= beta[e]
        Mk[:, i, i] += beta[e]
    Mk[:, np.arange(N), np.arange(N)] += cnt.T
    return np.linalg.eigvals(Mk)


def ral_cov_factor(geo: Geometry, Ainv):
    """Eq. (15) with a common R: R^ral_ij = (p_ij^T A_i^-1 p_ij) R; returns the factor (M, R)."""
    return np.einsum("ea,erab,eb->er", geo.pe, Ainv[geo.I], geo.pe)


# ----------------------------------------------------------------------------------------------
# Estimators: step(y, beta) -> zhat (M, D, R)
# ----------------------------------------------------------------------------------------------
class NoneEst:
    """No estimator: the last available measurement of each edge is held (0 before any)."""

    def __init__(self, ctx):
        self.z = np.zeros((ctx.M, ctx.D, ctx.R))

    def step(self, y, beta, k, t, x=None):
        np.copyto(self.z, y, where=beta[:, None, :] > 0)
        return self.z

    def cov_trace(self):
        return np.full(self.z.shape[2], np.nan)


class Oracle:
    """Reference only: the true edges (the control law's own floor, no estimation error)."""

    def __init__(self, ctx):
        self.z = np.zeros((ctx.M, ctx.D, ctx.R))

    def step(self, y, beta, k, t, x=None):
        np.copyto(self.z, x)
        return self.z

    def cov_trace(self):
        return np.full(self.z.shape[2], np.nan)


class RkfCA:
    """`rkf-ca`: the CA Kalman filter with intermittent observations, one per directed edge."""

    def __init__(self, ctx):
        self.ctx = ctx
        M, D, R = ctx.M, ctx.D, ctx.R
        n = M * D * R  # one filter per (edge, coordinate of the eigenbasis of R, run)
        self.gamma = np.zeros((3, n))  # gamma_0 = 0: position, velocity, acceleration
        self.lam = np.zeros((3, 3, n))
        for a in range(3):
            self.lam[a, a] = ctx.lam0[a]
        self.rmeas = np.broadcast_to(ctx.rdiag[None, :, None], (M, D, R)).reshape(n)
        self.zhat = np.empty((M, D, R))
        self.yr = np.empty((M, D, R))

    def estimates(self):
        c = self.ctx
        np.matmul(c.V, self.gamma[0].reshape(c.M, c.D, c.R), out=self.zhat)  # z = V z'
        return self.zhat

    def observe(self, y, beta, k, t):
        """The observation (8) and its covariance (10) in the eigenbasis; mask: correct or not."""
        c = self.ctx
        np.matmul(c.V.T, y, out=self.yr)  # y' = V^T y
        mask = np.broadcast_to(beta[:, None, :], (c.M, c.D, c.R)).reshape(-1)
        return self.yr.reshape(-1), self.rmeas, mask

    def step(self, y, beta, k, t, x=None):
        c = self.ctx
        kf_predict(self.gamma, self.lam, c.F3, c.Q3)
        yobs, r, mask = self.observe(y, beta, k, t)
        kf_correct(self.gamma, self.lam, yobs, r, mask)
        return self.estimates()

    def pos_var(self):
        """Position variances (M, D, R) in the eigenbasis; their sum over D is tr of the block."""
        c = self.ctx
        return self.lam[0, 0].reshape(c.M, c.D, c.R)

    def cov_trace(self):
        """Position-block trace summed over all edges, per run."""
        return self.pos_var().sum(axis=(0, 1))

    def edge_cov_trace(self, e):
        return self.pos_var()[e].sum(axis=0)


class Garkf(RkfCA):
    """`garkf`: Algorithm 1 with the corrections of issue 10 (see the module doc)."""

    def __init__(self, ctx):
        super().__init__(ctx)
        N, R, D = ctx.N, ctx.R, ctx.D
        self.theta = np.zeros((N, R, D, D))  # That_{i,0} = 0 (the paper gives none)
        self.psi = np.full((N, R), np.nan)  # held convergence indicator; NaN: no value yet
        self.Ainv = np.zeros((N, R, D, D))  # held A_i^-1 of the last feasible step
        self.theta_ral = np.zeros((N, R, D, D))
        self.feas = np.zeros((N, R), dtype=bool)
        self.cnt = np.zeros((N, R))
        self.n_geo = 0

    def observe(self, y, beta, k, t):
        c, geo = self.ctx, self.ctx.geo
        literal = c.infeasible == "literal"
        # lines 3-8: RAL (12)-(14), Definition 2
        th_ral, Ainv, feas, nobs = ral(geo, beta, y)
        # lines 9-10: convergence indicator (18), held when undefined
        psi = convergence_indicator(geo, beta, th_ral, feas, literal)
        ok = ~np.isnan(psi)
        self.psi[ok] = psi[ok]
        self.Ainv[feas] = Ainv[feas]
        # line 11: consensus (16)
        self.theta, self.cnt = consensus(geo, beta, self.theta, th_ral, feas, c.eps, literal)
        self.theta_ral, self.feas = th_ral, feas
        # lines 12-16: geometric observation for the edges without a measurement
        zgeo = np.einsum("erdf,ef->edr", self.theta[geo.I], geo.pe)  # (14) with That_{i,k}
        cfac = ral_cov_factor(geo, self.Ainv)  # (15)
        psi_e = self.psi[geo.I]  # (M, R)
        has = np.isfinite(psi_e)  # (a diverged run can overflow psi: no geometric update then)
        geo_ok = has & (beta == 0)
        # composite observation (8) and covariance (10): R^geo + psi I = V diag(c r_d / N + psi) V^T
        obs = (beta > 0)[:, None, :]
        yobs = np.where(obs, y, zgeo)
        np.matmul(c.V.T, yobs, out=self.yr)  # y' = V^T y
        rd = c.rdiag[None, :, None]
        rgeo = rd * (cfac / c.N)[:, None, :] + np.where(has, psi_e, 0.0)[:, None, :]
        r = np.where(obs, rd, rgeo).reshape(-1)
        mask = np.broadcast_to(((beta > 0) | geo_ok)[:, None, :], (c.M, c.D, c.R)).reshape(-1)
        self.n_geo += int(geo_ok.sum())
        return self.yr.reshape(-1), r, mask


# a run counts as diverged once delta_k exceeds this (the formation spans ~4 m: delta = 10^3 is an
# RMS position error of ~30 m); it then counts in no time average
DIVERGED = 1e3

KINDS = {"none": NoneEst, "rkf-ca": RkfCA, "garkf": Garkf, "oracle": Oracle}


# ----------------------------------------------------------------------------------------------
# Closed loop
# ----------------------------------------------------------------------------------------------
class Context:
    """Model constants shared by the estimators."""

    def __init__(self, sc, a):
        self.D = D = int(sc["dim"])
        self.N = N = int(sc["agents"])
        self.P = np.array(sc["config"], dtype=float)
        edges = [tuple(e) for e in sc["edges"]]
        self.M = M = len(edges)
        self.I = np.array([e[0] for e in edges])
        self.J = np.array([e[1] for e in edges])
        self.l = np.array(sc["weights"], dtype=float)
        self.leaders = np.array(sc.get("leaders", [0, 1, 2]), dtype=int)
        self.followers = np.array([i for i in range(N) if i not in set(self.leaders)], dtype=int)
        self.init_mean = np.array(sc["init_mean"], dtype=float)
        self.init_cov = np.array(sc["init_cov"], dtype=float)
        self.R = a.runs
        self.dt, self.steps, self.lam, self.gain = a.dt, a.steps, a.lam, a.gain
        self.eps, self.infeasible = a.eps, a.infeasible
        self.Rm = a.sigma_v ** 2 * np.array([[1.0, a.rho], [a.rho, 1.0]])  # R_ij, common
        rd, V = np.linalg.eigh(self.Rm)  # R = V diag(rd) V^T
        self.rdiag, self.V = rd, V
        self.F3, self.Q3 = ca_model(a.dt, a.sigma_w)
        # Lambda_0 per coordinate: position 2 (edge of two N(0, I) agents), velocity and
        # acceleration 1 (the paper gives no initial covariance).
        self.lam0 = np.array([2.0 * float(np.mean(np.diag(self.init_cov))), 1.0, 1.0])
        self.geo = Geometry(self.P, self.I, self.J, N)
        BT = np.zeros((M * D, N * D))
        C = np.zeros((N * D, M * D))
        for e, (i, j) in enumerate(edges):
            for d in range(D):
                BT[e * D + d, i * D + d] = 1.0
                BT[e * D + d, j * D + d] = -1.0
                if i not in set(self.leaders):
                    C[i * D + d, e * D + d] = -a.dt * a.gain * self.l[e]  # static law, times dt
        self.BT, self.C = BT, C


def simulate(sc, a, progress=True):
    ctx = Context(sc, a)
    D, N, M, R, L = ctx.D, ctx.N, ctx.M, ctx.R, len(a.estimators)
    rng = np.random.Generator(np.random.SFC64(a.seed))
    CR = np.linalg.cholesky(ctx.Rm)
    CP = np.linalg.cholesky(ctx.init_cov)
    est = [KINDS[k](ctx) for k in a.estimators]
    # Every lane starts from the same z_1: followers ~ N(mu, P), leaders on the target.
    z0 = ctx.init_mean[None, :, None] + np.einsum("ab,nbr->nar", CP, rng.standard_normal((N, D, R)))
    if a.init == "target":  # diagnostic: followers start on the target (no initial transient)
        z0 = target(ctx.dt, ctx.P)[0][:, :, None] + 0.0 * z0
    z = np.empty((L, N, D, R))
    z[...] = z0[None]
    zhat = np.zeros((L, M, D, R))
    ud = np.empty((L, N * D, R))
    x = np.empty((L, M * D, R))
    every = a.every
    rep = [k for k in range(1, a.steps + 1) if k == 1 or k % every == 0 or k == a.steps]
    nr = len(rep)
    out = {m: np.full((L, nr, R), np.nan) for m in ("tracking_error", "cov_trace", "edge_cov_trace", "psi",
                                                   "theta_error", "theta_ral_error")}
    delta = np.empty((L, a.steps, R))  # delta_k per lane and run (eq. 4)
    cov_excess = -np.inf  # max over checked steps of lambda_max(Lambda_garkf - Lambda_rkfca)
    qr = a.estimators.index("rkf-ca") if "rkf-ca" in a.estimators else None
    qg = a.estimators.index("garkf") if "garkf" in a.estimators else None
    diverged = np.zeros((L, R), dtype=bool)
    fl = ctx.followers
    # stability of the consensus iteration: sampled spectra of L_k + diag|J_i| (garkf only)
    eig_max = []
    # the target of every step, eq. (2)
    tgt = [target(k * ctx.dt, ctx.P) for k in range(1, a.steps + 1)]
    zs_all = np.array([g[0] for g in tgt])
    th_all = np.array([g[1] for g in tgt])
    B = 100  # steps of draws at once
    ri = 0
    t0, c0 = time.perf_counter(), time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        for k0 in range(1, a.steps + 1, B):
            nb = min(B, a.steps + 1 - k0)
            v = np.matmul(CR, rng.standard_normal((nb, M, D, R)))  # v_ij ~ N(0, R)
            beta = (rng.random((nb, M, R)) < ctx.lam).astype(float)  # beta_ij,k ~ Bernoulli(lambda)
            for s in range(nb):
                k = k0 + s
                t = k * ctx.dt
                zs, th_star = zs_all[k - 1], th_all[k - 1]
                z[:, ctx.leaders, :, :] = zs[ctx.leaders][None, :, :, None]  # leaders on the target
                np.matmul(ctx.BT, z.reshape(L, N * D, R), out=x)  # z_ij = z_i - z_j
                y = x.reshape(L, M, D, R) + v[s][None]  # y_ij = z_ij + v_ij (9)
                b = beta[s]
                xq = x.reshape(L, M, D, R)
                for q, f in enumerate(est):
                    zhat[q] = f.step(y[q], b, k, t, xq[q])
                dl = tracking_error(z, zs)
                bad = ~np.isfinite(dl) | (dl > DIVERGED)
                if bad.any():
                    diverged |= bad
                delta[:, k - 1] = np.where(diverged, np.nan, dl)
                if ri < nr and rep[ri] == k:
                    if a.checks and qr is not None and qg is not None and ri % 10 == 0:
                        dlam = (est[qg].lam - est[qr].lam).transpose(2, 0, 1)
                        dlam = dlam[np.isfinite(dlam).all(axis=(1, 2))]
                        if dlam.size:
                            cov_excess = max(cov_excess, float(np.linalg.eigvalsh(dlam).max()))
                    out["tracking_error"][:, ri] = np.where(diverged, np.nan, dl)
                    for q, f in enumerate(est):
                        out["cov_trace"][q, ri] = f.cov_trace()
                        if isinstance(f, RkfCA):
                            out["edge_cov_trace"][q, ri] = f.edge_cov_trace(a.edge)
                        if isinstance(f, Garkf):
                            with np.errstate(all="ignore"):
                                out["psi"][q, ri] = np.nanmean(f.psi, axis=0)
                            dth = f.theta - th_star[None, None]
                            out["theta_error"][q, ri] = np.einsum("nrab,nrab->r", dth, dth) / N
                            dr = f.theta_ral - th_star[None, None]
                            d2 = np.einsum("nrab,nrab->nr", dr, dr)
                            cnt = f.feas.sum(axis=0)
                            out["theta_ral_error"][q, ri] = np.where(
                                cnt > 0, (d2 * f.feas).sum(axis=0) / np.maximum(cnt, 1), np.nan)
                            if a.checks and ri % 10 == 0:
                                mu = consensus_bound(ctx.geo, b, f.cnt)
                                # mu = 0: an agent with no neighbour and no RAL input holds its
                                # estimate (marginal, not unstable); check the others
                                mu = mu[np.abs(mu) > 1e-9]
                                eig_max.append((float(np.abs(mu).max()),
                                                float(np.abs(1 - ctx.eps * mu).max())))
                    ri += 1
                # control u_k on the estimates (static law), followers move (3)
                np.matmul(ctx.C, zhat.reshape(L, M * D, R), out=ud)
                z[:, fl] += ud.reshape(L, N, D, R)[:, fl]
            if progress and (k0 // B) % 10 == 0:
                print(f"  step {k0 + nb - 1}/{a.steps}  {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    res = dict(ctx=ctx, est=est, rep=rep, out=out, wall=wall, cpu=cpu, diverged=diverged,
               delta=delta, consensus=eig_max, cov_excess=cov_excess)
    return res


def riccati_check(a, tol=1e-15, max_iter=200000):
    """The lambda = 1 steady state of rkf-ca, independently: the full 3D x 3D Riccati recursion
    (predict with F = F3 (x) I_D, Q = Q3 (x) I_D; update with G = [I 0 0], R) in the original
    coordinates, iterated to a fixed point.  Returns tr of the position block and iterations."""
    F3, Q3 = ca_model(a.dt, a.sigma_w)
    D = 2
    F, Q = np.kron(F3, np.eye(D)), np.kron(Q3, np.eye(D))
    G = np.kron(np.array([[1.0, 0.0, 0.0]]), np.eye(D))
    Rm = a.sigma_v ** 2 * np.array([[1.0, a.rho], [a.rho, 1.0]])
    Lam = np.eye(3 * D)
    I6 = np.eye(3 * D)
    for it in range(max_iter):
        Pp = F @ Lam @ F.T + Q
        K = Pp @ G.T @ np.linalg.inv(G @ Pp @ G.T + Rm)
        A = I6 - K @ G
        new = A @ Pp @ A.T + K @ Rm @ K.T
        new = 0.5 * (new + new.T)
        if np.abs(new - Lam).max() <= tol * np.abs(Lam).max():
            Lam = new
            break
        Lam = new
    return float(np.trace(Lam[:D, :D])), it + 1, Lam


def consistency_check(a, lam=0.2, edges=200, steps=4000, burn=1000, seed=3):
    """rkf-ca against its own model (not in the loop): edges that really follow the CA model
    (5a)-(7) with sigma_w, observed through the correlated R with availability lambda.  For a
    correct filter the mean squared position error equals the mean position-block trace
    (ratio 1 up to Monte Carlo error).  Uses the same kf_predict / kf_correct and the same
    eigenbasis rotation as the closed loop."""
    rng = np.random.default_rng(seed)
    F3, Q3 = ca_model(a.dt, a.sigma_w)
    Rm = a.sigma_v ** 2 * np.array([[1.0, a.rho], [a.rho, 1.0]])
    rd, V = np.linalg.eigh(Rm)
    D = 2
    # Q3 (7) is rank one: sigma_w^2 g g^T with g = [dt^2/2, dt, 1] (a random acceleration increment)
    g = np.array([[a.dt ** 2 / 2], [a.dt], [1.0]])
    assert np.allclose(a.sigma_w ** 2 * g @ g.T, Q3)
    CQ = np.kron(a.sigma_w * g, np.eye(D))  # (3D, D)
    CR = np.linalg.cholesky(Rm)
    Ft = np.kron(F3, np.eye(D))
    truth = np.zeros((3 * D, edges))  # [z, zdot, zddot] per edge, original coordinates
    n = edges * D
    gamma = np.zeros((3, n))
    lam_ = np.zeros((3, 3, n))
    lam_[0, 0], lam_[1, 1], lam_[2, 2] = 1.0, 1.0, 1.0
    truth[:D] = rng.standard_normal((D, edges))
    rmeas = np.broadcast_to(rd[None, :, None], (edges, D, 1)).reshape(n)
    se, tr = 0.0, 0.0
    for k in range(steps):
        truth = Ft @ truth + CQ @ rng.standard_normal((D, edges))
        y = truth[:D] + CR @ rng.standard_normal((D, edges))  # (D, E)
        beta = (rng.random(edges) < lam).astype(float)
        kf_predict(gamma, lam_, F3, Q3)
        yr = (V.T @ y).T.reshape(n)  # (E, D) rows in the eigenbasis
        mask = np.repeat(beta, D)
        kf_correct(gamma, lam_, yr, rmeas, mask)
        if k >= burn:
            zhat = V @ gamma[0].reshape(edges, D).T  # (D, E)
            se += float(np.sum((zhat - truth[:D]) ** 2)) / edges
            tr += float(lam_[0, 0].sum()) / edges
    return se / tr, tr / (steps - burn)


def write_metrics(path, labels, rep, out, dt):
    with open(path, "w") as f:
        f.write("estimator,step,time,metric,mean,std\n")
        for q, lab in enumerate(labels):
            for met, arr in out.items():
                a = arr[q]
                if np.all(np.isnan(a)):
                    continue
                for i, k in enumerate(rep):
                    v = a[i][np.isfinite(a[i])]
                    mu = float(v.mean()) if v.size else float("nan")
                    sd = float(v.std(ddof=1)) if v.size > 1 else float("nan")
                    f.write(f"{lab},{k},{k * dt!r},{met},{mu!r},{sd!r}\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario")
    ap.add_argument("--out")
    ap.add_argument("--lam", type=float, default=0.4, help="availability lambda of every directed edge")
    ap.add_argument("--gain", type=float, default=5.0, help="follower gain c of the static law")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--dt", type=float, default=0.01)
    ap.add_argument("--sigma-v", type=float, default=0.1)
    ap.add_argument("--rho", type=float, default=0.3)
    ap.add_argument("--sigma-w", type=float, default=1.0)
    ap.add_argument("--eps", type=float, default=0.08)
    ap.add_argument("--infeasible", choices=("masked", "literal"), default="masked")
    ap.add_argument("--estimators", default="none,rkf-ca,garkf")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--edge", type=int, default=0, help="directed edge index for edge_cov_trace")
    ap.add_argument("--checks", action="store_true",
                    help="also check Lambda_garkf <= Lambda_rkfca and sample the consensus spectra "
                         "(every 10th report; not for timing runs)")
    ap.add_argument("--init", choices=("random", "target"), default="random",
                    help="followers start ~ N(init_mean, init_cov) of the scenario (default), or on "
                         "the target (diagnostic)")
    ap.add_argument("--riccati", action="store_true",
                    help="only the checks: the lambda = 1 Riccati fixed point, and rkf-ca's consistency "
                         "against its own model at availability --lam")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    if a.riccati:
        tr, it, _ = riccati_check(a)
        ratio, mtr = consistency_check(a, lam=a.lam)
        print(json.dumps(dict(riccati_position_trace=tr, iterations=it,
                              consistency_lambda=a.lam, consistency_mse_over_trace=ratio,
                              consistency_mean_pos_trace=mtr)))
        return
    a.estimators = a.estimators.split(",")
    with open(a.scenario) as f:
        sc = json.load(f)
    res = simulate(sc, a, progress=not a.quiet)
    ctx = res["ctx"]
    L = len(a.estimators)
    agent_steps = a.runs * ctx.N * a.steps
    # Consensus stability (16): eps < 2 / lambda_max(L_k + diag|J_i|); the worst graph is the
    # nominal one with every edge available and every agent feasible (|J_i| = N_i + 1).
    full = consensus_bound(ctx.geo, np.ones((ctx.M, 1)), (ctx.geo.Sel.sum(axis=1) + 1)[:, None])
    lmax = float(np.abs(full).max())
    summ = dict(lam=a.lam, gain=a.gain, runs=a.runs, steps=a.steps, eps=a.eps,
                infeasible=a.infeasible, estimators=a.estimators,
                consensus_lambda_max_full_graph=lmax, consensus_eps_bound=2.0 / lmax,
                riccati_position_trace=riccati_check(a)[0],
                wall=res["wall"], cpu=res["cpu"],
                agent_steps_per_s=agent_steps / res["wall"],
                agent_steps_per_s_per_estimator=agent_steps * L / res["wall"],
                numpy=np.__version__, python=sys.version.split()[0], loadavg_after=os.getloadavg())
    if res["consensus"]:
        mu = np.array(res["consensus"])
        summ["consensus_sampled_max_abs_mu"] = float(mu[:, 0].max())
        summ["consensus_sampled_max_abs_1_minus_eps_mu"] = float(mu[:, 1].max())
    if a.checks and np.isfinite(res["cov_excess"]):
        summ["max_eig_Lambda_garkf_minus_Lambda_rkfca"] = res["cov_excess"]
    times = np.arange(1, a.steps + 1) * a.dt
    windows = {"0-60": (0.0, 1e9), "5-10": (5.0, 10.0), "10-60": (10.0, 1e9)}
    per_run = {}  # time-averaged delta per lane, window, run
    for q, lab in enumerate(a.estimators):
        dv = res["diverged"][q]
        f = res["est"][q]
        s = dict(diverged_runs=int(dv.sum()))
        for wn, (w0, w1) in windows.items():
            sel = (times > w0) & (times <= w1)
            dm = res["delta"][q][sel].mean(axis=0)
            dm[dv] = np.nan  # a run that diverged at any time counts in no window
            per_run[(lab, wn)] = dm
            ok = dm[np.isfinite(dm)]
            s[f"delta_{wn}"] = float(ok.mean()) if ok.size else None
            s[f"delta_{wn}_se"] = float(ok.std(ddof=1) / np.sqrt(ok.size)) if ok.size > 1 else None
        if isinstance(f, RkfCA):
            per_edge = f.pos_var().sum(axis=1)  # (M, R)
            s["final_pos_cov_per_edge_mean"] = float(per_edge.mean())
            s["final_pos_cov_per_edge_min_max"] = [float(per_edge.min()), float(per_edge.max())]
        if isinstance(f, Garkf):
            s["geometric_updates"] = f.n_geo
        summ[lab] = s
    # Paired differences (same draws): time-averaged delta of each estimator minus rkf-ca's.
    if "rkf-ca" in a.estimators:
        for lab in a.estimators:
            if lab == "rkf-ca":
                continue
            for wn in windows:
                d = per_run[(lab, wn)] - per_run[("rkf-ca", wn)]
                d = d[np.isfinite(d)]
                if d.size > 1:
                    summ[lab][f"delta_{wn}_minus_rkf_ca"] = [float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size))]
    if "rkf-ca" in a.estimators and "garkf" in a.estimators:
        f1 = res["est"][a.estimators.index("rkf-ca")]
        f2 = res["est"][a.estimators.index("garkf")]
        q1, q2 = a.estimators.index("rkf-ca"), a.estimators.index("garkf")
        summ["garkf_equals_rkf_ca_bitwise"] = bool(
            np.array_equal(f1.gamma, f2.gamma) and np.array_equal(f1.lam, f2.lam)
            and np.array_equal(res["delta"][q1], res["delta"][q2], equal_nan=True))
    print(json.dumps(summ, indent=1))
    if a.out:
        os.makedirs(a.out, exist_ok=True)
        write_metrics(os.path.join(a.out, "metrics.csv"), a.estimators, res["rep"], res["out"], a.dt)
        with open(os.path.join(a.out, "summary.json"), "w") as f:
            json.dump(summ, f, indent=1)
    return res, summ


if __name__ == "__main__":
    main()
