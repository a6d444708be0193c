"""Typed configuration of the 2D study (thesis chapters 3.1–3.2), one sub-model per concern.

Every number of the study lives here with its default; ``graph-slam planar --config FILE``
overrides any subset from YAML, and each run writes the resolved config next to its outputs.
"""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from graph_slam.config import ConfigModel


class Box(ConfigModel):
    """A rectangular obstacle standing on the surface, from ``x_m`` to ``x_m + width_m``."""

    x_m: float = Field(description="near edge (m, world x)")
    width_m: float = Field(gt=0, description="extent along x (m)")
    height_m: float = Field(gt=0, description="height above the surface under it (m)")


class Stairs(ConfigModel):
    """A flight of ``n_steps`` steps starting at ``x_m``; the floor stays at the top after it."""

    x_m: float
    n_steps: int = Field(gt=0)
    rise_m: float = Field(description="step height (m); negative for stairs down")
    run_m: float = Field(gt=0, description="tread depth (m)")


class Ramp(ConfigModel):
    """A slope from ``x_m`` over ``length_m`` that raises the floor by ``rise_m``."""

    x_m: float
    length_m: float = Field(gt=0)
    rise_m: float = Field(description="height gained (m); negative for a ramp down")


class TerrainConfig(ConfigModel):
    """The 2D occupancy grid (thesis 3.2): flat ground, stairs, rectangular obstacles, ramps."""

    resolution_m: float = Field(0.005, gt=0, description="occupancy-grid cell size")
    x_min_m: float = -1.0
    x_max_m: float = 7.0
    y_min_m: float = -0.5
    y_max_m: float = 2.0
    boxes: tuple[Box, ...] = (
        Box(x_m=0.45, width_m=0.357, height_m=0.15),
        Box(x_m=1.30, width_m=0.443, height_m=0.20),
        Box(x_m=2.05, width_m=0.20, height_m=0.10),
        Box(x_m=3.40, width_m=0.283, height_m=0.15),
        Box(x_m=5.60, width_m=0.30, height_m=1.50),
    )
    ramps: tuple[Ramp, ...] = (Ramp(x_m=2.5, length_m=0.6, rise_m=0.10),)
    stairs: tuple[Stairs, ...] = (Stairs(x_m=4.0, n_steps=4, rise_m=0.17, run_m=0.28),)

    @model_validator(mode="after")
    def _extent(self) -> TerrainConfig:
        if self.x_max_m <= self.x_min_m or self.y_max_m <= self.y_min_m:
            raise ValueError("x_max_m must exceed x_min_m and y_max_m must exceed y_min_m")
        return self


class LegConfig(ConfigModel):
    """Sagittal two-segment leg with a foot, and where the range sensor sits on the thigh.

    The thigh's angle from the vertical is hip flexion minus the anterior pelvic tilt, both
    from :mod:`kinematics.gait_curves` (``thigh_angle``).
    """

    thigh_length_m: float = Field(0.44, gt=0)
    shank_length_m: float = Field(0.44, gt=0)
    ankle_height_m: float = Field(0.08, gt=0, description="ankle joint above the sole")
    heel_back_m: float = Field(0.05, ge=0, description="heel behind the ankle joint")
    toe_forward_m: float = Field(0.17, gt=0, description="toe in front of the ankle joint")
    sensor_from_hip_m: float = Field(
        0.34, gt=0, description="sensor along the thigh below the hip (above the knee)"
    )
    sensor_forward_m: float = Field(0.06, description="sensor in front of the thigh axis")
    sensor_pitch_down_rad: float = Field(
        math.radians(40.0), description="boresight below the horizontal when the thigh is vertical"
    )
    sample_rate_hz: float = Field(
        900.0, gt=0, description="rate of the kinematic simulation (scans are sampled from it)"
    )

    @model_validator(mode="after")
    def _sensor_on_thigh(self) -> LegConfig:
        if self.sensor_from_hip_m >= self.thigh_length_m:
            raise ValueError("sensor_from_hip_m must be shorter than thigh_length_m (above knee)")
        return self


