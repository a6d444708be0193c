"""The gait events that cut strides and set the foot-loaded state, from one source
(``events.csv``, or the thigh IMU's causal estimator: :mod:`graph_slam.strides.online_events`),
with when each became known; :func:`stride_events` picks them from ``events.csv`` by the one
rule."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StrideEvents:
    """The gait events that cut strides and set the foot-loaded state, from one source.

    ``source``: the ``events.csv`` source they came from (None: every source in the file), or
    ``imu-online`` (:mod:`graph_slam.strides.online_events`). ``*_known_s``: when each event
    became known (an online estimator emits an event after it happened); None: at its time.
    """

    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    source: str | None = None
    foot_strikes_known_s: np.ndarray | None = None
    toe_offs_known_s: np.ndarray | None = None

    @property
    def strikes_known_s(self) -> np.ndarray:
        """When each foot strike is known (announce it then, with its time)."""
        known = self.foot_strikes_known_s
        return self.foot_strikes_s if known is None else known

    @property
    def toe_offs_known_by_s(self) -> np.ndarray:
        known = self.toe_offs_known_s
        return self.toe_offs_s if known is None else known

    def known_at(self, t_s: float) -> StrideEvents:
        """The events known at ``t_s`` (a causal view)."""
        fs = self.strikes_known_s <= t_s
        to = self.toe_offs_known_by_s <= t_s
        return StrideEvents(
            self.foot_strikes_s[fs],
            self.toe_offs_s[to],
            self.source,
            self.strikes_known_s[fs],
            self.toe_offs_known_by_s[to],
        )

    def foot_loaded(self, t_s: float) -> bool:
        """Loaded between a foot strike and the next toe-off, from the events known at ``t_s``
        (reads no event after ``t_s``, nor one not yet known then)."""
        known = self.known_at(t_s)
        strikes = known.foot_strikes_s[known.foot_strikes_s <= t_s]
        if strikes.size == 0:
            return False
        offs = known.toe_offs_s[(known.toe_offs_s > strikes[-1]) & (known.toe_offs_s <= t_s)]
        return offs.size == 0

    def next_strike_after(self, t_s: float) -> float | None:
        after = self.foot_strikes_s[self.foot_strikes_s > t_s]
        return float(after[0]) if after.size else None

    def last_strike_at_or_before(self, t_s: float) -> float | None:
        before = self.foot_strikes_s[self.foot_strikes_s <= t_s]
        return float(before[-1]) if before.size else None

    def toe_off_between(self, t0_s: float, t1_s: float) -> float | None:
        toe = self.toe_offs_s[(self.toe_offs_s > t0_s) & (self.toe_offs_s < t1_s)]
        return float(toe[0]) if toe.size else None


def stride_events(events, source: str | None, where: str = "events.csv") -> StrideEvents:
    """The events that cut strides: those of ``source`` (None: every source), by the one rule
    :meth:`graph_slam.session.records.GaitEvents.of_source`. ``events`` None: no strides."""
    if events is None or not len(events):
        return StrideEvents(np.zeros(0), np.zeros(0), source)
    picked = events.of_source(source, where)
    return StrideEvents(np.sort(picked.foot_strikes_s), np.sort(picked.toe_offs_s), source)
