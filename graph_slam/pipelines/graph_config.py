"""Typed configuration of the graph variants' front end: how a frame is registered against
a keyframe of its stride (:class:`GraphFrontendConfig`) and the registration presets it can
name (:data:`REGISTRATION_PRESETS`)."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Discriminator, Field, Tag, field_validator

from graph_slam.config import ConfigModel
from graph_slam.frontend.config import (
    DepthOnlyConfig,
    GicpConfig,
    LevelConfig,
    ProjectiveConfig,
    RegistrationConfig,
    gicp_registration,
    realtime_registration,
    thesis_registration,
)
from graph_slam.frontend.floor import FloorConfig
from graph_slam.frontend.treads import TreadsConfig
from graph_slam.pipelines.keyframe import KeyframeConfig


def _graph_registration() -> RegistrationConfig:
    """Frame-to-frame registration for the graph: colored ICP, 2 levels (4, 2 cm), Tukey."""
    return RegistrationConfig(
        method="colored",
        levels=(
            LevelConfig(voxel_m=0.04, max_correspondence_m=0.04, max_iterations=30),
            LevelConfig(voxel_m=0.02, max_correspondence_m=0.02, max_iterations=20),
        ),
        kernel="tukey",
    )


#: The graph's registration presets (``graph.registration: <name>`` in YAML): ``accurate``
#: (the default: colored ICP 4/2 cm, Tukey), ``thesis`` (colored ICP 4/2/1 cm, no kernel, the
#: thesis's), ``realtime`` (organised normals, projective association, colored ICP's objective
#: on 2 cm voxels, each frame prepared once: :mod:`graph_slam.frontend.projective`; it turns
#: the IMU guess on, see ``GraphFrontendConfig.imu_guess``), ``realtime-gicp`` (small_gicp's
#: GICP + the photometric stage: :mod:`graph_slam.frontend.gicp`). See docs/frontend.md.
REGISTRATION_PRESETS = {
    "accurate": _graph_registration,
    "thesis": thesis_registration,
    "realtime": realtime_registration,
    "realtime-gicp": gicp_registration,
}


def _registration_kind(value: Any) -> str:
    method = value.get("method") if isinstance(value, dict) else getattr(value, "method", None)
    return method if method in ("gicp", "projective") else "icp"


GraphRegistration = Annotated[
    Annotated[RegistrationConfig, Tag("icp")]
    | Annotated[GicpConfig, Tag("gicp")]
    | Annotated[ProjectiveConfig, Tag("projective")],
    Discriminator(_registration_kind),
]
"""Open3D ICP (:class:`RegistrationConfig`), the real-time GICP (:class:`GicpConfig`,
``method: gicp``) or the projective real-time front end (:class:`ProjectiveConfig`,
``method: projective``)."""


class GraphFrontendConfig(ConfigModel):
    """How the graph variants register frames (against a keyframe of the same stride)."""

    registration: GraphRegistration = Field(
        default_factory=_graph_registration,
        description="a preset name (accurate, thesis, realtime) or a full config: Open3D ICP, "
        "or GICP with 'method: gicp'",
    )
    constant_velocity_guess: bool = Field(
        True, description="initial guess: the last online relative motion scaled by Δt"
    )
    imu_guess: bool | None = Field(
        None,
        description="initial guess: the IMU preintegrated from the graph's current estimate "
        "(StrideSLAM.predict_relative); falls back to constant velocity at a stride's start "
        "or across an IMU gap. None: on with the projective (realtime) registration, whose "
        "single scale needs a close guess, off otherwise",
    )
    keyframe: KeyframeConfig = Field(
        default_factory=KeyframeConfig,
        description="which earlier frame a frame registers against (interval_s 0: the "
        "previous one)",
    )
    real_camera_floor: bool | None = Field(
        None,
        description="the ICP information's real-camera covariance floor (1.5 mm, 0.2 deg: "
        "systematic errors no residual shows; docs/frontend.md 'Calibrated information') on "
        "the accurate registration and the projective real-time preset, unless "
        "graph.registration sets a floor of its own. None: "
        "on, except on sessions the simulator or the synthetic generator wrote "
        "(session.yaml provenance), which render no systematic error",
    )
    icp_in_swing: bool = Field(
        True,
        description="False: no registration while the foot is unloaded, as if every swing "
        "registration failed (the bridging experiment: IMU + kinematics carry the swing)",
    )
    floor: FloorConfig = Field(
        default_factory=FloorConfig,
        description="the floor plane in the stride's first frame, fused into the anchor's tilt",
    )
    treads: TreadsConfig = Field(
        default_factory=TreadsConfig,
        description="where no floor passes the floor fit: several small level planes (stair "
        "treads) in the stride's first frame, fused into the anchor's tilt when level",
    )
    recolour_keyframe: bool = Field(
        False,
        description="True: a frame with colour whose keyframe has none (colour slower than "
        "depth) registers without colour, then becomes the keyframe with its colour, so the "
        "frames after it register with colour again; False: colourless until the keyframe is "
        "reset. Off: on simulated 30 Hz colour recordings it helped one walk and hurt another "
        "(docs/pipelines.md, Keyframes)",
    )
    depth_only: DepthOnlyConfig | None = Field(
        default_factory=DepthOnlyConfig,
        description="a session without colour: point-to-plane with these settings in place of "
        "the RGB-D ones (Open3D registration; docs/frontend.md, 'Depth-only sensors'); None: "
        "point-to-plane with the registration's own settings",
    )

    @field_validator("registration", mode="before")
    @classmethod
    def _preset(cls, value: Any) -> Any:
        """A preset name stands for its config."""
        if isinstance(value, str):
            if value not in REGISTRATION_PRESETS:
                raise ValueError(
                    f"unknown registration preset {value!r}; choose from "
                    f"{', '.join(REGISTRATION_PRESETS)} or give a full config"
                )
            return REGISTRATION_PRESETS[value]()
        return value
