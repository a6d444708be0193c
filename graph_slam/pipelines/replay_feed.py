"""The replay's feed: when a frame can be processed (:func:`ready_times`: once the sensor
streams cover it) and the session's streams delivered to the pipeline up to a time, in
timestamp order, never twice."""

from __future__ import annotations

import numpy as np

from graph_slam.pipelines.protocol import Pipeline
from graph_slam.strides.events import StrideEvents
from graph_slam.strides.streams import Streams


def _covering(t_s: np.ndarray, t: float) -> int:
    """How many samples a device has once its stream covers ``t``: up to and including the
    first one at or after ``t``."""
    return min(int(np.searchsorted(t_s, t, side="left")) + 1, t_s.size)


def ready_times(frame_t_s: np.ndarray, streams: Streams) -> np.ndarray:
    """When each frame can be processed: its time stamp, or later, when the IMU or encoder
    sample that covers it arrives (never before the stamp; a stream that ends does not
    hold frames back)."""
    stamp = np.asarray(frame_t_s, float)
    ready = stamp.copy()
    for t_s in (streams.imu_t_s, streams.joints_t_s):
        if t_s is None or t_s.size == 0:
            continue
        k = np.searchsorted(t_s, stamp, side="left")
        inside = k < t_s.size
        ready[inside] = np.maximum(ready[inside], t_s[k[inside]])
    return np.maximum.accumulate(ready)


class _Feed:
    """The session's streams, delivered up to a time in timestamp order (never twice)."""

    def __init__(self, pipe: Pipeline, streams: Streams) -> None:
        self.pipe = pipe
        self.s = streams
        self.i_imu = self.i_joint = self.i_strike = 0
        self.t_known = -np.inf
        self.strikes = streams.events.foot_strikes_s
        self.strikes_known = streams.events.strikes_known_s
        self.toe_offs = streams.events.toe_offs_s

    def _samples_until(self, t_s: float) -> None:
        """Every sample up to and including the first at or after ``t_s`` (per stream)."""
        s = self.s
        if s.imu_t_s is not None:
            j = _covering(s.imu_t_s, t_s)
            if j > self.i_imu:
                sl = slice(self.i_imu, j)
                self.pipe.add_imu(s.imu_t_s[sl], s.gyro_rad_s[sl], s.accel_m_s2[sl])
                self.i_imu = j
        if s.joints_t_s is not None:
            j = _covering(s.joints_t_s, t_s)
            if j > self.i_joint:
                sl = slice(self.i_joint, j)
                self.pipe.add_joints(s.joints_t_s[sl], s.knee_rad[sl], s.ankle_rad[sl])
                self.i_joint = j

    def until(self, t_s: float) -> None:
        """Samples and foot strikes stamped at or before ``t_s``; each strike after the
        samples up to it."""
        while self.i_strike < self.strikes.size and self.strikes_known[self.i_strike] <= t_s:
            t_strike = float(self.strikes[self.i_strike])
            self._samples_until(float(self.strikes_known[self.i_strike]))
            self.pipe.foot_strike(t_strike)
            self.i_strike += 1
        self._samples_until(t_s)
        self.t_known = t_s

    def known_events(self) -> StrideEvents:
        """The events delivered (known) so far."""
        return self.s.events.known_at(self.t_known)
