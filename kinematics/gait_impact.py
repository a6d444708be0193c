"""The foot strike's impact transient in a thigh accelerometer, and what it says about the
flexion sign of the sagittal axis.

At heel contact the ground stops the leg within a few milliseconds; the shock reaches the thigh
as a burst of high-frequency specific force (a few g, 20-40 Hz) that no other part of the gait
cycle produces: swing and stance accelerations are smooth (below ~6 Hz). The burst is seen
whatever the mounting (the envelope below uses the norm of the high-passed vector), and it
marks the strike better than the thigh's angle does: where the thigh reaches its flexion peak
relative to contact differs between people (and more so with a prosthesis), the shock does not.

:class:`ImpactEnvelope` is causal (one sample in, one value out, any sample rate): the
accelerometer vector through two cascaded first-order high-pass filters (``highpass_hz``), its
squared norm, then a first-order low-pass (time constant ``smooth_s``). A strike's **impact
onset** is the time the envelope rises through ``threshold_fraction`` of the walk's typical
impact peak; the contact precedes it by ``lag_s`` (the filters' delay plus the burst's rise).
On the Xsens thigh walk (19 strikes after the first, shank-derived reference, 120 Hz) the onset
is 27 ms after the reference strike (median; SD 6 ms); ``lag_s`` defaults to 25 ms, and is
learned online from a load cell when one gives the strikes (:mod:`kinematics.gait_phase`).

**Which events are strikes** (:func:`burst_ratio`): a toe-off unloads the leg smoothly, a
strike loads it with a shock, so the bursts at strikes stand far above those at toe-offs (on the
Xsens walk, 9-29 against 0.2-2.2 in envelope units, once walking). With the flexion axis the
wrong way round, a phase model puts its strikes at the true toe-offs and its toe-offs at the
true strikes: the ratio of the burst peaks at its strikes to those at its toe-offs falls below
one. This does not depend on the shape of an able-bodied thigh curve, only on contact being a
shock and lift-off not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class ImpactConfig:
    """Parameters of the impact transient (s, Hz)."""

    highpass_hz: float = 15.0
    smooth_s: float = 0.02
    threshold_fraction: float = 0.3
    """The onset is where the envelope rises through this fraction of the typical impact peak."""
    lag_s: float = 0.025
    """Contact precedes the onset by this much (filters' delay plus the burst's rise)."""
    window_s: tuple[float, float] = (-0.10, 0.20)
    """Where an onset is searched relative to the strike a phase model predicts."""
    min_strength: float = 50.0
    """Impacts count only when the typical impact peak is at least this many times the median
    of the envelope over the walk (the real walks: 300-600; differentiated motion capture or a
    synthetic signal without a shock model: below 20)."""
    min_local_fraction: float = 0.05
    """A strike whose burst stays below the typical threshold (a soft first step) is placed at
    ``threshold_fraction`` of its own burst's peak when that reaches this fraction of the
    typical peak."""
    min_burst_ratio: float = 2.0
    """The strikes are where the bursts are: the sign whose strikes carry bursts this many times
    larger than its toe-offs' wins (when the other's ratio is below one)."""


class ImpactEnvelope:
    """Causal envelope of the accelerometer's high-frequency energy (see the module docstring)."""

    def __init__(self, config: ImpactConfig | None = None) -> None:
        self.cfg = config or ImpactConfig()
        self._x1: np.ndarray | None = None
        self._y1 = np.zeros(3)
        self._y2 = np.zeros(3)
        self._env = 0.0
        self._t: float | None = None

    def update(self, t_s: float, accel_m_s2: np.ndarray) -> float:
        a = np.asarray(accel_m_s2, dtype=float)
        if self._x1 is None or self._t is None:
            self._x1, self._t = a.copy(), t_s
            return 0.0
        dt = t_s - self._t
        self._t = t_s
        if dt <= 0:
            return self._env
        rc = 1.0 / (2 * math.pi * self.cfg.highpass_hz)
        alpha = rc / (rc + dt)
        y1 = alpha * (self._y1 + a - self._x1)
        y2 = alpha * (self._y2 + y1 - self._y1)
        self._x1, self._y1, self._y2 = a.copy(), y1, y2
        beta = min(1.0, dt / self.cfg.smooth_s)
        self._env += beta * (float(y2 @ y2) - self._env)
        return self._env


def envelope(t_s: np.ndarray, accel_m_s2: np.ndarray, config: ImpactConfig | None = None):
    """:class:`ImpactEnvelope` over a whole series (the same causal filter, sample by sample)."""
    env = ImpactEnvelope(config)
    a = np.asarray(accel_m_s2, dtype=float)
    return np.array([env.update(float(t), a[k]) for k, t in enumerate(np.asarray(t_s, float))])


def typical_peak(t_s: np.ndarray, env: np.ndarray, strikes_s: np.ndarray, cfg: ImpactConfig):
    """The median of the envelope's largest value near each strike, and its strength (that
    median over the median envelope); (nan, 0) without strikes."""
    peaks = []
    for ts in strikes_s:
        m = (t_s >= ts + cfg.window_s[0]) & (t_s <= ts + cfg.window_s[1])
        if m.any():
            peaks.append(float(env[m].max()))
    if not peaks:
        return math.nan, 0.0
    p = float(np.median(peaks))
    return p, p / max(float(np.median(env)), 1e-12)


