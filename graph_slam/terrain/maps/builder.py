"""The terrain map as a pipeline output: every stride's map from its online and smoothed poses.

A pipeline gives :class:`TerrainBuilder` each frame as it arrives (:meth:`add_frame` keeps the
frame's map cloud, every ``pixel_step``-th depth pixel within range) and, when a stride closes,
its poses (:meth:`close_stride`): the builder fuses the stride's clouds on a fixed grid,
grids the heights and extracts the floor and boxes (:func:`build_stride_map`) once from the
online poses and again from the smoothed ones. Frames without a pose (NaN) are left out.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.terrain.grid.online import OnlineTerrainConfig
from graph_slam.terrain.maps.stride_map import MappingConfig, StrideMap, build_stride_map

log = logging.getLogger(__name__)

PoseKind = Literal["online", "smoothed"]


class TerrainConfig(ConfigModel):
    """Which maps a pipeline builds per stride, and from which depth."""

    enabled: bool = Field(True, description="build each stride's terrain map")
    poses: tuple[PoseKind, ...] = Field(
        ("online", "smoothed"),
        description="pose sets each stride's map is fused from (the baseline's smoothed poses "
        "are its online ones: one map serves both)",
    )
    pixel_step: int = Field(
        2, ge=1, le=16, description="map clouds use every n-th depth pixel in u and v"
    )
    max_depth_m: float = Field(
        2.0,
        gt=0,
        description="map clouds leave out depth beyond this (and beyond the pipeline's "
        "max_depth_m): the D455's depth noise grows as z² (1.9 mm at 1 m, 7.6 mm at 2 m, 17 mm "
        "at 3 m) and far readings blur box edges; the thesis measured boxes within ~1 m",
    )
    map: MappingConfig = MappingConfig()
    online: OnlineTerrainConfig = Field(
        default_factory=OnlineTerrainConfig,
        description="the per-frame elevation grid for the controller (FrameOutput.terrain; "
        "docs/terrain.md), independent of ``enabled``",
    )


@dataclass(frozen=True, eq=False)
class StrideTerrain:
    """One stride's terrain: the map fused from each pose set (None: not built or no pose)."""

    stride_index: int
    frame_indices: tuple[int, ...]
    online: StrideMap | None = None
    smoothed: StrideMap | None = None

    def by_kind(self, kind: str) -> StrideMap | None:
        return self.online if kind == "online" else self.smoothed


def scaled_intrinsics(intrinsics, step: int):
    """Intrinsics of the image subsampled by ``step`` (pixel ``u`` becomes ``u / step``)."""
    if step == 1:
        return intrinsics
    return dataclasses.replace(
        intrinsics,
        width_px=len(range(0, intrinsics.width_px, step)),
        height_px=len(range(0, intrinsics.height_px, step)),
        fx_px=intrinsics.fx_px / step,
        fy_px=intrinsics.fy_px / step,
        cx_px=intrinsics.cx_px / step,
        cy_px=intrinsics.cy_px / step,
    )


def map_pixels(frame, step: int, min_m: float, max_m: float):
    """Full-resolution (v, u) of every ``step``-th pixel with depth in ``(min_m, max_m)``."""
    depth = frame.depth_m[::step, ::step]
    v, u = np.nonzero((depth > min_m) & (depth < max_m))
    return v * step, u * step


def map_cloud(frame, intrinsics, step: int, min_m: float, max_m: float, pixels=None):
    """The frame's map cloud (camera frame): every ``step``-th pixel with depth in
    ``(min_m, max_m)`` (``pixels``: those of :func:`map_pixels`, when already found); colours
    uint8 (None for a depth-only frame)."""
    v_px, u_px = pixels if pixels is not None else map_pixels(frame, step, min_m, max_m)
    z = frame.depth_m[v_px, u_px].astype(np.float64)
    v, u = v_px // step, u_px // step
    pts = np.column_stack(
        [
            (u_px - intrinsics.cx_px) * z / intrinsics.fx_px,
            (v_px - intrinsics.cy_px) * z / intrinsics.fy_px,
            z,
        ]
    )
    colors = None if frame.color_rgb is None else frame.color_rgb[::step, ::step][v, u]
    return pts, colors


class TerrainBuilder:
    """Per-stride terrain maps for a pipeline (see the module docstring)."""

    def __init__(
        self, config: TerrainConfig, intrinsics, min_depth_m: float, max_depth_m: float
    ) -> None:
        self.cfg = config
        self.intrinsics = intrinsics
        self.min_depth_m = float(min_depth_m)
        self.max_depth_m = float(min(max_depth_m, config.max_depth_m))
        self._clouds: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
        self._waiting: dict[int, list] = {}  # stride index -> clouds for a later smoothed map

    def add_frame(self, frame_index: int, frame) -> None:
        """Keep the frame's map cloud until its stride closes."""
        if self.cfg.enabled:
            self._clouds[frame_index] = map_cloud(
                frame, self.intrinsics, self.cfg.pixel_step, self.min_depth_m, self.max_depth_m
            )

    def close_stride(
        self,
        stride_index: int,
        frame_indices: Sequence[int],
        online_stride_T_camera: np.ndarray,
        smoothed_stride_T_camera: np.ndarray | None,
        smoothed_later: bool = False,
    ) -> StrideTerrain:
        """Fuse the stride's frames with each configured pose set; forget their clouds.
        ``smoothed_stride_T_camera`` None: the online poses are the smoothed ones.
        ``smoothed_later``: the smoothed poses come later (deferred smoothing): the clouds
        wait for :meth:`fuse_smoothed` when a smoothed map is configured."""
        frames = tuple(int(i) for i in frame_indices)
        clouds = [self._clouds.pop(i, None) for i in frames]
        if not self.cfg.enabled or any(c is None for c in clouds):
            return StrideTerrain(stride_index, frames)
        if smoothed_later:
            if "smoothed" in self.cfg.poses:
                self._waiting[stride_index] = clouds
            online = None
            if "online" in self.cfg.poses:
                online = self._fuse(clouds, np.asarray(online_stride_T_camera))
            return StrideTerrain(stride_index, frames, online, None)
        poses = {"online": online_stride_T_camera, "smoothed": smoothed_stride_T_camera}
        maps: dict[str, StrideMap | None] = {}
        for kind in self.cfg.poses:
            if kind == "smoothed" and poses["smoothed"] is None:
                continue  # filled from the online map below
            maps[kind] = self._fuse(clouds, np.asarray(poses[kind]))
        if smoothed_stride_T_camera is None and "smoothed" in self.cfg.poses:
            maps["smoothed"] = maps.get("online") or self._fuse(
                clouds, np.asarray(online_stride_T_camera)
            )
        return StrideTerrain(stride_index, frames, maps.get("online"), maps.get("smoothed"))

    def fuse_smoothed(self, terrain: StrideTerrain, smoothed_stride_T_camera) -> StrideTerrain:
        """The stride's map from its (deferred) smoothed poses; ``terrain`` unchanged when no
        clouds wait for it."""
        clouds = self._waiting.pop(terrain.stride_index, None)
        if clouds is None:
            return terrain
        return dataclasses.replace(
            terrain, smoothed=self._fuse(clouds, np.asarray(smoothed_stride_T_camera))
        )

    def _fuse(self, clouds, stride_T_camera: np.ndarray) -> StrideMap:
        colors = [c for _, c in clouds]
        has_colors = all(c is not None for c in colors)
        return build_stride_map(
            [p for p, _ in clouds], stride_T_camera, colors if has_colors else None, self.cfg.map
        )
