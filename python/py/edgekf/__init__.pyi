"""Type stubs of the Python package `edgekf` (the docstrings are in `__init__.py`)."""

import os
from typing import Any, Dict, List, Optional, Sequence, SupportsIndex, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

ScenarioLike = Union[str, os.PathLike[str], Dict[str, Any]]
F64 = npt.NDArray[np.float64]
# A whole number: an int or a NumPy integer (anything with __index__); range-checked by name.
Count = Optional[SupportsIndex]
# A real number: a Python or NumPy float or integer.
Real = Union[float, np.floating[Any], np.integer[Any]]

class Result:
    """The outcome of a Monte Carlo study."""

    @property
    def scenario(self) -> Dict[str, Any]: ...
    @property
    def estimators(self) -> List[str]: ...
    @property
    def metrics(self) -> List[str]: ...
    @property
    def runs(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def steps(self) -> npt.NDArray[np.int64]: ...
    def metrics_of(self, estimator: str) -> List[str]: ...
    def metric(self, estimator: str, name: str) -> Tuple[F64, F64, F64]:
        """(time, mean, std) across runs; e.g. `est_error` is ε_k of thesis eq. (4.34)."""
    def paths(self, estimator: str) -> F64:
        """Positions of the recorded run (reported steps × agents × D)."""
    def inputs(self, estimator: str) -> F64: ...
    @property
    def frame_steps(self) -> npt.NDArray[np.int64]: ...
    def frames(self, estimator: str) -> List[Dict[str, Any]]:
        """Recorded runs frame by frame: run, positions, estimates, covariances, observed, present."""
    @property
    def frame_targets(self) -> Optional[F64]: ...
    @property
    def edges(self) -> npt.NDArray[np.int64]: ...
    def to_rerun(
        self,
        path: Union[str, os.PathLike[str]],
        *,
        estimators: Optional[Sequence[str]] = ...,
        runs: Optional[Sequence[int]] = ...,
    ) -> None:
        """A Rerun recording (.rrd) of the recorded frames and the metrics (needs rerun-sdk)."""
    def status(self, estimator: str) -> Dict[str, Any]: ...
    def metrics_csv(self) -> str: ...
    def to_pandas(self) -> Any: ...
    def save(
        self, dir: Union[str, os.PathLike[str]], *, figures: bool = ..., force: bool = ...
    ) -> None:
        """Writes the CLI's files (metrics.csv byte-identical to `edgekf run`), provenance.json
        (with the list of files) and the figures. FileExistsError if `dir` holds another study
        (`force=True` empties it), OSError if it cannot be written."""
    @property
    def sweep_parameter(self) -> Optional[str]: ...
    def sweep_summary(self) -> Optional[Dict[str, Any]]: ...

def run(
    scenario: ScenarioLike,
    *,
    runs: Count = ...,
    steps: Count = ...,
    seed: Count = ...,
    threads: Count = ...,
    every: Count = ...,
    progress: bool = ...,
    max_hours: Real = ...,
) -> Result:
    """Runs a scenario as `edgekf run` does; ValueError with the CLI's message on bad input
    (naming the parameter for a count or seed out of range), FileNotFoundError for a missing
    file."""

def resolve(scenario: ScenarioLike) -> Dict[str, Any]: ...
def list_reproductions() -> List[Dict[str, Any]]: ...
def reproduce(
    name: str,
    *,
    runs: Count = ...,
    steps: Count = ...,
    seed: Count = ...,
    every: Count = ...,
    threads: Count = ...,
    progress: bool = ...,
    max_hours: Real = ...,
) -> Result: ...
def design(
    config: npt.ArrayLike,
    edges: npt.ArrayLike,
    *,
    method: str = ...,
    leaders: Union[None, Sequence[int], str] = ...,
    leader_mode: str = ...,
    name: str = ...,
    max_hours: Real = ...,
) -> Dict[str, Any]:
    """Stress weights by the thesis SDP (3.5), Yang et al. 2019, or the sparse design."""

def check(
    config: npt.ArrayLike,
    edges: npt.ArrayLike,
    weights: npt.ArrayLike,
    *,
    leaders: Optional[Sequence[int]] = ...,
) -> Dict[str, Any]: ...

class EdgeFilter:
    """Edge filters for a user's own loop: kind "rkf" (EUSIPCO eq. (5); x0: (D,) or (B, D))
    or "rkf-ca" (Li & Rajan eqs. 5–7, intermittent observations; x0: (3, D) or (B, 3, D))."""

    kind: str
    batched: bool
    dim: int
    batch: int
    def __init__(
        self,
        kind: str = ...,
        *,
        R: npt.ArrayLike,
        x0: npt.ArrayLike,
        P0: npt.ArrayLike,
        Q: Optional[npt.ArrayLike] = ...,
        dt: Optional[Real] = ...,
        sigma_w: Real = ...,
    ) -> None:
        """ValueError naming the argument (and the edge) when x0, P0, Q or R has the wrong
        shape or a non-finite entry, or a covariance is not symmetric, P0 or Q not positive
        semidefinite, R not positive definite."""
    def predict(self, du: Optional[npt.ArrayLike] = ...) -> Tuple[F64, F64]:
        """RKF (5c), (5d); CA eqs. (6), (7) (du None)."""
    def update(self, y: npt.ArrayLike, observed: Optional[npt.ArrayLike] = ...) -> Tuple[F64, F64]:
        """RKF (5e)–(5g), Joseph form; CA: the observed edges only."""
    def step(
        self, du: Optional[npt.ArrayLike], y: npt.ArrayLike, observed: Optional[npt.ArrayLike] = ...
    ) -> Tuple[F64, F64]: ...
    @property
    def x(self) -> F64: ...
    @property
    def P(self) -> F64: ...
