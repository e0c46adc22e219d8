"""``Result.to_rerun``: a run as a Rerun recording (``.rrd``), on the ``rerun-sdk`` package.

Entity paths (the guide's Python chapter lists them too), on the time lines ``time`` (simulated
seconds, ``k * dt``) and ``step`` (``k``):

- ``runs/<r>/<estimator>/agents``: true positions ``z_k``, labelled by agent id; leaders orange,
  followers blue, departed agents grey.
- ``runs/<r>/<estimator>/links``: the edges agent *i* measured at that step (Li & Rajan's
  ``β_ij,k = 1``), between true positions; ``lost_links``: those it did not (red).
- ``runs/<r>/<estimator>/estimates``: the formation as each agent estimates it, a line from
  ``z_i`` to ``z_i − x̂_ij`` per edge (*i*, *j*) of a present agent *i*.
- ``runs/<r>/<estimator>/uncertainty``: the 1σ ellipses (2-D, as line loops) or ellipsoids (3-D)
  of those estimates, from their posterior covariances.
- ``target``: the target formation ``Z*_k`` where the scenario has a maneuver.
- ``metrics/<metric>/<estimator>``: the metric's mean across all runs (``metrics.csv``), per
  reported step.

``<r>`` is the run's index; estimator labels are escaped as entity path parts.
"""

from __future__ import annotations

import os
import tempfile
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

_LEADER = (230, 126, 34)
_FOLLOWER = (52, 101, 164)
_DEPARTED = (160, 160, 160)
_LINK = (120, 120, 120)
_LOST = (204, 0, 0)
_ESTIMATE = (46, 139, 87)
_TARGET = (90, 90, 90)
_LOOP = 32  # segments of a 2-D ellipse


def _import_rerun() -> Any:
    try:
        import rerun as rr
    except ImportError as e:
        raise ImportError(
            "Result.to_rerun() needs the rerun-sdk package: pip install 'edgekf[rerun]' "
            "(or pip install rerun-sdk)"
        ) from e
    if not hasattr(rr, "Scalars") or not hasattr(rr, "TimeColumn"):
        raise ImportError(
            f"Result.to_rerun() needs rerun-sdk >= 0.23 (found {getattr(rr, '__version__', '?')}): "
            "pip install -U rerun-sdk"
        )
    return rr


def ellipse_loops(centers: np.ndarray, covs: np.ndarray, points: int = _LOOP) -> np.ndarray:
    """The 1σ ellipses ``{c + x : xᵀ P⁻¹ x = 1}`` of K 2 × 2 covariances as closed loops
    (K × (``points`` + 1) × 2; a degenerate direction collapses to a segment)."""
    lam, vec = np.linalg.eigh(0.5 * (covs + np.swapaxes(covs, 1, 2)))
    axes = vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]
    th = np.linspace(0.0, 2.0 * np.pi, points + 1)
    circle = np.stack([np.cos(th), np.sin(th)], axis=1)
    return centers[:, None, :] + np.einsum("ked,pd->kpe", axes, circle)


def ellipsoids(covs: np.ndarray) -> tuple:
    """``(half_sizes K × 3, quaternions K × 4 as xyzw)`` of the 1σ ellipsoids of K 3 × 3
    covariances."""
    lam, vec = np.linalg.eigh(0.5 * (covs + np.swapaxes(covs, 1, 2)))
    flip = np.linalg.det(vec) < 0
    vec[flip, :, 2] *= -1.0
    quats = np.array([_quaternion(r) for r in vec]).reshape(-1, 4)
    return np.sqrt(np.clip(lam, 0.0, None)), quats


def _quaternion(r: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method)."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(max(1.0 + r[i, i] - r[j, j] - r[k, k], 1e-300))
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
    q = np.asarray(q)
    return q / np.linalg.norm(q)


