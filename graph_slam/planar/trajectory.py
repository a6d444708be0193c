"""The thigh-mounted sensor's trajectory over whole strides, from gait kinematics.

A sagittal leg — thigh, shank and a rigid foot (heel and toe) — is driven by the reference
curves of :mod:`kinematics.gait_curves` at the walking speed: thigh angle from the vertical
(hip flexion minus anterior pelvic tilt), knee flexion and ankle dorsiflexion. The other leg
follows the same curves half a cycle later. The hip is placed so that no foot goes below the
ground: its height is the larger reach of the two legs (the leg that reaches farther is the
stance leg), and the stance leg's lowest foot point (heel, then toe) stays pinned where it
touched — the hip's forward motion follows from the leg's rotation about it.

The sensor sits on the front of the thigh above the knee; its boresight points
``sensor_pitch_down_rad`` below the horizontal when the thigh is vertical and turns with the
thigh. Frames: world (x forward, y up); stride k (origin on the ground under the heel at the
k-th foot strike of the instrumented leg, axes parallel to the world's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import PlanarError
from graph_slam.planar import se2
from graph_slam.planar.config import LegConfig
from kinematics import gait_curves

THIGH, KNEE, ANKLE = 0, 1, 2  # columns of the leg angles


def leg_angles_rad(phase: np.ndarray, speed_m_s: float) -> np.ndarray:
    """(n, 3) thigh angle from the vertical, knee flexion, ankle dorsiflexion at ``phase``."""
    q = gait_curves.joint_angles(phase, speed_m_s)
    thigh = gait_curves.thigh_angle(phase, speed_m_s)
    return np.column_stack([thigh, q["knee"], q["ankle"]])


def leg_points(angles_rad: np.ndarray, leg: LegConfig) -> dict[str, np.ndarray]:
    """Heel, toe and sensor positions relative to the hip, and the sensor heading: (n, 2)/(n,).

    Forward kinematics of eq.-free geometry: knee = hip + l_t (sin φ, -cos φ), shank angle
    ψ = φ - knee flexion, foot pitch (toe up +) γ = ψ + dorsiflexion.
    """
    phi, knee, ankle = angles_rad[:, THIGH], angles_rad[:, KNEE], angles_rad[:, ANKLE]
    down = np.column_stack([np.sin(phi), -np.cos(phi)])  # along the thigh, hip -> knee
    psi = phi - knee
    ankle_xy = leg.thigh_length_m * down + leg.shank_length_m * np.column_stack(
        [np.sin(psi), -np.cos(psi)]
    )
    gamma = psi + ankle
    foot_fwd = np.column_stack([np.cos(gamma), np.sin(gamma)])
    foot_down = np.column_stack([np.sin(gamma), -np.cos(gamma)])
    sole = ankle_xy + leg.ankle_height_m * foot_down
    thigh_fwd = np.column_stack([np.cos(phi), np.sin(phi)])
    return {
        "heel": sole - leg.heel_back_m * foot_fwd,
        "toe": sole + leg.toe_forward_m * foot_fwd,
        "sensor": leg.sensor_from_hip_m * down + leg.sensor_forward_m * thigh_fwd,
        "sensor_heading": phi - leg.sensor_pitch_down_rad,
    }


def heel_T_sensor(angles_rad: np.ndarray, leg: LegConfig) -> np.ndarray:
    """(n, 3, 3) sensor pose relative to the heel's ground point, from the leg's angles.

    This is the leg-kinematic measurement at foot strike: thigh inclination (an IMU), knee
    and ankle angles (encoders); the heel is on the ground, frame axes parallel to world.
    """
    pts = leg_points(angles_rad, leg)
    rel = pts["sensor"] - pts["heel"]
    return np.stack(
        [se2.se2(x, y, th) for (x, y), th in zip(rel, pts["sensor_heading"], strict=True)]
    )


@dataclass(frozen=True)
class GaitTrajectory:
    """True sensor poses at the scan times, with the gait events that cut them into strides."""

    speed_m_s: float
    stride_time_s: float
    t_s: np.ndarray  # (n,) scan times, 0 = first foot strike
    phase: np.ndarray  # (n,) phase of the gait curves (their 0 is near, not at, the strike)
    stride_index: np.ndarray  # (n,) which stride each scan belongs to
    world_T_sensor: np.ndarray  # (n, 3, 3)
    leg_angles_rad: np.ndarray  # (n, 3) thigh, knee, ankle (truth)
    world_T_stride: np.ndarray  # (n_strides, 3, 3) at each foot strike
    foot_strike_t_s: np.ndarray  # (n_strides,)
    in_stance: np.ndarray  # (n,) the instrumented leg is the one on the ground
    hip_speed_m_s: float  # mean forward speed of the hip that the leg geometry produced


def simulate_gait(
    speed_m_s: float, n_strides: int, scan_rate_hz: float, leg: LegConfig
) -> GaitTrajectory:
    """Walk ``n_strides`` strides at ``speed_m_s`` and sample the sensor pose at the scan rate.

    A foot strike is the moment the instrumented leg becomes the stance leg (its heel touches
    the ground in this geometry); time 0 is the first one. A rigid leg model cannot keep both
    feet on the ground, so double support shrinks to the instant of the switch, and the strike
    comes about 0.1 cycle after the curves' phase 0 (the end of their double support).
    """
    stride_s = gait_curves.stride_time_s(speed_m_s)
    dt = 1.0 / leg.sample_rate_hz
    t_fine = np.arange(-0.25 * stride_s, (n_strides + 0.25) * stride_s, dt)
    phase = t_fine / stride_s
    legs = [leg_points(leg_angles_rad(phase + shift, speed_m_s), leg) for shift in (0.0, 0.5)]
    # Foot points relative to the hip, indexed (leg, point) -> 0 heel, 1 toe, 2 other heel, 3 toe.
    feet = np.stack([leg_pts[key] for leg_pts in legs for key in ("heel", "toe")])
    contact = feet[..., 1].argmin(axis=0)  # the lowest point below the hip touches the ground

    contact_rel = feet[contact, np.arange(len(t_fine))]
    hip = np.empty((len(t_fine), 2))
    hip[:, 1] = -contact_rel[:, 1]
    # Pin the contact point where it was when it became the contact.
    hip[0, 0] = 0.0
    pinned_x = contact_rel[0, 0]
    for i in range(1, len(t_fine)):
        if contact[i] != contact[i - 1]:
            pinned_x = hip[i - 1, 0] + contact_rel[i, 0]
        hip[i, 0] = pinned_x - contact_rel[i, 0]
    ours = contact < 2
    strikes = np.flatnonzero(ours[1:] & ~ours[:-1]) + 1
    if len(strikes) < n_strides + 1:
        raise PlanarError(
            f"the leg model found {len(strikes)} foot strikes in "
            f"{n_strides + 0.5} cycles at {speed_m_s} m/s (expected one per cycle)"
        )
    t0 = t_fine[strikes[0]]
    t_fine = t_fine - t0
    hip[:, 0] -= hip[strikes[0], 0] + legs[0]["heel"][strikes[0], 0]  # first heel strike at x=0
    strike_t = t_fine[strikes[: n_strides + 1]]
    sensor_xy = hip + legs[0]["sensor"]
    heading = legs[0]["sensor_heading"]

    t_s = np.arange(0.0, strike_t[-1] - 1e-9, 1.0 / scan_rate_hz)
    x = np.interp(t_s, t_fine, sensor_xy[:, 0])
    y = np.interp(t_s, t_fine, sensor_xy[:, 1])
    th = np.interp(t_s, t_fine, heading)
    heel_x = hip[strikes[:n_strides], 0] + legs[0]["heel"][strikes[:n_strides], 0]
    stride_index = np.searchsorted(strike_t, t_s, side="right") - 1
    phase_s = (t_s + t0) / stride_s
    return GaitTrajectory(
        speed_m_s=float(speed_m_s),
        stride_time_s=stride_s,
        t_s=t_s,
        phase=phase_s % 1.0,
        stride_index=stride_index,
        world_T_sensor=np.stack([se2.se2(*p) for p in zip(x, y, th, strict=True)]),
        leg_angles_rad=leg_angles_rad(phase_s, speed_m_s),
        world_T_stride=np.stack([se2.se2(hx, 0.0, 0.0) for hx in heel_x]),
        foot_strike_t_s=strike_t[:n_strides],
        in_stance=np.interp(t_s, t_fine, ours.astype(float)) > 0.5,
        hip_speed_m_s=float((hip[-1, 0] - hip[0, 0]) / (t_fine[-1] - t_fine[0])),
    )
