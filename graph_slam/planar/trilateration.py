"""Sensor position by trilateration (thesis 3.1.3, eq. 3.9–3.10).

Each world point (x_i, y_i) at measured range d_i from the sensor gives

    (x_s - x_i)^2 + (y_s - y_i)^2 = d_i^2                                           (3.9)

and subtracting the equation of point i-1 from that of point i leaves one linear equation

    (2x_i - 2x_{i-1}) x_s + (2y_i - 2y_{i-1}) y_s
        = d_{i-1}^2 - d_i^2 - x_{i-1}^2 + x_i^2 - y_{i-1}^2 + y_i^2               (3.10)

All consecutive pairs of the scan are stacked and solved by linear least squares.
"""

from __future__ import annotations

import numpy as np

from graph_slam.errors import PlanarError


def trilaterate(world_xy_m: np.ndarray, ranges_m: np.ndarray) -> np.ndarray:
    """Least-squares sensor position (x_s, y_s) from points and their ranges (eq. 3.10)."""
    if len(world_xy_m) != len(ranges_m):
        raise PlanarError(f"trilaterate: {len(world_xy_m)} points but {len(ranges_m)} ranges")
    if len(world_xy_m) < 3:
        raise PlanarError(f"trilaterate: needs at least 3 points, got {len(world_xy_m)}")
    x, y, d = world_xy_m[:, 0], world_xy_m[:, 1], ranges_m
    a = np.column_stack([2 * (x[1:] - x[:-1]), 2 * (y[1:] - y[:-1])])
    b = d[:-1] ** 2 - d[1:] ** 2 - x[:-1] ** 2 + x[1:] ** 2 - y[:-1] ** 2 + y[1:] ** 2
    solution, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
    if rank < 2:
        raise PlanarError(
            "trilaterate: the points are collinear along the rays; the position is not determined"
        )
    return solution
