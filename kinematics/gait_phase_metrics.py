"""Scores of an online gait-phase estimate against true events.

:func:`score_online` gives, per recording: foot-strike and toe-off errors (estimated − true),
latencies (detection − true), missed and extra events (matched within a gate), and the phase
RMSE against the reference phase (linear between consecutive true foot strikes; scored where both
the reference and the estimate exist, i.e. between the first and the last true strike while the
estimator reports walking).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EventScore:
    """Matched errors (s) of one event kind, and the unmatched counts."""

    errors_s: np.ndarray
    latencies_s: np.ndarray
    true: int
    missed: int
    extra: int


@dataclass(frozen=True)
class OnlineScore:
    foot_strike: EventScore
    toe_off: EventScore
    phase_rmse_cyc: float
    phase_scored_fraction: float
    """Share of the samples between the first and last true strike with a phase estimate."""


def match_online(
    estimated_s: np.ndarray,
    detected_s: np.ndarray,
    truth_s: np.ndarray,
    gate_s: float = 0.25,
) -> EventScore:
    """Match each true event to the nearest estimated one within ``gate_s``."""
    est = np.asarray(estimated_s, float)
    det = np.asarray(detected_s, float)
    truth = np.asarray(truth_s, float)
    used = np.zeros(est.size, dtype=bool)
    errors, latencies, missed = [], [], 0
    for t in truth:
        if est.size == 0:
            missed += 1
            continue
        d = np.abs(est - t)
        d[used] = np.inf
        k = int(np.argmin(d))
        if d[k] < gate_s:
            used[k] = True
            errors.append(est[k] - t)
            latencies.append(det[k] - t)
        else:
            missed += 1
    return EventScore(
        errors_s=np.asarray(errors),
        latencies_s=np.asarray(latencies),
        true=int(truth.size),
        missed=missed,
        extra=int((~used).sum()),
    )


def reference_phase(
    t_s: np.ndarray, strikes_s: np.ndarray, max_stride_s: float = 2.5
) -> np.ndarray:
    """Phase linear between consecutive true strikes (0 at a strike); NaN outside them and
    between strikes more than ``max_stride_s`` apart (standing between walking bouts)."""
    t = np.asarray(t_s, float)
    s = np.sort(np.asarray(strikes_s, float))
    out = np.full(t.size, np.nan)
    if s.size < 2:
        return out
    inside = (t >= s[0]) & (t < s[-1])
    k = np.searchsorted(s, t[inside], side="right") - 1
    span = s[k + 1] - s[k]
    out[inside] = np.where(span <= max_stride_s, (t[inside] - s[k]) / span, np.nan)
    return out


def score_online(result, strikes_s: np.ndarray, toe_offs_s: np.ndarray) -> OnlineScore:
    """Score an :class:`~kinematics.gait_phase.OnlineGaitResult` against true events."""
    fs = match_online(
        result.times("foot_strike"), result.times("foot_strike", detected=True), strikes_s
    )
    to = match_online(result.times("toe_off"), result.times("toe_off", detected=True), toe_offs_s)
    ref = reference_phase(result.t_s, strikes_s)
    est = np.asarray(result.phase_cyc)
    inside = np.isfinite(ref)
    both = inside & np.isfinite(est)
    if both.any():
        diff = np.mod(est[both] - ref[both] + 0.5, 1.0) - 0.5
        rmse = float(np.sqrt(np.mean(diff**2)))
    else:
        rmse = float("nan")
    frac = float(both.sum() / max(inside.sum(), 1))
    return OnlineScore(fs, to, rmse, frac)
