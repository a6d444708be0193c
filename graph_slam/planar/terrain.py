"""The 2D occupancy-grid terrain of thesis 3.2 and ray casting through it.

The world is the sagittal plane: x forward, y up against gravity, metres. The surface height
``h(x)`` is flat ground at 0 plus ramps and stairs (which change the floor level for good) and
rectangular boxes standing on that floor; the grid marks a cell occupied when its centre lies
below the surface. Rays leaving the grid, or going farther than the sensor's range, return
nothing (the caller turns that into a max-range return).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.planar.config import TerrainConfig


def surface_height_m(x_m: np.ndarray, config: TerrainConfig) -> np.ndarray:
    """Height of the terrain's top surface at ``x_m`` (floor level plus any box on it)."""
    x_m = np.asarray(x_m, dtype=float)
    floor = np.zeros_like(x_m)
    for ramp in config.ramps:
        floor += np.clip((x_m - ramp.x_m) / ramp.length_m, 0.0, 1.0) * ramp.rise_m
    for flight in config.stairs:
        steps = np.clip(np.floor((x_m - flight.x_m) / flight.run_m) + 1, 0, flight.n_steps)
        floor += steps * flight.rise_m
    height = floor.copy()
    for box in config.boxes:
        on_box = (x_m >= box.x_m) & (x_m <= box.x_m + box.width_m)
        height = np.where(on_box, np.maximum(height, floor + box.height_m), height)
    return height


@dataclass(frozen=True)
class OccupancyGrid:
    """A boolean grid: ``occupied[i, j]`` is the cell at x = x0 + (j+½)·res, y = y0 + (i+½)·res."""

    occupied: np.ndarray
    origin_xy_m: tuple[float, float]
    resolution_m: float

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) for plotting."""
        rows, cols = self.occupied.shape
        x0, y0 = self.origin_xy_m
        return (x0, x0 + cols * self.resolution_m, y0, y0 + rows * self.resolution_m)

    def is_occupied(self, points_xy_m: np.ndarray) -> np.ndarray:
        """Occupancy at (..., 2) points; outside the grid is free."""
        x0, y0 = self.origin_xy_m
        col = np.floor((points_xy_m[..., 0] - x0) / self.resolution_m).astype(int)
        row = np.floor((points_xy_m[..., 1] - y0) / self.resolution_m).astype(int)
        rows, cols = self.occupied.shape
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        out = np.zeros(col.shape, dtype=bool)
        out[inside] = self.occupied[row[inside], col[inside]]
        return out


def build_terrain(config: TerrainConfig) -> OccupancyGrid:
    """Rasterise the configured course into an occupancy grid."""
    res = config.resolution_m
    cols = int(np.ceil((config.x_max_m - config.x_min_m) / res))
    rows = int(np.ceil((config.y_max_m - config.y_min_m) / res))
    x_centres = config.x_min_m + (np.arange(cols) + 0.5) * res
    y_centres = config.y_min_m + (np.arange(rows) + 0.5) * res
    occupied = y_centres[:, None] < surface_height_m(x_centres, config)[None, :]
    return OccupancyGrid(occupied, (config.x_min_m, config.y_min_m), res)


def cast_rays(
    grid: OccupancyGrid,
    origin_xy_m: np.ndarray,
    directions_rad: np.ndarray,
    max_range_m: float,
) -> np.ndarray:
    """Distance to the first occupied cell along each ray, NaN where none is within range.

    Rays are marched in steps of a quarter cell; the hit is placed half a step before the
    first occupied sample (so the quantisation error is below a quarter cell).
    """
    step = grid.resolution_m / 4.0
    dist = np.arange(step, max_range_m + step / 2, step)
    dirs = np.stack([np.cos(directions_rad), np.sin(directions_rad)], axis=-1)
    samples = origin_xy_m[None, None, :] + dist[None, :, None] * dirs[:, None, :]
    occ = grid.is_occupied(samples)
    hit = occ.any(axis=1)
    first = occ.argmax(axis=1)
    ranges = dist[first] - step / 2
    return np.where(hit, ranges, np.nan)
