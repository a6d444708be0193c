"""A stride's first-state priors: the session's first stride (anchor or gravity-aligned, weak
velocity and bias) and every later one (the previous stride's end state carried by the IMU).
Used by :class:`graph_slam.backend.stride_chain.StrideChain`; see its module docstring."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import PriorConfig
from graph_slam.backend.measurements import KinematicMeasurement


def gravity_aligned_rotation(up_in_imu: np.ndarray) -> np.ndarray:
    """``nav_R_imu`` with z along ``up_in_imu`` and zero yaw of the IMU's x axis (if possible)."""
    z = up_in_imu / np.linalg.norm(up_in_imu)  # nav z expressed in the IMU frame
    x_imu = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x_imu - (x_imu @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])  # rows: nav axes in IMU coordinates -> nav_R_imu


@dataclass(eq=False)
class StartPriors:
    """Priors of a stride's first state (IMU local covariances, rotation first)."""

    stride_T_imu: gtsam.Pose3
    cov_pose: np.ndarray
    velocity_m_s: np.ndarray
    cov_velocity: np.ndarray
    bias: gtsam.imuBias.ConstantBias
    cov_bias: np.ndarray
    flags: list[str] = field(default_factory=list)
    old_stride_T_imu: np.ndarray | None = None
    """The predicted IMU pose in the previous stride's frame when a new stride frame starts
    (``world_T_stride`` chains by it), else None."""


def first_stride_priors(
    pc: PriorConfig,
    camera_T_imu: np.ndarray,
    anchor: KinematicMeasurement | None,
    gravity_in_imu: np.ndarray | None,
) -> StartPriors:
    """The session's first state: the anchor, or gravity-aligned; weak velocity/bias priors."""
    flags = []
    if anchor is not None:
        pose, cov_pose = factors.camera_pose_to_imu(
            anchor.stride_T_camera, anchor.covariance, camera_T_imu
        )
    else:
        rot = np.eye(3) if gravity_in_imu is None else gravity_aligned_rotation(gravity_in_imu)
        pose = gtsam.Pose3(gtsam.Rot3(rot), np.zeros(3))
        s = np.r_[
            pc.first_roll_pitch_sigma_rad,
            pc.first_roll_pitch_sigma_rad,
            pc.first_yaw_sigma_rad,
            np.full(3, pc.first_position_sigma_m),
        ]
        # roll/pitch sigmas are about the nav axes: rotate into the body (local) frame
        ad = np.zeros((6, 6))
        ad[:3, :3] = ad[3:, 3:] = rot.T
        cov_pose = ad @ np.diag(s**2) @ ad.T
        flags.append("no_anchor" if gravity_in_imu is not None else "no_anchor_no_gravity")
    cov_bias = np.diag(
        np.r_[
            np.full(3, pc.first_accel_bias_sigma_m_s2**2),
            np.full(3, pc.first_gyro_bias_sigma_rad_s**2),
        ]
    )
    cov_vel = np.eye(3) * pc.first_velocity_sigma_m_s**2
    bias = gtsam.imuBias.ConstantBias()
    return StartPriors(pose, cov_pose, np.zeros(3), cov_vel, bias, cov_bias, flags)


def _accel_bias_reset(pc: PriorConfig, bias, cov_b: np.ndarray):
    """The accelerometer's bias back to the session's first prior (zero, its σ), uncorrelated
    with the gyroscope's, which is kept."""
    cov = np.array(cov_b, float)
    cov[:3, :] = 0.0
    cov[:, :3] = 0.0
    cov[:3, :3] = np.eye(3) * pc.first_accel_bias_sigma_m_s2**2
    return gtsam.imuBias.ConstantBias(np.zeros(3), np.asarray(bias.gyroscope())), cov


