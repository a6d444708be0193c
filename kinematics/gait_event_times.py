"""Event times after detection: matching against true events, merging foot strikes closer
than a plausible stride, and the gait phase between strikes."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from kinematics.gait_event_config import GaitEventConfig

# the offline detectors' warnings keep the logger of their public module
logger = logging.getLogger("kinematics.gait_events")


def match_events(
    detected_s: np.ndarray, truth_s: np.ndarray, gate_s: float = 0.25
) -> tuple[np.ndarray, int, int]:
    """Match detected event times to true ones: (errors of the detection nearest each matched
    true event, detected − true, in s; number of true events with no detection within
    ``gate_s``; number of detections with no true event within ``gate_s``)."""
    detected_s = np.asarray(detected_s, float)
    truth_s = np.asarray(truth_s, float)
    errors, missed = [], 0
    for t in truth_s:
        if detected_s.size and np.min(np.abs(detected_s - t)) < gate_s:
            errors.append(detected_s[np.argmin(np.abs(detected_s - t))] - t)
        else:
            missed += 1
    extra = sum(1 for d in detected_s if truth_s.size == 0 or np.min(np.abs(truth_s - d)) >= gate_s)
    return np.asarray(errors), missed, extra


def merge_close_strikes(
    strikes_s: np.ndarray, min_stride_s: float, source: str = ""
) -> tuple[np.ndarray, int]:
    """Merge foot strikes closer than ``min_stride_s`` (keep the first); warn and count."""
    kept, pairs = merge_strike_pairs(strikes_s, min_stride_s, source)
    return kept, len(pairs)


def merge_strike_pairs(
    strikes_s: np.ndarray, min_stride_s: float, source: str = ""
) -> tuple[np.ndarray, list[tuple[float, float]]]:
    strikes = np.sort(np.asarray(strikes_s, dtype=float))
    kept: list[float] = []
    pairs: list[tuple[float, float]] = []
    for t in strikes:
        if kept and t - kept[-1] < min_stride_s:
            pairs.append((kept[-1], float(t)))
            logger.warning(
                "%sfoot strikes at %.3f s and %.3f s are %.3f s apart, less than the minimum "
                "plausible stride time %.2f s: merged into one (at %.3f s)",
                f"{source}: " if source else "",
                kept[-1],
                t,
                t - kept[-1],
                min_stride_s,
                kept[-1],
            )
            continue
        kept.append(float(t))
    return np.asarray(kept), pairs


def gait_phase(
    t_s: float | np.ndarray,
    foot_strikes_s: Sequence[float] | np.ndarray,
    max_stride_s: float = GaitEventConfig.max_stride_s,
) -> np.ndarray:
    """Gait phase in [0, 1) at times ``t_s``: linear between consecutive foot strikes.

    NaN before the first strike, after the last, and within gaps longer than
    ``max_stride_s`` (not walking).
    """
    t = np.asarray(t_s, dtype=float)
    fs = np.sort(np.asarray(foot_strikes_s, dtype=float))
    out = np.full(t.shape, np.nan)
    if fs.size < 2:
        return out
    k = np.searchsorted(fs, t, side="right") - 1
    inside = (k >= 0) & (k < fs.size - 1)
    kk = np.where(inside, k, 0)
    start, end = fs[kk], fs[np.minimum(kk + 1, fs.size - 1)]
    ok = inside & (end - start <= max_stride_s)
    out[ok] = ((t - start) / (end - start))[ok]
    return out
