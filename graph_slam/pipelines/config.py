"""Typed configuration of the pipelines (one sub-model per concern)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Discriminator, Field, Tag, field_validator, model_validator

from graph_slam.backend.config import BackendConfig
from graph_slam.config import ConfigModel, merge_dicts
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
from graph_slam.frontend.treads import TreadsConfig
from graph_slam.pipelines.keyframe import KeyframeConfig
from graph_slam.strides.mount import MountEstimateConfig
from graph_slam.terrain.maps.builder import TerrainConfig
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


BASELINE_CLOUD_WIDTH_PX = 212
"""The thesis baseline's cloud width by default (``baseline.pixel_step`` None)."""


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
    pixel_step: int | None = Field(
        None,
        ge=1,
        le=8,
        description="the cloud from every n-th row and column of the depth image; None: the "
        "212x120 cloud (image width // 212: 2 at 424x240, 4 at 848x480, 1 below), the "
        "default presets' budget; 1: every pixel (the accurate and thesis presets)",
    )

    def pixel_step_for(self, width_px: int) -> int:
        """The pixel step for an image ``width_px`` wide (``pixel_step``, or the 212x120
        cloud's)."""
        if self.pixel_step is not None:
            return self.pixel_step
        return max(1, int(width_px) // BASELINE_CLOUD_WIDTH_PX)

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


PresetName = Literal["realtime", "realtime-gicp", "accurate", "thesis"]
"""The names of :data:`PIPELINE_PRESETS`."""
DEFAULT_PRESET = "realtime"
"""The configuration every entry point runs by default (library, ``run``, ``compare``,
``batch``, ``demo``, the examples)."""


class PipelineConfig(ConfigModel):
    """Everything ``run_session`` needs: the variant, front end, back end, baseline, events,
    terrain. ``preset`` (:data:`PIPELINE_PRESETS`) sets the fields it governs before the
    ones given explicitly (``preset: accurate`` in YAML, then any field over it).
    ``backend.variant`` follows ``variant`` (set from it when the config is built)."""

    preset: PresetName = Field(
        DEFAULT_PRESET,
        description="the named configuration under the explicit fields: realtime (the "
        "default: the real-time front end, the baseline on the 212x120 cloud), "
        "realtime-gicp, accurate (colored ICP 4/2 cm, batch smoothing, stride maps, the "
        "baseline on every pixel) or thesis (the thesis's ICP levels)",
    )
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
    gravity_first_strike_kinematics: bool = Field(
        True,
        description="at a session's first foot strike (IMU window shorter than "
        "gravity_min_window_s) take the up vector from the encoders (the foot at the leg "
        "model's nominal heel-strike pitch): 3.7-7.5° off on the terrain walker where the "
        "accelerometer's short mean was 19-65° off (graph_slam.strides.anchor). Needs a leg "
        "model; False: the accelerometer's",
    )
    gravity_first_strike_kinematics_sigma_rad: float | None = Field(
        0.1,
        gt=0,
        description="σ of that up vector (3.7-7.5° measured on ten first strikes): the first "
        "strike is anchored like a later one (the anchor's tilt σ, the level test of the "
        "floor and the treads' search against it; on stairs-ascent the treads then fix the "
        "up to 0.1°). None: no σ, the kinematics' heel-strike covariance and the first "
        "strike's heel rule for the floor",
    )
    gravity_from_graph: bool = Field(
        False,
        description="fuse the accelerometer's up at a foot strike with the open stride's "
        "online attitude (carried by the gyro; its tilt along the heading weighed by its "
        "marginal covariance, gated at 3σ): graph_slam.strides.up_fusion. The anchor's up "
        "came within 0.2° on the terrain walker but the poses did not follow "
        "(docs/benchmarks.md). False: the accelerometer's alone",
    )
    gravity_mean_acceleration: bool = Field(
        True,
        description="the accelerometer's up at a foot strike averaged over the open stride "
        "with the stride's estimated velocity change removed (its mean acceleration, "
        "StrideSLAM.velocity_change): over a stride that starts or ends a climb or a "
        "descent it is not zero (graph_slam.strides.anchor)",
    )
    gravity_lateral_bias_max_sigma_m_s2: float | None = Field(
        0.05,
        gt=0,
        description="the open stride's lateral accelerometer bias (StrideSLAM.lateral_bias) "
        "is removed from the accelerometer's up at a foot strike when its marginal σ is at "
        "most this (a lateral bias reads as a roll): 0.021 m/s² out of strides since a level "
        "plane was fused, 0.06-0.25 where none was (the stairs, whose estimate was off by "
        "0.1-0.5 m/s²). None: never",
    )
    max_frames: int | None = Field(None, ge=1, description="stop after this many frames")
    deterministic: bool = Field(
        True,
        description="the same input gives the same poses, bit for bit: Open3D runs its "
        "sums on one thread (graph_slam.determinism) and the causal replay's virtual clock "
        "advances by a fixed cost, not the measured time. False: Open3D on every core "
        "(docs/pipelines.md, 'Determinism', for the gain) and the replay's clock measured",
    )
    keep_frames: int | None = Field(
        None,
        ge=1,
        description="the results keep about this many of the latest frame records (1–2×; "
        "older ones are counted, not kept: a controller running for hours, ~3 KB a frame); "
        "None: every frame (evaluation and scoring need them all)",
    )

    @model_validator(mode="before")
    @classmethod
    def _preset_then_variant(cls, data: Any) -> Any:
        """The preset's settings under the explicit ones; then the graph's factor set is the
        variant's: ``backend.variant`` is derived, never set apart (the baseline leaves the
        back end's default, which it does not use)."""
        if not isinstance(data, dict):
            return data
        preset = data.get("preset", DEFAULT_PRESET)
        if isinstance(preset, str) and preset in PIPELINE_PRESETS:
            data = merge_dicts(PIPELINE_PRESETS[preset], data)
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


#: Named settings of a whole pipeline: ``PipelineConfig.preset`` (under the explicit fields)
#: or ``with_preset`` (over a config: the ``VARIANT:PRESET`` rows of the benchmarks,
#: ``--preset``). Each preset sets every field any preset sets, so one applied over a config
#: built from another leaves nothing of the other behind. ``realtime`` (the default): the
#: real-time registration preset with the IMU's initial guess, iSAM2 as the stride's smoother
#: (``backend.smoothing: false``: a stride's smoothed poses are iSAM2's estimate at its close
#: plus one Gauss-Newton step, no batch LM; measured on the 424×240 sessions,
#: docs/benchmarks.md), that step and the end-state marginals on the frame after the foot
#: strike (``backend.end_state: next_frame``: the strike's frame already carries the floor
#: fit), the online grid without kept clouds (``terrain.online.keep_clouds: false``: no
#: re-fusion at the close; the stride's grid is the online one), no stride maps (fusing a
#: stride's map at its close takes 0.3–1.2 s at 424×240, which the real-time path cannot
#: afford; ``compare`` turns them on to score them) and the thesis baseline on the 212×120
#: cloud (``baseline.pixel_step`` None). ``accurate`` and ``thesis``: colored ICP (4/2 cm with
#: a Tukey kernel; the thesis's 4/2/1 cm without), batch smoothing at the close, stride maps
#: from kept clouds, the baseline on every pixel. The terrain for the controller is the
#: incremental grid updated at every frame (``terrain.online``, docs/terrain.md), on in every
#: preset.
_REALTIME_REST: dict[str, Any] = {
    "backend": {"smoothing": False, "end_state": "next_frame"},
    "terrain": {"enabled": False, "online": {"enabled": True, "keep_clouds": False}},
    "baseline": {"pixel_step": None},
}
_ACCURATE_REST: dict[str, Any] = {
    "backend": {"smoothing": True, "end_state": "at_close"},
    "terrain": {"enabled": True, "online": {"enabled": True, "keep_clouds": True}},
    "baseline": {"pixel_step": 1},
}
PIPELINE_PRESETS: dict[str, dict[str, Any]] = {
    "realtime": {"graph": {"registration": "realtime", "imu_guess": True}, **_REALTIME_REST},
    "realtime-gicp": {
        "graph": {"registration": "realtime-gicp", "imu_guess": True},
        **_REALTIME_REST,
    },
    "accurate": {"graph": {"registration": "accurate", "imu_guess": None}, **_ACCURATE_REST},
    "thesis": {"graph": {"registration": "thesis", "imu_guess": None}, **_ACCURATE_REST},
}


def with_preset(data: dict[str, Any], preset: str) -> dict[str, Any]:
    """``data`` (a ``PipelineConfig`` as a dict) with the named preset's settings merged over
    it and ``preset`` set; a :class:`ConfigError` naming the presets when ``preset`` is
    unknown."""
    from graph_slam.errors import ConfigError

    if preset not in PIPELINE_PRESETS:
        raise ConfigError(
            f"unknown pipeline preset {preset!r}; choose from {', '.join(PIPELINE_PRESETS)}"
        )

    return {**merge_dicts(data, PIPELINE_PRESETS[preset]), "preset": preset}


def parse_row(row: str) -> tuple[Variant, str | None]:
    """``VARIANT[:PRESET]`` (a benchmark row, ``--variants``-style) → the variant and the
    preset (None when the row names none); a :class:`ConfigError` naming the row when either
    is unknown."""
    from graph_slam.errors import ConfigError

    name, _, preset = row.strip().partition(":")
    if name not in VARIANT_NAMES:
        raise ConfigError(
            f"row {row!r}: unknown variant {name!r} (known: {', '.join(v.value for v in Variant)})"
        )
    if preset and preset not in PIPELINE_PRESETS:
        raise ConfigError(
            f"row {row!r}: unknown pipeline preset {preset!r}; choose from "
            f"{', '.join(PIPELINE_PRESETS)}"
        )
    return Variant(name), preset or None
