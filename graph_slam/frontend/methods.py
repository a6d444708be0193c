"""The registration method, chosen once: ``make_registration(config, intrinsics, ...)``.

The three methods share one small interface (:class:`Registration`):

* ``prepare(frame, grid_T_cloud)`` turns a frame into a :class:`PreparedFrame`, once: the
  source of its own registration and, unchanged, the target of later frames;
* ``register(source, target, target_T_source)`` aligns a prepared source with a prepared
  target from an initial guess and returns the one
  :class:`~graph_slam.frontend.result.RegistrationResult`, or raises
  :class:`~graph_slam.errors.RegistrationError`.

The config's type chooses the method:

* :class:`RegistrationConfig`: Open3D's multi-scale point-to-plane or colored ICP
  (:mod:`graph_slam.frontend.registration`; the ``accurate`` and ``thesis`` presets). A frame
  is its cloud and its pyramid on its own grid; the source is voxelised on the target's grid
  inside the registration (``grid_T_cloud`` is not used).
* :class:`GicpConfig`: small_gicp's GICP (:mod:`graph_slam.frontend.gicp`, ``realtime-gicp``):
  voxel means on the grid ``grid_T_cloud``, covariances and a k-d tree.
* :class:`ProjectiveConfig`: projective association on the organised depth image
  (:mod:`graph_slam.frontend.projective`, the ``realtime`` preset).

``grid_T_cloud``: the frame whose origin anchors the new frame's voxel grid; a frame about to
be registered is prepared on its target's grid through the guess
(``target.grid_T_cloud @ guess``), so both are sampled on the same grid.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from graph_slam.errors import ConfigError, RegistrationError, RegistrationFailure
from graph_slam.frontend.cloud import Cloud, build_pyramid, depth_to_cloud
from graph_slam.frontend.config import (
    CloudConfig,
    GicpConfig,
    ProjectiveConfig,
    RegistrationConfig,
)
from graph_slam.frontend.gicp import prepare_frame, register_prepared
from graph_slam.frontend.projective import (
    OrganisedDepth,
    organise_depth,
    prepare_depth,
    register_depth,
    uses_color,
)
from graph_slam.frontend.registration import register
from graph_slam.frontend.result import RegistrationResult
from graph_slam.session.records import CameraIntrinsics, RgbdFrame


@dataclass(frozen=True, eq=False)
class PreparedFrame:
    """A frame ready to register and to be registered against, whatever the method.

    ``cloud``: the frame's points in its camera frame (what the floor fit reads); ``data``:
    the method's own form (a :class:`~graph_slam.frontend.cloud.Pyramid`, a
    :class:`~graph_slam.frontend.gicp.GicpFrame` or a
    :class:`~graph_slam.frontend.projective.DepthFrame`), None when the frame cannot be a
    target; ``timing_s``: ``cloud`` (depth → points), ``voxel`` and ``normals`` (normals or
    covariances)."""

    cloud: Cloud
    data: object | None
    grid_T_cloud: np.ndarray
    timing_s: dict[str, float] = field(default_factory=dict)

    @property
    def is_target(self) -> bool:
        """Whether later frames can be registered against this one."""
        return self.data is not None


class Registration(Protocol):
    """One registration method (module docstring)."""

    config: RegistrationConfig | GicpConfig | ProjectiveConfig
    needs_guess: bool
    """The method needs a good initial guess (one scale, a tight correspondence distance):
    a pipeline then asks the IMU for it."""

    def prepare(self, frame: RgbdFrame, grid_T_cloud: np.ndarray | None = None) -> PreparedFrame:
        """The frame prepared once, on the grid fixed in frame ``grid`` (its own by default)."""

    def register(
        self,
        source: PreparedFrame,
        target: PreparedFrame,
        initial_target_T_source: np.ndarray | None = None,
    ) -> RegistrationResult:
        """``source`` aligned with ``target`` from the guess (identity by default)."""


def make_registration(
    config: RegistrationConfig | GicpConfig | ProjectiveConfig,
    intrinsics: CameraIntrinsics,
    cloud_config: CloudConfig | None = None,
    has_color: bool = True,
) -> Registration:
    """The method ``config`` names, for frames of ``intrinsics`` (``has_color``: the sensor
    has a colour image; without it the Open3D and projective methods use depth alone)."""
    cloud_config = cloud_config or CloudConfig()
    if isinstance(config, GicpConfig):
        return _Gicp(config, intrinsics, cloud_config)
    if isinstance(config, ProjectiveConfig):
        return _Projective(config, intrinsics, cloud_config, has_color)
    if isinstance(config, RegistrationConfig):
        return _Open3d(config, intrinsics, cloud_config, has_color)
    raise ConfigError(
        f"registration: {type(config).__name__} is not a registration config "
        "(RegistrationConfig, GicpConfig or ProjectiveConfig)"
    )


class _Open3d:
    """Open3D's multi-scale ICP (:func:`graph_slam.frontend.registration.register`)."""

    needs_guess = False

    def __init__(self, config, intrinsics, cloud_config, has_color: bool) -> None:
        self.config, self.intrinsics, self.cloud_config = config, intrinsics, cloud_config
        self.use_color = has_color and config.method == "colored"

    def prepare(self, frame, grid_T_cloud=None) -> PreparedFrame:
        t0 = time.perf_counter()
        cloud, _ = depth_to_cloud(frame, self.intrinsics, self.cloud_config)
        if not self.use_color:
            cloud = Cloud(cloud.points_m)
        t1 = time.perf_counter()
        try:
            pyramid = build_pyramid(cloud, self.config)
            timing = pyramid.timing_s
        except RegistrationError:
            pyramid, timing = None, {"voxel": time.perf_counter() - t1, "normals": 0.0}
        return PreparedFrame(cloud, pyramid, np.eye(4), {"cloud": t1 - t0, **timing})

    def register(self, source, target, initial_target_T_source=None) -> RegistrationResult:
        if target.data is None:
            raise RegistrationError(
                RegistrationFailure.EMPTY_TARGET, "the target frame has no pyramid (no normals)"
            )
        return register(source.cloud, target.data, self.config, initial_target_T_source)


