"""edgekf: relative (edge-state) Kalman filtering for distributed formation control.

The Rust engine, the weight designs and the edge filters of the ``edgekf`` project, NumPy in
and out. The numbers are the command-line program's: the same scenario and seed give the same
bits, and :meth:`Result.save` writes the CLI's files (``metrics.csv`` byte-identical to
``edgekf run``).

Conventions (``docs/formats.md``): agents ``0..N``, dimensions ``0..D``; a directed edge
``(i, j)`` means agent *i* measures agent *j*, its state is ``z_ij = z_i - z_j`` (thesis eq. 4.5).

Quick start::

    import edgekf
    res = edgekf.run("scenarios/eusipco.toml", runs=20, steps=2000, seed=1)
    t, mean, std = res.metric("rkf", "est_error")   # thesis eq. (4.34)
    res.save("out")                                 # the CLI's tables
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _edgekf

__all__ = [
    "run",
    "resolve",
    "Result",
    "reproduce",
    "list_reproductions",
    "design",
    "check",
    "EdgeFilter",
    "__version__",
]

__version__: str = _edgekf.__version__

ScenarioLike = Union[str, "os.PathLike[str]", Dict[str, Any]]


def _source(scenario: ScenarioLike) -> Tuple[str, str, Optional[str], bool]:
    """(source, text, base directory, is_dict) of a path or a dict."""
    if isinstance(scenario, dict):
        try:
            text = json.dumps(scenario, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise ValueError(f"<dict>: cannot be read as a scenario: {e}") from None
        return "<dict>", text, os.getcwd(), True
    if isinstance(scenario, (str, os.PathLike)):
        path = os.fspath(scenario)
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except OSError as e:
            raise ValueError(f"cannot read {path}: {e.strerror or e}") from None
        base = os.path.dirname(path) or None
        return path, text, base, False
    raise TypeError(
        f"scenario: expected a path (str or os.PathLike) or a dict, got {type(scenario).__name__}"
    )


class Result:
    """The outcome of a Monte Carlo study (``edgekf.run`` / ``edgekf.reproduce``).

    Attributes
    ----------
    scenario : dict
        The resolved scenario (schema ``edgekf.scenario/1``): anyone can recompute from it.
    estimators : list of str
        Estimator labels, in scenario order.
    metrics : list of str
        Metric names (union over the estimators, in order): ``est_error`` (ε_k, thesis eq.
        4.34), ``est_error_sq``, ``cov_trace``, ``procrustes`` (thesis Def. 2.9),
        ``tracking_error`` (Li & Rajan eq. 4), …
    """

    def __init__(self, inner: "_edgekf._Result") -> None:
        self._r = inner
        self._scenario: Optional[Dict[str, Any]] = None

    @property
    def scenario(self) -> Dict[str, Any]:
        if self._scenario is None:
            self._scenario = json.loads(self._r.scenario_json())
        return self._scenario

    @property
    def estimators(self) -> List[str]:
        return self._r.estimators()

    @property
    def metrics(self) -> List[str]:
        seen: List[str] = []
        for e in self._r.estimators():
            for m in self._r.metrics_of(e):
                if m not in seen:
                    seen.append(m)
        return seen

    @property
    def runs(self) -> int:
        """Monte Carlo runs."""
        return self._r.runs

    @property
    def dt(self) -> float:
        """Time step Δt."""
        return self._r.dt

    @property
    def steps(self) -> np.ndarray:
        """Reported steps k (1-based), as int64; time is ``k * dt``."""
        return self._r.steps().astype(np.int64)

    def metrics_of(self, estimator: str) -> List[str]:
        """Metric names of one estimator."""
        return self._r.metrics_of(estimator)

    def metric(self, estimator: str, name: str) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(time, mean, std)`` of metric ``name`` of ``estimator`` across the runs.

        float64 arrays over the reported steps the estimator completed (all of them unless it
        diverged); ``std`` has ddof = 1, as in ``metrics.csv``.

        Raises ``ValueError`` for an unknown estimator or metric.
        """
        return self._r.metric(estimator, name)

    def paths(self, estimator: str) -> np.ndarray:
        """Positions of the recorded run: float64 array (reported steps × agents × D)."""
        return self._r.paths(estimator)

    def inputs(self, estimator: str) -> np.ndarray:
        """Inputs u of the recorded run: float64 array (reported steps × agents × D)."""
        return self._r.inputs(estimator)

    def status(self, estimator: str) -> Dict[str, Any]:
        """How an estimator ended: ``{"status": "completed"|"diverged", "step", "run", "cause"}``."""
        s, step, run_, cause = self._r.status(estimator)
        return {"status": s, "step": step, "run": run_, "cause": cause}

    def metrics_csv(self) -> str:
        """The text of ``metrics.csv`` (``estimator,step,time,metric,mean,std``)."""
        return self._r.metrics_csv()

    def to_pandas(self) -> "Any":
        """A tidy ``pandas.DataFrame`` with the columns of ``metrics.csv``.

        Raises ``ImportError`` when pandas is not installed.
        """
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Result.to_pandas() needs pandas: pip install pandas") from e
        frames = []
        steps = self.steps
        for e in self.estimators:
            for m in self.metrics_of(e):
                t, mean, std = self.metric(e, m)
                n = len(t)
                frames.append(
                    pd.DataFrame(
                        {
                            "estimator": [e] * n,
                            "step": steps[:n],
                            "time": t,
                            "metric": [m] * n,
                            "mean": mean,
                            "std": std,
                        }
                    )
                )
        if not frames:
            return pd.DataFrame(columns=["estimator", "step", "time", "metric", "mean", "std"])
        return pd.concat(frames, ignore_index=True)

    def save(self, dir: Union[str, "os.PathLike[str]"]) -> None:
        """Writes the CLI's tables into ``dir`` (created if missing), atomically.

        ``scenario.json``, ``metrics.csv`` (byte-identical to ``edgekf run``'s), ``paths.csv``,
        ``inputs.csv`` (when the scenario has input figures) and ``status.csv``, through the
        CLI's own writers. Figures (PNG) and ``provenance.json`` are the CLI's alone.
        """
        self._r.save(os.fspath(dir))

    def __repr__(self) -> str:
        return (
            f"<edgekf.Result {self.scenario.get('name', '?')!r}: {self.runs} runs, "
            f"estimators {self.estimators}>"
        )


