"""Typed configuration of the back end (one sub-model per concern)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.variants import GRAPH_VARIANTS, Variant

RobustKernel = Literal["none", "huber", "cauchy", "tukey"]

#: Which factor families each graph variant uses. ``icp`` (the thesis baseline: ICP
#: accumulation, no graph) is run by the pipelines layer, not by this back end.
VARIANT_FACTORS: dict[str, dict[str, bool]] = {v.value: v.factors for v in GRAPH_VARIANTS}


class ImuNoiseConfig(ConfigModel):
    """Continuous-time IMU noise (a sensor profile's ``imu`` section) and sample checks."""

    gyro_noise_density_rad_s_sqrt_hz: float = Field(1.7e-4, gt=0)
    accel_noise_density_m_s2_sqrt_hz: float = Field(2.0e-3, gt=0)
    gyro_random_walk_rad_s2_sqrt_hz: float = Field(1.9e-5, gt=0)
    accel_random_walk_m_s3_sqrt_hz: float = Field(3.0e-3, gt=0)
    noise_inflation: float = Field(
        3.0, ge=1, description="multiplies the white-noise densities (datasheets are optimistic)"
    )
    integration_sigma: float = Field(1e-4, gt=0, description="integration noise (GTSAM)")
    gravity_m_s2: float = Field(9.81, gt=9.7, lt=9.9)
    max_gap_s: float = Field(
        0.05, gt=0, description="a hole longer than this splits preintegration"
    )
    max_gyro_rad_s: float = Field(35.0, gt=0)
    max_accel_m_s2: float = Field(16 * 9.81, gt=0)

    @classmethod
    def from_sensor_profile(
        cls, imu_section: Mapping[str, Any], **overrides: Any
    ) -> ImuNoiseConfig:
        """Build from a sensor profile's ``imu:`` mapping (``models/sensors/*.yaml``)."""
        keys = (
            "gyro_noise_density_rad_s_sqrt_hz",
            "accel_noise_density_m_s2_sqrt_hz",
            "gyro_random_walk_rad_s2_sqrt_hz",
            "accel_random_walk_m_s3_sqrt_hz",
        )
        data = {k: imu_section[k] for k in keys if k in imu_section}
        data.update(overrides)
        return cls(**data)


class GateConfig(ConfigModel):
    """When an ICP registration becomes a factor, and how much it is trusted."""

    min_fitness: float = Field(0.3, ge=0, le=1)
    max_inlier_rmse_m: float = Field(0.02, gt=0)
    min_correspondences: int = Field(200, ge=0)
    degenerate_eigenvalue_ratio: float = Field(
        1e-3, ge=0, lt=1, description="a direction with λ < ratio·λmax carries no information"
    )
    min_eigenvalue: float = Field(
        1.0, ge=0, description="a direction with λ below this (info units) carries none"
    )
    min_rank: int = Field(
        3,
        ge=1,
        le=6,
        description="fewer constrained directions: rejected (the frame is bridged by the IMU "
        "and kinematics); a flat floor holds 3 (height, roll, pitch)",
    )
    max_step_m: float = Field(
        0.3, gt=0, description="a larger motion between a frame and its target frame: rejected"
    )
    max_step_rad: float = Field(0.5, gt=0)
    information_scale: float = Field(
        1.0, gt=0, description="multiplies the registration's information (<1: less trust)"
    )
    robust_kernel: RobustKernel = "huber"
    robust_k: float = Field(1.5, gt=0)


class KinematicFactorConfig(ConfigModel):
    """Leg-kinematic anchor at foot strike and stance factors."""

    sigma_scale: float = Field(
        1.0, gt=0, description="multiplies the kinematics' sigmas of stance factors"
    )
    robust_kernel: RobustKernel = "huber"
    robust_k: float = Field(2.0, gt=0)
    gravity_window_s: float = Field(0.1, gt=0, description="accel averaging before a strike")
    max_mahalanobis: float = Field(
        10.0,
        gt=0,
        description="a stance factor farther than this (in its sigmas) from the IMU prediction "
        "is inconsistent (e.g. a missed foot strike: the foot is elsewhere) and is not added",
    )
    stance_model: Literal["contact_points", "foot_pose"] = Field(
        "contact_points",
        description="stance factors from the encoders: 'contact_points' (the heel stays at the "
        "stride origin until heel-off, the toe at its foot-flat position from foot flat to "
        "toe-off; the foot may pivot about them) or 'foot_pose' (the whole foot held in its "
        "orientation at foot strike: wrong once the foot rolls flat or lifts its heel)",
    )
    contact_sigma_m: float = Field(
        0.01,
        gt=0,
        description="σ of a contact point's position (encoders + contact), m; 4 mm, 1 and 2 cm "
        "tried on the simulator (docs/benchmarks.md)",
    )
    contact_pitch_rad: float = Field(
        0.0175,
        gt=0,
        description="foot pitch (from the predicted orientation and the encoders) beyond which "
        "the heel (toe down) or the toe (toe up) is taken to be off the ground",
    )


class PriorConfig(ConfigModel):
    """Priors of the first state of a session and carry-over between strides."""

    first_velocity_sigma_m_s: float = Field(1.0, gt=0)
    first_accel_bias_sigma_m_s2: float = Field(0.2, gt=0)
    first_gyro_bias_sigma_rad_s: float = Field(0.05, gt=0)
    first_roll_pitch_sigma_rad: float = Field(0.05, gt=0)
    first_yaw_sigma_rad: float = Field(1e-3, gt=0, description="the frame's yaw is defined")
    first_position_sigma_m: float = Field(1e-3, gt=0, description="the frame's origin is defined")
    anchor_yaw_sigma_rad: float = Field(
        1e-3,
        gt=0,
        description="stride anchor with a known up vector: yaw σ added to the encoders' (the "
        "foot defines the frame's x)",
    )
    anchor_position_sigma_m: float = Field(
        1e-3,
        gt=0,
        description="stride anchor with a known up vector: position σ added to the encoders' "
        "(the heel defines the origin)",
    )
    first_stride_refit: bool = Field(
        True,
        description="smooth the session's first stride again (smoothed output only) once the "
        "first foot strike's up vector is known (graph_slam.backend.first_stride)",
    )
    first_stride_refit_tilt_sigma_rad: float = Field(
        0.5,
        gt=0,
        description="the first state's roll/pitch σ in that second smoothing: its up vector "
        "came from a short window of a moving leg",
    )
    carry_inflation: float = Field(1.0, ge=1, description="multiplies carried covariances")
    first_carry_inflation: float = Field(
        10.0,
        ge=1,
        description="also multiplies the covariances carried out of the session's first stride "
        "when it began with the foot unloaded (a recording started in swing: weak priors, a "
        "fraction of a stride, an anchor that assumes the foot on the ground): measured "
        "over-confident, its velocity and bias pulled the next stride's anchor by 9 mm / 0.44° "
        "(full resolution, 1.4 m/s)",
    )
    loose_tilt_bias_inflation: float = Field(
        1.0,
        ge=1,
        description="multiplies the bias covariance carried out of a stride whose "
        "anchor had no known up σ (the session's first strike, its up 10-50° off) into one "
        "whose anchor has: that stride's lateral accel bias came out 0.3-0.4 m/s² off on the "
        "terrain walker. 10 helped the stairs and hurt the mixed course (docs/benchmarks.md, "
        "'Terrain-following walker'; the accelerometer's block alone: the same on the course, "
        "less on the stairs): off by default",
    )
    loose_tilt_bias_reset: bool = Field(
        False,
        description="out of such a stride (or one whose anchor took a plane as level at the "
        "session's first strike, an assumption) the accelerometer bias restarts from the "
        "session's first prior (zero, first_accel_bias_sigma_m_s2) instead of being carried",
    )
    carry_bias_with_tilt: bool = Field(
        False,
        description="the lateral accelerometer bias carried into a stride whose anchor has a "
        "known up σ moves with the anchor's roll correction, g·Δroll "
        "(graph_slam.backend.priors.bias_with_tilt: across the sagittal plane the "
        "accelerometer fixes gravity plus bias, not each). On the stairs it turned the second "
        "stride's roll from -0.66° to +0.87° (seed 3) and from -0.29° to +0.89° (seed 4): the "
        "stride's own factors set the roll as much as the prior (docs/pipelines.md, "
        "'The stairs' roll'); off by default",
    )
    missed_strike_inflation: float = Field(
        4.0, ge=1, description="multiplies carried covariances when a foot strike was missed"
    )
    max_stride_s: float = Field(2.5, gt=0, description="longer: a missed foot strike")


class BackendConfig(ConfigModel):
    """The per-stride graph back end."""

    variant: Variant = Variant.ICP_IMU_KIN
    imu: ImuNoiseConfig = ImuNoiseConfig()
    gate: GateConfig = GateConfig()
    kinematics: KinematicFactorConfig = KinematicFactorConfig()
    priors: PriorConfig = PriorConfig()
    smoothing: bool = Field(True, description="batch LM over the stride at its end")
    defer_smoothing: bool = Field(
        False,
        description="real time: at a stride's end carry the iSAM2 estimate and its marginals "
        "into the next stride (milliseconds) and queue the batch smoothing for "
        "StrideSLAM.smooth_deferred() (the pipeline runs it at finish): no smoothing spike "
        "at the foot strike",
    )
    max_deferred_strides: int | None = Field(
        None,
        ge=0,
        description="with defer_smoothing: at most this many closed strides wait for their "
        "smoothing (each holds its graph); when a stride close makes more, the oldest are "
        "smoothed then (their cost falls on that frame). None: all wait for the end of the run "
        "(memory grows with the run's length)",
    )
    covariances: bool = Field(False, description="per-frame marginal covariances (slower)")
    end_state: Literal["at_close", "next_frame"] = Field(
        "at_close",
        description="when a closed stride's Gauss-Newton step and end-state marginals (what "
        "the next stride's priors carry) are computed: at the close, on the foot strike's "
        "frame, or on the frame after it (next_frame: the new stride starts from the live "
        "iSAM2's end state and marginals and gets the settled priors one frame later; the "
        "strike's frame then carries only the floor fit; 8-14 ms moved off it at 424x240, "
        "docs/benchmarks.md)",
    )
    end_state_frames: int = Field(
        4,
        ge=1,
        description="with end_state next_frame: over how many frames after the strike's "
        "(the first half linearise slices of the factors, the rest eliminate ranges of "
        "states: 1-3 ms each at 424x240, the last 3-5 ms with the summary and the new priors; "
        "graph_slam.backend.end_state)",
    )
    isam2_relinearize_threshold: float = Field(
        0.01,
        gt=0,
        description="iSAM2 relinearises a variable whose update exceeds this: pose (rad, m) "
        "and gyroscope bias (rad/s)",
    )
    isam2_velocity_relinearize_threshold: float = Field(
        0.05, gt=0, description="the same for the velocity (m/s)"
    )
    isam2_accel_bias_relinearize_threshold: float = Field(
        0.3,
        gt=0,
        description="the same for the accelerometer bias (m/s²). Below these two, the IMU "
        "factor is nearly linear (preintegration's bias Jacobians); at 0.01 for every "
        "variable, updates of 0.01 m/s or 0.01 m/s² spread along the stride (the bias random "
        "walk ties every frame's bias together) made iSAM2 re-eliminate the whole stride on "
        "one frame in five, 5–15 ms each (docs/benchmarks.md, '2026-12-02, commit 1ede288')",
    )
    gap_bridge_rot_sigma_rad: float = Field(0.3, gt=0)
    gap_bridge_trans_sigma_m: float = Field(0.2, gt=0)

    @model_validator(mode="after")
    def _variant_supported(self) -> BackendConfig:
        from graph_slam.errors import ConfigError

        if self.variant not in VARIANT_FACTORS:
            raise ConfigError(
                f"field 'variant': '{self.variant}' is the thesis baseline (no factor graph); "
                "run it through the pipelines layer (graph_slam.pipelines), not StrideSLAM"
            )
        return self

    @property
    def factors(self) -> dict[str, bool]:
        """Which factor families this variant uses (``icp``, ``imu``, ``kin``)."""
        return VARIANT_FACTORS[self.variant]
