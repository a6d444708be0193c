"""The one interface every pipeline variant implements, and what both pipelines build the same
way: the sensor's registration, the frame's cloud, the up-vector and terrain components."""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import numpy as np

from graph_slam.frontend.config import (
    CloudConfig,
    DepthOnlyConfig,
    ProjectiveConfig,
    RegistrationConfig,
    with_real_camera_floor,
)
from graph_slam.pipelines.results import FrameOutput, PipelineResults
from graph_slam.pipelines.strikes import StrikeClock
from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.variants import Variant


def sensor_registration(
    reg: RegistrationConfig, has_color: bool, depth_only: DepthOnlyConfig | None = None
) -> RegistrationConfig:
    """``reg`` for the session's camera: colored ICP falls back to point-to-plane without
    colour (a depth-only sensor such as the Pico Flexx), with the ``depth_only`` settings
    when given (the graph's ``graph.depth_only``; the thesis baseline keeps its own)."""
    if has_color or reg.method != "colored":
        return reg
    update: dict = {"method": "point_to_plane"}
    if depth_only is not None:
        update.update(depth_only.model_dump())
    return reg.model_copy(update=update)


def with_camera_floor(reg, on: bool | None):
    """``reg`` with the real-camera covariance floor (``graph.real_camera_floor``; None counts
    as on: a pipeline made without a session is a camera's) when it is the accurate (Open3D)
    registration or the projective real-time preset and sets no floor of its own (GICP, the
    ``realtime-gicp`` preset, has none)."""
    if on is False or not isinstance(reg, RegistrationConfig | ProjectiveConfig):
        return reg
    if reg.information_floor_m > 0 or reg.information_floor_rad > 0:
        return reg
    return with_real_camera_floor(reg)


def frame_cloud(
    frame: RgbdFrame,
    intrinsics: CameraIntrinsics,
    config: CloudConfig,
    has_color: bool,
    pixel_step: int = 1,
):
    """The frame's cloud in the camera frame (colours dropped for a depth-only sensor), from
    every ``pixel_step``-th row and column."""
    from graph_slam.frontend import depth_to_cloud

    cloud, _ = depth_to_cloud(frame, intrinsics, config, pixel_step)
    return cloud if has_color else type(cloud)(cloud.points_m)


@runtime_checkable
class Pipeline(Protocol):
    """A SLAM pipeline fed in time order: sensor streams (any chunking), per frame
    ``foot_strike`` (when one happened since the previous frame) and ``add_frame``.

    Every input arrives through these methods (no attribute is set from outside): the IMU
    reaches the estimator and the up-vector component by ``add_imu`` alone. Each closed
    stride carries its terrain maps (``StrideOutput.terrain``)."""

    variant: Variant

    def add_imu(self, t_s: np.ndarray, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray) -> None:
        """IMU samples on the camera clock (IMU frame)."""

    def add_joints(self, t_s: np.ndarray, knee_rad: np.ndarray, ankle_rad: np.ndarray) -> None:
        """Encoder samples on the camera clock."""

    def foot_strike(self, t_s: float) -> None:
        """A foot strike: the stride ends, the next frame starts a new one."""

    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        """Process one frame; returns its online output."""

    def finish(self) -> PipelineResults:
        """Close the open stride and return everything."""


def make_gravity(config):
    """The up-vector component of a pipeline (:mod:`graph_slam.strides.gravity`)."""
    from graph_slam.strides.gravity import GravityEstimator

    return GravityEstimator(default_window_s=config.gravity_window_s)


def make_terrain(config, intrinsics: CameraIntrinsics):
    """The terrain-map component of a pipeline (:mod:`graph_slam.terrain.maps.builder`)."""
    from graph_slam.terrain.maps.builder import TerrainBuilder

    return TerrainBuilder(
        config.terrain, intrinsics, config.cloud.min_depth_m, config.cloud.max_depth_m
    )


def make_live_terrain(
    config, intrinsics: CameraIntrinsics, link_strides: bool = True, refuse: bool = True
):
    """The per-frame terrain component of a pipeline (:mod:`graph_slam.terrain.grid.live`);
    ``refuse: False`` (a pipeline without smoothed poses) keeps no clouds for a re-fusion."""
    from graph_slam.terrain.grid.live import LiveTerrain

    online = config.terrain.online
    if not refuse:
        online = online.model_copy(update={"keep_clouds": False})
    return LiveTerrain(
        online,
        intrinsics,
        config.cloud.min_depth_m,
        config.cloud.max_depth_m,
        link_strides=link_strides,
    )


class PipelineBase:
    """What both pipelines build and keep the same way: the streaming contract's checks
    (:class:`~graph_slam.pipelines.strikes.StrikeClock`), the up-vector component
    (:func:`make_gravity`), each stride's terrain maps (:func:`make_terrain`), the per-frame
    grid (:func:`make_live_terrain`; ``link_strides`` and ``refuse`` as there) and the results,
    which keep every frame's record without its grid (memory: ``keep_frames``)."""

    def __init__(
        self,
        config,
        variant: Variant,
        intrinsics: CameraIntrinsics,
        camera_T_imu: np.ndarray,
        *,
        link_strides: bool = True,
        refuse: bool = True,
    ) -> None:
        self.cfg = config
        self.variant = variant
        self.intrinsics = intrinsics
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.gravity = make_gravity(config)
        self.terrain = make_terrain(config, intrinsics)
        self.live_terrain = make_live_terrain(config, intrinsics, link_strides, refuse)
        self.results = PipelineResults(variant=variant, config=config.model_dump(mode="json"))
        self.strike_clock = StrikeClock()  # the streaming contract (pipelines/strikes.py)

    def _record(self, out: FrameOutput) -> FrameOutput:
        """Keep the frame's record (without its grid) and return the output."""
        self.results.frames.append(dataclasses.replace(out, terrain=None))
        self.results.release_frames(self.cfg.keep_frames)
        return out
