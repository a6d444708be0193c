"""Typed configuration of the pipelines (one sub-model per concern): :class:`PipelineConfig`
here; the graph's front end in :mod:`graph_slam.pipelines.graph_config`, the thesis baseline's
in :mod:`graph_slam.pipelines.baseline_config`, the presets in
:mod:`graph_slam.pipelines.presets` (every name importable from here too)."""

from __future__ import annotations

from typing import Any

from pydantic import Field, model_validator

from graph_slam.backend.config import BackendConfig
from graph_slam.config import ConfigModel, merge_dicts
from graph_slam.frontend.config import (  # noqa: F401 (re-exported)
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
from graph_slam.frontend.floor import FloorConfig  # noqa: F401 (re-exported)
from graph_slam.frontend.treads import TreadsConfig  # noqa: F401 (re-exported)
from graph_slam.pipelines.baseline_config import (  # noqa: F401 (re-exported)
    BASELINE_CLOUD_WIDTH_PX,
    BaselineConfig,
)
from graph_slam.pipelines.graph_config import (  # noqa: F401 (re-exported)
    REGISTRATION_PRESETS,
    GraphFrontendConfig,
    GraphRegistration,
    _graph_registration,
    _registration_kind,
)
from graph_slam.pipelines.keyframe import KeyframeConfig  # noqa: F401 (re-exported)
from graph_slam.pipelines.presets import (  # noqa: F401 (re-exported)
    _ACCURATE_REST,
    _REALTIME_REST,
    DEFAULT_PRESET,
    PIPELINE_PRESETS,
    VARIANT_NAMES,
    PresetName,
    parse_row,
    with_preset,
)
from graph_slam.strides.mount import MountEstimateConfig
from graph_slam.terrain.maps.builder import TerrainConfig
from graph_slam.variants import Variant

PipelineVariant = Variant
"""Former name of :class:`graph_slam.variants.Variant` (kept for imports)."""


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
