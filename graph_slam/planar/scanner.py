"""The simulated 2D range sensor: ray casting with Gaussian noise and max-range returns.

Thesis 3.2: 150 rays over 75° at 45 Hz, Gaussian white noise on the ranges. Where a ray
finds no terrain within range it returns exactly the maximum range, as a real scanner's
no-return does; :attr:`Scan.hit` keeps the truth about which rays those are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.config import ScannerConfig
from graph_slam.planar.terrain import OccupancyGrid, cast_rays


@dataclass(frozen=True)
class Scan:
    """One scan in the sensor frame (x along the boresight, y 90° anticlockwise from it)."""

    t_s: float
    angles_rad: np.ndarray
    ranges_m: np.ndarray
    hit: np.ndarray  # False: no terrain in range, range set to max_range_m

    def points_xy_m(self, drop_max_range: bool = False) -> np.ndarray:
        """(n, 2) points in the sensor frame, in ray order."""
        keep = self.hit if drop_max_range else np.ones_like(self.hit)
        r, a = self.ranges_m[keep], self.angles_rad[keep]
        return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def ray_angles_rad(config: ScannerConfig) -> np.ndarray:
    """Ray directions in the sensor frame, evenly over the field of view."""
    half = config.fov_rad / 2.0
    return np.linspace(-half, half, config.n_rays)


def simulate_scan(
    grid: OccupancyGrid,
    world_T_sensor: np.ndarray,
    t_s: float,
    config: ScannerConfig,
    rng: np.random.Generator,
) -> Scan:
    """Ray-cast one scan from ``world_T_sensor`` and add seeded Gaussian range noise."""
    angles = ray_angles_rad(config)
    heading = se2.xyt(world_T_sensor)[2]
    true_ranges = cast_rays(grid, world_T_sensor[:2, 2], heading + angles, config.max_range_m)
    hit = np.isfinite(true_ranges)
    noise = rng.normal(0.0, config.range_sigma_m, size=angles.shape)
    noisy = np.clip(true_ranges + noise, 0.0, config.max_range_m)
    ranges = np.where(hit, noisy, config.max_range_m)
    return Scan(t_s=t_s, angles_rad=angles, ranges_m=ranges, hit=hit)
