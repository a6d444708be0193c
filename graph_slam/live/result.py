"""What a live run did (:class:`LiveResult`) and where its time went (:class:`Timing`): the
figures ``graph-slam live`` prints and writes as ``live.json``."""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def _floats() -> array:
    return array("d")


@dataclass
class Timing:
    """Where a live run's time went, per processed frame (``*_cpu_s``: CPU time of the
    estimator's thread, ``time.thread_time``; the rest wall time from the frame's arrival).
    Kept as packed arrays (8 bytes a value: 20 MB an hour at 90 Hz)."""

    wait_s: array = field(default_factory=_floats)  #: arrival → the estimator starts it
    ready_s: array = field(default_factory=_floats)  #: arrival → ready (its IMU arrived)
    feed_cpu_s: array = field(default_factory=_floats)  #: IMU, joints, events given
    pipeline_cpu_s: array = field(default_factory=_floats)  #: ``add_frame``
    after_cpu_s: array = field(default_factory=_floats)  #: writer hand-off, viewer
    since_start_s: array = field(default_factory=_floats)  #: when its pose came
    book_cpu_s: float = 0.0  #: booking arrivals and the skip rule, the whole run
    prepare_cpu_s: array = field(default_factory=_floats)  #: per arrived frame, preparing
    prepare_color: array = field(default_factory=lambda: array("b"))  #: ... with colour
    ahead_cpu_s: array = field(default_factory=_floats)  #: ... the pipeline's part, ahead

    def frame(self, **values: float) -> None:
        for key, value in values.items():
            getattr(self, key).append(value)

    def summary(self) -> dict[str, object]:
        """Medians and 95th percentiles in ms (the status and the run's ``live.json``)."""

        def stats(values) -> dict[str, float | None]:
            v = np.asarray(values, dtype=float) * 1e3
            if not v.size:
                return {"median_ms": None, "p95_ms": None}
            return {"median_ms": round(float(np.median(v)), 3),
                    "p95_ms": round(float(np.percentile(v, 95)), 3)}  # fmt: skip

        color = np.asarray(self.prepare_color, dtype=bool)
        prep = np.asarray(self.prepare_cpu_s, dtype=float)
        n = max(len(self.wait_s), 1)
        return {
            "estimator_thread_cpu": {
                "feed": stats(self.feed_cpu_s), "pipeline": stats(self.pipeline_cpu_s),
                "after": stats(self.after_cpu_s),
                "booking_per_frame_ms": round(1e3 * self.book_cpu_s / n, 3),
            },
            "preparing_thread_cpu": {"with_colour": stats(prep[color]),
                                     "depth_only": stats(prep[~color]),
                                     "pipeline_ahead": stats(self.ahead_cpu_s)},
            "wait_for_imu": stats(self.ready_s), "wait_to_start": stats(self.wait_s),
            "processed_in_first_second": int(np.sum(np.asarray(self.since_start_s) <= 1.0)),
        }  # fmt: skip


@dataclass
class LiveResult:
    """What a live run did: the pipeline's results, timing, counts, why it stopped."""

    results: object
    latency_s: np.ndarray
    n_arrived: int
    skipped: int
    stop_reason: str
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    session: Path | None = None
    outputs: Path | None = None
    timing: Timing = field(default_factory=Timing)
    warm_up_s: float = 0.0

    @property
    def n_processed(self) -> int:
        return int(self.latency_s.size)

    def summary(self) -> dict[str, object]:
        """The run's figures (written as ``live.json``; the CLI's last lines)."""
        lat = self.latency_s * 1e3
        return {
            "stop_reason": self.stop_reason,
            "frames": {"arrived": self.n_arrived, "processed": self.n_processed,
                       "skipped": self.skipped,
                       "skipped_percent": round(100.0 * self.skipped / max(self.n_arrived, 1), 2),
                       "skipped_by_reason": dict(self.counts.get("skipped", {}))},
            "latency_ms": {"median": round(float(np.median(lat)), 3) if lat.size else None,
                           "p95": round(float(np.percentile(lat, 95)), 3) if lat.size else None},
            "warm_up_s": round(self.warm_up_s, 3),
            "timing": self.timing.summary(),
            "counts": self.counts,
        }  # fmt: skip
