"""The causal replay's clocks: ``virtual`` (session time that only the estimator's work
advances, by a ``compute_cost``) and ``wall`` (the real clock); :func:`clock_cost` picks the
virtual clock's cost for a config (docs/pipelines.md, "Causal replay")."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Literal

from graph_slam.errors import ConfigError

Pace = Literal["virtual", "wall"]
PACES: tuple[str, ...] = ("virtual", "wall")

ComputeCost = Callable[[int, float], float]
"""``(session frame index, measured seconds) -> seconds on the virtual clock``."""

MEASURED = "measured"
"""``compute_cost`` that advances the virtual clock by the measured time (a timing study)."""


def no_cost(_frame_index: int, _measured_s: float) -> float:
    """The deterministic virtual clock's cost: none (every frame is taken when it arrives)."""
    return 0.0


def clock_cost(compute_cost: ComputeCost | str | None, deterministic: bool) -> ComputeCost | None:
    """The virtual clock's cost function (None: as measured) for ``replay_session``'s
    ``compute_cost`` and the config's ``deterministic``."""
    if compute_cost == MEASURED:
        return None
    if isinstance(compute_cost, str):
        raise ConfigError(f"compute_cost {compute_cost!r}: a function or {MEASURED!r}")
    if compute_cost is None:
        return no_cost if deterministic else None
    return compute_cost


class _VirtualClock:
    """Session time that only the estimator's measured work advances."""

    def __init__(self, t0_s: float, cost: ComputeCost | None) -> None:
        self.now_s = t0_s
        self._cost = cost

    def now(self) -> float:
        return self.now_s

    def wait_until(self, t_s: float) -> None:
        self.now_s = max(self.now_s, t_s)

    def spent(self, frame_index: int, measured_s: float) -> None:
        self.now_s += measured_s if self._cost is None else self._cost(frame_index, measured_s)

    def pause(self, _measured_s: float) -> None:
        pass


class _WallClock:
    """Session time on the real clock: ``t0_s`` now, then as the wall clock runs."""

    def __init__(self, t0_s: float) -> None:
        self._origin = time.perf_counter() - t0_s

    def now(self) -> float:
        return time.perf_counter() - self._origin

    def wait_until(self, t_s: float) -> None:
        delay = t_s - self.now()
        if delay > 0:
            time.sleep(delay)

    def spent(self, _frame_index: int, _measured_s: float) -> None:
        pass

    def pause(self, measured_s: float) -> None:
        self._origin += measured_s  # the session's clock stood still meanwhile
