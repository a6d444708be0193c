"""The stride frame and ``stride_T_camera`` at foot strike.

Stride frame (DEVELOPERS.md conventions): origin at the heel contact point at foot strike,
z up against gravity, x forward along the foot (the horizontal projection of the sole's
x axis), y = z × x (to the left). It is fixed to the ground for the whole stride.

At foot strike the camera's pose in it is

    stride_T_camera = stride_T_foot · foot_T_camera(q)

* ``foot_T_camera(q)`` comes from the leg model (forward kinematics of knee and ankle).
* ``stride_T_foot`` is a pure rotation (the foot frame's origin *is* the heel contact point):
  the foot's roll and pitch relative to gravity. Its yaw is zero by the definition of x.
  Two ways to get it:

  - from the IMU (preferred): the thigh IMU's "up" direction (its accelerometer averaged over
    a quiet window, or an attitude filter's estimate) is carried into the foot frame by
    ``foot_T_imu(q)``; that fixes roll and pitch, whatever the ground slope;
  - from the foot's pitch on the ground (no IMU): the foot pitched toe-up by the given angle
    at heel strike (default :func:`nominal_heel_strike_pitch_rad`), or flat (0) at foot flat,
    on level ground, zero roll.

The uncertainty of the result is :meth:`LegModel.camera_covariance` with the matching foot
contact term (heel strike: the foot can still rotate about the heel; foot flat: the sole
fixes roll and pitch).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinematics.errors import KinematicsError
from kinematics.leg_model import Contact, ContactNoise, LegModel

DEFAULT_ENCODER_VAR_RAD2 = math.radians(0.2) ** 2
"""Default encoder variance: 0.2 deg sigma (a 12-bit absolute encoder plus backlash)."""


@dataclass(frozen=True)
class StrideAnchor:
    """The camera pose in the stride frame at foot strike, with its uncertainty."""

    stride_T_camera: np.ndarray
    """4x4 pose of the camera optical frame in the stride frame."""
    covariance: np.ndarray
    """6x6, rotation first, right perturbation (camera local coordinates), for a Pose3 prior."""
    stride_T_foot: np.ndarray
    """4x4 (rotation only): the foot's roll and pitch relative to gravity."""
    foot_pitch_rad: float
    """Toe-up pitch of the sole relative to horizontal."""
    foot_roll_rad: float
    """Roll of the sole about its x axis relative to horizontal (left side up +)."""
    contact: Contact
    source: str
    """"imu_gravity" or "foot_pitch" (how stride_T_foot was obtained)."""


def nominal_heel_strike_pitch_rad(speed_m_s: float = 1.2) -> float:
    """Toe-up foot pitch at foot strike from the gait reference curves (about 0.3 rad).

    Sagittal-plane sum at phase 0: thigh inclination - knee flexion + ankle dorsiflexion.
    """
    from kinematics.gait_curves import joint_angles, thigh_angle

    q = joint_angles(0.0, speed_m_s)
    return float(thigh_angle(0.0, speed_m_s) - q["knee"] + q["ankle"])


def stride_T_foot_from_up(up_in_foot: Sequence[float] | np.ndarray) -> np.ndarray:
    """``stride_T_foot`` (4x4 rotation) from the up direction expressed in the foot frame."""
    up = np.asarray(up_in_foot, dtype=float)
    norm = float(np.linalg.norm(up)) if up.shape == (3,) else 0.0
    if up.shape != (3,) or not np.all(np.isfinite(up)) or norm < 1e-9:
        raise KinematicsError(f"up direction must be a finite non-zero 3-vector, got {up!r}")
    z_s = up / norm
    x_f = np.array([1.0, 0.0, 0.0])
    x_h = x_f - (x_f @ z_s) * z_s
    if np.linalg.norm(x_h) < 0.1:
        raise KinematicsError(
            "the foot's x axis is within 6 deg of vertical: the stride frame's forward "
            "direction is undefined (is the up vector in the foot frame?)"
        )
    x_s = x_h / np.linalg.norm(x_h)
    y_s = np.cross(z_s, x_s)
    out = np.eye(4)
    out[:3, :3] = np.vstack([x_s, y_s, z_s])  # rows: stride axes in foot coordinates
    return out


def stride_T_foot_from_pitch(foot_pitch_rad: float) -> np.ndarray:
    """``stride_T_foot`` for a foot pitched toe-up by ``foot_pitch_rad`` on level ground."""
    a = float(foot_pitch_rad)
    if not math.isfinite(a) or abs(a) > math.radians(80.0):
        raise KinematicsError(f"foot_pitch_rad={foot_pitch_rad!r}: need a finite |pitch| < 80 deg")
    out = np.eye(4)
    c, s = math.cos(a), math.sin(a)
    # Rotation about y by -a: the sole's x axis maps to (cos a, 0, sin a) (toe up).
    out[:3, :3] = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    return out


def stride_T_camera(
    model: LegModel,
    q: Sequence[float] | np.ndarray,
    *,
    up_in_imu: Sequence[float] | np.ndarray | None = None,
    foot_pitch_rad: float | None = None,
    contact: Contact = "heel_strike",
    encoder_cov_rad2: float | Sequence[float] | np.ndarray = DEFAULT_ENCODER_VAR_RAD2,
    contact_noise: ContactNoise | None = None,
) -> StrideAnchor:
    """The camera pose in the stride frame at foot strike (see the module docstring).

    ``q``: [knee, ankle] at the foot strike (rad). ``up_in_imu``: up direction in the IMU
    frame (e.g. the mean accelerometer reading, m/s², over a quiet window: at rest it measures
    +g upward). Without it, ``foot_pitch_rad`` (toe up +) is used, defaulting to
    :func:`nominal_heel_strike_pitch_rad` at heel strike and 0 at foot flat.
    """
    q_arr = model.check_q(q)
    foot_T_camera = model.foot_T_camera(q_arr)
    if up_in_imu is not None:
        up = np.asarray(up_in_imu, dtype=float)
        if up.shape != (3,) or not np.all(np.isfinite(up)) or np.linalg.norm(up) < 1e-9:
            raise KinematicsError(f"up_in_imu must be a finite non-zero 3-vector, got {up!r}")
        foot_R_imu = model.foot_T_imu(q_arr)[:3, :3]
        stride_T_foot = stride_T_foot_from_up(foot_R_imu @ up)
        source = "imu_gravity"
    else:
        if foot_pitch_rad is None:
            foot_pitch_rad = nominal_heel_strike_pitch_rad() if contact == "heel_strike" else 0.0
        stride_T_foot = stride_T_foot_from_pitch(foot_pitch_rad)
        source = "foot_pitch"
    x_f_in_s = stride_T_foot[:3, 0]
    y_f_in_s = stride_T_foot[:3, 1]
    pitch = math.atan2(x_f_in_s[2], math.hypot(x_f_in_s[0], x_f_in_s[1]))
    roll = math.asin(float(np.clip(y_f_in_s[2], -1.0, 1.0)))
    cov = model.camera_covariance(q_arr, encoder_cov_rad2, contact, contact_noise)
    return StrideAnchor(
        stride_T_camera=stride_T_foot @ foot_T_camera,
        covariance=cov,
        stride_T_foot=stride_T_foot,
        foot_pitch_rad=pitch,
        foot_roll_rad=roll,
        contact=contact,
        source=source,
    )