def onset_near(
    t_s: np.ndarray, env: np.ndarray, t_guess_s: float, peak: float, cfg: ImpactConfig
) -> float:
    """Time the envelope rises through ``threshold_fraction * peak`` in the search window
    around ``t_guess_s`` (interpolated); nan if it does not."""
    level = cfg.threshold_fraction * peak
    return first_rise(t_s, env, level, t_guess_s + cfg.window_s[0], t_guess_s + cfg.window_s[1])


def first_rise(t_s: np.ndarray, env: np.ndarray, level: float, lo_s: float, hi_s: float) -> float:
    """First time in [lo_s, hi_s] the envelope rises through ``level`` (interpolated); nan if
    it does not."""
    m = np.flatnonzero((t_s >= lo_s) & (t_s <= hi_s))
    if m.size < 2:
        return math.nan
    above = env[m] >= level
    rises = np.flatnonzero(~above[:-1] & above[1:])
    if rises.size == 0:
        return math.nan
    k = m[rises[0]]
    e0, e1 = env[k], env[k + 1]
    frac = (level - e0) / (e1 - e0) if e1 != e0 else 0.0
    return float(t_s[k] + frac * (t_s[k + 1] - t_s[k]))


def burst_peaks(t_s: np.ndarray, env: np.ndarray, times_s: np.ndarray, cfg: ImpactConfig):
    """The envelope's largest value in the search window around each time."""
    out = []
    for ts in times_s:
        m = (t_s >= ts + cfg.window_s[0]) & (t_s <= ts + cfg.window_s[1])
        out.append(float(env[m].max()) if m.any() else math.nan)
    return np.asarray(out)


def burst_ratio(
    t_s: np.ndarray, env: np.ndarray, strikes_s: np.ndarray, toe_offs_s: np.ndarray, cfg
) -> float:
    """Median burst peak at the strikes over that at the toe-offs (nan without both)."""
    s = burst_peaks(t_s, env, strikes_s, cfg)
    o = burst_peaks(t_s, env, toe_offs_s, cfg)
    s, o = s[np.isfinite(s)], o[np.isfinite(o)]
    if s.size == 0 or o.size == 0:
        return math.nan
    return float(np.median(s) / max(float(np.median(o)), 1e-12))


@dataclass(frozen=True)
class ImpactRefinement:
    """Strikes placed on impact onsets, and the sign evidence (see :func:`refine_strikes`)."""

    strikes_s: np.ndarray
    from_impact: int
    """Strikes placed on an impact onset (the others: the phase model's time plus its bias)."""
    template_bias_s: float
    """Median (impact strike − phase-model strike) of this walk (0 when not measured)."""
    strength: float


def _wide_windows(strikes_s: np.ndarray, cfg: ImpactConfig) -> ImpactConfig:
    """The search window widened to half the walk's median stride after the phase model's
    strike (see :func:`refine_strikes`)."""
    gaps = np.diff(np.sort(strikes_s))
    gaps = gaps[gaps <= 2.5]
    stride = float(np.median(gaps)) if gaps.size else 1.2
    return replace(cfg, window_s=(cfg.window_s[0], max(cfg.window_s[1], 0.5 * stride)))


def refine_strikes(
    t_s: np.ndarray,
    env: np.ndarray,
    model_strikes_s: np.ndarray,
    config: ImpactConfig | None = None,
) -> ImpactRefinement:
    """Move each strike a phase model found to its impact onset minus ``lag_s``.

    The onset is searched in ``window_s`` around the model's strike, and where none rises
    there, up to half a stride after it: a template of able-bodied thigh motion can place the
    strike well before the shock (on the OpenSense right femur 0.1-0.35 s, before the thigh's
    flexion peak), and within half a stride after a strike the largest burst is this leg's
    (the other leg's strike comes half a stride later, felt only through the pelvis). The
    typical peak and the strength are measured over those wider windows too.
    Strikes with no onset in their window (a soft first step) keep the model's time plus the
    walk's median model bias (measured on the others, when at least three have an onset).
    Without impacts (strength below ``min_strength``) the strikes are returned unchanged."""
    cfg = config or ImpactConfig()
    t = np.asarray(t_s, dtype=float)
    strikes = np.asarray(model_strikes_s, dtype=float)
    wide = _wide_windows(strikes, cfg)
    peak, strength = typical_peak(t, env, strikes, wide)
    if strikes.size == 0 or strength < cfg.min_strength:
        return ImpactRefinement(strikes, 0, 0.0, strength)
    onsets = np.array([onset_near(t, env, s, peak, cfg) for s in strikes])
    for i in np.flatnonzero(~np.isfinite(onsets)):
        onsets[i] = onset_near(t, env, strikes[i], peak, wide)
    found = np.isfinite(onsets)
    impact_strikes = onsets - cfg.lag_s
    bias = float(np.median(impact_strikes[found] - strikes[found])) if found.sum() >= 3 else 0.0
    for i in np.flatnonzero(~found):  # once more around the model's time corrected by its bias
        guess = strikes[i] + bias + cfg.lag_s + 0.05  # a wider window: +0.1 s later
        m = (t >= guess + cfg.window_s[0]) & (t <= guess + cfg.window_s[1])
        local = float(env[m].max()) if m.any() else 0.0
        if local >= cfg.min_local_fraction * peak:
            wide = replace(cfg, window_s=(cfg.window_s[0] - 0.05, cfg.window_s[1] + 0.05))
            onsets[i] = onset_near(t, env, guess, min(local, peak), wide)
    found = np.isfinite(onsets)
    impact_strikes = onsets - cfg.lag_s
    out = np.where(found, impact_strikes, strikes + bias)
    return ImpactRefinement(np.sort(out), int(found.sum()), bias, strength)
