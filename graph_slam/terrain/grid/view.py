"""The read-only snapshot of a stride's elevation grid at one frame: :class:`TerrainView`.

What a controller gets from :class:`~graph_slam.terrain.grid.online.OnlineElevationMap` (its
``view()`` after every update, ``refuse()`` after the smoothing): heights, their variances
(the sums of :mod:`graph_slam.terrain.grid.online`), counts and times per cell in the stride
frame (metres, seconds), and, computed once on demand, the boxes and features on the grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numba
import numpy as np

from graph_slam.errors import MappingError

if TYPE_CHECKING:
    from graph_slam.terrain.grid.online import CellSums


@dataclass(frozen=True, eq=False)
class TerrainView:
    """A read-only snapshot of the stride's elevation grid at one frame (stride frame, metres).

    Arrays are (nx, ny), axis 0 x, axis 1 y; empty cells are NaN (``count`` 0 and not carried).
    ``count`` counts this stride's points; a cell known only from the previous stride (carried)
    has a height and ``count`` 0."""

    stride_index: int
    t_s: float
    origin_xy_m: np.ndarray
    """(x, y) of the corner of cell (0, 0)."""
    cell_m: float
    sums: CellSums
    shape: tuple[int, int]
    toe_x_m: float = 0.2

    @cached_property
    def _height_variance(self) -> tuple[np.ndarray, np.ndarray]:
        s = self.sums
        h, v = _height_variance(s.w, s.wz, s.a, s.b, s.wz2, s.d)
        return _frozen(h.reshape(self.shape)), _frozen(v.reshape(self.shape))

    @property
    def height_m(self) -> np.ndarray:
        """Height: ``WZ/W`` (NaN where no point)."""
        return self._height_variance[0]

    @property
    def variance_m2(self) -> np.ndarray:
        """Height variance: depth noise (averaged) + camera pose (correlated) + the spread
        beyond the depth noise."""
        return self._height_variance[1]

    @property
    def sigma_m(self) -> np.ndarray:
        return np.sqrt(self.variance_m2)

    @cached_property
    def count(self) -> np.ndarray:
        return _frozen(self.sums.count.reshape(self.shape))

    @cached_property
    def last_update_t_s(self) -> np.ndarray:
        """Time of the latest point in each cell (NaN: none this stride)."""
        return _frozen(self.sums.last_t_s.reshape(self.shape))

    @property
    def known(self) -> np.ndarray:
        return self.sums.w.reshape(self.shape) > 0

    def cell_centers_m(self) -> tuple[np.ndarray, np.ndarray]:
        """x centres (nx,) and y centres (ny,)."""
        nx, ny = self.shape
        x = self.origin_xy_m[0] + (np.arange(nx) + 0.5) * self.cell_m
        y = self.origin_xy_m[1] + (np.arange(ny) + 0.5) * self.cell_m
        return x, y

    def _cell(self, x_m: float, y_m: float) -> tuple[int, int] | None:
        """The cell holding (x, y); None off the grid, or for a NaN / infinite coordinate."""
        if not (math.isfinite(x_m) and math.isfinite(y_m)):
            return None
        i = int(np.floor((x_m - self.origin_xy_m[0]) / self.cell_m))
        j = int(np.floor((y_m - self.origin_xy_m[1]) / self.cell_m))
        return (i, j) if 0 <= i < self.shape[0] and 0 <= j < self.shape[1] else None

    def height_at(self, x_m: float, y_m: float) -> float:
        """Height (stride z, m) of the cell holding (x, y); NaN when unknown or off the grid."""
        ij = self._cell(x_m, y_m)
        return float("nan") if ij is None else float(self.height_m[ij])

    def sigma_at(self, x_m: float, y_m: float) -> float:
        ij = self._cell(x_m, y_m)
        return float("nan") if ij is None else float(self.sigma_m[ij])

    @cached_property
    def obstacle_map(self):
        """The boxes on the grid (:func:`graph_slam.terrain.grid.grid_obstacles.grid_obstacles`),
        computed once on demand; None when no floor is found."""
        from graph_slam.terrain.grid.grid_obstacles import grid_obstacles

        try:
            return grid_obstacles(self)
        except MappingError:
            return None

    def obstacles_ahead(self, min_x_m: float | None = None) -> tuple:
        """Boxes whose leading edge lies ahead of ``min_x_m`` (default: the toe), nearest
        first."""
        m = self.obstacle_map
        if m is None:
            return ()
        lo = self.toe_x_m if min_x_m is None else min_x_m
        return tuple(o for o in m.obstacles if o.leading_edge_x_m >= lo)

    @cached_property
    def features(self):
        """Stairs, ramps, curbs and boxes of the grid with σ
        (:func:`graph_slam.terrain.features.extract.features_of_view`), computed once on demand."""
        from graph_slam.terrain.features.extract import features_of_view

        return features_of_view(self)

    def features_ahead(self, min_x_m: float | None = None):
        """The features reaching beyond ``min_x_m`` (default: the toe)
        (:class:`graph_slam.terrain.features.model.TerrainFeatures`)."""
        return self.features.ahead(self.toe_x_m if min_x_m is None else min_x_m)


@numba.njit(cache=True, nogil=True)
def _height_variance(w, wz, a, b, wz2, d):  # pragma: no cover - compiled
    """Per cell (flat sums): height ``wz/w`` and variance ``a/w² + (b/w)² + max(0, wz2/w -
    h² - d/w)``, NaN where ``w`` is 0 (one loop, the numpy formulation's arithmetic)."""
    n = w.size
    h = np.full(n, np.nan)
    v = np.full(n, np.nan)
    for k in range(n):
        if w[k] > 0:
            hk = wz[k] / w[k]
            excess = max(0.0, wz2[k] / w[k] - hk * hk - d[k] / w[k])
            bw = b[k] / w[k]
            h[k] = hk
            v[k] = a[k] / (w[k] * w[k]) + bw * bw + excess
    return h, v


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a
