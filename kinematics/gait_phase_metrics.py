"""Scores of an online gait-phase estimate against true events.

:func:`score_online` gives, per recording: foot-strike and toe-off errors (estimated − true),
latencies (detection − true), missed and extra events (matched within a gate), and the phase
RMSE against the reference phase (linear between consecutive true foot strikes; scored where both
the reference and the estimate exist, i.e. between the first and the last true strike while the
estimator reports walking; not across standing or a swing whose strike has no reference).
:func:`phase_error_by_stride` and :func:`phase_error_by_true_phase` say where the error lies:
in which reference strides, and where in the cycle.
"""

from __future__ import annotations

import itertools
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
    t_s: np.ndarray,
    strikes_s: np.ndarray,
    max_stride_s: float = 2.5,
    unreferenced_s: np.ndarray | None = None,
) -> np.ndarray:
    """Phase linear between consecutive true strikes (0 at a strike); NaN outside them, between
    strikes more than ``max_stride_s`` apart (standing between walking bouts), and between
    strikes that hold one of ``unreferenced_s`` (times of swings whose strike has no reference,
    e.g. :attr:`kinematics.gait_two_legs.DerivedStrikes.unreferenced_s`' starts: the span
    covers two strides, and a phase linear over it would be no stride's phase)."""
    t = np.asarray(t_s, float)
    s = np.sort(np.asarray(strikes_s, float))
    out = np.full(t.size, np.nan)
    if s.size < 2:
        return out
    span = np.diff(s)
    valid = span <= max_stride_s
    if unreferenced_s is not None and np.size(unreferenced_s):
        u = np.asarray(unreferenced_s, float).reshape(-1)
        held = np.array([bool(np.any((u > a) & (u < b))) for a, b in itertools.pairwise(s)])
        valid &= ~held
    inside = (t >= s[0]) & (t < s[-1])
    k = np.searchsorted(s, t[inside], side="right") - 1
    out[inside] = np.where(valid[k], (t[inside] - s[k]) / span[k], np.nan)
    return out


def phase_error(estimate: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Estimate − reference, wrapped to [-0.5, 0.5) cycle (NaN where either is NaN)."""
    return np.mod(np.asarray(estimate, float) - np.asarray(reference, float) + 0.5, 1.0) - 0.5


@dataclass(frozen=True)
class StridePhaseError:
    """The phase error within one reference stride."""

    start_s: float
    end_s: float
    rmse_cyc: float
    """NaN when no sample of the stride has an estimate."""
    mean_cyc: float
    """Mean signed error (+: the estimate ahead)."""
    scored_fraction: float
    """Share of the stride's samples with an estimate."""


def phase_error_by_stride(
    t_s: np.ndarray, estimate: np.ndarray, reference: np.ndarray, strikes_s: np.ndarray
) -> list[StridePhaseError]:
    """The error of ``estimate`` against ``reference`` (:func:`reference_phase` of
    ``strikes_s``) within each stride of the reference (strides without one are skipped)."""
    t = np.asarray(t_s, float)
    d = phase_error(estimate, reference)
    s = np.sort(np.asarray(strikes_s, float))
    out = []
    for a, b in itertools.pairwise(s):
        m = (t >= a) & (t < b) & np.isfinite(np.asarray(reference, float))
        if not m.any():
            continue
        scored = m & np.isfinite(d)
        e = d[scored]
        rmse = float(np.sqrt(np.mean(e**2))) if e.size else float("nan")
        mean = float(np.mean(e)) if e.size else float("nan")
        out.append(StridePhaseError(float(a), float(b), rmse, mean, float(scored.sum() / m.sum())))
    return out


def phase_error_by_true_phase(
    estimate: np.ndarray, reference: np.ndarray, bins: int = 10
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(RMSE, mean signed error, sample count) of ``estimate`` in ``bins`` equal bins of the
    reference phase (bin k: reference phase in [k / bins, (k + 1) / bins)); NaN for an empty
    bin."""
    ref = np.asarray(reference, float)
    d = phase_error(estimate, ref)
    ok = np.isfinite(d)
    k = np.minimum((ref[ok] * bins).astype(int), bins - 1)
    e = d[ok]
    count = np.bincount(k, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        rmse = np.sqrt(np.bincount(k, e**2, minlength=bins) / count)
        mean = np.bincount(k, e, minlength=bins) / count
    return rmse, mean, count


def score_online(
    result,
    strikes_s: np.ndarray,
    toe_offs_s: np.ndarray,
    unreferenced_s: np.ndarray | None = None,
) -> OnlineScore:
    """Score an :class:`~kinematics.gait_phase.OnlineGaitResult` against true events
    (``unreferenced_s``: see :func:`reference_phase`)."""
    fs = match_online(
        result.times("foot_strike"), result.times("foot_strike", detected=True), strikes_s
    )
    to = match_online(result.times("toe_off"), result.times("toe_off", detected=True), toe_offs_s)
    ref = reference_phase(result.t_s, strikes_s, unreferenced_s=unreferenced_s)
    est = np.asarray(result.phase_cyc)
    inside = np.isfinite(ref)
    both = inside & np.isfinite(est)
    if both.any():
        diff = phase_error(est[both], ref[both])
        rmse = float(np.sqrt(np.mean(diff**2)))
    else:
        rmse = float("nan")
    frac = float(both.sum() / max(inside.sum(), 1))
    return OnlineScore(fs, to, rmse, frac)