def run(
    scenario: ScenarioLike,
    *,
    runs: Optional[int] = None,
    steps: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    every: Optional[int] = None,
    progress: bool = False,
) -> Result:
    """Runs the Monte Carlo study of a scenario, as ``edgekf run`` does.

    Parameters
    ----------
    scenario
        Path to a TOML scenario or a resolved ``scenario.json``, or a dict with the same keys
        (a TOML scenario's tables, or a resolved scenario with its ``schema`` key).
    runs, steps, seed, every
        The CLI's ``--runs``, ``--steps``, ``--seed``, ``--every`` overrides.
    threads
        Worker threads (default: one per core), the CLI's ``--threads``.
    progress
        Print the progress to stderr.

    The GIL is released during the run; Ctrl-C (``KeyboardInterrupt``) stops it cleanly.

    Raises
    ------
    ValueError
        Bad input, with the CLI's message (file, key, problem).
    """
    source, text, base, is_dict = _source(scenario)
    return Result(
        _edgekf.run_text(
            source,
            text,
            base,
            is_dict,
            runs=runs,
            steps=steps,
            every=every,
            seed=seed,
            threads=threads,
            progress=progress,
        )
    )


def resolve(scenario: ScenarioLike) -> Dict[str, Any]:
    """Checks a scenario without running it; returns the resolved scenario as a dict."""
    source, text, base, is_dict = _source(scenario)
    return json.loads(_edgekf.resolve_text(source, text, base, is_dict))


def list_reproductions() -> List[Dict[str, Any]]:
    """The reproducible figures of the papers: ``[{name, description, simulation, plots, slam}]``."""
    return [
        {"name": n, "description": d, "simulation": s, "plots": list(p), "slam": slam}
        for (n, d, s, p, slam) in _edgekf.reproductions()
    ]


