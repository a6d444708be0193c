"""Fuse registered camera-frame clouds into one coloured, voxel-averaged map in the stride frame.

The voxel grid has a fixed origin (``origin_m``, the stride origin by default), not each cloud's
minimum point as Open3D's ``voxel_down_sample`` uses, so every frame falls on the same grid and
fusing again with other poses (e.g. smoothed ones) gives a map on the same cells. Fusion is a pure
function of the clouds and the poses: to re-fuse after smoothing, call :func:`fuse_clouds` again
with the smoothed ``stride_T_camera``.

A frame whose pose is missing (NaN, a failed registration with nothing to bridge it) is skipped
and counted, never placed at the previous pose.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import MappingError
from graph_slam.frontend.cloud import VoxelSums, voxel_index
from graph_slam.session.records import Cloud

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class FusedMap:
    """A voxel-averaged map: one point per occupied voxel, in the frame of the poses given.

    ``points_m`` is the mean of the points that fell in each voxel; ``colors_rgb`` (uint8) their
    mean colour (None when no cloud had colours); ``counts`` how many points each voxel averaged;
    ``voxel_keys`` the integer cell index (i, j, k) of each voxel on the fixed grid.
    """

    points_m: np.ndarray
    colors_rgb: np.ndarray | None
    counts: np.ndarray
    voxel_keys: np.ndarray
    voxel_m: float
    origin_m: np.ndarray
    frames_fused: int
    frames_skipped: int
    """Frames left out because their pose was missing (NaN)."""

    def __len__(self) -> int:
        return int(self.points_m.shape[0])

    def to_point_cloud(self) -> Cloud:
        """As a :class:`~graph_slam.session.records.Cloud` (e.g. for
        ``graph_slam.session.adapters.ply.write_ply``, which writes these colours back exactly)."""
        return Cloud(self.points_m, None if self.colors_rgb is None else self.colors_rgb / 255.0)


def voxel_keys(points_m: np.ndarray, voxel_m: float, origin_m: np.ndarray) -> np.ndarray:
    """Integer voxel index of each point on the grid anchored at ``origin_m``
    (:func:`graph_slam.frontend.cloud.voxel_index` of the points relative to it)."""
    return voxel_index(points_m - origin_m, voxel_m)


def _check_cloud(i: int, points: np.ndarray, colors: np.ndarray | None) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise MappingError(f"fuse_clouds: cloud {i} has shape {points.shape}; it must be N×3")
    if not np.isfinite(points).all():
        raise MappingError(f"fuse_clouds: cloud {i} has NaN or inf points; drop them first")
    if colors is not None and colors.shape != points.shape:
        raise MappingError(
            f"fuse_clouds: colours of cloud {i} have shape {colors.shape}, points {points.shape}"
        )


def fuse_clouds(
    clouds_camera_m: Sequence[np.ndarray],
    stride_T_camera: np.ndarray,
    colors_rgb: Sequence[np.ndarray | None] | None = None,
    *,
    voxel_m: float = 0.01,
    origin_m: Sequence[float] = (0.0, 0.0, 0.0),
) -> FusedMap:
    """Transform each camera-frame cloud by its ``stride_T_camera`` and voxel-average them.

    Args:
        clouds_camera_m: per frame, N×3 points in the camera frame (metres).
        stride_T_camera: F×4×4 poses, one per cloud; a pose containing NaN skips its frame.
        colors_rgb: per frame, N×3 colours (uint8 0–255 or float 0–1) or None. The map has colours
            only if every fused frame has them.
        voxel_m: voxel edge (metres).
        origin_m: the grid's fixed origin, in the stride frame.
    """
    poses = np.asarray(stride_T_camera, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or poses.shape[0] != len(clouds_camera_m):
        raise MappingError(
            f"fuse_clouds: stride_T_camera has shape {poses.shape}; it must be "
            f"{len(clouds_camera_m)}×4×4 (one pose per cloud)"
        )
    if colors_rgb is not None and len(colors_rgb) != len(clouds_camera_m):
        raise MappingError(
            f"fuse_clouds: {len(colors_rgb)} colour arrays for {len(clouds_camera_m)} clouds"
        )
    if not (np.isfinite(voxel_m) and voxel_m > 0):
        raise MappingError(f"fuse_clouds: voxel_m must be > 0, got {voxel_m!r}")
    origin = np.asarray(origin_m, dtype=np.float64).reshape(3)

    points_all, colors_all, skipped = [], [], 0
    have_colors = colors_rgb is not None
    for i, cloud in enumerate(clouds_camera_m):
        points = np.asarray(cloud, dtype=np.float64)
        colors = None if colors_rgb is None else colors_rgb[i]
        colors = None if colors is None else np.asarray(colors)
        _check_cloud(i, points, colors)
        if not np.isfinite(poses[i]).all():
            skipped += 1
            continue
        points_all.append(points @ poses[i, :3, :3].T + poses[i, :3, 3])
        if colors is None:
            have_colors = False
        elif have_colors:
            scale = 1.0 if colors.dtype == np.uint8 else 255.0
            colors_all.append(colors.astype(np.float64) * scale)
    if skipped:
        log.info("fuse_clouds: %d of %d frames skipped (no pose)", skipped, len(poses))

    fused = len(clouds_camera_m) - skipped
    if not points_all or sum(p.shape[0] for p in points_all) == 0:
        empty = np.zeros((0, 3))
        return FusedMap(
            empty, None, np.zeros(0, np.int64), np.zeros((0, 3), np.int64),
            voxel_m, origin, fused, skipped,
        )  # fmt: skip
    points = np.concatenate(points_all)
    colors = np.concatenate(colors_all) if have_colors and colors_all else None
    sums = VoxelSums.of(voxel_keys(points, voxel_m, origin), points, colors)
    mean_colors = sums.mean_colors()
    if mean_colors is not None:
        mean_colors = np.clip(np.rint(mean_colors), 0, 255).astype(np.uint8)
    counts = sums.counts.astype(np.int64)
    return FusedMap(
        sums.mean_points(), mean_colors, counts, sums.index, voxel_m, origin, fused, skipped
    )
