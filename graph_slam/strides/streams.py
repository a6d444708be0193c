"""Session streams as the pipelines use them: time offsets applied, strides cut at events
(one rule: :func:`stride_events`).

The up vector at a foot strike is :mod:`graph_slam.strides.gravity`'s; the leg model matching
a calibration and the IMU's up vector in it are :mod:`graph_slam.strides.kinematics`'s.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StrideEvents:
    """The gait events that cut strides and set the foot-loaded state, from one source.

    ``source``: the ``events.csv`` source they came from (None: every source in the file), or
    ``imu-online`` (:mod:`graph_slam.strides.online_events`). ``*_known_s``: when each event
    became known (an online estimator emits an event after it happened); None: at its time.
    """

    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    source: str | None = None
    foot_strikes_known_s: np.ndarray | None = None
    toe_offs_known_s: np.ndarray | None = None

    @property
    def strikes_known_s(self) -> np.ndarray:
        """When each foot strike is known (announce it then, with its time)."""
        known = self.foot_strikes_known_s
        return self.foot_strikes_s if known is None else known

    @property
    def toe_offs_known_by_s(self) -> np.ndarray:
        known = self.toe_offs_known_s
        return self.toe_offs_s if known is None else known

    def known_at(self, t_s: float) -> StrideEvents:
        """The events known at ``t_s`` (a causal view)."""
        fs = self.strikes_known_s <= t_s
        to = self.toe_offs_known_by_s <= t_s
        return StrideEvents(
            self.foot_strikes_s[fs],
            self.toe_offs_s[to],
            self.source,
            self.strikes_known_s[fs],
            self.toe_offs_known_by_s[to],
        )

    def foot_loaded(self, t_s: float) -> bool:
        """Loaded between a foot strike and the next toe-off, from the events known at ``t_s``
        (reads no event after ``t_s``, nor one not yet known then)."""
        known = self.known_at(t_s)
        strikes = known.foot_strikes_s[known.foot_strikes_s <= t_s]
        if strikes.size == 0:
            return False
        offs = known.toe_offs_s[(known.toe_offs_s > strikes[-1]) & (known.toe_offs_s <= t_s)]
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
    """The events that cut strides: those of ``source`` (None: every source), by the one rule
    :meth:`graph_slam.session.records.GaitEvents.of_source`. ``events`` None: no strides."""
    if events is None or not len(events):
        return StrideEvents(np.zeros(0), np.zeros(0), source)
    picked = events.of_source(source, where)
    return StrideEvents(np.sort(picked.foot_strikes_s), np.sort(picked.toe_offs_s), source)


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