_OVERRIDES = ("runs", "steps", "seed", "every", "threads", "progress")


def reproduce(name: str, **overrides: Any) -> Result:
    """Runs the simulation behind a figure of the papers (``edgekf reproduce NAME``).

    ``overrides``: ``runs``, ``steps``, ``seed``, ``every``, ``threads``, ``progress``, as for
    :func:`run`. SLAM studies run with the CLI only.
    """
    bad = sorted(set(overrides) - set(_OVERRIDES))
    if bad:
        raise ValueError(
            f"reproduce: unknown override(s) {', '.join(bad)}; allowed: {', '.join(_OVERRIDES)}"
        )
    return Result(_edgekf.reproduce(name, **overrides))


def _config_list(config: Any) -> List[List[float]]:
    a = np.asarray(config, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"config: expected an N × D array of points, got shape {a.shape}")
    return a.tolist()


def _edges_list(edges: Any) -> List[List[int]]:
    a = np.asarray(edges)
    if a.size == 0:
        return []
    if a.ndim != 2 or a.shape[1] != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"edges: expected an L × 2 array of agent indices, got shape {a.shape}")
    if (a < 0).any():
        raise ValueError("edges: agent indices must be non-negative")
    return a.tolist()


def design(
    config: Any,
    edges: Any,
    *,
    method: str = "sdp",
    leaders: Union[None, Sequence[int], str] = None,
    leader_mode: str = "clique",
    name: str = "python",
) -> Dict[str, Any]:
    """Designs stress weights for a framework (``edgekf design``).

    ``method``: ``"sdp"`` (thesis SDP (3.5), stress matrix PSD with maximal gap), ``"yang"``
    (Yang et al. 2019 construction) or ``"sparse"`` (ℓ1-penalised). ``leaders``: a list of
    D + 1 agents, ``"auto"`` (chosen by ``leader_mode``: ``"clique"`` or ``"affine"``), or None.

    Returns the ``edgekf.framework/1`` document with ``weights`` (``edges`` reduced to the links
    with a nonzero weight). Raises ``ValueError`` when the input is malformed or infeasible (the
    failed condition named).
    """
    mode = None
    lead: Optional[List[int]] = None
    if isinstance(leaders, str):
        if leaders != "auto":
            raise ValueError(f"leaders: expected a list of agents, 'auto' or None, got {leaders!r}")
        mode = leader_mode
    elif leaders is not None:
        lead = [int(i) for i in leaders]
    doc = _edgekf.design_json(
        _config_list(config), _edges_list(edges), method, lead, mode, name
    )
    return json.loads(doc)


def check(
    config: Any, edges: Any, weights: Any, *, leaders: Optional[Sequence[int]] = None
) -> Dict[str, Any]:
    """Checks a weighted framework (the report of ``edgekf design``).

    Returns its numbers (``eigenvalues`` of the stress matrix, ``rank`` vs ``expected_rank``
    N − D − 1, ``equilibrium_residual`` of Ω p = 0, ``stress_gap``, …), the conditions
    (``connected``, ``generic``, ``equilibrium``, ``psd``, ``universally_rigid``), ``passed``,
    ``verdict`` (``"passed"`` or the failed condition) and ``report`` (the CLI's text).
    Raises ``ValueError`` for malformed input only.
    """
    w = np.asarray(weights, dtype=np.float64).ravel().tolist()
    lead = None if leaders is None else [int(i) for i in leaders]
    return _edgekf.check(_config_list(config), _edges_list(edges), w, lead)


def _mat(a: Any, what: str, b: int, d: int, batched: bool) -> np.ndarray:
    m = np.asarray(a, dtype=np.float64)
    if m.ndim == 0:
        m = m * np.eye(d)
    if m.shape == (d, d):
        if what == "P0":
            m = np.broadcast_to(m, (b, d, d))
    elif not (batched and m.shape == (b, d, d)):
        want = f"({d}, {d})" + (f" or ({b}, {d}, {d})" if batched else "")
        raise ValueError(f"{what}: expected shape {want}, got {m.shape}")
    return np.ascontiguousarray(m)


