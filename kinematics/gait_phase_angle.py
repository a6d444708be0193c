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
  the wobble of the thigh at contact is not the swing) — ``r`` is the last strides' time from
  the largest extension to the strike, less the time since it;
* **after mid-swing** (the angle rising through the middle of the last stride's range, where
  it moves fastest and its timing is sharpest) — ``r`` the last strides' time from mid-swing to
  the strike, less the time since it.

The landmarks' times to the strike are medians over the last ``calibration_strides`` strides
(a stride whose angle range is below ``min_range_rad``, a turn's pivot or a shuffle, gives
none). The phase is kept monotone within a stride (its running maximum) and below 1 until the
next strike. ``AnglePhaseConfig(hedged=True)`` replaces ``d / (d + r)`` by its expectation over
the strike's uncertain time given that no strike was detected yet (:func:`hedged_phase`; not
the default: docs/kinematics.md, "A hedged phase"). This is a phase variable in the sense of
the prosthesis-control literature (the thigh's motion, normalised per stride by its own
running extrema, tells the progress through the stride: Villarreal & Gregg; Quintero et al.),
used here to re-time the stride rather than as a polar angle of the phase portrait, which
winds back and forth about the flexion peak right at the strike (docs/kinematics.md, "The
phase within a stride from the thigh's motion").
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from statistics import NormalDist

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
    weigh_strides: int = 3
    """The stride time and the landmarks are scored by their error in predicting the strike
    over this many recent strides (median squared error: one odd stride, a turn's pivot or the
    first after a start, does not decide)."""
    min_scored: int = 2
    """A predictor is compared with the other once it has predicted this many strikes."""
    error_floor_s: float = 0.01
    """Added in quadrature to both errors before they are compared (a sample interval at
    100 Hz): two predictors both exact to within a sample are equal."""
    time_advantage: float = 2.0
    """Once a landmark is passed it predicts the strike, unless the stride time predicted the
    last strikes this many times better (RMS error; in turns, whose swings differ from step to
    step while the stride time holds). Equal errors keep the landmark: the swing, which it
    times, varies less than the stance when the pace changes."""
    hedged: bool = False
    """``True``: the phase is the expected ``d / T`` over the strike's time ``T`` given that no
    strike was detected yet (:func:`hedged_phase`: past the predicted strike it keeps rising,
    more slowly, instead of waiting at 0.999), ``T`` about the predictor in use with its recent
    RMS error as the spread. Off by default: on the real walks it moved the femurs' phase RMSE
    by 0.1-0.2 % and lost up to 0.3 % on synthetic walks (docs/kinematics.md, "A hedged
    phase")."""
    spread_floor_s: float = 0.015
    """With ``hedged``: added in quadrature to a predictor's recent RMS error (the spread of
    ``T``)."""
    spread_prior: float = 0.1
    """With ``hedged``: the spread, as a share of the predicted stride, of a predictor scored
    on fewer than ``min_scored`` strikes."""
    strike_latency_s: float = 0.1
    """With ``hedged``: a strike is detected within this time (the online latency target), so
    the strike not yet detected means ``T`` later than now less this."""
    lognormal: bool = False
    """With ``hedged``: ``T`` log-normal rather than normal."""


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
        self._stride_pred = math.nan  # the stride time predicted for the current stride
        m = self.cfg.weigh_strides
        self._sq_err = {k: deque(maxlen=m) for k in ("time", "ext", "mid")}

    def strike(self, t_s: float) -> None:
        """A foot strike at ``t_s`` (emitted now, possibly a few samples later): the stride
        that ends there calibrates the landmarks; a new one starts."""
        if self._strike_s is not None and 0.0 < t_s - self._strike_s <= self.cfg.max_stride_s:
            self._score(t_s)
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
        self._stride_pred = stride_s
        d = max(t_s - self._strike_s, 0.0)
        rest, used = self._rest(t_s, d, stride_s)
        if self.cfg.hedged:
            spread = self._spread(used, stride_s)
            c = self.cfg
            phase = hedged_phase(d, d + rest, spread, c.strike_latency_s, c.lognormal)
        else:
            phase = d / (d + rest) if rest > 0.0 else 0.999
        self._out = min(max(self._out, phase), 0.999)
        return self._out

    # --- inside ------------------------------------------------------------------------------
    def _predicted(self, t_s: float, stride_s: float) -> dict[str, float]:
        """The next strike's time as each predictor at hand sees it at ``t_s``."""
        out = {"time": self._strike_s + stride_s} if math.isfinite(stride_s) else {}
        if math.isfinite(self._ext_s) and self._from_ext:
            out["ext"] = self._ext_s + float(np.median(self._from_ext))
        if math.isfinite(self._mid_s) and self._from_mid:
            out["mid"] = self._mid_s + float(np.median(self._from_mid))
        return out

    def _spread(self, used: str, stride_s: float) -> float:
        """The spread of the strike's time about predictor ``used``: its RMS error over the last
        ``weigh_strides`` strikes, or ``spread_prior`` of the stride before ``min_scored``."""
        sq = self._sq_err[used]
        var = float(np.mean(sq)) if len(sq) >= self.cfg.min_scored else math.nan
        if not math.isfinite(var):
            var = (self.cfg.spread_prior * stride_s) ** 2
        return math.sqrt(var + self.cfg.spread_floor_s**2)

    def _rest(self, t_s: float, d: float, stride_s: float) -> tuple[float, str]:
        """The time still to come before the next strike: the latest landmark passed predicts
        it, unless the stride time predicted the recent strikes ``time_advantage`` times better
        (:meth:`_time_better`); before a landmark, the stride time, held back while the swing
        is still to come (unless the stride time did better than the largest extension). Also
        the predictor used ("time", "ext" or "mid")."""
        rest = max(stride_s - d, 0.0)
        pred = self._predicted(t_s, stride_s)
        landmark = "mid" if "mid" in pred else "ext" if "ext" in pred else None
        if landmark is None:
            if self._from_ext and not self._time_better("ext"):
                since_low = t_s - self._low[1] if math.isfinite(self._low[1]) else 0.0
                rest = max(rest, float(np.median(self._from_ext)) - since_low)
            return rest, "time"
        if "time" in pred and self._time_better(landmark):
            return rest, "time"
        return pred[landmark] - t_s, landmark

    def _time_better(self, landmark: str) -> bool:
        """The stride time predicted the recent strikes ``time_advantage`` times better (RMS,
        each error with ``error_floor_s`` added in quadrature) than ``landmark``, both scored on
        ``min_scored`` strikes or more."""
        err = {
            k: float(np.median(self._sq_err[k])) + self.cfg.error_floor_s**2
            for k in ("time", landmark)
            if len(self._sq_err[k]) >= self.cfg.min_scored
        }
        return len(err) == 2 and err["time"] * self.cfg.time_advantage**2 < err[landmark]

    def _score(self, t_s: float) -> None:
        """Each predictor's error on the strike at ``t_s`` (before this stride calibrates)."""
        for k, p in self._predicted(t_s, self._stride_pred).items():
            self._sq_err[k].append((p - t_s) ** 2)

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


_GL_U, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_U, _GL_W = 0.5 * (_GL_U + 1.0), 0.5 * _GL_W  # Gauss-Legendre on (0, 1)
_NORMAL = NormalDist()


def hedged_phase(
    d_s: float, stride_s: float, sigma_s: float, latency_s: float = 0.0, lognormal: bool = False
) -> float:
    """The phase that minimises the expected squared error at ``d_s`` after the strike when the
    stride's length ``T`` is uncertain: ``E[phase | T > d - latency]``, ``T`` normal (or
    log-normal, ``sigma_s / stride_s`` its log's SD) about ``stride_s`` with SD ``sigma_s``,
    given that no strike was detected yet (a strike is detected within ``latency_s``). The
    phase is ``d / T`` while the strike is to come; a strike past but not yet detected
    (``T <= d``) counts as the next stride's phase, unwrapped: ``1 + (d - T) / stride_s``.

    Unlike the point phase ``d / stride_s`` it does not stop below 1 once the predicted strike
    has passed: it keeps rising, more slowly, as the strike becomes ever more overdue. Computed
    by 8-point Gauss-Legendre quadrature over the quantiles of ``T`` beyond ``d - latency``
    (continuous in ``d``). ``sigma_s`` of 0 gives the point phase ``d / max(stride_s, d)``.
    May exceed 1 (by at most ``latency_s / stride_s``): the caller clips."""
    if d_s <= 0.0:
        return 0.0
    if not sigma_s > 0.0:
        return d_s / max(stride_s, d_s)
    cut = d_s - latency_s
    if lognormal:
        s = sigma_s / stride_s
        a = (math.log(cut) - math.log(stride_s)) / s if cut > 0.0 else -math.inf
    else:
        s = sigma_s
        a = (cut - stride_s) / s
    q = 0.5 * math.erfc(a / math.sqrt(2.0))  # P(T > cut)
    if q < 1e-12:  # far beyond: the mean residual life of a normal tail, sigma / a
        t_mean = cut + s / a if not lognormal else math.exp(math.log(cut) + s / a)
        return d_s / t_mean
    total = 0.0
    for u, w in zip(_GL_U, _GL_W, strict=True):
        z = -_NORMAL.inv_cdf(q * (1.0 - u))  # P(Z > z) = q (1 - u)
        t = stride_s * math.exp(s * z) if lognormal else stride_s + s * z
        # a strike already past but not yet detected: the next stride's phase, unwrapped
        total += w * (d_s / t if t > d_s else 1.0 + (d_s - t) / stride_s)
    return total
