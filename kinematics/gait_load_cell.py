"""Foot strikes and toe-offs from an axial load cell: a hysteresis comparator; contacts or
swings shorter than a minimum are chatter and are dropped (counted)."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_event_config import DetectedEvents, GaitEventConfig
from kinematics.gait_event_times import merge_strike_pairs

# the offline detectors' warnings keep the logger of their public module
logger = logging.getLogger("kinematics.gait_events")


def detect_from_load_cell(
    t_s: Sequence[float] | np.ndarray,
    load_n: Sequence[float] | np.ndarray,
    *,
    on_threshold_n: float | None = None,
    off_threshold_n: float | None = None,
    config: GaitEventConfig | None = None,
    min_load_range_n: float = 100.0,
    source: str = "<load cell>",
) -> DetectedEvents:
    """Foot strikes / toe-offs from an axial load (N, compression +) with hysteresis.

    Default thresholds: 15 % (on) and 8 % (off) of the load range (5th to 95th percentile);
    when that range is below ``min_load_range_n`` (standing only) there are no events.
    A strike is the interpolated time the load rises through ``on_threshold_n``; a toe-off the
    time it falls through ``off_threshold_n``. States shorter than ``min_contact_s`` /
    ``min_swing_s`` are chatter: dropped and counted in ``rejected``.
    """
    cfg = config or GaitEventConfig()
    t, f = _check_load(t_s, load_n, source)
    lo, hi = np.percentile(f, [5, 95])
    if on_threshold_n is None or off_threshold_n is None:
        if hi - lo < min_load_range_n:
            logger.info(
                "%s: load range %.0f N < %.0f N: no walking", source, hi - lo, min_load_range_n
            )
            return DetectedEvents(np.zeros(0), np.zeros(0), method="load_cell")
        on_threshold_n = lo + 0.15 * (hi - lo) if on_threshold_n is None else on_threshold_n
        off_threshold_n = lo + 0.08 * (hi - lo) if off_threshold_n is None else off_threshold_n
    if not off_threshold_n < on_threshold_n:
        raise GaitInputError(
            f"{source}: off_threshold_n ({off_threshold_n}) must be below on_threshold_n "
            f"({on_threshold_n}) for hysteresis"
        )
    transitions = _transitions(t, f, on_threshold_n, off_threshold_n)
    rejected = _drop_chatter(transitions, cfg, source)
    strikes = np.array([x for x, k in transitions if k == "foot_strike"])
    toe_offs = np.array([x for x, k in transitions if k == "toe_off"])
    strikes, pairs = merge_strike_pairs(strikes, cfg.min_stride_s, source)
    # a toe-off between two merged strikes (a heel bounce) goes with them
    inside = np.zeros(toe_offs.size, dtype=bool)
    for first, second in pairs:
        inside |= (toe_offs > first) & (toe_offs < second)
    toe_offs = toe_offs[~inside]
    return DetectedEvents(
        foot_strikes_s=strikes,
        toe_offs_s=toe_offs,
        method="load_cell",
        merged_strikes=len(pairs),
        rejected=rejected + int(inside.sum()),
        details={
            "on_threshold_n": float(on_threshold_n),
            "off_threshold_n": float(off_threshold_n),
        },
    )


def _check_load(
    t_s: Sequence[float] | np.ndarray, load_n: Sequence[float] | np.ndarray, source: str
) -> tuple[np.ndarray, np.ndarray]:
    """The times and loads as arrays: same length N >= 2, finite, time strictly increasing."""
    t = np.asarray(t_s, dtype=float)
    f = np.asarray(load_n, dtype=float)
    if t.ndim != 1 or f.shape != t.shape or t.size < 2:
        raise GaitInputError(f"{source}: need t_s and load_n of the same length N >= 2")
    bad = ~np.isfinite(f) | ~np.isfinite(t)
    if bad.any():
        raise GaitInputError(f"{source}: sample {int(np.flatnonzero(bad)[0])} is not finite")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise GaitInputError(f"{source}: sample {k}: t_s must increase strictly")
    return t, f


def _transitions(
    t: np.ndarray, f: np.ndarray, on_threshold_n: float, off_threshold_n: float
) -> list[tuple[float, str]]:
    """The hysteresis comparator's (time, kind) transitions, at interpolated crossing times."""

    def crossing(k: int, level: float) -> float:
        f0, f1 = f[k - 1], f[k]
        a = (level - f0) / (f1 - f0) if f1 != f0 else 1.0
        return float(t[k - 1] + a * (t[k] - t[k - 1]))

    contact = bool(f[0] >= on_threshold_n)
    transitions: list[tuple[float, str]] = []
    for k in range(1, f.size):
        if not contact and f[k] >= on_threshold_n:
            contact = True
            transitions.append((crossing(k, on_threshold_n), "foot_strike"))
        elif contact and f[k] <= off_threshold_n:
            contact = False
            transitions.append((crossing(k, off_threshold_n), "toe_off"))
    return transitions


def _drop_chatter(transitions: list[tuple[float, str]], cfg: GaitEventConfig, source: str) -> int:
    """Drop chatter in place: a state that lasts less than its minimum removes both its
    transitions; returns how many were dropped (warned)."""
    rejected = 0
    changed = True
    while changed:
        changed = False
        for i in range(len(transitions) - 1):
            (t0, k0), (t1, _) = transitions[i], transitions[i + 1]
            min_len = cfg.min_contact_s if k0 == "foot_strike" else cfg.min_swing_s
            if t1 - t0 < min_len:
                del transitions[i : i + 2]
                rejected += 2
                changed = True
                break
    if rejected:
        logger.warning(
            "%s: %d threshold crossings dropped as chatter (states shorter than %.2f/%.2f s)",
            source,
            rejected,
            cfg.min_contact_s,
            cfg.min_swing_s,
        )
    return rejected
