"""A frame's per-stage wall time (``FrameOutput.stages_s``), timed by one context manager.

    timer = StageTimer()
    with timer("graph"):
        est = slam.add_frame(...)
    timer.stages_s  # {"graph": 0.0021}

A block adds its time to its stage; a stage timed inside another counts in both (``terrain``
holds ``terrain_online``). A block whose work turned out to be nothing sets ``lap.keep =
False`` and records no time (a stage that did not happen at this frame has no key).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


@dataclass
class Lap:
    """One timed block: ``keep`` False leaves its stage out."""

    keep: bool = True


class StageTimer:
    """Per-stage wall time of one frame (module docstring)."""

    def __init__(self) -> None:
        self.stages_s: dict[str, float] = {}

    @contextmanager
    def __call__(self, stage: str) -> Iterator[Lap]:
        lap = Lap()
        t0 = time.perf_counter()
        try:
            yield lap
        finally:
            if lap.keep:
                self.add(stage, time.perf_counter() - t0)

    def add(self, stage: str, seconds: float) -> None:
        self.stages_s[stage] = self.stages_s.get(stage, 0.0) + seconds

    def exclude(self, stage: str, inner: str) -> None:
        """``stage`` less the time of ``inner``, which was timed inside it as a stage of its
        own (the frame's cloud inside its preparation, a stride's smoothing inside the floor
        fit's block)."""
        self.stages_s[stage] -= self.get(inner)

    def get(self, stage: str) -> float:
        return self.stages_s.get(stage, 0.0)

    @property
    def total_s(self) -> float:
        """The stages so far, added up (before any nested one)."""
        return float(sum(self.stages_s.values()))
