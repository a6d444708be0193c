"""What :func:`graph_slam.pipelines.replay.replay_session` returns: the pipeline's results
and the timing of every processed frame on the replay's clock."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graph_slam.pipelines.memory import RssSample
from graph_slam.pipelines.results import PipelineResults


@dataclass(frozen=True)
class ProcessedFrame:
    """One processed frame on the replay's clock (session time, s)."""

    session_index: int
    t_s: float
    arrival_s: float
    start_s: float
    """When the estimator took it (before the buffered samples were delivered)."""
    finish_s: float
    compute_s: float
    """Wall time of ``add_frame``."""
    cpu_s: float
    """Process CPU time of ``add_frame`` (every thread)."""
    feed_s: float
    """Wall time delivering the buffered samples and foot strikes before it."""
    stages_s: dict[str, float] = field(default_factory=dict)
    """The pipeline's per-stage times (:attr:`FrameOutput.stages_s`)."""

    @property
    def latency_s(self) -> float:
        return self.finish_s - self.arrival_s


@dataclass(eq=False)
class ReplayResult:
    """What :func:`replay_session` produced: the pipeline's results over the processed frames
    (``results.frames[k]`` is ``frames[k]``) and the timing of each."""

    pace: str
    results: PipelineResults
    frames: list[ProcessedFrame]
    skipped: np.ndarray
    """Session indices of the frames skipped by the policy."""
    n_delivered: int
    duration_s: float
    """Session time from the first to the last delivered frame."""
    finish_call_s: float
    """Wall time of the pipeline's ``finish`` (closing the last stride)."""
    rss: list[RssSample]

    @property
    def n_processed(self) -> int:
        return len(self.frames)

    @property
    def n_skipped(self) -> int:
        return int(self.skipped.size)

    @property
    def session_indices(self) -> np.ndarray:
        return np.array([f.session_index for f in self.frames], dtype=int)

    @property
    def latency_s(self) -> np.ndarray:
        return np.array([f.latency_s for f in self.frames])

    @property
    def compute_s(self) -> np.ndarray:
        return np.array([f.compute_s for f in self.frames])

    @property
    def cpu_s(self) -> np.ndarray:
        return np.array([f.cpu_s for f in self.frames])

    @property
    def delivered_rate_hz(self) -> float:
        return (self.n_delivered - 1) / self.duration_s if self.duration_s > 0 else float("nan")

    @property
    def achieved_rate_hz(self) -> float:
        """Processed frames per second of session time (the delivered rate when none is
        skipped)."""
        if self.duration_s <= 0:
            return float("nan")
        return self.delivered_rate_hz * self.n_processed / self.n_delivered

    @property
    def peak_rss_mb(self) -> float:
        return max((s.peak_mb for s in self.rss), default=float("nan"))

    def stage_s(self, name: str) -> np.ndarray:
        """The stage's time on every processed frame where it ran."""
        return np.array([f.stages_s[name] for f in self.frames if name in f.stages_s])