class EdgeFilter:
    """Relative Kalman filter(s) of edge states, for a user's own loop (EUSIPCO eq. (5)).

    One edge: ``x0`` of shape (D,); a batch of B edges (or runs): ``x0`` of shape (B, D), and
    every call takes and returns arrays with that leading batch axis, so a Python loop calls
    Rust once per step, not once per edge.

    Per step, with ``du = Δt (u_i − u_j)`` the communicated inputs' displacement and ``y`` the
    mean of the T measurements of ``z_ij``:

    - predict (5c), (5d): ``x̂⁻ = x̂ + du``, ``P⁻ = P + Q``;
    - update (5e)–(5g): ``K = P⁻ (P⁻ + R)⁻¹``, ``x̂ = x̂⁻ + K (y − x̂⁻)``,
      ``P = (I − K) P⁻ (I − K)ᵀ + K R Kᵀ`` (Joseph form).

    ``R`` is the covariance of ``y`` (for T samples of covariance R_ij: R_ij / T); ``Q`` the
    edge's process covariance (Q_ij = B̄_ijᵀ Q B̄_ij, both ends' noise). Matrices may be scalars
    (times I), (D, D), or (B, D, D) in the batched form.
    """

    def __init__(
        self,
        kind: str = "rkf",
        *,
        R: Any,
        Q: Any,
        x0: Any,
        P0: Any,
    ) -> None:
        if kind != "rkf":
            raise ValueError(f"EdgeFilter: unknown kind {kind!r}; available: 'rkf'")
        self.kind = kind
        x = np.asarray(x0, dtype=np.float64)
        if x.ndim == 1:
            self.batched = False
            x = x[None, :]
        elif x.ndim == 2:
            self.batched = True
        else:
            raise ValueError(f"x0: expected shape (D,) or (B, D), got {x.shape}")
        b, d = x.shape
        if not 1 <= d <= 3:
            raise ValueError(f"x0: D must be 1, 2 or 3, got {d}")
        self._bank = _edgekf._EdgeBank(
            np.ascontiguousarray(x),
            _mat(P0, "P0", b, d, self.batched),
            _mat(Q, "Q", b, d, self.batched),
            _mat(R, "R", b, d, self.batched),
        )
        self.dim = d
        self.batch = b

    def _arg(self, a: Any, what: str) -> np.ndarray:
        v = np.asarray(a, dtype=np.float64)
        want = (self.batch, self.dim) if self.batched else (self.dim,)
        if v.shape != want:
            raise ValueError(f"{what}: expected shape {want}, got {v.shape}")
        return v if self.batched else v[None, :]

    def _out(self, xp: Tuple[np.ndarray, np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
        x, p = xp
        return (x, p) if self.batched else (x[0], p[0])

    def predict(self, du: Any) -> Tuple[np.ndarray, np.ndarray]:
        """Prediction (5c), (5d) with the input displacement ``du``; returns ``(x̂⁻, P⁻)``."""
        return self._out(self._bank.predict(self._arg(du, "du")))

    def update(self, y: Any) -> Tuple[np.ndarray, np.ndarray]:
        """Update (5e)–(5g) with the measurement mean ``y``; returns ``(x̂, P)``.

        Raises ``ValueError`` (naming the edge) if ``P⁻ + R`` is not positive definite; the
        state is then unchanged.
        """
        return self._out(self._bank.update(self._arg(y, "y")))

    def step(self, du: Any, y: Any) -> Tuple[np.ndarray, np.ndarray]:
        """``predict(du)`` then ``update(y)``; returns ``(x̂, P)``. Atomic on error."""
        return self._out(self._bank.step(self._arg(du, "du"), self._arg(y, "y")))

    @property
    def x(self) -> np.ndarray:
        """Current estimate ``x̂`` ((D,) or (B, D))."""
        return self._out(self._bank.state())[0]

    @property
    def P(self) -> np.ndarray:
        """Current covariance ``P`` ((D, D) or (B, D, D))."""
        return self._out(self._bank.state())[1]
