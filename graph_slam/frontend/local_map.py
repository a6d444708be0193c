"""A local map for frame-to-map registration: voxel means on a grid fixed in the map frame.

Insert registered frames with ``insert(cloud_in_camera, map_T_camera)``; ``cloud()`` returns one
point (and colour) per voxel, the mean of everything that fell in it. The grid's origin is the
map frame's origin, so a voxel covers the same piece of the world whichever frame filled it.
Register a new frame against it with
``register(frame_cloud, build_pyramid(local_map.cloud(), config, viewpoint_m), config, map_T_camera_guess)``.
"""

from __future__ import annotations

import numpy as np

from graph_slam.errors import ConfigError
from graph_slam.frontend.cloud import Cloud, VoxelSums, voxel_index
from graph_slam.session.checks import check_pose


class LocalMap:
    """Running voxel means in the map frame (:class:`VoxelSums` over every inserted frame)."""

    def __init__(self, voxel_m: float, *, with_colors: bool = True) -> None:
        if not voxel_m > 0:
            raise ConfigError(f"LocalMap.voxel_m: must be > 0, got {voxel_m!r}")
        self.voxel_m = float(voxel_m)
        self.with_colors = with_colors
        self.clear()

    def clear(self) -> None:
        self._sums = VoxelSums.empty(self.with_colors)
        self.frames_inserted = 0

    def __len__(self) -> int:
        return len(self._sums)

    def insert(self, cloud: Cloud, map_T_cloud: np.ndarray) -> None:
        """Add ``cloud`` (in its own frame) at pose ``map_T_cloud``."""
        check_pose("LocalMap.insert", "map_T_cloud", np.asarray(map_T_cloud, float))
        if self.with_colors and cloud.colors is None:
            raise ConfigError("LocalMap.with_colors: the map keeps colours, the cloud has none")
        points = cloud.points_m @ map_T_cloud[:3, :3].T + map_T_cloud[:3, 3]
        self._sums = self._sums.added(voxel_index(points, self.voxel_m), points, cloud.colors)
        self.frames_inserted += 1

    def cloud(self) -> Cloud:
        """One point per voxel (the mean), in the map frame."""
        return self._sums.cloud()
