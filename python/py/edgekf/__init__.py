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
    res.save("out")                                 # the CLI's files and figures
"""

from __future__ import annotations

# First, before NumPy's long import: a Ctrl-C that CPython drops in an import's weakref
# callback is raised again (python/src/interrupt.rs says why this is native code).
from . import _edgekf

_edgekf.keep_dropped_interrupts()

import csv
import io
import json
import operator
import os
import sys
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

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

_U64_MAX = 2**64 - 1


def _count(name: str, value: Any, minimum: int = 1, maximum: int = _U64_MAX) -> Optional[int]:
    """A whole-number argument (``int`` or a NumPy integer), checked against its range; the
    error names the parameter (``None`` passes through)."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected a whole number, got {value!r}")
    try:
        v = operator.index(value)
    except TypeError:
        raise TypeError(
            f"{name}: expected a whole number, got {type(value).__name__} {value!r}"
        ) from None
    if not minimum <= v <= maximum:
        bound = "2^64 - 1" if maximum == _U64_MAX else str(maximum)
        raise ValueError(f"{name}: must be a whole number in {minimum}..={bound}, got {v}")
    return v


def _json_default(o: Any) -> Any:
    """NumPy scalars and arrays where a scenario takes Python numbers and lists."""
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"Object of type {type(o).__name__} is not a scenario value")


