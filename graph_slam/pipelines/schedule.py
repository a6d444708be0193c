"""The replay's skip policy as pure functions: which frame an estimator that is one worker
takes when it becomes free (the newest that has arrived; the older waiting ones are skipped),
and that rule applied to a timing trace. No clock, no pipeline: tested on hand-made traces."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import EstimationError


def pick_frame(arrival_s: np.ndarray, next_index: int, free_at_s: float) -> tuple[int, float]:
    """The skip policy: which frame the estimator takes when it becomes free.

    ``arrival_s``: every frame's arrival time (non-decreasing); ``next_index``: the first frame
    not yet handled; ``free_at_s``: when the estimator is free. Returns ``(index, start_s)``:
    the newest frame that has arrived by ``free_at_s``, started then (the frames
    ``next_index..index-1`` are skipped); if none has arrived, the next one, started at its
    arrival (nothing skipped).
    """
    if not 0 <= next_index < arrival_s.size:
        raise IndexError(f"next_index {next_index} outside 0..{arrival_s.size - 1}")
    if arrival_s[next_index] > free_at_s:
        return next_index, float(arrival_s[next_index])
    newest = int(np.searchsorted(arrival_s, free_at_s, side="right")) - 1
    return max(newest, next_index), float(free_at_s)


@dataclass(frozen=True)
class Schedule:
    """The policy applied to a timing trace: which frames were processed, when."""

    processed: np.ndarray
    """Indices of the processed frames."""
    skipped: np.ndarray
    """Indices of the skipped frames."""
    start_s: np.ndarray
    finish_s: np.ndarray
    latency_s: np.ndarray
    """finish − arrival of each processed frame."""


def schedule(arrival_s: Sequence[float], compute_s: Sequence[float]) -> Schedule:
    """Apply :func:`pick_frame` to a trace: ``compute_s[i]`` is how long frame ``i`` takes if
    it is processed (the replay measures it as it goes; this is its pure core, for tests and
    what-if questions such as "at twice the compute time")."""
    arrival = np.asarray(arrival_s, float)
    compute = np.asarray(compute_s, float)
    if arrival.shape != compute.shape or arrival.ndim != 1:
        raise EstimationError(
            "schedule: arrival_s and compute_s must be 1-D and of the same length"
        )
    if np.any(np.diff(arrival) < 0):
        raise EstimationError("schedule: arrival_s must be non-decreasing")
    processed, skipped, start, finish = [], [], [], []
    i, free_at = 0, -np.inf
    while i < arrival.size:
        j, t0 = pick_frame(arrival, i, free_at)
        skipped.extend(range(i, j))
        free_at = t0 + compute[j]
        processed.append(j)
        start.append(t0)
        finish.append(free_at)
        i = j + 1
    p = np.array(processed, dtype=int)
    return Schedule(
        processed=p,
        skipped=np.array(skipped, dtype=int),
        start_s=np.array(start),
        finish_s=np.array(finish),
        latency_s=np.array(finish) - arrival[p] if p.size else np.zeros(0),
    )


def subset_cost(arrival_s: Sequence[float], keep: Sequence[int]):
    """A ``compute_cost`` for ``replay_session``'s virtual clock under which the replay
    processes exactly the frames ``keep`` (indices from 0, the first frame; the
    session's last frame is always processed): each kept frame's work ends between the
    arrival of the next kept frame and the one after it, so :func:`pick_frame` takes that
    frame and skips the ones between. A deterministic stand-in for an estimator too slow for
    the camera (a sparse-frame test)."""
    arrival = np.asarray(arrival_s, float)
    kept = np.unique(np.asarray(keep, int))
    if kept.size == 0 or kept[0] != 0 or kept[-1] >= arrival.size:
        raise EstimationError(
            f"subset_cost: keep must start at frame 0 and index 0..{arrival.size - 1}"
        )
    following = dict(zip(kept[:-1].tolist(), kept[1:].tolist(), strict=True))
    state = {"start_s": float(arrival[kept[0]])}

    def cost(frame_index: int, _measured_s: float) -> float:
        k = following.get(int(frame_index))
        if k is None:  # the last kept frame: the rest is skipped up to the session's last
            return float(arrival[-1] - state["start_s"]) + 1.0
        after = arrival[k + 1] if k + 1 < arrival.size else arrival[k] + 1.0
        finish = float(arrival[k] + 0.5 * (after - arrival[k]))
        spent, state["start_s"] = finish - state["start_s"], finish
        return spent

    return cost