class _Gicp:
    """small_gicp's GICP (:mod:`graph_slam.frontend.gicp`)."""

    needs_guess = False

    def __init__(self, config, intrinsics, cloud_config) -> None:
        self.config, self.intrinsics, self.cloud_config = config, intrinsics, cloud_config
        self.pixel_step = config.pixel_step_for(intrinsics)

    def prepare(self, frame, grid_T_cloud=None) -> PreparedFrame:
        t0 = time.perf_counter()
        cloud, _ = depth_to_cloud(frame, self.intrinsics, self.cloud_config, self.pixel_step)
        t1 = time.perf_counter()
        prepared = prepare_frame(cloud, self.config, grid_T_cloud)
        timing = {
            "cloud": t1 - t0,
            "voxel": prepared.timing_s["voxel"],
            "normals": prepared.timing_s["covariances"],
        }
        return PreparedFrame(cloud, prepared, prepared.grid_T_cloud, timing)

    def register(self, source, target, initial_target_T_source=None) -> RegistrationResult:
        return register_prepared(source.data, target.data, self.config, initial_target_T_source)


PROJECTIVE_MIN_FOCAL_PX = 100.0
"""The decimated image's focal length (pixels) the projective preset's voxel, depth-jump and
correspondence limits are set for: 106 px at 212×120 (every pixel) and 424×240 (every 2nd)."""


def projective_for_camera(config: ProjectiveConfig, intrinsics: CameraIntrinsics):
    """``config`` for a camera whose decimated pixels are coarser than the preset's: the
    voxel, the depth-jump limit between neighbouring pixels and the correspondence distance
    grow with the pixel's angle. On a 106×60 image the preset's 2 cm voxels held one pixel
    each (a voxel needs ``min_pixel_normals``) and the floor's neighbouring rows differed by
    more than the jump limit, so no frame had a point to register. Unchanged at 212×120 and
    above."""
    focal_px = intrinsics.fx_px / config.pixel_step_for(intrinsics)
    scale = PROJECTIVE_MIN_FOCAL_PX / focal_px if focal_px > 0 else 1.0
    if scale <= 1.0:
        return config
    return config.model_copy(
        update={
            "voxel_m": config.voxel_m * scale,
            "max_jump_ratio": config.max_jump_ratio * scale,
            "max_correspondence_m": config.max_correspondence_m * scale,
        }
    )


class OrganisedAhead:
    """Frames' frame-only preparation done ahead of their turn (:func:`organise_depth`, on
    another thread), for the projective registrations that share it; each one is taken once,
    by the frame made of the same arrays; at most ``size`` wait (the oldest are dropped: a
    frame the live loop skipped never takes its own)."""

    def __init__(self, size: int = 8) -> None:
        self._lock = threading.Lock()
        self._waiting: deque[OrganisedDepth] = deque(maxlen=size)

    def put(self, organised: OrganisedDepth) -> None:
        with self._lock:
            self._waiting.append(organised)

    def take(self, frame, color: bool) -> OrganisedDepth | None:
        with self._lock:
            for i, organised in enumerate(self._waiting):
                if organised.fits(frame, color):
                    del self._waiting[i]
                    return organised
        return None

    def __len__(self) -> int:
        return len(self._waiting)


class _Projective:
    """Projective association on the organised depth (:mod:`graph_slam.frontend.projective`)."""

    needs_guess = True

    def __init__(self, config, intrinsics, cloud_config, has_color: bool) -> None:
        self.config = projective_for_camera(config, intrinsics)
        self.intrinsics, self.cloud_config = intrinsics, cloud_config
        self.has_color = has_color
        self.ahead: OrganisedAhead | None = None  # frames organised ahead (:meth:`organise`)

    def organise(self, frame) -> OrganisedDepth:
        """The frame-only part of :meth:`prepare` (any thread: it reads the config only)."""
        return organise_depth(frame, self.intrinsics, self.config, self.cloud_config,
                              self.has_color)  # fmt: skip

    def prepare(self, frame, grid_T_cloud=None) -> PreparedFrame:
        organised = None
        if self.ahead is not None:
            organised = self.ahead.take(frame, uses_color(frame, self.config, self.has_color))
        depth = prepare_depth(frame, self.intrinsics, self.config, self.cloud_config,
                              grid_T_cloud, self.has_color, organised)  # fmt: skip
        timing = {stage: depth.timing_s[stage] for stage in ("cloud", "voxel", "normals")}
        return PreparedFrame(Cloud(depth.pixel_points_m), depth, depth.grid_T_cloud, timing)

    def register(self, source, target, initial_target_T_source=None) -> RegistrationResult:
        return register_depth(source.data, target.data, self.config, initial_target_T_source)
