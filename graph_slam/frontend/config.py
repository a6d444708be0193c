"""Typed configuration of the registration front end.

:class:`CloudConfig` (depth image → cloud) and :class:`RegistrationConfig` (pyramid, ICP,
robust kernel, quality gates); the pipelines' config holds both. Presets:
:func:`thesis_registration` (the thesis: multi-scale colored ICP as in Open3D's tutorial, no
robust kernel), :func:`colored_registration` (the default: the same with a Tukey kernel),
:func:`refined_colored_registration` (then a depth-noise-weighted refinement at 5 mm) and
:func:`fast_point_to_plane` (depth only, one 2 cm level); :func:`with_real_camera_floor` puts
the covariance floor of a real camera on any of them. :class:`GicpConfig` and
:func:`realtime_registration`: the real-time front end (small_gicp's GICP on one fixed-grid
scale, each frame prepared once: :mod:`graph_slam.frontend.gicp`).

The registration's models and presets live in :mod:`graph_slam.frontend.registration_config`,
the real-time ones in :mod:`graph_slam.frontend.realtime_config`; every name is importable from
here too.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.frontend.realtime_config import (  # noqa: F401 (re-exported)
    GicpConfig,
    PreparedFrameConfig,
    ProjectiveConfig,
    gicp_registration,
    realtime_registration,
)
from graph_slam.frontend.registration_config import (  # noqa: F401 (re-exported)
    THESIS_LEVELS,
    ConstraintAnalysisConfig,
    DepthOnlyConfig,
    Kernel,
    LevelConfig,
    Method,
    RefineConfig,
    RegistrationConfig,
    _levels,
    colored_registration,
    fast_point_to_plane,
    refined_colored_registration,
    thesis_registration,
)


class CloudConfig(ConfigModel):
    """Depth image → cloud in the camera frame: pixels outside the range are dropped (counted)."""

    min_depth_m: float = Field(0.1, gt=0, description="closer readings are dropped")
    max_depth_m: float = Field(3.0, gt=0, description="farther readings are dropped")

    @model_validator(mode="after")
    def _range(self) -> CloudConfig:
        if self.max_depth_m <= self.min_depth_m:
            raise ValueError(
                f"max_depth_m ({self.max_depth_m}) must be greater than min_depth_m "
                f"({self.min_depth_m})"
            )
        return self


# The covariance floor that makes the accurate preset's χ² honest on a real RGB-D camera (the
# TUM fr1/xyz frames against their motion-capture truth: χ²/dof median 0.83; without it 663):
# millimetres of systematic error (calibration, depth bias, timing, and the reference's own
# error) that the simulator does not render. docs/frontend.md.
REAL_CAMERA_FLOOR_M = 0.0015
REAL_CAMERA_FLOOR_RAD = 0.0035  # 0.2 deg


def with_real_camera_floor(config: RegistrationConfig | ProjectiveConfig):
    """``config`` (the accurate path's or the projective real-time preset's) with the
    real-camera covariance floor (:data:`REAL_CAMERA_FLOOR_M`, :data:`REAL_CAMERA_FLOOR_RAD`):
    for recorded sessions; the simulator needs the default."""
    return config.model_copy(
        update={
            "information_floor_m": REAL_CAMERA_FLOOR_M,
            "information_floor_rad": REAL_CAMERA_FLOOR_RAD,
        }
    )
