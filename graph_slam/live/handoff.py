"""The live loop's frames between their arrival and the estimator, and the skip rule.

No thread and no clock of its own (the loop passes ``now``): tested on hand-made timelines.

A frame waits here from its arrival until it is **ready**: the IMU has a sample at or after its
time stamp (the estimator interpolates the IMU to the frame's time; with no IMU every frame is
ready on arrival). Waiting for the IMU blocks nothing: newer frames and samples keep arriving
and are booked meanwhile. Then:

- the estimator, when free, takes the **oldest** ready frame, unless a newer frame became ready
  while it was busy with an earlier one: then it takes the newest ready frame and the older ready
  ones are skipped, counted as ``busy``. A frame is skipped as busy only when the estimator was
  processing when a newer frame became ready, never because of the wait for the IMU (frames made
  ready together by a late IMU sample while the estimator was idle are all processed, in order);
- a frame still not ready ``imu_wait_s`` after its arrival is skipped, counted as ``imu late``
  (its IMU samples, when they come, go to the next processed frame: no sample is lost). It is
  not processed with the IMU stopping short of its time: the estimator would extrapolate, and
  the outputs would differ from ``graph-slam run`` on the same frames;
- when the streams end, the frames that can no longer become ready are skipped, counted as
  ``stream ended``;
- a frame that cannot be decoded is skipped, counted as ``unreadable`` (the run goes on).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

SKIP_REASONS: tuple[str, ...] = ("busy", "imu late", "stream ended", "unreadable")


@dataclass
class Waiting:
    """A frame in the queue: the loop's item, its stamp and arrival, when it became ready."""

    item: Any
    t_s: float
    arrival_s: float
    ready_s: float | None = None
    ready_while_busy: bool = False


class FrameQueue:
    """Frames in arrival order (module docstring). ``imu_wait_s``: how long a frame may wait
    for its IMU sample; ``needs_imu``: False when the camera has no IMU."""

    def __init__(self, imu_wait_s: float, needs_imu: bool = True) -> None:
        self.imu_wait_s, self.needs_imu = imu_wait_s, needs_imu
        self.waiting: deque[Waiting] = deque()
        self.imu_until_s = -math.inf
        self.skips: dict[str, int] = dict.fromkeys(SKIP_REASONS, 0)
        self.skipped: list[tuple[float, str]] = []  #: (frame time s, reason)
        self.n_arrived = 0

    # ------------------------------------------------------------------ bookkeeping
    def frame(self, item: Any, t_s: float, arrival_s: float) -> None:
        self.n_arrived += 1
        self.waiting.append(Waiting(item, t_s, arrival_s))

    def unreadable(self, t_s: float) -> None:
        """A frame arrived that could not be decoded."""
        self.n_arrived += 1
        self.skips["unreadable"] += 1
        self.skipped.append((t_s, "unreadable"))

    def imu(self, last_t_s: float) -> None:
        """IMU samples up to ``last_t_s`` have arrived."""
        self.imu_until_s = max(self.imu_until_s, last_t_s)

    def _skip(self, w: Waiting, reason: str) -> None:
        self.skips[reason] += 1
        self.skipped.append((w.t_s, reason))

    def update(self, now_s: float, *, busy: bool) -> None:
        """Mark the frames that became ready (``busy``: the estimator was processing since the
        last update) and skip those whose IMU wait ran out."""
        kept: deque[Waiting] = deque()
        for w in self.waiting:
            if w.ready_s is None and (not self.needs_imu or self.imu_until_s >= w.t_s):
                w.ready_s, w.ready_while_busy = now_s, busy
            if w.ready_s is None and now_s - w.arrival_s > self.imu_wait_s:
                self._skip(w, "imu late")
            else:
                kept.append(w)
        self.waiting = kept

    # ------------------------------------------------------------------ the estimator's side
    def take(self) -> Waiting | None:
        """The frame the free estimator processes now (None: none ready)."""
        n_ready = 0
        for w in self.waiting:  # ready frames come first (IMU coverage grows with time)
            if w.ready_s is None:
                break
            n_ready += 1
        if n_ready == 0:
            return None
        if n_ready > 1 and self.waiting[n_ready - 1].ready_while_busy:
            for _ in range(n_ready - 1):
                self._skip(self.waiting.popleft(), "busy")
        return self.waiting.popleft()

    def deadline_s(self) -> float | None:
        """When the oldest frame not yet ready runs out of IMU wait (None: none waits)."""
        for w in self.waiting:
            if w.ready_s is None:
                return w.arrival_s + self.imu_wait_s
        return None

    def end(self) -> None:
        """The streams ended: the frames not ready will never be (skipped, ``stream ended``)."""
        for w in [w for w in self.waiting if w.ready_s is None]:
            self._skip(w, "stream ended")
        self.waiting = deque(w for w in self.waiting if w.ready_s is not None)

    @property
    def n_skipped(self) -> int:
        return sum(self.skips.values())