def _source(scenario: ScenarioLike) -> Tuple[str, str, Optional[str], bool]:
    """(source, text, base directory, is_dict) of a path or a dict.

    A missing file raises ``FileNotFoundError`` (an unreadable one its ``OSError``), naming it.
    """
    if isinstance(scenario, dict):
        try:
            text = json.dumps(scenario, allow_nan=False, default=_json_default)
        except (TypeError, ValueError) as e:
            raise ValueError(f"<dict>: cannot be read as a scenario: {e}") from None
        return "<dict>", text, os.getcwd(), True
    if isinstance(scenario, (str, os.PathLike)):
        path = os.fspath(scenario)
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except OSError as e:
            raise type(e)(e.errno, f"cannot read {path}: {e.strerror or e}", path) from None
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

    def __init__(self, inner: "_edgekf._Result", call: Optional[str] = None) -> None:
        self._r = inner
        self._call = call
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

    @property
    def frame_steps(self) -> np.ndarray:
        """Steps k of the recorded frames, as int64 (time ``k * dt``); empty when none were.

        A few runs (at most 3) are recorded frame by frame (at most 100 frames, the first and last
        reported steps kept), as the CLI records them for ``frames.json`` and the report's player.
        """
        return self._r.frame_steps().astype(np.int64)

    def frames(self, estimator: str) -> List[Dict[str, Any]]:
        """The recorded runs of one estimator, frame by frame (``docs/formats.md``, frames.json).

        One dict per recorded run: ``run`` (its index), ``positions`` (frames × agents × D,
        true ``z_k`` [m]), ``estimates`` (frames × edges × D: ``x̂_ij`` as agent *i* holds it
        [m]), ``covariances`` (frames × edges × D × D, its posterior covariance [m²]; NaN where
        the estimator has none), ``observed`` (frames × edges, bool: agent *i* measured edge
        (*i*, *j*)) and ``present`` (frames × agents, bool). Edges are in the order of
        :attr:`edges`; an estimator that diverged has fewer frames than :attr:`frame_steps`.
        """
        out = []
        for run_, pos, est, cov, obs, pres in self._r.frames(estimator):
            out.append(
                {
                    "run": run_,
                    "positions": pos,
                    "estimates": est,
                    "covariances": cov,
                    "observed": obs,
                    "present": pres,
                }
            )
        return out

    @property
    def frame_targets(self) -> Optional[np.ndarray]:
        """The target formation ``Z*_k`` at the frames (frames × agents × D), ``None`` without
        a maneuver."""
        return self._r.frame_targets()

    @property
    def edges(self) -> np.ndarray:
        """The directed edges ``(i, j)`` (edges × 2, int64): agent *i* measures ``z_i − z_j``."""
        return self._r.edges().astype(np.int64)

    def to_rerun(
        self,
        path: Union[str, "os.PathLike[str]"],
        *,
        estimators: Optional[Sequence[str]] = None,
        runs: Optional[Sequence[int]] = None,
    ) -> None:
        """Writes a Rerun recording (``.rrd``) of the run: open it with ``rerun FILE.rrd``.

        On the time line ``time`` (seconds of simulated time; also ``step``): per recorded run
        and estimator the true positions, the formation each agent estimates (lines from agent
        *i* to where it puts neighbour *j*, ``z_i − x̂_ij``), 1σ ellipses (2-D) or ellipsoids
        (3-D) of those estimates, measured and lost links, departed agents; the target
        formation where there is a maneuver; and every metric's mean across runs as a time
        series. The entity paths are in the guide ("Python", Rerun recordings).

        ``estimators`` and ``runs`` (indices of recorded runs, see :meth:`frames`) select; the
        default is everything recorded. Needs the ``rerun-sdk`` package (``pip install
        'edgekf[rerun]'``): ``ImportError`` otherwise. Written to a temporary file, then
        renamed, so ``path`` is complete or untouched.
        """
        from . import _rerun

        _rerun.write(self, os.fspath(path), estimators, runs)

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
                # As in metrics.csv: a step where no run defines the quantity (ψ before any
                # feasible geometric observation) has no row.
                keep = ~np.isnan(mean)
                t, mean, std = t[keep], mean[keep], std[keep]
                n = len(t)
                frames.append(
                    pd.DataFrame(
                        {
                            "estimator": [e] * n,
                            "step": steps[: len(keep)][keep],
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

    def save(
        self, dir: Union[str, "os.PathLike[str]"], *, figures: bool = True, force: bool = False
    ) -> None:
        """Writes the CLI's files into ``dir`` (created if missing), atomically.

        ``scenario.json``, ``metrics.csv`` (byte-identical to ``edgekf run``'s), ``paths.csv``,
        ``inputs.csv`` (when the scenario has input figures), ``status.csv``, a sweep's
        ``summary.csv`` and ``sweep_metrics.csv``, ``provenance.json`` (this package's version
        and git commit, and the Python call that made the result) and, unless ``figures`` is
        false, the scenario's figures as PNG — through the CLI's own writers and plotting code.
        ``edgekf report DIR`` then makes the HTML page of the directory.

        Outputs never mix: ``dir`` must be new, empty, or hold this same study (the same
        scenario ``name``, as its ``provenance.json`` records; the files this save does not
        write again are removed). A folder that holds another study or files edgekf did not
        write raises ``FileExistsError`` naming them, unless ``force`` (which empties it
        first). An unwritable folder raises ``OSError`` (``PermissionError``, …).
        """
        d = os.fspath(dir)
        if self._call is not None:
            command = [sys.executable, "-c", f"import edgekf; {self._call}.save({d!r})"]
        else:
            command = [sys.executable] + list(sys.argv)
        self._r.save(d, command, figures, bool(force))

    @property
    def sweep_parameter(self) -> Optional[str]:
        """The swept key of a scenario with a ``[sweep]`` (``None`` otherwise)."""
        return self._r.sweep_parameter

    def sweep_summary(self) -> Optional[Dict[str, Any]]:
        """A sweep's summary (the columns of ``summary.csv``; ``None`` without a sweep).

        ``{"estimator": [...], "parameter": [...], "value": [...], "metric": [...],
        "mean": ndarray, "std": ndarray}``, one entry per estimator, value and summary metric;
        ``value`` is the value's label as written in the scenario.
        """
        text = self._r.summary_csv()
        if text is None:
            return None
        rows = list(csv.DictReader(io.StringIO(text)))
        out: Dict[str, Any] = {k: [r[k] for r in rows] for k in ("estimator", "parameter", "value", "metric")}
        out["mean"] = np.array([float(r["mean"]) for r in rows])
        out["std"] = np.array([float(r["std"]) for r in rows])
        return out

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
    max_hours: float = 1.0,
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
    max_hours
        Refuse a study estimated to take longer (the CLI's ``--max-hours``, default 1 h);
        one that needs more than 80 % of the available memory is refused too. Both are
        checked before the run starts.

    The GIL is released during the run; Ctrl-C (``KeyboardInterrupt``) stops it cleanly.

    Raises
    ------
    ValueError
        Bad input, with the CLI's message (file, key, problem); a count or seed out of range,
        naming the parameter.
    TypeError
        A count or seed that is not a whole number (``int`` or a NumPy integer).
    FileNotFoundError
        A missing scenario or framework file (``OSError`` for other unreadable files).
    """
    runs, steps, every, threads = (
        _count("runs", runs),
        _count("steps", steps),
        _count("every", every),
        _count("threads", threads),
    )
    seed = _count("seed", seed, minimum=0)
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
            max_hours=float(max_hours),
        ),
        None
        if is_dict
        else _call("run", repr(os.path.abspath(os.fspath(scenario))), runs=runs, steps=steps, every=every, seed=seed),
    )


def _call(fn: str, first: str, **kw: Any) -> str:
    """The Python call that re-makes a result (for ``provenance.json``)."""
    args = [first] + [f"{k}={v!r}" for k, v in kw.items() if v is not None]
    return f"edgekf.{fn}({', '.join(args)})"


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


_OVERRIDES = ("runs", "steps", "seed", "every", "threads", "progress", "max_hours")


def reproduce(name: str, **overrides: Any) -> Result:
    """Runs the simulation behind a figure of the papers (``edgekf reproduce NAME``).

    ``overrides``: ``runs``, ``steps``, ``seed``, ``every``, ``threads``, ``progress``,
    ``max_hours``, as for :func:`run`. SLAM studies run with the CLI only.
    """
    bad = sorted(set(overrides) - set(_OVERRIDES))
    if bad:
        raise ValueError(
            f"reproduce: unknown override(s) {', '.join(bad)}; allowed: {', '.join(_OVERRIDES)}"
        )
    for k in ("runs", "steps", "every", "threads", "seed"):
        if k in overrides:
            overrides[k] = _count(k, overrides[k], minimum=0 if k == "seed" else 1)
    if "max_hours" in overrides:
        overrides["max_hours"] = float(overrides["max_hours"])
    kw = {k: v for k, v in overrides.items() if k not in ("threads", "progress", "max_hours")}
    return Result(_edgekf.reproduce(name, **overrides), _call("reproduce", repr(name), **kw))


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
    max_hours: float = 1.0,
) -> Dict[str, Any]:
    """Designs stress weights for a framework (``edgekf design``).

    ``method``: ``"sdp"`` (thesis SDP (3.5), stress matrix PSD with maximal gap), ``"yang"``
    (Yang et al. 2019 construction) or ``"sparse"`` (ℓ1-penalised). ``leaders``: a list of
    D + 1 agents, ``"auto"`` (chosen by ``leader_mode``: ``"clique"`` or ``"affine"``), or None.

    Returns the ``edgekf.framework/1`` document with ``weights`` (``edges`` reduced to the links
    with a nonzero weight). Raises ``ValueError`` when the input is malformed or infeasible (the
    failed condition named), or when the design is estimated to take longer than ``max_hours``
    (default 1 h, as ``edgekf design --max-hours``) or more than 80 % of the available memory.
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
        _config_list(config), _edges_list(edges), method, lead, mode, name, float(max_hours)
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
    """A covariance argument as a float64 array: a scalar (times I), (D, D) for every edge, or
    (B, D, D) in the batched form; shapes checked here, the rest (finite, symmetric, PSD / PD)
    by the extension, naming ``what``."""
    m = np.asarray(a, dtype=np.float64)
    if m.ndim == 0:
        m = m * np.eye(d)
    if m.shape != (d, d) and not (batched and m.shape == (b, d, d)):
        want = f"({d}, {d})" + (f" or ({b}, {d}, {d})" if batched else "")
        raise ValueError(f"{what}: expected shape {want}, got {m.shape}")
    return np.ascontiguousarray(m)


class EdgeFilter:
    """Kalman filter(s) of edge states for a user's own loop: one edge, or a batch of B edges
    (or runs) stepped by one call into Rust per step, not one per edge.

    ``kind="rkf"`` — the relative Kalman filter of EUSIPCO eq. (5) (thesis §4.3). One edge:
    ``x0`` of shape (D,); a batch: (B, D), and every call takes and returns arrays with that
    leading batch axis. Per step, with ``du = Δt (u_i − u_j)`` the communicated inputs'
    displacement and ``y`` the mean of the T measurements of ``z_ij``:

    - predict (5c), (5d): ``x̂⁻ = x̂ + du``, ``P⁻ = P + Q``;
    - update (5e)–(5g): ``K = P⁻ (P⁻ + R)⁻¹``, ``x̂ = x̂⁻ + K (y − x̂⁻)``,
      ``P = (I − K) P⁻ (I − K)ᵀ + K R Kᵀ`` (Joseph form).

    ``R`` is the covariance of ``y`` (for T samples of covariance R_ij: R_ij / T); ``Q`` the
    edge's process covariance (Q_ij = B̄_ijᵀ Q B̄_ij, both ends' noise). Matrices may be scalars
    (times I), (D, D), or (B, D, D) in the batched form.

    ``kind="rkf-ca"`` — the constant-acceleration edge filter with intermittent observations of
    Li & Rajan (eqs. 5–7; the engine's ``rkf-ca``): state ``γ = [z, ż, z̈]`` given as ``x0`` of
    shape (3, D) (rows: position, velocity, acceleration) or (B, 3, D); ``P0`` (3D, 3D), a
    scalar (times I) or (B, 3D, 3D); ``R`` the observation covariance as above; ``dt`` the step
    and ``sigma_w`` the jerk intensity of ``Q = σ_w² q qᵀ ⊗ I_D``, ``q = [Δt²/2, Δt, 1]``
    (eq. 7). No input: ``predict()`` / ``step(None, y)``. The update corrects only the observed
    edges: ``observed`` a boolean per edge, or by default the rows of ``y`` without NaN.
    Returns ``x̂`` as (3, D) / (B, 3, D) and ``P`` as (3D, 3D) / (B, 3D, 3D).

    Everything is checked when the filter is built, with the CLI's standards, and a
    ``ValueError`` names the argument (and, in a batch, the edge): shapes, finite entries,
    ``P0`` and ``Q`` symmetric positive semidefinite, ``R`` symmetric positive definite (the
    update inverts ``P⁻ + R``), ``dt`` and ``sigma_w`` finite and positive. NumPy scalars are
    taken wherever numbers are.
    """

    def __init__(
        self,
        kind: str = "rkf",
        *,
        R: npt.ArrayLike,
        x0: npt.ArrayLike,
        P0: npt.ArrayLike,
        Q: Optional[npt.ArrayLike] = None,
        dt: Optional[float] = None,
        sigma_w: float = 1.0,
    ) -> None:
        if kind not in ("rkf", "rkf-ca"):
            raise ValueError(f"EdgeFilter: unknown kind {kind!r}; available: 'rkf', 'rkf-ca'")
        self.kind = kind
        x = np.asarray(x0, dtype=np.float64)
        ca = kind == "rkf-ca"
        if ca:
            if Q is not None:
                raise ValueError("EdgeFilter('rkf-ca'): Q is set by dt and sigma_w (Li & Rajan eq. 7); leave Q out")
            if dt is None:
                raise ValueError("EdgeFilter('rkf-ca'): dt (the step, s) is required")
            if x.ndim == 2:
                self.batched = False
                x = x[None]
            elif x.ndim == 3:
                self.batched = True
            else:
                raise ValueError(f"x0: expected shape (3, D) or (B, 3, D), got {x.shape}")
            if x.shape[1] != 3:
                raise ValueError(
                    f"x0: expected shape (3, D) or (B, 3, D) (rows: position, velocity, acceleration), got {np.shape(x0)}"
                )
            b, d = x.shape[0], x.shape[2]
        else:
            if Q is None:
                raise ValueError("EdgeFilter('rkf'): Q (the edge's process covariance) is required")
            if dt is not None:
                raise ValueError("EdgeFilter('rkf'): dt applies to kind 'rkf-ca' only (the RKF's prediction takes du)")
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
        self.dim = d
        self.batch = b
        if ca:
            p0 = np.asarray(P0, dtype=np.float64)
            if p0.ndim == 0:
                p0 = p0 * np.eye(3 * d)
            elif p0.ndim == 3 and not self.batched:
                raise ValueError(f"P0: expected shape ({3 * d}, {3 * d}), got {p0.shape}")
            self._ca = _edgekf._CaBank(
                float(dt),
                float(sigma_w),
                np.ascontiguousarray(x),
                np.ascontiguousarray(p0),
                _mat(R, "R", b, d, self.batched),
            )
        else:
            self._bank = _edgekf._EdgeBank(
                np.ascontiguousarray(x),
                _mat(P0, "P0", b, d, self.batched),
                _mat(Q, "Q", b, d, self.batched),
                _mat(R, "R", b, d, self.batched),
            )

    def _arg(self, a: Any, what: str) -> np.ndarray:
        v = np.asarray(a, dtype=np.float64)
        want = (self.batch, self.dim) if self.batched else (self.dim,)
        if v.shape != want:
            raise ValueError(f"{what}: expected shape {want}, got {v.shape}")
        return v if self.batched else v[None, :]

    def _out(self, xp: Tuple[np.ndarray, np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
        x, p = xp
        return (x, p) if self.batched else (x[0], p[0])

    def _no_du(self, du: Any) -> None:
        if du is not None:
            raise ValueError("du: the CA model (kind 'rkf-ca') has no input; pass None")

    def _observed(self, y: np.ndarray, observed: Any) -> np.ndarray:
        if observed is None:
            return ~np.isnan(y).any(axis=1)
        m = np.asarray(observed)
        if m.dtype != np.bool_:
            raise ValueError(f"observed: expected booleans, got dtype {m.dtype}")
        want = (self.batch,) if self.batched else ()
        if m.shape != want:
            raise ValueError(f"observed: expected shape {want}, got {m.shape}")
        return np.ascontiguousarray(m.reshape(self.batch))

    def predict(self, du: Optional[npt.ArrayLike] = None) -> Tuple[np.ndarray, np.ndarray]:
        """Prediction: RKF (5c), (5d) with the input displacement ``du``; CA: ``γ̂ ← F γ̂``,
        ``Λ ← F Λ Fᵀ + Q`` (Li & Rajan eqs. 6, 7; ``du`` must be None). Returns ``(x̂⁻, P⁻)``."""
        if self.kind == "rkf-ca":
            self._no_du(du)
            self._ca.predict()
            return self._out(self._ca.state())
        if du is None:
            raise ValueError("du: the RKF's prediction needs the input displacement Δt (u_i − u_j)")
        return self._out(self._bank.predict(self._arg(du, "du")))

    def update(
        self, y: npt.ArrayLike, observed: Optional[npt.ArrayLike] = None
    ) -> Tuple[np.ndarray, np.ndarray]:
        """Update with the measurement ``y``; returns ``(x̂, P)``.

        RKF: (5e)–(5g), every edge observed (``observed`` must be None); raises ``ValueError``
        (naming the edge) if ``P⁻ + R`` is not positive definite, the state then unchanged.
        CA: the Joseph-form correction of the observed edges only (``observed``, or the rows of
        ``y`` without NaN).
        """
        if self.kind == "rkf-ca":
            v = self._arg(y, "y")
            self._ca.update(np.ascontiguousarray(v), self._observed(v, observed))
            return self._out(self._ca.state())
        if observed is not None:
            raise ValueError("observed: kind 'rkf' observes every edge; use kind 'rkf-ca' for intermittent observations")
        return self._out(self._bank.update(self._arg(y, "y")))

    def step(
        self,
        du: Optional[npt.ArrayLike],
        y: npt.ArrayLike,
        observed: Optional[npt.ArrayLike] = None,
    ) -> Tuple[np.ndarray, np.ndarray]:
        """``predict(du)`` then ``update(y, observed)``; returns ``(x̂, P)``. Atomic on error."""
        if self.kind == "rkf-ca":
            self._no_du(du)
            v = self._arg(y, "y")
            mask = self._observed(v, observed)
            bad = np.flatnonzero(mask & ~np.isfinite(v).all(axis=1))
            if bad.size:
                raise ValueError(f"y: row {bad[0]} is observed but not finite (mark a missing observation with observed = False or a NaN row)")
            self._ca.predict()
            self._ca.update(np.ascontiguousarray(v), mask)
            return self._out(self._ca.state())
        if observed is not None:
            raise ValueError("observed: kind 'rkf' observes every edge; use kind 'rkf-ca' for intermittent observations")
        return self._out(self._bank.step(self._arg(du, "du"), self._arg(y, "y")))

    def _state(self) -> Tuple[np.ndarray, np.ndarray]:
        return self._out(self._ca.state() if self.kind == "rkf-ca" else self._bank.state())

    @property
    def x(self) -> np.ndarray:
        """Current estimate ``x̂`` (RKF: (D,) or (B, D); CA: (3, D) or (B, 3, D))."""
        return self._state()[0]

    @property
    def P(self) -> np.ndarray:
        """Current covariance ``P`` (RKF: (D, D) or (B, D, D); CA: (3D, 3D) or (B, 3D, 3D))."""
        return self._state()[1]
