"""Typed configuration of the pipelines (one sub-model per concern)."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Discriminator, Field, Tag, field_validator, model_validator

from graph_slam.backend.config import BackendConfig
from graph_slam.config import ConfigModel
from graph_slam.frontend.config import (
    THESIS_LEVELS,
    CloudConfig,
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
from graph_slam.pipelines.keyframe import KeyframeConfig
from graph_slam.strides.mount import MountEstimateConfig
from graph_slam.terrain.builder import TerrainConfig
from graph_slam.variants import Variant

VARIANT_NAMES = frozenset(v.value for v in Variant)

PipelineVariant = Variant
"""Former name of :class:`graph_slam.variants.Variant` (kept for imports)."""


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


class BaselineConfig(ConfigModel):
    """The thesis pipeline (Ch. 3.3-3.4): reset at foot strike, ICP to the global map."""

    registration: RegistrationConfig = Field(
        default_factory=lambda: RegistrationConfig(
            method="colored",
            levels=THESIS_LEVELS,
            kernel="none",
            min_fitness=0.0,
            check_convergence=False,
        ),
        description="3 levels (4, 2, 1 cm), colored ICP (point_to_plane for depth-only "
        "sensors); min_fitness 0 here: the stop rule below decides; no convergence check "
        "(the thesis took Open3D's result, which does not say whether it converged)",
    )
    stop_fitness: float = Field(
        0.3, ge=0, le=1, description="fitness below this stops registration for the stride"
    )
    pixel_step: int = Field(
        1,
        ge=1,
        le=8,
        description="the cloud from every n-th row and column of the depth image (2 at "
        "424x240 gives the 212x120 cloud and cost; the demo sets it so)",
    )
    stop_on_any_failure: bool = Field(
        True,
        description="a registration that fails otherwise also stops the stride; with the "
        "default registration these are the failures Open3D reports as fitness 0 (no "
        "overlap, an empty cloud) or a non-finite transform",
    )
    map_voxel_m: float = Field(
        0.01, gt=0, description="fusion: running mean per voxel of a grid fixed in the stride frame"
    )


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


class PipelineConfig(ConfigModel):
    """Everything ``run_session`` needs: the variant, front end, back end, baseline, events,
    terrain. ``backend.variant`` follows ``variant`` (set from it when the config is built)."""

    variant: Variant = Variant.ICP_IMU_KIN
    cloud: CloudConfig = CloudConfig()
    graph: GraphFrontendConfig = GraphFrontendConfig()
    baseline: BaselineConfig = BaselineConfig()
    backend: BackendConfig = BackendConfig()
    terrain: TerrainConfig = TerrainConfig()
    event_source: str | None = Field(
        "load_cell",
        description="events.csv source used to cut strides (None: every source in the file), "
        "or 'imu-online': the causal thigh-IMU gait estimator (kinematics.gait_phase)",
    )
    mount_pitch_deg: float | None = Field(
        None,
        ge=30,
        le=45,
        description="leg model camera mount pitch (deg below horizontal, leg straight); None = "
        "fit to the session's thigh_T_camera, or estimated from the session's IMU, encoders "
        "and gait events when that is the identity (mount_estimate)",
    )
    mount_estimate: MountEstimateConfig = MountEstimateConfig()
    gravity_window_s: float = Field(
        1.0,
        gt=0,
        description="gyro-rotated accel averaging before a reset (about one stride; the "
        "previous stride's duration when known)",
    )
    gravity_sigma_rad: float | None = Field(
        0.01,
        gt=0,
        description="σ of the stride-start up vector's direction (graph variants; measured "
        "within 0.3° on the simulator): the anchor's tilt σ. None: the kinematics' contact "
        "covariance (up to 5°), which lets the accel bias and the tilt trade off",
    )
    gravity_min_window_s: float = Field(
        0.8,
        gt=0,
        description="a shorter gravity window (the session's first foot strike) keeps the "
        "kinematics' covariance: its up vector was 13° off on the simulator",
    )
    gravity_short_sigma_rad: float = Field(
        0.2,
        gt=0,
        description="σ assumed for an up vector from a window shorter than "
        "gravity_min_window_s when fusing it with the floor (widens the floor's angle gate)",
    )
    max_frames: int | None = Field(None, ge=1, description="stop after this many frames")
    keep_frames: int | None = Field(
        None,
        ge=1,
        description="the results keep about this many of the latest frame records (1–2×; "
        "older ones are counted, not kept: a controller running for hours, ~3 KB a frame); "
        "None: every frame (evaluation and scoring need them all)",
    )

    @model_validator(mode="before")
    @classmethod
    def _backend_variant_follows(cls, data: Any) -> Any:
        """The graph's factor set is the variant's: ``backend.variant`` is derived, never
        set apart (the baseline leaves the back end's default, which it does not use)."""
        if not isinstance(data, dict):
            return data
        name = data.get("variant", Variant.ICP_IMU_KIN)
        variant = Variant(name) if name in VARIANT_NAMES else None
        if variant is None or variant.is_baseline:
            return data
        backend = data.get("backend", {})
        if isinstance(backend, BackendConfig):
            backend = backend.model_copy(update={"variant": variant})
        elif isinstance(backend, dict):
            backend = {**backend, "variant": variant}
        return {**data, "backend": backend}


#: Named settings of a whole pipeline, applied over a config (``VARIANT:PRESET`` rows of the
#: benchmarks). ``realtime``: the real-time registration preset with the IMU's initial guess,
#: iSAM2 as the stride's smoother (``backend.smoothing: false``: a stride's smoothed poses are
#: iSAM2's estimate at its close plus one Gauss-Newton step, no batch LM; measured on the
#: 424×240 sessions, docs/benchmarks.md), that step and the end-state marginals on the frame
#: after the foot strike (``backend.end_state: next_frame``: the strike's frame already
#: carries the floor fit), the online grid without kept clouds (``terrain.online.
#: keep_clouds: false``: no re-fusion at the close; the stride's grid is the online one) and
#: no stride maps: fusing a stride's map at its close takes 0.3–1.2 s at 424×240, which the
#: real-time path cannot afford; the terrain for the controller is the incremental grid
#: updated at every frame (``terrain.online``, docs/terrain.md), on in every preset.
#: ``terrain.enabled: true`` over the preset measures the stride maps' cost.
PIPELINE_PRESETS: dict[str, dict[str, Any]] = {
    "accurate": {"graph": {"registration": "accurate"}},
    "thesis": {"graph": {"registration": "thesis"}},
    "realtime": {
        "graph": {"registration": "realtime", "imu_guess": True},
        "backend": {"smoothing": False, "end_state": "next_frame"},
        "terrain": {"enabled": False, "online": {"enabled": True, "keep_clouds": False}},
    },
    "realtime-gicp": {
        "graph": {"registration": "realtime-gicp", "imu_guess": True},
        "backend": {"smoothing": False, "end_state": "next_frame"},
        "terrain": {"enabled": False, "online": {"enabled": True, "keep_clouds": False}},
    },
}


def with_preset(data: dict[str, Any], preset: str) -> dict[str, Any]:
    """``data`` (a ``PipelineConfig`` as a dict) with the named preset's settings merged in;
    a :class:`ConfigError` naming the presets when ``preset`` is unknown."""
    from graph_slam.errors import ConfigError

    if preset not in PIPELINE_PRESETS:
        raise ConfigError(
            f"unknown pipeline preset {preset!r}; choose from {', '.join(PIPELINE_PRESETS)}"
        )

    def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
        out = dict(base)
        for key, value in over.items():
            if isinstance(value, dict) and isinstance(out.get(key), dict):
                out[key] = merge(out[key], value)
            else:
                out[key] = value
        return out

    return merge(data, PIPELINE_PRESETS[preset])
