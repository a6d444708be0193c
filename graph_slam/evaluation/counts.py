"""Frames recorded, registered and bridged (thesis Table 4.2's counts, plus bridging)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class FrameCounts:
    """How a stride's frames fared.

    ``recorded``: frames in the stride (what the camera delivered, after drops);
    ``registered``: frames whose pose came from an accepted registration that held all six
    directions; ``partial``: frames whose registration held only some (a factor on those
    directions; e.g. a plain floor: height, roll, pitch), the rest bridged; ``bridged``: frames
    whose pose was carried over a failed or rejected registration by other factors (IMU,
    kinematics) instead; ``other``: every remaining frame (no pose, first frame...).
    ``other`` is what is left after ``registered``, ``bridged`` and ``partial``.
    """

    recorded: int
    registered: int
    bridged: int
    other: int
    partial: int = 0

    def to_dict(self) -> dict[str, int]:
        return asdict(self)


def frame_counts(
    statuses: Sequence[str],
    *,
    registered: Iterable[str] = ("registered",),
    bridged: Iterable[str] = ("bridged",),
    partial: Iterable[str] = ("partial",),
) -> FrameCounts:
    """Count per-frame status strings; which strings mean registered, partial and bridged is
    stated."""
    tally = Counter(statuses)
    n_registered = sum(tally[s] for s in set(registered))
    n_bridged = sum(tally[s] for s in set(bridged))
    n_partial = sum(tally[s] for s in set(partial))
    return FrameCounts(
        recorded=len(statuses),
        registered=n_registered,
        bridged=n_bridged,
        other=len(statuses) - n_registered - n_bridged - n_partial,
        partial=n_partial,
    )