def bias_with_tilt(
    bias: gtsam.imuBias.ConstantBias,
    old_R_imu: np.ndarray,
    new_R_imu: np.ndarray,
    gravity_m_s2: float,
) -> gtsam.imuBias.ConstantBias:
    """The accelerometer's bias carried into a stride whose anchor rolls the IMU's up from
    ``old_R_imu``'s (the previous stride's end state, predicted to the strike) to
    ``new_R_imu``'s (both ``stride_R_imu``: z up, y the new stride's lateral axis).

    An accelerometer measures gravity plus its bias. Along the sagittal plane a stride
    separates the two (the thigh pitches through ±30°, turning gravity against a fixed
    bias), across it they are one: a lateral bias reads as a roll while the thigh swings
    about its lateral axis, so the previous stride fixed ``g·up_lateral + b_lateral``, not
    each. An anchor that rolls the up by Δ therefore implies the lateral bias moved by
    ``g·Δ``; carried unchanged, the bias prior pulls the new stride's roll back towards the
    old stride's. Only the lateral component moves (the anchor's pitch carries the window's
    mean acceleration, which the sagittal bias estimate does not)."""
    lateral = np.asarray(new_R_imu, float)[1]  # the stride's y axis in IMU coordinates
    d_up = np.asarray(old_R_imu, float)[2] - np.asarray(new_R_imu, float)[2]
    accel = np.asarray(bias.accelerometer()) + gravity_m_s2 * float(d_up @ lateral) * lateral
    return gtsam.imuBias.ConstantBias(accel, np.asarray(bias.gyroscope()))


def carried_priors(
    pc: PriorConfig,
    camera_T_imu: np.ndarray,
    reason: str,
    pred: gtsam.NavState,
    cov_x: np.ndarray,
    cov_v: np.ndarray,
    bias: gtsam.imuBias.ConstantBias,
    cov_b: np.ndarray,
    anchor: KinematicMeasurement | None,
    out_of_unloaded_first: bool = False,
    out_of_loose_tilt: bool = False,
    gravity_m_s2: float | None = None,
) -> StartPriors:
    """The previous stride's end state ``pred`` (propagated to this frame, covariances incl.
    preintegration) as the new stride's priors; see the module docstring for the inflation.
    ``out_of_loose_tilt``: that stride's anchor had no known up σ (the session's first
    strike): its bias covariance is also × ``loose_tilt_bias_inflation`` (and with
    ``loose_tilt_bias_reset`` the accelerometer's bias restarts from the first prior).
    ``gravity_m_s2`` (with ``carry_bias_with_tilt``; None where the new anchor's up has no
    known σ, a session's first strike): the accelerometer's bias moves with the anchor's
    tilt correction (:func:`bias_with_tilt`)."""
    infl = pc.carry_inflation if reason == "foot_strike" else pc.missed_strike_inflation
    if out_of_unloaded_first:
        infl *= pc.first_carry_inflation
    if out_of_loose_tilt:
        cov_b = cov_b * pc.loose_tilt_bias_inflation
        if pc.loose_tilt_bias_reset:
            bias, cov_b = _accel_bias_reset(pc, bias, cov_b)
    if anchor is not None and reason == "foot_strike":
        pose, cov_pose = factors.camera_pose_to_imu(
            anchor.stride_T_camera, anchor.covariance, camera_T_imu
        )
        if pc.carry_bias_with_tilt and gravity_m_s2 is not None:
            bias = bias_with_tilt(
                bias, pred.pose().rotation().matrix(), pose.rotation().matrix(), gravity_m_s2
            )
        new_R_old = pose.rotation().matrix() @ pred.pose().rotation().matrix().T
        vel = new_R_old @ np.asarray(pred.velocity())
        cov_vel = new_R_old @ cov_v @ new_R_old.T * infl
        old = pred.pose().matrix()
        return StartPriors(pose, cov_pose, vel, cov_vel, bias, cov_b * infl, [], old)
    flags = []  # no new stride frame: continue in the previous one, inflated
    if reason == "foot_strike":
        flags.append("no_anchor")
        infl = pc.missed_strike_inflation
    pose, vel = pred.pose(), np.asarray(pred.velocity())
    return StartPriors(pose, cov_x * infl, vel, cov_v * infl, bias, cov_b * infl, flags)
