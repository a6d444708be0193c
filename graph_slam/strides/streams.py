"""Session streams as the pipelines use them: time offsets applied, strides cut at events.

Also the up vector at a foot strike (gyro-rotated accelerometer mean). The leg model matching
a calibration and the IMU's up vector in it are in :mod:`graph_slam.strides.kinematics`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import SessionError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Streams:
    """IMU and joints on the camera clock (calibration offsets applied), events for strides."""

    imu_t_s: np.ndarray | None
    gyro_rad_s: np.ndarray | None
    accel_m_s2: np.ndarray | None
    joints_t_s: np.ndarray | None
    knee_rad: np.ndarray | None
    ankle_rad: np.ndarray | None
    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray

    def foot_loaded(self, t_s: float) -> bool:
        """Loaded between a foot strike and the next toe-off (load-cell events)."""
        strikes = self.foot_strikes_s[self.foot_strikes_s <= t_s]
        if strikes.size == 0:
            return False
        offs = self.toe_offs_s[(self.toe_offs_s > strikes[-1]) & (self.toe_offs_s <= t_s)]
        return offs.size == 0

    def window_before(self, t_s: float, default_s: float) -> float:
        """The previous stride's duration (strike to strike) when known, else ``default_s``."""
        before = self.foot_strikes_s[self.foot_strikes_s < t_s - 0.3]
        return float(t_s - before[-1]) if before.size else default_s

    def q_at(self, t_s: float) -> np.ndarray | None:
        if self.joints_t_s is None or not self.joints_t_s[0] <= t_s <= self.joints_t_s[-1]:
            return None
        return np.array(
            [
                np.interp(t_s, self.joints_t_s, self.knee_rad),
                np.interp(t_s, self.joints_t_s, self.ankle_rad),
            ]
        )

    def mean_accel(self, t0_s: float, t1_s: float) -> np.ndarray | None:
        if self.imu_t_s is None:
            return None
        m = (self.imu_t_s >= t0_s) & (self.imu_t_s <= t1_s) & np.isfinite(self.accel_m_s2).all(1)
        if not m.any():
            return None
        return self.accel_m_s2[m].mean(axis=0)


def session_streams(session, event_source: str | None) -> Streams:
    """Read a session's streams, shift IMU and joints onto the camera clock."""
    calib = session.calibration
    imu = session.imu
    joints = session.joints
    events = session.events
    strikes = np.zeros(0)
    offs = np.zeros(0)
    if events is not None and len(events):
        kinds = np.asarray(events.kind)
        use = np.ones(len(events), dtype=bool)
        if event_source is not None:
            use = np.asarray(events.source) == event_source
            if not use.any():
                raise SessionError(
                    f"{session.path}/events.csv: no event with source {event_source!r} "
                    f"(found {sorted(set(events.source))}); set event_source"
                )
        t = np.asarray(events.t_s)
        strikes = np.sort(t[use & (kinds == "foot_strike")])
        offs = np.sort(t[use & (kinds == "toe_off")])
    return Streams(
        imu_t_s=None if imu is None else np.asarray(imu.t_s) + calib.imu_time_offset_s,
        gyro_rad_s=None if imu is None else np.asarray(imu.gyro_rad_s),
        accel_m_s2=None if imu is None else np.asarray(imu.accel_m_s2),
        joints_t_s=None if joints is None else np.asarray(joints.t_s) + calib.joints_time_offset_s,
        knee_rad=None if joints is None else np.asarray(joints.q_rad)[:, 0],
        ankle_rad=None if joints is None else np.asarray(joints.q_rad)[:, 1],
        foot_strikes_s=strikes,
        toe_offs_s=offs,
    )


def gravity_up(streams: Streams, t_s: float, window_s: float) -> np.ndarray | None:
    """Up (m/s², IMU frame at ``t_s``) averaged over ``[t_s - window_s, t_s]`` with every
    accelerometer sample rotated into the frame at ``t_s`` by the integrated gyro.

    A plain mean of the accelerometer just before a foot strike is dominated by the swing
    leg's deceleration (measured here: ~15° of pitch error in the stride frame). Over about
    one stride the leg's mean acceleration is near zero (the velocity at consecutive foot
    strikes is nearly the same), so the rotated mean is gravity.
    """
    if streams.imu_t_s is None:
        return None
    t = streams.imu_t_s
    m = (t >= t_s - window_s) & (t <= t_s)
    m &= np.isfinite(streams.accel_m_s2).all(1) & np.isfinite(streams.gyro_rad_s).all(1)
    idx = np.flatnonzero(m)
    if idx.size < 10:
        return None
    from scipy.spatial.transform import Rotation

    tt, w, a = t[idx], streams.gyro_rad_s[idx], streams.accel_m_s2[idx]
    # backward integration: R[k] = frame(t_s)_R_frame(t_k)
    rot = np.empty((idx.size, 3, 3))
    rot[-1] = np.eye(3)
    for k in range(idx.size - 2, -1, -1):
        dt = tt[k + 1] - tt[k]
        step = Rotation.from_rotvec(0.5 * (w[k] + w[k + 1]) * dt).as_matrix()  # k_R_{k+1}
        rot[k] = rot[k + 1] @ step.T
    up = np.einsum("kij,kj->i", rot, a) / idx.size
    return up
