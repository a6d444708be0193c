"""The process's memory during a real-time loop: resident memory sampled at session times
(:class:`RssSample`) and CPython's heap frozen for the loop (:func:`frozen_heap`)."""

from __future__ import annotations

import contextlib
import gc
import resource
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

RSS_MARKS_S: tuple[float, ...] = (60.0, 300.0, 600.0)
"""Session times (s after the first frame) at which the resident memory is sampled."""


@dataclass(frozen=True)
class RssSample:
    """Resident memory at a moment of the replay."""

    session_s: float
    """Session time since the first frame."""
    rss_mb: float
    peak_mb: float


def rss_mb() -> float:
    """The process's resident memory now (MB; Linux ``/proc``, else the peak)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return peak_rss_mb()
    return pages * resource.getpagesize() / 1e6


def peak_rss_mb() -> float:
    """The process's peak resident memory so far (MB; ``ru_maxrss``)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 1e6 if sys.platform == "darwin" else peak / 1e3  # bytes on macOS, else KiB


@contextlib.contextmanager
def frozen_heap(enabled: bool = True) -> Iterator[None]:
    """CPython's garbage collector with the heap built so far frozen (``gc.freeze``), for a
    real-time loop; unfrozen on exit.

    With GTSAM, Open3D, numba and scipy loaded the process holds ~170k tracked objects, and
    every full (generation 2) collection walks all of them: 60–100 ms, measured on the
    424×240 replays, during which 5–9 frames arrive (the normal session skipped 9 with
    one). Frozen, a full
    collection walks only the objects made since. A controller running a pipeline does the
    same once it is built: ``gc.collect(); gc.freeze()`` before the walk.
    """
    if not enabled:
        yield
        return
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