class _Writer:
    """Logs one result's frames and metrics into a recording stream."""

    def __init__(self, rr: Any, rec: Any, res: Any) -> None:
        self.rr, self.rec, self.res = rr, rec, res
        scen = res.scenario
        self.edges = res.edges
        self.leaders = set(int(x) for x in scen.get("leaders", []))

    def time(self, step: int) -> None:
        self.rec.set_time("step", sequence=int(step))
        self.rec.set_time("time", duration=float(step) * self.res.dt)

    def points(self, xy: np.ndarray, **kw: Any) -> Any:
        rr = self.rr
        return (rr.Points2D if xy.shape[-1] == 2 else rr.Points3D)(xy, **kw)

    def strips(self, lines: np.ndarray, **kw: Any) -> Any:
        """Line strips from an array (strips × points × D)."""
        rr = self.rr
        return (rr.LineStrips2D if lines.shape[-1] == 2 else rr.LineStrips3D)(lines, **kw)

    def frame(self, base: str, fr: Dict[str, Any], f: int) -> None:
        """One frame of one run of one estimator under ``base``."""
        z, est, cov = fr["positions"][f], fr["estimates"][f], fr["covariances"][f]
        obs, pres = fr["observed"][f], fr["present"][f]
        n = z.shape[0]
        colors = np.array([_LEADER if i in self.leaders else _FOLLOWER for i in range(n)])
        colors[~pres] = _DEPARTED
        self.rec.log(
            f"{base}/agents",
            self.points(z, colors=colors, labels=[str(i) for i in range(n)], radii=0.08),
        )
        i, j = self.edges[:, 0], self.edges[:, 1]
        both = pres[i] & pres[j]
        true = np.stack([z[i], z[j]], axis=1)
        guess = z[i] - est
        owned = pres[i] & np.isfinite(guess).all(axis=1)
        lines = np.stack([z[i], guess], axis=1)[owned]
        with_cov = owned & np.isfinite(cov).all(axis=(1, 2))
        self.rec.log(f"{base}/links", self.strips(true[both & obs], colors=_LINK, radii=0.015))
        self.rec.log(f"{base}/lost_links", self.strips(true[both & ~obs], colors=_LOST, radii=0.02))
        self.rec.log(f"{base}/estimates", self.strips(lines, colors=_ESTIMATE, radii=0.01))
        self.uncertainty(f"{base}/uncertainty", guess[with_cov], cov[with_cov])

    def uncertainty(self, path: str, centers: np.ndarray, covs: np.ndarray) -> None:
        rr = self.rr
        if centers.shape[1] == 2:
            loops = ellipse_loops(centers, covs)
            self.rec.log(path, rr.LineStrips2D(loops, colors=_ESTIMATE, radii=0.005))
        else:
            sizes, quats = ellipsoids(covs)
            self.rec.log(
                path,
                rr.Ellipsoids3D(
                    centers=centers, half_sizes=sizes, quaternions=quats, colors=_ESTIMATE
                ),
            )

    def metrics(self, estimators: Sequence[str]) -> None:
        rr = self.rr
        steps = self.res.steps
        for e in estimators:
            for m in self.res.metrics_of(e):
                t, mean, _ = self.res.metric(e, m)
                keep = np.isfinite(mean)
                if not keep.any():
                    continue
                self.rec.send_columns(
                    f"metrics/{m}/{rr.escape_entity_path_part(e)}",
                    indexes=[
                        rr.TimeColumn("time", duration=t[keep]),
                        rr.TimeColumn("step", sequence=steps[: len(t)][keep]),
                    ],
                    columns=rr.Scalars.columns(scalars=mean[keep]),
                )


def _blueprint(rr: Any, views: List[tuple], metrics: List[str], dim: int) -> Any:
    """One spatial view per (run, estimator) with the target in each, beside a tab per metric."""
    import rerun.blueprint as rrb

    view = rrb.Spatial2DView if dim == 2 else rrb.Spatial3DView
    spatial = [
        view(origin=origin, contents=["$origin/**", "/target/**"], name=name)
        for origin, name in views
    ]
    series = [rrb.TimeSeriesView(origin=f"metrics/{m}", name=m) for m in metrics]
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Grid(*spatial), rrb.Tabs(*series), column_shares=[2, 1]),
        collapse_panels=False,
    )


def write(res: Any, path: str, estimators: Optional[Sequence[str]], runs: Optional[Sequence[int]]) -> None:
    """``Result.to_rerun``: see its docstring."""
    rr = _import_rerun()
    names = list(res.estimators if estimators is None else estimators)
    for e in names:
        if e not in res.estimators:
            raise ValueError(f"unknown estimator {e!r}; this result has {', '.join(res.estimators)}")
    steps = res.frame_steps
    frames = {e: res.frames(e) for e in names}
    recorded = sorted({fr["run"] for e in names for fr in frames[e]})
    if runs is not None:
        missing = [r for r in runs if r not in recorded]
        if missing:
            raise ValueError(f"runs {missing} were not recorded frame by frame; recorded: {recorded}")
        recorded = [r for r in recorded if r in set(runs)]
    dim = int(res.scenario["dim"])
    views = [
        (f"runs/{r}/{rr.escape_entity_path_part(e)}", f"run {r}: {e}")
        for r in recorded
        for e in names
        if any(fr["run"] == r for fr in frames[e])
    ]
    metrics = [m for m in res.metrics if any(m in res.metrics_of(e) for e in names)]
    target = os.path.abspath(path)
    fd, tmp = tempfile.mkstemp(suffix=".rrd.tmp", dir=os.path.dirname(target) or ".")
    os.close(fd)
    try:
        rec = rr.RecordingStream("edgekf")
        rec.save(tmp, default_blueprint=_blueprint(rr, views, metrics, dim))
        rec.send_recording_name(str(res.scenario.get("name", "edgekf")))
        w = _Writer(rr, rec, res)
        targets = res.frame_targets
        for f, k in enumerate(steps):
            w.time(k)
            if targets is not None:
                rec.log("target", w.points(targets[f], colors=_TARGET, radii=0.05))
            for e in names:
                for fr in frames[e]:
                    if fr["run"] in recorded and f < fr["positions"].shape[0]:
                        w.frame(f"runs/{fr['run']}/{rr.escape_entity_path_part(e)}", fr, f)
        w.metrics(names)
        rec.flush()
        rec.disconnect()
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
