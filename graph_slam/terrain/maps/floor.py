"""The floor of a stride map: the plane the boxes stand on, and the floor frame.

Steps (the first two of :mod:`graph_slam.terrain.maps.obstacles`, whose settings,
:class:`ObstacleConfig`, are kept here with the floor's):

1. **Floor**: RANSAC (seeded) on planes whose normal is within ``max_floor_tilt_rad`` of stride
   z. The plane with most inliers wins, unless a plane parallel to it (within 0.1 rad) and lower
   has at least ``dominant_fraction`` of its inliers (a large box top is a plane too): the lowest
   dominant plane is the floor. It is refined by least squares (SVD) on its inliers, re-selected
   in a band of 3 robust sigmas until stable, so the feet of box sides do not tilt it.
2. **Floor frame**: z along the floor normal (up), x the stride x axis projected onto the floor,
   origin the stride origin projected onto the floor. Heights are distances above the floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.errors import MappingError
from graph_slam.frontend.floor import plane_hypotheses


class ObstacleConfig(ConfigModel):
    """Floor fitting and box segmentation settings (metres, radians)."""

    floor_distance_m: float = Field(0.01, gt=0)
    """RANSAC inlier distance to the floor plane."""
    ransac_iterations: int = Field(300, ge=1)
    ransac_max_points: int = Field(20000, ge=3)
    """The RANSAC search uses at most this many points (a seeded subsample)."""
    refit_max_points: int = Field(50000, ge=3)
    """The least-squares refits use at most this many points (evenly strided; a stride
    map's 200–250k points took 0.25–0.45 s per fit, 8 % of a profiled 3-stride demo; the plane's
    statistical error from 50k points is ~10 µm)."""
    max_floor_tilt_rad: float = Field(0.35, gt=0, le=1.5)
    dominant_fraction: float = Field(0.5, gt=0, le=1)
    seed: int = Field(0, ge=0, description="RANSAC random generator seed")
    min_height_m: float = Field(0.02, gt=0)
    """Points at least this high above the floor may belong to an obstacle."""
    cell_m: float = Field(0.01, gt=0)
    min_cells: int = Field(20, ge=1)
    """Least occupied cells of an obstacle."""
    join_gap_cells: int = Field(1, ge=0)
    """Small components up to this many empty cells from an obstacle count in its
    "points beyond the top" check (a sparsely seen top would otherwise fall apart, its dense
    part passing for the whole box)."""
    top_band_m: float = Field(0.01, gt=0)
    top_layer_min_m: float = Field(0.005, gt=0)
    """Least half-thickness of the top layer. Voxel-averaged edge cells mix top and side points
    and sit a few mm low; this keeps them (measured on the test scene: extents within 1.3 mm on
    raw clouds, 2 mm on a 5 mm voxel map, 4 mm on a 1 cm voxel map, where the voxel limits)."""
    extent_trim_fraction: float = Field(0.002, ge=0, lt=0.5)
    """Fraction of a component's points ignored at each end of its x and y extents (noise
    tails and stray points would otherwise widen every box by several sigmas)."""
    coverage_cell_m: float = Field(0.02, gt=0)
    """Cell of the coverage grid: which parts of the floor plane the map observed."""
    coverage_closing_cells: int = Field(1, ge=0)
    """Morphological closing of the observed cells (bridges gaps between sparse far points)."""
    edge_margin_m: float = Field(0.04, gt=0)
    """A box is seen whole only if its footprint grown by this margin stays clear of the
    unobserved area beyond the map and of other obstacles."""
    min_floor_seen_fraction: float = Field(0.4, ge=0, le=1)
    """Least fraction of that margin ring in which floor was seen (the box's own shadow
    behind it is the rest)."""
    min_top_fill_fraction: float = Field(0.8, ge=0, le=1)
    """Least fraction of the measured rectangle's coverage cells holding top-face points."""
    max_beyond_top_fraction: float = Field(0.03, ge=0, le=1)
    """Most of a box's points (above ``min_height_m``) that may lie farther than
    ``beyond_top_margin_m`` outside its top face's rectangle: more means side faces reach past
    a top seen only in part (measured on simulated strides: whole boxes ≤ 1.6 %, partial ones
    ≥ 5 %)."""
    beyond_top_margin_m: float = Field(0.02, gt=0)


