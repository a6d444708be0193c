"""The thigh's phase-portrait phase variable, given the past foot strikes: a yardstick for the
online phase, not part of the estimator.

The prosthesis-control literature takes the gait phase from the thigh's own motion: the polar
angle of its phase portrait (the thigh angle against its rate or integral), each axis normalised
by the last stride's extrema (Villarreal, Poonawala & Gregg, IEEE TNSRE 25(3), 2017; Quintero et
al., IEEE T-RO 34(3), 2018). If every stride were a time-scaled copy of the last, the angle would
advance through the stride in proportion to time whatever the stride's length, which a phase
extrapolated in time from past strides cannot do.

:func:`portrait_phase` computes it causally from the thigh angle and the strikes known so far
(each strike known at its own time, as a reference would tell it): within stride k (from strike
k to strike k + 1) the angle and its rate (first difference, first-order low-pass at
``lowpass_hz``) are normalised by stride k − 1's mid-range and half-range; the polar angle
``ψ = atan2(−ω̂, θ̂)`` (0 at the flexion peak, π at the largest extension, increasing through
the cycle) is unwrapped from the strike; and it is mapped to the stride's time fraction through
the mean of the last ``map_strides`` strides' own ψ → fraction curves (the portrait's angular
speed is not uniform), kept monotone within the stride and below 1. NaN before the second
strike of a walk, and in a stride whose previous stride is longer than ``max_stride_s`` or
spans a smaller angle range than ``min_range_rad`` or lacks the rate at some sample (the
recording's first stride: the rate starts at its second sample).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from kinematics.errors import GaitInputError

_GRID = np.linspace(0.0, 2.0 * np.pi, 65)


@dataclass(frozen=True)
class PortraitConfig:
    """Parameters of :func:`portrait_phase`."""

    lowpass_hz: float = 8.0
    """Cut-off of the first-order low-pass on the angle's first difference (the rate)."""
    map_strides: int = 3
    """The ψ → time-fraction map is the mean over this many past strides."""
    max_stride_s: float = 2.5
    """Strikes further apart are different walks."""
    min_range_rad: float = math.radians(10.0)
    """A stride with a smaller angle range normalises nothing (a turn's pivot, a shuffle)."""


def causal_rate(t_s: np.ndarray, angle_rad: np.ndarray, lowpass_hz: float) -> np.ndarray:
    """The angle's first difference, low-passed (first order, causal); NaN where undefined."""
    t = np.asarray(t_s, float)
    a = np.asarray(angle_rad, float)
    out = np.full(t.size, np.nan)
    w = math.nan
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        if not (dt > 0 and math.isfinite(a[k]) and math.isfinite(a[k - 1])):
            w = math.nan
            continue
        raw = (a[k] - a[k - 1]) / dt
        g = min(1.0, 2.0 * math.pi * lowpass_hz * dt)
        w = raw if not math.isfinite(w) else w + g * (raw - w)
        out[k] = w
    return out


def _portrait_angle(a: np.ndarray, w: np.ndarray, norm: tuple[float, float, float, float]):
    """ψ unwrapped from the first sample (the strike), kept monotone."""
    ca, ha, cw, hw = norm
    psi = np.unwrap(np.arctan2(-(w - cw) / hw, (a - ca) / ha))
    return np.maximum.accumulate(psi - psi[0])


def portrait_phase(
    t_s: np.ndarray,
    angle_rad: np.ndarray,
    strikes_s: np.ndarray,
    config: PortraitConfig | None = None,
) -> np.ndarray:
    """The phase-portrait phase at each sample (see the module docstring)."""
    cfg = config or PortraitConfig()
    t = np.asarray(t_s, float)
    a = np.asarray(angle_rad, float)
    if t.shape != a.shape or t.ndim != 1:
        raise GaitInputError(f"t_s {t.shape} and angle_rad {a.shape}: need two equal 1-D arrays")
    s = np.sort(np.asarray(strikes_s, float))
    w = causal_rate(t, a, cfg.lowpass_hz)
    out = np.full(t.size, np.nan)
    maps: deque[np.ndarray] = deque(maxlen=cfg.map_strides)
    norm = None
    for k in range(1, s.size):
        span = (t >= s[k - 1]) & (t < s[k])
        prev = span & np.isfinite(w)
        whole = prev.sum() == span.sum()  # a rate from the strike on (not the filter's start)
        if s[k] - s[k - 1] > cfg.max_stride_s or prev.sum() < 5 or not whole:
            maps.clear()
            norm = None
        else:
            ap, wp = a[prev], w[prev]
            if ap.max() - ap.min() >= cfg.min_range_rad:
                norm = (
                    0.5 * (ap.max() + ap.min()),
                    0.5 * (ap.max() - ap.min()),
                    0.5 * (wp.max() + wp.min()),
                    max(0.5 * (wp.max() - wp.min()), 1e-6),
                )
                frac = (t[prev] - s[k - 1]) / (s[k] - s[k - 1])
                maps.append(np.interp(_GRID, _portrait_angle(ap, wp, norm), frac, right=1.0))
        end = s[k + 1] if k + 1 < s.size else t[-1] + 1.0
        cur = (t >= s[k]) & (t < end) & np.isfinite(w)
        if norm is None or not maps or not cur.any():
            continue
        curve = np.maximum.accumulate(np.mean(np.asarray(maps), axis=0))
        psi = _portrait_angle(a[cur], w[cur], norm)
        out[cur] = np.minimum(np.interp(psi, _GRID, curve), 0.999)
    return out
