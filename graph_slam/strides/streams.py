"""Session streams as the pipelines use them: time offsets applied, strides cut at events
(one rule: :func:`graph_slam.strides.events.stride_events`).

The up vector at a foot strike is :mod:`graph_slam.strides.gravity`'s; the leg model matching
a calibration and the IMU's up vector in it are :mod:`graph_slam.strides.kinematics`'s.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from graph_slam.strides.events import StrideEvents, stride_events

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
    events: StrideEvents

    @property
    def foot_strikes_s(self) -> np.ndarray:
        return self.events.foot_strikes_s

    def foot_loaded(self, t_s: float) -> bool:
        return self.events.foot_loaded(t_s)


def session_streams(session, event_source: str | None) -> Streams:
    """Read a session's streams, shift IMU and joints onto the camera clock, select the
    events that cut strides (:func:`~graph_slam.strides.events.stride_events`)."""
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
        events=_events(session, event_source, imu, calib.imu_time_offset_s),
    )


def _events(session, event_source: str | None, imu, imu_offset_s: float) -> StrideEvents:
    """``events.csv`` (one source, or all), or ``imu-online``: the causal estimator's events
    from the thigh IMU (:mod:`graph_slam.strides.online_events`)."""
    from graph_slam.strides.online_events import ONLINE_SOURCE, online_stride_events

    if event_source != ONLINE_SOURCE:
        return stride_events(session.events, event_source, f"{session.path}/events.csv")
    if imu is None:
        from graph_slam.errors import SessionError

        raise SessionError(
            f"{session.path}: event_source {ONLINE_SOURCE!r} needs the thigh IMU (imu.csv)"
        )
    return online_stride_events(
        np.asarray(imu.t_s) + imu_offset_s,
        np.asarray(imu.gyro_rad_s),
        np.asarray(imu.accel_m_s2),
        str(session.path),
    )