@dataclass(frozen=True, eq=False)
class FloorPlane:
    """``normal · p + offset = 0`` in the stride frame, normal unit and pointing up."""

    normal: np.ndarray
    offset_m: float
    inliers: int
    rms_m: float
    """RMS distance of the inliers to the refined plane."""

    def height_m(self, points_m: np.ndarray) -> np.ndarray:
        """Signed distance of each point above the plane."""
        return points_m @ self.normal + self.offset_m

    def floor_T_stride(self) -> np.ndarray:
        """The floor frame (z up the normal, x the projected stride x, origin under the foot)."""
        z = self.normal
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        rotation = np.stack([x, y, z])  # rows: floor axes in stride coordinates
        origin = -self.offset_m * z  # the stride origin projected onto the plane
        floor_T_stride = np.eye(4)
        floor_T_stride[:3, :3] = rotation
        floor_T_stride[:3, 3] = -rotation @ origin
        return floor_T_stride


@numba.njit(cache=True, nogil=True)
def inlier_counts(
    points: np.ndarray, normals: np.ndarray, offsets: np.ndarray, distance_m: float
) -> np.ndarray:
    """Per plane ``normals[k] · p + offsets[k] = 0``: how many ``points`` lie within
    ``distance_m`` of it (one pass, no N×K distance matrix: that was most of a stride map's
    floor fit)."""
    counts = np.zeros(normals.shape[0], dtype=np.int64)
    for k in range(normals.shape[0]):
        nx, ny, nz, o = normals[k, 0], normals[k, 1], normals[k, 2], offsets[k]
        n = 0
        for i in range(points.shape[0]):
            d = points[i, 0] * nx + points[i, 1] * ny + points[i, 2] * nz + o
            if abs(d) < distance_m:
                n += 1
        counts[k] = n
    return counts


def fit_floor(points_m: np.ndarray, config: ObstacleConfig | None = None) -> FloorPlane:
    """The lowest dominant near-horizontal plane (RANSAC, then least squares on its inliers)."""
    cfg = config or ObstacleConfig()
    points = np.asarray(points_m, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 3:
        raise MappingError(f"fit_floor: need N×3 points with N >= 3, got shape {points.shape}")
    rng = np.random.default_rng(cfg.seed)
    sample = points
    if len(points) > cfg.ransac_max_points:
        sample = points[rng.choice(len(points), cfg.ransac_max_points, replace=False)]
    triples = sample[rng.integers(0, len(sample), size=(cfg.ransac_iterations, 3))]
    normals, offsets = plane_hypotheses(triples, np.array([0.0, 0.0, 1.0]))
    ok = np.isfinite(normals).all(axis=1) & (normals[:, 2] >= np.cos(cfg.max_floor_tilt_rad))
    if not ok.any():
        raise MappingError(
            "fit_floor: no near-horizontal plane found (is the cloud in the stride frame?)"
        )
    normals, offsets = normals[ok], offsets[ok]
    inliers = inlier_counts(sample, normals, offsets, cfg.floor_distance_m)
    # The plane with most inliers, unless a parallel plane below it is nearly as well supported
    # (a large box top can outnumber the floor); heights compared at the best plane's centroid.
    top = int(np.argmax(inliers))
    centroid = sample[np.abs(sample @ normals[top] + offsets[top]) < cfg.floor_distance_m].mean(
        axis=0
    )
    parallel = normals @ normals[top] > np.cos(0.1)
    dominant = np.flatnonzero(parallel & (inliers >= cfg.dominant_fraction * inliers[top]))
    height = -(normals[dominant, :2] @ centroid[:2] + offsets[dominant]) / normals[dominant, 2]
    best = dominant[np.argmin(height)]
    normal, offset = normals[best], float(offsets[best])
    band = cfg.floor_distance_m
    refit = points[:: max(1, -(-len(points) // cfg.refit_max_points))]
    for _ in range(10):
        # Least squares on the inliers, then a tighter band (3 robust sigmas) so that the feet
        # of walls and box sides, which lie within the RANSAC band, do not tilt the plane.
        distance = np.abs(refit @ normal + offset)
        mask = distance < band
        if mask.sum() < 3:
            break
        inlier_points = refit[mask]
        centroid = inlier_points.mean(axis=0)
        _, _, vt = np.linalg.svd(inlier_points - centroid, full_matrices=False)
        normal = vt[2] if vt[2, 2] > 0 else -vt[2]
        offset = -float(normal @ centroid)
        residual = np.abs(inlier_points @ normal + offset)
        band = min(cfg.floor_distance_m, max(3 * 1.4826 * float(np.median(residual)), 1e-4))
    mask = np.abs(points @ normal + offset) < band
    rms = float(np.sqrt(np.mean((points[mask] @ normal + offset) ** 2)))
    return FloorPlane(normal=normal, offset_m=offset, inliers=int(mask.sum()), rms_m=rms)
