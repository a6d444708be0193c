"""A prosthesis's own sensors in the online gait estimator: the load cell defines the events,
the knee encoder and the load cell check the thigh IMU's flexion sign.

* :class:`LoadCellEvents`: a causal hysteresis comparator on the axial load (compression +,
  tared: about 0 N in swing): a foot strike when the load rises through ``load_on_n``, a toe-off
  when it falls through ``load_off_n`` (interpolated); a transition within ``min_state_s`` of the
  previous one is chatter (dropped, counted). The load cell is *alive* while finite samples keep
  coming (none missing for ``lost_after_s``); the estimator then emits its events and takes the
  thigh IMU's strike bias from them (:meth:`kinematics.gait_phase_impact.StrikeTiming.reference`),
  and keeps that bias when the load cell is lost.
* :class:`ProsthesisSign`: with the foot loaded the thigh extends (the body passes over the
  foot), unloaded it flexes (swing); with the knee flexed past ``knee_swing_rad`` it is in
  swing. So the mean flexion rate unloaded (or knee flexed) minus loaded (or knee straight) is
  positive when the IMU's flexion axis is right, whatever the shape of the thigh curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ProsthesisConfig:
    load_on_n: float = 150.0
    load_off_n: float = 60.0
    min_state_s: float = 0.15
    lost_after_s: float = 0.5
    knee_swing_rad: float = math.radians(20.0)
    min_evidence_s: float = 1.0
    """Time in each state (loaded/unloaded, or knee straight/flexed) before the sign is judged."""


class LoadCellEvents:
    """Causal load-cell events (see the module docstring)."""

    def __init__(self, config: ProsthesisConfig | None = None) -> None:
        self.cfg = config or ProsthesisConfig()
        self.contact: bool | None = None
        self._last: tuple[float, float] | None = None
        self._last_transition_s = -math.inf
        self._last_finite_s = -math.inf
        self.chatter = 0

    def alive(self, t_s: float) -> bool:
        return t_s - self._last_finite_s <= self.cfg.lost_after_s

    def update(self, t_s: float, load_n: float | None) -> tuple[str, float] | None:
        """One sample; (kind, time) of an event at it, else None."""
        if load_n is None or not math.isfinite(load_n):
            return None
        self._last_finite_s = t_s
        prev, self._last = self._last, (t_s, float(load_n))
        if self.contact is None:
            self.contact = load_n >= self.cfg.load_on_n
            return None
        level, kind = (
            (self.cfg.load_off_n, "toe_off")
            if self.contact
            else (self.cfg.load_on_n, "foot_strike")
        )
        crossed = load_n <= level if self.contact else load_n >= level
        if not crossed:
            return None
        t0, f0 = prev if prev is not None else (t_s, load_n)
        frac = (level - f0) / (load_n - f0) if load_n != f0 else 1.0
        t_event = t0 + min(max(frac, 0.0), 1.0) * (t_s - t0)
        self.contact = not self.contact
        if t_event - self._last_transition_s < self.cfg.min_state_s:
            self.chatter += 1
            self._last_transition_s = t_event
            return None
        self._last_transition_s = t_event
        return kind, t_event


class ProsthesisSign:
    """Flexion-rate sums per state from the load cell or the knee (see the module docstring)."""

    def __init__(self, config: ProsthesisConfig | None = None) -> None:
        self.cfg = config or ProsthesisConfig()
        self._sums = {True: [0.0, 0.0], False: [0.0, 0.0]}  # swing?: [rate·dt, dt]

    def add(self, rate_rad_s: float, dt: float, contact: bool | None, knee_rad: float | None):
        if dt <= 0:
            return
        if contact is not None:
            swing = not contact
        elif knee_rad is not None and math.isfinite(knee_rad):
            swing = knee_rad > self.cfg.knee_swing_rad
        else:
            return
        self._sums[swing][0] += rate_rad_s * dt
        self._sums[swing][1] += dt

    def evidence(self) -> float:
        """Mean rate in swing minus in stance (rad/s); nan until both states were seen long
        enough."""
        (s_sum, s_t), (c_sum, c_t) = self._sums[True], self._sums[False]
        if min(s_t, c_t) < self.cfg.min_evidence_s:
            return math.nan
        return s_sum / s_t - c_sum / c_t

    def reset(self) -> None:
        self._sums = {True: [0.0, 0.0], False: [0.0, 0.0]}
