"""A recorded session played in a loop: a long stream from a short recording.

``LoopedSession(session, minutes=10)`` repeats a session's strides back to back so that an
online replay can run for minutes (memory over a long run) without simulating or
storing minutes of frames. A *lap* is the recording from its first foot strike up to (not
including) its last one, ``L = t_last − t_first`` long; the loop plays the recording from its
start up to the last strike, then laps, each shifted by ``L`` further. Every seam is therefore
a foot strike, where the per-stride graph starts anew, and every stride of the loop is a
whole stride of the recording.

It offers what :func:`graph_slam.pipelines.replay.replay_session` and the scoring read of a
:class:`~graph_slam.session.reader.Session` (``path``, ``name``, ``manifest``,
``intrinsics``, ``calibration``, ``frame_times_s``, ``n_frames``, ``frame``, ``imu``,
``joints``, ``events``, ``ground_truth``, ``scene``). The ground truth repeats too: the world
frame jumps at each seam (scoring is per stride, so no stride crosses a jump). Frames are read
from the recording (decoded on demand); samples are the recording's, never interpolated.
"""

from __future__ import annotations

import dataclasses
from functools import cached_property

import numpy as np

from graph_slam.errors import SessionError
from graph_slam.session.records import (
    GaitEvents,
    ImuSeries,
    JointSeries,
    PoseTrajectory,
    RgbdFrame,
)

__all__ = ["LoopedSession"]


class LoopedSession:
    """``session`` repeated (from its last foot strike on, a lap from its first strike) until
    the loop lasts at least ``minutes`` of session time from its first frame."""

    def __init__(self, session, minutes: float, event_source: str | None = None) -> None:
        if not minutes > 0:
            raise SessionError(f"{session.path}: minutes to loop must be > 0, got {minutes}")
        events = session.events
        if events is None:
            raise SessionError(f"{session.path}: a looped session needs events.csv (foot strikes)")
        strikes = np.sort(events.of_source(event_source, "events.csv").foot_strikes_s)
        t_frames = np.asarray(session.frame_times_s, float)
        if strikes.size < 2 or t_frames.size == 0:
            raise SessionError(
                f"{session.path}/events.csv: a loop needs at least two foot strikes and frames "
                f"(got {strikes.size} strikes, {t_frames.size} frames)"
            )
        self.base = session
        self.t_first_s = float(strikes[0])
        self.t_last_s = float(strikes[-1])
        self.lap_s = self.t_last_s - self.t_first_s
        span = self.t_last_s - float(t_frames[0])
        self.laps = max(0, int(np.ceil((minutes * 60.0 - span) / self.lap_s)))
        """Laps after the recording's own first pass."""
        idx, t = self._loop(t_frames, 0.0)
        self._frame_source = idx
        self._frame_t_s = t

    # ------------------------------------------------------------------ the rule
    def _loop(self, t_s: np.ndarray, offset_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Indices into ``t_s`` (a stream on a clock ``offset_s`` behind the camera's) and
        their looped times, in order."""
        t_cam = np.asarray(t_s, float) + offset_s
        first = np.flatnonzero(t_cam < self.t_last_s)
        lap = np.flatnonzero((t_cam >= self.t_first_s) & (t_cam < self.t_last_s))
        idx = [first] + [lap] * self.laps
        shift = [np.zeros(first.size)] + [
            np.full(lap.size, (k + 1) * self.lap_s) for k in range(self.laps)
        ]
        i = np.concatenate(idx)
        return i, np.asarray(t_s, float)[i] + np.concatenate(shift)

    # ------------------------------------------------------------------ metadata
    @property
    def path(self):
        return self.base.path

    @property
    def name(self) -> str:
        return f"{self.base.name}-loop{self.laps}"

    @property
    def manifest(self):
        return self.base.manifest

    @property
    def intrinsics(self):
        return self.base.intrinsics

    @property
    def calibration(self):
        return self.base.calibration

    @property
    def scene(self):
        return self.base.scene

    @property
    def duration_s(self) -> float:
        return float(self._frame_t_s[-1] - self._frame_t_s[0])

    # ------------------------------------------------------------------ frames
    @property
    def frame_times_s(self) -> np.ndarray:
        return self._frame_t_s

    @property
    def n_frames(self) -> int:
        return int(self._frame_t_s.size)

    @property
    def n_color_frames(self) -> int:
        """Loop frames with a colour image (all of them when the recording's frames have)."""
        if self.base.n_color_frames == self.base.n_frames:
            return self.n_frames
        return sum(self.base.frame(int(i)).color_rgb is not None for i in self._frame_source)

    def __len__(self) -> int:
        return self.n_frames

    def frame(self, index: int) -> RgbdFrame:
        """The recording's frame behind loop frame ``index``, stamped with the loop's time."""
        if not 0 <= index < self.n_frames:
            raise IndexError(f"frame index {index} out of range 0..{self.n_frames - 1}")
        f = self.base.frame(int(self._frame_source[index]))
        return dataclasses.replace(f, t_s=float(self._frame_t_s[index]), index=index)

    def source_index(self, index: int) -> int:
        """The recording's frame index behind loop frame ``index``."""
        return int(self._frame_source[index])

    # ------------------------------------------------------------------ streams
    @cached_property
    def imu(self) -> ImuSeries | None:
        imu = self.base.imu
        if imu is None:
            return None
        i, t = self._loop(imu.t_s, self.calibration.imu_time_offset_s)
        return ImuSeries(t, np.asarray(imu.gyro_rad_s)[i], np.asarray(imu.accel_m_s2)[i])

    @cached_property
    def joints(self) -> JointSeries | None:
        j = self.base.joints
        if j is None:
            return None
        i, t = self._loop(j.t_s, self.calibration.joints_time_offset_s)
        return JointSeries(t, np.asarray(j.knee_rad)[i], np.asarray(j.ankle_rad)[i])

    @cached_property
    def events(self) -> GaitEvents:
        e = self.base.events
        i, t = self._loop(e.t_s, 0.0)
        return GaitEvents(t, tuple(e.kind[k] for k in i), tuple(e.source[k] for k in i))

    @cached_property
    def ground_truth(self) -> PoseTrajectory | None:
        gt = self.base.ground_truth
        if gt is None:
            return None
        i, t = self._loop(gt.t_s, 0.0)
        return PoseTrajectory(t, np.asarray(gt.parent_T_child)[i], gt.parent, gt.child)

    @property
    def ground_truth_hf(self) -> PoseTrajectory | None:
        return None
