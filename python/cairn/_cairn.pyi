"""Type stubs of Cairn's native module."""

import os
import pathlib
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]
_Vector = npt.ArrayLike
_Matrix = npt.ArrayLike

def read_g2o(path: _Path, repair_information: bool = False, se3_error: str = "g2o") -> Graph:
    """Reads a g2o file into a Graph (OSError: unreadable; ValueError: bad content, the line named).

    se3_error: "g2o" (translation and quaternion vector part) or "logmap"
    (translation and rotation vector) for EDGE_SE3:QUAT edges."""

class Summary:
    """The result of Graph.optimize."""

    chi2_initial: float
    """χ² before the solve (at the first start tried)."""
    chi2: float
    """χ² of the estimate the solve returned."""
    iterations: int
    """Iterations of the run whose estimate was kept."""
    termination: str
    """relative_decrease, gradient_norm, step_size, max_iterations, no_improvement,
    not_positive_definite, non_finite, error_increased or nothing_to_optimize."""
    converged: bool
    """Whether the termination counts as convergence."""
    init: str
    """The start whose estimate was kept."""
    kept_start: bool
    """Whether the solve ended above its start, so the values were kept."""
    time: float
    """Seconds the kept run took."""
    @property
    def trace(self) -> list[dict[str, Any]]:
        """One dict per iteration: iteration, chi2, lambda, radius, trials,
        gradient_max, step_max, time, cumulative_time."""

class Graph:
    """A factor graph with g2o's conventions (χ² = Σ eᵀΩe, information in g2o's order)."""

    def __init__(self) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_edges(self) -> int: ...
    def copy(self) -> Graph:
        """A deep copy."""
    def add_se2(self, id: int, x: float, y: float, theta: float) -> None:
        """Adds an SE2 pose."""
    def add_xy(self, id: int, x: float, y: float) -> None:
        """Adds a 2D point."""
    def add_se3(self, id: int, t: _Vector, q: _Vector) -> None:
        """Adds an SE3 pose: t (3), q (qx, qy, qz, qw), normalised."""
    def add_edge_se2(self, i: int, j: int, measurement: _Vector, information: _Matrix) -> int:
        """Relative SE2 measurement (x, y, theta), 3×3 information; returns the edge's number."""
    def add_edge_se2_xy(self, i: int, j: int, measurement: _Vector, information: _Matrix) -> int:
        """Landmark j seen from pose i at (x, y), 2×2 information."""
    def add_prior_se2(self, i: int, measurement: _Vector, information: _Matrix) -> int:
        """Prior (x, y, theta) on pose i, 3×3 information."""
    def add_edge_se3(self, i: int, j: int, measurement: _Vector, information: _Matrix) -> int:
        """Relative SE3 measurement (x, y, z, qx, qy, qz, qw), 6×6 information, translation first."""
    def fix(self, ids: Sequence[int], fixed: bool = True) -> None:
        """Holds vertices constant (or frees them)."""
    def chi2(self) -> float:
        """χ² = Σ eᵀΩe at the current values."""
    def write_g2o(self, path: _Path) -> None:
        """Writes a g2o file atomically."""
    def optimize(
        self,
        solver: str = "gn",
        init: str = "auto",
        max_iterations: int = 100,
        robust_kernel: Optional[str] = None,
        robust_kernel_width: float = 1.0,
    ) -> Summary:
        """Optimises in place; solver gn|lm|dogleg, init auto|file|chordal|chordal-isotropic|spanning-tree."""
    def se2_array(self) -> npt.NDArray[np.float64]:
        """(n, 4): id, x, y, theta."""
    def xy_array(self) -> npt.NDArray[np.float64]:
        """(n, 3): id, x, y."""
    def se3_array(self) -> npt.NDArray[np.float64]:
        """(n, 8): id, x, y, z, qx, qy, qz, qw."""
    def marginals(self, ids: Sequence[int]) -> dict[int, npt.NDArray[np.float64]]:
        """Marginal covariance of each vertex (ValueError for fixed or gauge vertices)."""

def fs_slam(
    log_path: _Path,
    estimator: str = "graph",
    association: str = "ml",
    config: Optional[_Path] = None,
    particles: int = 100,
    seed: int = 0,
) -> dict[str, Any]:
    """Runs a cone-SLAM estimator on a FORMAT.md log: map (n, 5), colors, trajectory (m, 4),
    associations (k, 3), warnings."""

def fs_sim(
    out: _Path,
    track: Optional[_Path] = None,
    seed: int = 0,
    laps: float = 2.0,
    speed: float = 5.0,
    preset: str = "standard",
) -> list[pathlib.Path]:
    """Simulates a run and writes log.jsonl and its truth files into `out`."""
