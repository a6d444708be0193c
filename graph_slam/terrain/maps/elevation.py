"""An elevation grid ahead of the foot: per-cell height, variance and point count.

The grid lies in the stride frame's x–y plane (x forward along the foot, y left, z up against
gravity; origin at the heel contact point at foot strike). Cell ``(i, j)`` covers
``x in [x0 + i*cell, x0 + (i+1)*cell)`` and ``y in [y0 + j*cell, y0 + (j+1)*cell)``. A cell's
height is the mean z of the map points in it, its variance their population variance (a large
variance marks an edge or a noisy cell); empty cells (fewer than ``min_points`` points) are NaN.
A swing planner reads ``height_m`` for clearance and ``variance_m2`` for trust.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.errors import MappingError


class ElevationConfig(ConfigModel):
    """Extent and resolution of the elevation grid (stride frame, metres)."""

    cell_m: float = Field(0.02, gt=0)
    x_range_m: tuple[float, float] = (-0.2, 1.6)
    """Along the walking direction; the foot is at x = 0."""
    y_range_m: tuple[float, float] = (-0.6, 0.6)
    min_points: int = Field(1, ge=1)

    @model_validator(mode="after")
    def _ranges(self) -> ElevationConfig:
        for name in ("x_range_m", "y_range_m"):
            lo, hi = getattr(self, name)
            if not hi > lo:
                raise ValueError(f"{name}: the upper bound must exceed the lower, got {lo}, {hi}")
        return self


@dataclass(frozen=True, eq=False)
class ElevationGrid:
    """Per-cell statistics, arrays of shape (nx, ny): axis 0 is x, axis 1 is y."""

    height_m: np.ndarray
    variance_m2: np.ndarray
    count: np.ndarray
    origin_xy_m: np.ndarray
    """(x, y) of the corner of cell (0, 0)."""
    cell_m: float
    points_outside: int
    """Points that fell outside the grid (not used)."""

    @property
    def shape(self) -> tuple[int, int]:
        return self.height_m.shape

    def cell_centers_m(self) -> tuple[np.ndarray, np.ndarray]:
        """x centres (nx,) and y centres (ny,)."""
        nx, ny = self.shape
        x = self.origin_xy_m[0] + (np.arange(nx) + 0.5) * self.cell_m
        y = self.origin_xy_m[1] + (np.arange(ny) + 0.5) * self.cell_m
        return x, y

    def height_at(self, x_m: float, y_m: float) -> float:
        """Height of the cell containing (x, y); NaN when empty or outside (or for a NaN or
        infinite coordinate)."""
        if not (math.isfinite(x_m) and math.isfinite(y_m)):
            return float("nan")
        i = int(np.floor((x_m - self.origin_xy_m[0]) / self.cell_m))
        j = int(np.floor((y_m - self.origin_xy_m[1]) / self.cell_m))
        if 0 <= i < self.shape[0] and 0 <= j < self.shape[1]:
            return float(self.height_m[i, j])
        return float("nan")


def elevation_grid(
    points_stride_m: np.ndarray, config: ElevationConfig | None = None
) -> ElevationGrid:
    """Bin stride-frame points into the grid and return per-cell mean height and variance."""
    cfg = config or ElevationConfig()
    points = np.asarray(points_stride_m, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise MappingError(f"elevation_grid: points have shape {points.shape}; they must be N×3")
    if not np.isfinite(points).all():
        raise MappingError("elevation_grid: points contain NaN or inf")
    x0, x1 = cfg.x_range_m
    y0, y1 = cfg.y_range_m
    nx = round((x1 - x0) / cfg.cell_m)
    ny = round((y1 - y0) / cfg.cell_m)
    i = np.floor((points[:, 0] - x0) / cfg.cell_m).astype(np.int64)
    j = np.floor((points[:, 1] - y0) / cfg.cell_m).astype(np.int64)
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    flat = i[inside] * ny + j[inside]
    z = points[inside, 2]
    count = np.bincount(flat, minlength=nx * ny)
    total = np.bincount(flat, weights=z, minlength=nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
        # Two-pass variance: subtract the cell mean before squaring (no cancellation).
        dev2 = np.bincount(flat, weights=(z - mean[flat]) ** 2, minlength=nx * ny)
        var = dev2 / count
    empty = count < cfg.min_points
    mean[empty] = np.nan
    var[empty] = np.nan
    return ElevationGrid(
        height_m=mean.reshape(nx, ny),
        variance_m2=var.reshape(nx, ny),
        count=count.reshape(nx, ny),
        origin_xy_m=np.array([x0, y0]),
        cell_m=cfg.cell_m,
        points_outside=int((~inside).sum()),
    )
