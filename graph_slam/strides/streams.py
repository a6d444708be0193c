"""Session streams as the pipelines use them: time offsets applied, strides cut at events
(one rule: :func:`stride_events`).

Also the leg model matching a session's calibration and the thesis's odometry reset at foot
strike (encoders -> ``foot_T_camera``, IMU gravity for roll and pitch).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import ConfigError, SessionError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StrideEvents:
    """The gait events that cut strides and set the foot-loaded state, from one source.

    ``source``: the ``events.csv`` source they came from (None: every source in the file).
    """

    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    source: str | None = None

    def foot_loaded(self, t_s: float) -> bool:
        """Loaded between a foot strike and the next toe-off (reads no event after ``t_s``)."""
        strikes = self.foot_strikes_s[self.foot_strikes_s <= t_s]
        if strikes.size == 0:
            return False
        offs = self.toe_offs_s[(self.toe_offs_s > strikes[-1]) & (self.toe_offs_s <= t_s)]
        return offs.size == 0

    def next_strike_after(self, t_s: float) -> float | None:
        after = self.foot_strikes_s[self.foot_strikes_s > t_s]
        return float(after[0]) if after.size else None

    def last_strike_at_or_before(self, t_s: float) -> float | None:
        before = self.foot_strikes_s[self.foot_strikes_s <= t_s]
        return float(before[-1]) if before.size else None

    def toe_off_between(self, t0_s: float, t1_s: float) -> float | None:
        toe = self.toe_offs_s[(self.toe_offs_s > t0_s) & (self.toe_offs_s < t1_s)]
        return float(toe[0]) if toe.size else None


def stride_events(events, source: str | None, where: str = "events.csv") -> StrideEvents:
    """The one rule for which events cut strides: those of ``source`` (a ``SessionError``
    naming the sources found when there is none), or every event when ``source`` is None.
    ``events``: a :class:`graph_slam.session.records.GaitEvents` or None (no strides)."""
    if events is None or not len(events):
        return StrideEvents(np.zeros(0), np.zeros(0), source)
    kinds = np.asarray(events.kind)
    use = np.ones(len(events), dtype=bool)
    if source is not None:
        use = np.asarray(events.source) == source
        if not use.any():
            raise SessionError(
                f"{where}: no event with source {source!r} "
                f"(found {sorted(set(events.source))}); set event_source"
            )
    t = np.asarray(events.t_s)
    return StrideEvents(
        np.sort(t[use & (kinds == "foot_strike")]), np.sort(t[use & (kinds == "toe_off")]), source
    )


@dataclass(frozen=True)
class Streams:
    """IMU and joints on the camera clock (calibration offsets applied), events for strides."""

    imu_t_s: np.ndarray | None
    gyro_rad_s: np.ndarray | None
    accel_m_s2: np.ndarray | None
    joints_t_s: np.ndarray | None
    knee_rad: np.ndarray | None
    ankle_rad: np.ndarray | None
    events: StrideEvents

    @property
    def foot_strikes_s(self) -> np.ndarray:
        return self.events.foot_strikes_s

    def foot_loaded(self, t_s: float) -> bool:
        return self.events.foot_loaded(t_s)

    def q_at(self, t_s: float) -> np.ndarray | None:
        """Knee and ankle angles (rad) at ``t_s``, linear between samples; None outside."""
        if self.joints_t_s is None or not self.joints_t_s[0] <= t_s <= self.joints_t_s[-1]:
            return None
        return np.array(
            [
                np.interp(t_s, self.joints_t_s, self.knee_rad),
                np.interp(t_s, self.joints_t_s, self.ankle_rad),
            ]
        )


def session_streams(session, event_source: str | None) -> Streams:
    """Read a session's streams, shift IMU and joints onto the camera clock, select the
    events that cut strides (:func:`stride_events`)."""
    calib = session.calibration
    imu = session.imu
    joints = session.joints
    return Streams(
        imu_t_s=None if imu is None else np.asarray(imu.t_s) + calib.imu_time_offset_s,
        gyro_rad_s=None if imu is None else np.asarray(imu.gyro_rad_s),
        accel_m_s2=None if imu is None else np.asarray(imu.accel_m_s2),
        joints_t_s=None if joints is None else np.asarray(joints.t_s) + calib.joints_time_offset_s,
        knee_rad=None if joints is None else np.asarray(joints.q_rad)[:, 0],
        ankle_rad=None if joints is None else np.asarray(joints.q_rad)[:, 1],
        events=stride_events(session.events, event_source, f"{session.path}/events.csv"),
    )


def leg_model_for(thigh_T_camera: np.ndarray, mount_pitch_deg: float | None = None):
    """The ``LegModel`` whose camera mount matches the calibration's ``thigh_T_camera``.

    With ``mount_pitch_deg`` None the pitch is fitted (30-45°); the fitted mount must reproduce
    the calibration within 1 mm / 1 mrad, else :class:`ConfigError`.
    """
    from scipy.optimize import minimize_scalar

    from kinematics.leg_model import LegModel
    from kinematics.leg_params import LegParams

    def model(pitch_rad: float) -> LegModel:
        return LegModel(LegParams(mount_pitch_down_rad=pitch_rad))

    def mismatch(m) -> float:
        d = np.linalg.inv(m.thigh_T_frame("camera_optical")) @ thigh_T_camera
        return float(np.linalg.norm(d[:3, 3]) + np.linalg.norm(d[:3, :3] - np.eye(3)))

    if mount_pitch_deg is not None:
        return model(math.radians(mount_pitch_deg))
    fit = minimize_scalar(
        lambda p: mismatch(model(p)),
        bounds=(math.radians(30), math.radians(45)),
        method="bounded",
        options={"xatol": 1e-9},
    )
    best = model(float(fit.x))
    if mismatch(best) > 1e-3:
        raise ConfigError(
            "calibration.thigh_T_camera: no leg-model camera mount (pitch 30-45°, default "
            f"geometry) reproduces it (mismatch {mismatch(best):.3g}); set mount_pitch_deg"
        )
    return best


def imu_up_in_model(model, camera_T_imu: np.ndarray, up_in_imu: np.ndarray) -> np.ndarray:
    """The session IMU's up vector expressed in the leg model's ``imu`` frame (via the camera)."""
    model_camera_R_imu = (
        np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")
    )[:3, :3]
    return model_camera_R_imu.T @ camera_T_imu[:3, :3] @ up_in_imu