class ScannerConfig(ConfigModel):
    """The simulated 2D range sensor (thesis 3.2: 150 rays over 75° at 45 Hz)."""

    n_rays: int = Field(150, ge=8)
    fov_rad: float = Field(math.radians(75.0), gt=0, lt=math.pi)
    rate_hz: float = Field(45.0, gt=0)
    max_range_m: float = Field(4.0, gt=0)
    range_sigma_m: float = Field(0.005, ge=0, description="Gaussian range noise")


class FeatureConfig(ConfigModel):
    """Line features by the roughness factor (eq. 3.1)."""

    neighbours: int = Field(3, ge=1, description="points on each side in eq. 3.1")
    roughness_threshold: float = Field(0.5, gt=0, description="below: the point lies on a line")
    max_gap_m: float = Field(
        0.10, gt=0, description="a line ends where consecutive points are farther apart"
    )
    line_tolerance_m: float = Field(
        0.02, gt=0, description="a run is split where a point is farther from its chord"
    )
    min_line_points: int = Field(5, ge=3)


class IcpConfig(ConfigModel):
    """Point-to-plane ICP (eq. 3.2–3.7) and when its result counts as a failure."""

    max_iterations: int = Field(30, ge=1)
    tolerance: float = Field(1e-4, gt=0, description="stop when the update's norm is below")
    max_pair_distance_m: float | None = Field(
        0.15, gt=0, description="pairs farther apart are dropped (None: keep all)"
    )
    min_pairs: int = Field(20, ge=3)
    min_information: float = Field(
        1.0, gt=0, description="smallest eigenvalue of A^T A (metres scale): below, degenerate"
    )


class ThesisConfig(ConfigModel):
    """Choices of the thesis pipeline that the thesis fixes; here to measure their effect."""

    keep_max_range: bool = Field(
        True, description="use max-range returns as points (the thesis does, 3.2)"
    )


class GraphConfig(ConfigModel):
    """The per-stride Pose2 factor graph: kinematic prior, inertial-like prior, gated ICP."""

    tilt_sigma_rad: float = Field(
        math.radians(1.0), gt=0, description="thigh IMU inclination: white noise per scan"
    )
    tilt_bias_sigma_rad: float = Field(
        math.radians(0.5), ge=0, description="thigh IMU inclination: a bias drawn per stride"
    )
    encoder_sigma_rad: float = Field(math.radians(0.2), gt=0, description="knee and ankle")
    motion_sigma_m: float = Field(0.004, gt=0, description="inertial-like prior, per scan")
    motion_sigma_rad: float = Field(math.radians(0.1), gt=0)
    icp_sigma_m: float = Field(0.008, gt=0, description="point-to-line residual sigma")
    gate_chi2: float = Field(
        16.27, gt=0, description="ICP vs prior Mahalanobis gate (chi2, 3 dof, p = 0.001)"
    )
    keyframe_overlap: float = Field(
        0.5, gt=0, le=1, description="new keyframe when fewer of its line points pair up"
    )
    drop_max_range: bool = Field(True, description="ignore max-range (no-return) rays")


class PlanarConfig(ConfigModel):
    """The whole 2D study: terrain, leg, sensor, thesis pipeline, graph, and the runs."""

    seed: int = Field(7, ge=0, description="random seed (non-negative)")
    speeds_m_s: tuple[float, ...] = (0.83, 1.33)
    n_strides: int = Field(2, ge=1)
    terrain: TerrainConfig = TerrainConfig()
    leg: LegConfig = LegConfig()
    scanner: ScannerConfig = ScannerConfig()
    features: FeatureConfig = FeatureConfig()
    icp: IcpConfig = IcpConfig()
    thesis: ThesisConfig = ThesisConfig()
    graph: GraphConfig = GraphConfig()

    @model_validator(mode="after")
    def _speeds(self) -> PlanarConfig:
        if not self.speeds_m_s or any(v <= 0 for v in self.speeds_m_s):
            raise ValueError("speeds_m_s must be a non-empty list of positive speeds")
        return self
