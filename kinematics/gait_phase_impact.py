"""Online strike timing for the gait-phase estimator: the impact transient and the phase bias.

The phase EKF (:mod:`kinematics.gait_phase`) follows the shape of a reference thigh curve; where
a wearer's thigh reaches its flexion peak relative to contact differs from that curve (tens of
milliseconds on real walks), so its strike phase carries a bias. :class:`StrikeTiming` measures
that bias online and removes it:

* every sample feeds the causal impact envelope (:class:`kinematics.gait_impact.ImpactEnvelope`);
* around each strike the EKF predicts, a window opens (``window_s`` of :class:`ImpactConfig`
  around the calibrated prediction); the largest envelope value inside it is the stride's burst
  peak. Once a strike window has held a burst ``min_strength`` times above the median
  envelope, **impact mode** is on: the strike is emitted at the envelope's rise through
  ``threshold_fraction`` of that median peak, at ``onset − lag_s`` (detection 25-40 ms after
  contact). Until the typical peak rests on ``settle_bursts`` bursts (after a start, the one
  burst seen may be a turn's or a first step's, far weaker than the walk's) the onset is held
  while its burst is followed (at most ``follow_s``) and placed at ``threshold_fraction`` of
  the larger of the typical peak and the burst's own: a threshold learned from a weak burst
  is crossed early in a strong burst's slow rise;
* each strike placed on an impact (or given by a load cell, :meth:`StrikeTiming.reference`)
  adds a sample of the EKF's strike bias (reference time − the EKF's own strike time); the bias
  is the median of the last ``bias_strides`` samples and shifts the phase the estimator reports,
  its toe-offs, and its strikes when no impact is seen. The bias is kept when the impacts or
  the load cell disappear;
* the bursts around the estimator's toe-offs are followed too: at strikes the leg takes a
  shock, at toe-offs it does not, so when the bursts at its toe-offs stand well above those at
  its strikes (:func:`kinematics.gait_impact.burst_ratio`), its axis is the wrong way round and
  it flips it (:meth:`StrikeTiming.sign_is_wrong`).
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from kinematics.gait_impact import ImpactConfig, ImpactEnvelope, envelope, onset_near


@dataclass(frozen=True)
class StrikeTimingConfig:
    impact: ImpactConfig = field(default_factory=ImpactConfig)
    window_s: tuple[float, float] = (-0.10, 0.30)
    """The strike's search window around the calibrated prediction (a shock 0.3 s after the
    prediction still belongs to it: the next event, a toe-off, is 0.5 s or more away)."""
    flip_burst_ratio: float = 5.0
    """The axis is flipped when the bursts at the toe-offs stand this many times above those at
    the strikes (real walks: strikes 15× the toe-offs; a smooth signal's sharp thigh reversal
    near toe-off reaches 2-3× a strike window's noise)."""
    bias_strides: int = 8
    """The phase bias is the median over this many recent strides."""
    history_s: float = 0.4
    """Envelope history kept for the toe-offs' bursts."""
    swing_cyc: float = 0.6
    """A shock outside any strike window is this leg's strike when the thigh reached a flexion
    peak within this share of the recent stride before it (the swing, at most 0.45 of a
    stride, and the terminal swing after the peak) ..."""
    min_swing_rad: float = math.radians(10.0)
    """... having flexed by at least this much before that peak (a walking thigh swings by
    30-50°; the other leg's strike, felt through the pelvis, comes in this leg's mid-stance,
    while it extends)."""
    settle_bursts: int = 2
    """Until this many strong strike bursts are measured the typical peak is not yet the
    walk's (a single burst, often a turn's or a first step's weak one: on the OpenSense right
    femur 0.38 against 2-5 later): an onset is then held while its burst is followed
    (``follow_s``) and placed at ``threshold_fraction`` of the larger of the typical peak and
    the burst's own peak."""
    follow_s: float = 0.12
    """The longest an onset is held while its burst is followed (the detection latency it may
    add); the hold ends sooner once the burst has outgrown the typical peak and turned down, or
    the burst has fallen below half its peak (it is over)."""
    outgrown_ratio: float = 2.0
    """A held burst this many times the typical peak shows that the typical came from weaker
    bursts: its own peak (once the envelope turns down) sets the threshold."""


@dataclass
class StrikeWindow:
    """The open search window of one strike (times in s)."""

    target: int
    close_at_s: float
    raw_s: float
    """The EKF's own strike time (uncalibrated)."""
    calibrated_s: float
    peak: float
    emitted: bool = False


class StrikeTiming:
    """See the module docstring. The estimator opens a window per strike (:meth:`arm`), polls
    it every sample (:meth:`poll`) and closes it (:meth:`close`)."""

    def __init__(self, config: StrikeTimingConfig | None = None) -> None:
        self.cfg = config or StrikeTimingConfig()
        self.envelope = ImpactEnvelope(self.cfg.impact)
        self.env = 0.0
        self._prev_env = 0.0
        self._t_now: float | None = None
        self._t_before: float | None = None
        self._envs: deque[float] = deque(maxlen=400)
        self._floor: float | None = None
        """The median of ``_envs``, kept until the next envelope sample is added."""
        self._n = 0
        self.peaks: deque[float] = deque(maxlen=8)
        """Burst peak of each strike window (strong or not)."""
        self.bias_samples: deque[float] = deque(maxlen=self.cfg.bias_strides)
        self.bias_s = 0.0
        self.bias_source = "none"
        self._hist: deque[tuple[float, float]] = deque()
        self._toe_offs: list[float] = []
        self.toe_off_peaks: deque[float] = deque(maxlen=5)
        self.window: StrikeWindow | None = None
        self._armed_above = False
        self._post: tuple[float, float] | None = None
        """(until, peak): the burst after an onset, followed to its peak."""
        self._held: tuple[float, float, float] | None = None
        """(first rise, peak since, below half the peak since): an onset held while its burst
        is followed (``follow_s``)."""

    # --- per sample ----------------------------------------------------------------------
    def sample(self, t_s: float, accel_m_s2: np.ndarray) -> None:
        self._prev_env, self._t_before, self._t_now = self.env, self._t_now, t_s
        self.env = self.envelope.update(t_s, accel_m_s2)
        self._n += 1
        if self._n % 5 == 0:
            self._envs.append(self.env)
            self._floor = None
        self._hist.append((t_s, self.env))
        while self._hist and self._hist[0][0] < t_s - self.cfg.history_s:
            self._hist.popleft()
        w0, w1 = self.cfg.window_s
        while self._toe_offs and t_s >= self._toe_offs[0] + w1:
            t_to = self._toe_offs.pop(0)
            inside = [e for t, e in self._hist if t_to + w0 <= t <= t_to + w1]
            if inside:
                self.toe_off_peaks.append(max(inside))
        if self.window is not None:
            self.window.peak = max(self.window.peak, self.env)
        if self._post is not None:
            until, peak = self._post
            self._post = (until, max(peak, self.env))
            if t_s >= until:
                self.peaks.append(self._post[1])
                self._post = None

    def toe_off(self, t_s: float) -> None:
        """An emitted toe-off: its burst is measured once its window has passed."""
        self._toe_offs.append(t_s)

    def sign_is_wrong(self, min_strides: int) -> bool:
        """Each of the last ``min_strides`` toe-offs' bursts stands ``flip_burst_ratio`` above the
        strikes' (median of the last five) and is strong (an impact)."""
        if (
            min_strides <= 0
            or len(self.toe_off_peaks) < min_strides
            or len(self.peaks) < min_strides
        ):
            return False
        strikes = float(np.median(list(self.peaks)[-5:]))
        toe_offs = float(min(list(self.toe_off_peaks)[-min_strides:]))  # each of them
        strong = toe_offs >= self.cfg.impact.min_strength * self.floor
        return strong and toe_offs >= self.cfg.flip_burst_ratio * max(strikes, 1e-12)

    def forget_bursts(self) -> None:
        """After a flip: the bursts seen so far belong to the other events."""
        self.peaks.clear()
        self.toe_off_peaks.clear()
        self._toe_offs.clear()
        self.bias_samples.clear()
        self.bias_s = 0.0

    # --- state ---------------------------------------------------------------------------
    @property
    def floor(self) -> float:
        """The median envelope (recent samples): the level the bursts are measured against."""
        if not self._envs:
            return math.inf
        if self._floor is None:
            self._floor = max(float(np.median(self._envs)), 1e-12)
        return self._floor

    @property
    def typical_peak(self) -> float:
        """Median of the strike windows' strong burst peaks (nan before the first)."""
        least = self.cfg.impact.min_strength * self.floor
        strong = [p for p in self.peaks if p >= least]
        return float(np.median(strong)) if strong else math.nan

    @property
    def settled(self) -> bool:
        """``settle_bursts`` strike windows' bursts or more are measured."""
        return len(self.peaks) >= self.cfg.settle_bursts

    @property
    def holding(self) -> bool:
        """An onset is held while its burst is followed (the window must stay open)."""
        return self._held is not None

    @property
    def impact_mode(self) -> bool:
        """Strikes are timed by impacts once a strike window has held a strong burst."""
        return len(self._envs) >= 20 and math.isfinite(self.typical_peak)

    def level(self) -> float:
        """The onset threshold: ``threshold_fraction`` of the typical peak."""
        return self.cfg.impact.threshold_fraction * self.typical_peak

    # --- strike windows ------------------------------------------------------------------
    def arm(self, target: int, close_at_s: float, raw_s: float, calibrated_s: float):
        """Open the window of strike ``target``."""
        self.window = StrikeWindow(target, close_at_s, raw_s, calibrated_s, self.env)
        self._armed_above = self.impact_mode and self.env >= self.level()
        self._held = None
        return self.window

    def _past_rise(self) -> float | None:
        """The envelope was already above the threshold when the window opened: its last rise
        through it in the recent history (the samples are past, so this stays causal)."""
        level = self.level()
        hist = list(self._hist)
        for (t0, e0), (t1, e1) in zip(reversed(hist[:-1]), reversed(hist[1:]), strict=True):
            if e0 < level <= e1:
                return t0 + (level - e0) / (e1 - e0) * (t1 - t0)
        return None

    def _first_rise_since(self, t_from_s: float, level: float) -> float | None:
        """The first rise through ``level`` at or after ``t_from_s`` in the recent history (the
        sample before ``t_from_s`` included: the rise may lie between it and the next)."""
        hist = list(self._hist)
        k = next((i for i, (t, _) in enumerate(hist) if t >= t_from_s), len(hist))
        hist = hist[max(k - 1, 0) :]
        for (t0, e0), (t1, e1) in itertools.pairwise(hist):
            if e0 < level <= e1:
                return t0 + (level - e0) / (e1 - e0) * (t1 - t0)
        return None

    def poll(self) -> float | None:
        """The impact onset at the latest sample when the envelope has just risen through the
        threshold in impact mode (interpolated), else None. Before the typical peak is
        settled (:attr:`settled`) the onset is held while its burst is followed and returned
        once the hold ends (:meth:`_release`)."""
        if self.window is None or not self.impact_mode or self._t_before is None:
            return None
        if self._held is not None:
            return self._release()
        onset = None
        if self._armed_above:
            self._armed_above = False
            onset = self._past_rise()
        if onset is None:
            onset = self.rise_now()
        if onset is None or self.settled:
            return onset
        self._held = (onset, max(e for t, e in self._hist if t >= onset - 1e-9), math.inf)
        return self._release()

    def _release(self) -> float | None:
        """A held onset once its burst is followed: ``follow_s`` past the first rise; sooner
        when the burst outgrew the typical peak (``outgrown_ratio`` times it) and the envelope
        has turned down (the burst's peak is behind: the threshold's basis is this burst), or
        when the burst fell below half its peak (over). The onset is then the first rise, since
        the held one, through ``threshold_fraction`` of the larger of the typical peak and the
        burst's peak (the threshold learned from weaker bursts is crossed early in a strong
        burst's rise); None while held."""
        first, peak, below = self._held
        turned = self.env < self._prev_env
        peak = max(peak, self.env)
        below = self._t_now if self.env < 0.5 * peak else math.inf
        self._held = (first, peak, below)
        typical = self.typical_peak
        outgrown = peak >= self.cfg.outgrown_ratio * typical and turned
        over = math.isfinite(below)
        if not (outgrown or over) and self._t_now < first + self.cfg.follow_s:
            return None
        self._held = None
        level = self.cfg.impact.threshold_fraction * max(typical, peak)
        onset = self._first_rise_since(first, level)
        return onset if onset is not None else first

    def rise_now(self) -> float | None:
        """The onset when the envelope has just risen through the threshold (impact mode,
        window or not; interpolated), else None."""
        if not self.impact_mode or self._t_before is None:
            return None
        level = self.level()
        if self._prev_env < level <= self.env:
            frac = (level - self._prev_env) / (self.env - self._prev_env)
            return self._t_before + frac * (self._t_now - self._t_before)
        return None

    def close(self, onset_s: float | None) -> float | None:
        """Close the window; return the strike time from the onset (None without one). The
        window's burst peak joins the typical peak; an onset adds a bias sample."""
        win, self.window = self.window, None
        self._held = None
        if win is None:
            return None
        if onset_s is None:
            if win.peak > 0:
                self.peaks.append(win.peak)
            return None
        self._post = (onset_s + 0.1, win.peak)
        strike = onset_s - self.cfg.impact.lag_s
        self.reference(strike, win.raw_s, source="impact")
        return strike

    def reference(self, strike_s: float, raw_strike_s: float, source: str) -> None:
        """A strike time known from elsewhere (impact, load cell) against the EKF's own."""
        self.bias_samples.append(strike_s - raw_strike_s)
        self.bias_s = float(np.median(self.bias_samples))
        self.bias_source = source


def impact_strikes_in_buffer(
    t_s: np.ndarray,
    accel_m_s2: np.ndarray,
    strikes_s: np.ndarray,
    config: StrikeTimingConfig,
    only_impacts: bool = False,
) -> np.ndarray:
    """Strikes found in a past buffer (the estimator's learning buffer, emitted once the axis
    is fixed) moved to their impact onsets minus ``lag_s``: the onset at ``threshold_fraction``
    of the largest burst in each strike's window, when that burst stands ``min_strength``
    times above the buffer's median envelope; the others are kept (dropped with
    ``only_impacts``)."""
    strikes = np.asarray(strikes_s, dtype=float)
    if strikes.size == 0 or len(t_s) < 10:
        return strikes[:0] if only_impacts else strikes
    cfg = config.impact
    t = np.asarray(t_s, dtype=float)
    env = envelope(t, accel_m_s2, cfg)
    floor = max(float(np.median(env)), 1e-12)
    out = strikes.copy()
    found = np.zeros(strikes.size, dtype=bool)
    # the phase's first strikes are the least certain: a window reaching 0.3 s either side
    window = (-0.3, config.window_s[1])
    window_cfg = ImpactConfig(**{**cfg.__dict__, "window_s": window})
    for i, ts in enumerate(strikes):
        m = (t >= ts + window[0]) & (t <= ts + window[1])
        if not m.any():
            continue
        peak = float(env[m].max())
        if peak < cfg.min_strength * floor:
            continue
        onset = onset_near(t, env, ts, peak, window_cfg)
        if math.isfinite(onset):
            out[i] = onset - cfg.lag_s
            found[i] = True
    return out[found] if only_impacts else out
