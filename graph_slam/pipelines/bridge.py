"""Flag the frames whose pose rests on the IMU alone since the stride's anchor.

A stride's graph starts from the kinematic anchor at the foot strike; its first accepted
registration ties the camera to the scene. Until then a frame's pose is the IMU preintegrated
from the anchor with the velocity the previous stride left, which is only as good as that
stride's registrations. When frames are sparse (an estimator too slow for the camera skips
most of them) every registration of a stride can fail (no overlap across the gap), and the
IMU-only pose drifts by metres within half a second on a 3-stride level walk
(docs/reliability.md). Such a frame is flagged ``imu_only:<seconds>s`` once it is more than
:data:`MAX_UNREGISTERED_S` after the anchor, so that no consumer takes it for a registered
pose. A frame registered later in the stride, or a bridge after an accepted registration (a
swing without ICP), is not flagged.
"""

from __future__ import annotations

MAX_UNREGISTERED_S = 0.1
"""Seconds after a stride's anchor without any accepted registration before frames are
flagged (9 frames at 90 Hz; at full rate a stride's first frames register)."""


class UnregisteredStride:
    """Per frame: the ``imu_only`` flag while the open stride has no accepted registration."""

    def __init__(self, max_s: float = MAX_UNREGISTERED_S) -> None:
        self.max_s = float(max_s)
        self._anchor_t_s: float | None = None
        self._registered = False

    def frame(self, t_s: float, stride_start: bool, accepted: bool) -> tuple[str, ...]:
        """The flags of a frame at ``t_s``: ``stride_start`` (the anchor's frame),
        ``accepted`` (its registration became a factor)."""
        if stride_start:
            self._anchor_t_s, self._registered = float(t_s), False
            return ()
        self._registered = self._registered or accepted
        if self._registered or self._anchor_t_s is None:
            return ()
        gap_s = float(t_s) - self._anchor_t_s
        return (f"imu_only:{gap_s:.2f}s",) if gap_s > self.max_s else ()
