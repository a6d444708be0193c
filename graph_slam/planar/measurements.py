"""The non-visual measurements of the graph, simulated from the true trajectory (seeded).

* A thigh IMU's inclination at every scan: the true thigh angle plus a bias drawn once per
  stride and white noise. Minus the known mounting pitch it is the sensor's heading, which
  gravity makes observable in the sagittal plane.
* Leg kinematics at foot strike: that inclination with the knee and ankle encoder angles
  gives the sensor pose relative to the heel, i.e. in the new stride's frame; its covariance
  is the angle noise propagated through the forward kinematics (numerical Jacobian).
* An inertial-like motion prior between consecutive scans: the true relative pose perturbed
  by Gaussian noise on (x, y, θ) — a stand-in for IMU preintegration over one scan period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.config import GraphConfig, LegConfig
from graph_slam.planar.trajectory import THIGH, GaitTrajectory, heel_T_sensor


@dataclass(frozen=True)
class LegPrior:
    """stride_T_sensor measured by leg kinematics at a stride's first scan, with covariance."""

    scan_index: int
    stride_T_sensor: np.ndarray  # 3x3
    covariance: np.ndarray  # 3x3 over gtsam Pose2 local coordinates (x, y, θ)


@dataclass(frozen=True)
class GraphMeasurements:
    """Everything the graph gets besides the scans."""

    leg_priors: list[LegPrior]  # one per stride
    motion: np.ndarray  # (n, 3, 3) measured prev_T_curr (index 0: identity, unused)
    heading_rad: np.ndarray  # (n,) sensor heading from the thigh IMU's inclination
    heading_sigma_rad: float


def _leg_prior(
    scan_index: int, angles_rad: np.ndarray, sigmas_rad: np.ndarray, leg: LegConfig
) -> LegPrior:
    """Forward kinematics of measured angles, covariance J diag(sigma^2) J^T."""
    stride_T_sensor = heel_T_sensor(angles_rad[None, :], leg)[0]
    nominal = se2.to_pose2(stride_T_sensor)
    jac = np.empty((3, 3))
    h = 1e-6
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        plus = se2.to_pose2(heel_T_sensor((angles_rad + step)[None, :], leg)[0])
        minus = se2.to_pose2(heel_T_sensor((angles_rad - step)[None, :], leg)[0])
        jac[:, j] = (nominal.localCoordinates(plus) - nominal.localCoordinates(minus)) / (2 * h)
    cov = jac @ np.diag(sigmas_rad**2) @ jac.T + np.eye(3) * 1e-10
    return LegPrior(scan_index, stride_T_sensor, cov)


def simulate_measurements(
    trajectory: GaitTrajectory, leg: LegConfig, config: GraphConfig, rng: np.random.Generator
) -> GraphMeasurements:
    """Draw the IMU inclination, encoder angles and motion prior of a walk."""
    n = len(trajectory.t_s)
    bias = rng.normal(0.0, config.tilt_bias_sigma_rad, size=len(trajectory.world_T_stride))
    tilt = (
        trajectory.leg_angles_rad[:, THIGH]
        + bias[trajectory.stride_index]
        + rng.normal(0.0, config.tilt_sigma_rad, size=n)
    )
    tilt_sigma = float(np.hypot(config.tilt_sigma_rad, config.tilt_bias_sigma_rad))
    sigmas = np.array([tilt_sigma, config.encoder_sigma_rad, config.encoder_sigma_rad])
    priors = []
    for stride in range(len(trajectory.world_T_stride)):
        k = int(np.flatnonzero(trajectory.stride_index == stride)[0])
        angles = trajectory.leg_angles_rad[k].copy()
        angles[THIGH] = tilt[k]
        angles[1:] += rng.normal(0.0, config.encoder_sigma_rad, size=2)
        priors.append(_leg_prior(k, angles, sigmas, leg))
    motion = np.empty_like(trajectory.world_T_sensor)
    motion[0] = np.eye(3)
    motion_sigmas = np.array(
        [config.motion_sigma_m, config.motion_sigma_m, config.motion_sigma_rad]
    )
    for k in range(1, n):
        true_rel = se2.inverse(trajectory.world_T_sensor[k - 1]) @ trajectory.world_T_sensor[k]
        motion[k] = true_rel @ se2.se2(*rng.normal(0.0, motion_sigmas))
    return GraphMeasurements(priors, motion, tilt - leg.sensor_pitch_down_rad, tilt_sigma)
