"""The phase within a stride re-timed by the thigh's own motion, causal.

A phase linear in time from the last strike over the recent stride time cannot follow a stride
that is longer or shorter than the last ones (a turn, a change of pace). The thigh says where
in the stride it is: it extends from the strike to its largest extension (the end of stance)
and then flexes through mid-swing to its flexion peak before the next strike. Swing lasts
nearly the same from stride to stride while stance stretches or shortens (slower walking,
turn steps), so the time from these landmarks to the next strike is better known than the
stride's length.

:class:`ThighAnglePhase` keeps the phase ``d / (d + r)``: ``d`` the time since the last strike,
``r`` the time still to come before the next one:

* **stance** (before the largest extension is confirmed) — ``r`` is the predicted stride minus
  ``d``, but at least the time the last strides took from their largest extension to the
  strike, less the time since the lowest angle so far (the swing is still to come: a stance
  that lasts longer than predicted holds the phase back);
* **after the largest extension** (confirmed once the angle, having extended past the middle
  of the last stride's range, rose ``rise_fraction`` of that range above its running minimum:
  the wobble of the thigh at contact is not the swing) — ``r`` is the last strides' time from the largest
  extension to the strike, less the time since it;
* **after mid-swing** (the angle rising through the middle of the last stride's range, where
  it moves fastest and its timing is sharpest) — ``r`` the last strides' time from mid-swing to
  the strike, less the time since it.

The landmarks' times to the strike are medians over the last ``calibration_strides`` strides
(a stride whose angle range is below ``min_range_rad``, a turn's pivot or a shuffle, gives
none). The phase is kept monotone within a stride (its running maximum) and below 1 until the
next strike. This is a phase variable in the sense of the prosthesis-control literature (the
thigh's motion, normalised per stride by its own running extrema, tells the progress through
the stride: Villarreal & Gregg; Quintero et al.), used here to re-time the stride rather than
as a polar angle of the phase portrait, which winds back and forth about the flexion peak right
at the strike (docs/kinematics.md, "The phase within a stride from the thigh's motion").
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AnglePhaseConfig:
    """The thigh-landmark phase (:class:`ThighAnglePhase`)."""

    rise_fraction: float = 0.15
    """The largest extension is confirmed once the angle rose this share of the last stride's
    range above its running minimum (a stance wobble is not the swing)."""
    calibration_strides: int = 3
    """The landmarks' times to the strike are medians over this many recent strides."""
    min_range_rad: float = math.radians(10.0)
    """A stride whose angle range is smaller gives no calibration."""
    max_stride_s: float = 2.5
    """Strikes further apart are different walks (no stride between them)."""
    max_sample_gap_s: float = 0.1
    """A stride with a longer gap between its samples (the walk stopped, the lock was lost)
    gives no calibration."""


class ThighAnglePhase:
    """Causal phase from the time since the strike and the thigh's landmarks (module docstring)."""

    def __init__(self, config: AnglePhaseConfig | None = None) -> None:
        self.cfg = config or AnglePhaseConfig()
        self._samples: deque[tuple[float, float]] = deque()
        self._strike_s: float | None = None
        n = self.cfg.calibration_strides
        self._from_ext: deque[float] = deque(maxlen=n)  # largest extension -> strike, s
        self._from_mid: deque[float] = deque(maxlen=n)  # mid-swing -> strike, s
        self._range: tuple[float, float] | None = None  # last stride's (min, max) angle
        self._low = (math.inf, math.nan)  # running minimum since the strike (angle, t_s)
        self._ext_s = math.nan  # the largest extension's time, once confirmed
        self._mid_s = math.nan  # mid-swing's time, once passed
        self._out = 0.0

    def strike(self, t_s: float) -> None:
        """A foot strike at ``t_s`` (emitted now, possibly a few samples later): the stride
        that ends there calibrates the landmarks; a new one starts."""
        if self._strike_s is not None and 0.0 < t_s - self._strike_s <= self.cfg.max_stride_s:
            self._calibrate(self._strike_s, t_s)
        self._strike_s = t_s
        self._low, self._ext_s, self._mid_s, self._out = (
            (math.inf, math.nan),
            math.nan,
            math.nan,
            0.0,
        )
        for t, a in self._samples:
            if t >= t_s:
                self._track(t, a)

    @property
    def calibrated(self) -> bool:
        """The landmarks' times to the strike are known (from this wearer's strides)."""
        return bool(self._from_ext)

    def update(self, t_s: float, angle_rad: float, stride_s: float) -> float:
        """The phase at ``t_s``; ``stride_s``: the stride time predicted from past strides."""
        if math.isfinite(angle_rad):
            self._samples.append((t_s, angle_rad))
            if self._strike_s is not None and t_s >= self._strike_s:
                self._track(t_s, angle_rad)
        while self._samples and self._samples[0][0] < t_s - 2 * self.cfg.max_stride_s:
            self._samples.popleft()
        if self._strike_s is None:
            return math.nan
        d = max(t_s - self._strike_s, 0.0)
        rest = max(stride_s - d, 0.0)
        if math.isfinite(self._mid_s) and self._from_mid:
            rest = float(np.median(self._from_mid)) - (t_s - self._mid_s)
        elif math.isfinite(self._ext_s) and self._from_ext:
            rest = float(np.median(self._from_ext)) - (t_s - self._ext_s)
        elif self._from_ext:  # the swing is still to come after the lowest angle so far
            since_low = t_s - self._low[1] if math.isfinite(self._low[1]) else 0.0
            rest = max(rest, float(np.median(self._from_ext)) - since_low)
        phase = d / (d + rest) if rest > 0.0 else 0.999
        self._out = min(max(self._out, phase), 0.999)
        return self._out

    # --- inside ------------------------------------------------------------------------------
    def _track(self, t_s: float, angle: float) -> None:
        if self._range is None:
            return
        lo, hi = self._range
        if not math.isfinite(self._ext_s):
            if angle < self._low[0]:
                self._low = (angle, t_s)
            extended = self._low[0] < 0.5 * (lo + hi)  # past the middle: not a contact wobble
            if extended and angle - self._low[0] > self.cfg.rise_fraction * (hi - lo):
                self._ext_s = self._low[1]
        passed_mid = angle >= 0.5 * (self._low[0] + hi)
        if math.isfinite(self._ext_s) and not math.isfinite(self._mid_s) and passed_mid:
            self._mid_s = t_s

    def _calibrate(self, t0: float, t1: float) -> None:
        seg = [(t, a) for t, a in self._samples if t0 <= t <= t1]
        if len(seg) < 5:
            return
        t = np.array([s[0] for s in seg])
        a = np.array([s[1] for s in seg])
        if np.max(np.diff(np.concatenate([[t0], t, [t1]]))) > self.cfg.max_sample_gap_s:
            return  # samples missing (a stop in between): not a stride to learn from
        k_lo = int(np.argmin(a))
        k_hi = k_lo + int(np.argmax(a[k_lo:]))
        lo, hi = float(a[k_lo]), float(a[k_hi])
        if hi - lo < self.cfg.min_range_rad:
            return
        k_mid = k_lo + int(np.argmax(a[k_lo : k_hi + 1] >= 0.5 * (lo + hi)))
        self._range = (lo, hi)
        self._from_ext.append(float(t1 - t[k_lo]))
        self._from_mid.append(float(t1 - t[k_mid]))
