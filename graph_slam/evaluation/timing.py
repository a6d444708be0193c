"""Per-frame processing time: median and 95th percentile."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from graph_slam.errors import EvaluationError


@dataclass(frozen=True)
class TimingStats:
    """Seconds per frame; ``p95_s`` is numpy's linear-interpolated 95th percentile."""

    n: int
    median_s: float
    p95_s: float
    mean_s: float
    max_s: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def timing_stats(durations_s: np.ndarray) -> TimingStats:
    """Statistics of per-frame durations (seconds, finite, >= 0)."""
    d = np.asarray(durations_s, dtype=np.float64).reshape(-1)
    if d.size == 0:
        raise EvaluationError("timing_stats: no durations given")
    if not np.isfinite(d).all() or (d < 0).any():
        raise EvaluationError("timing_stats: durations must be finite and >= 0")
    return TimingStats(
        n=int(d.size),
        median_s=float(np.median(d)),
        p95_s=float(np.percentile(d, 95)),
        mean_s=float(d.mean()),
        max_s=float(d.max()),
    )
