"""Time handling shared by the sources: ordering, association, interpolation, depth units.

Every function here counts what it keeps and what it drops; nothing is repaired silently.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import DepthUnitsError
from graph_slam.session.files import PLAUSIBLE_MEDIAN_DEPTH_M
from graph_slam.session.records import ImuSeries


# --------------------------------------------------------------------------- ordering
@dataclass(frozen=True)
class Ordering:
    """Indices that put a stream in strictly increasing time order."""

    keep: np.ndarray  #: indices into the original stream, in time order, duplicates removed
    reordered: int  #: samples that arrived after a later-stamped one (then sorted into place)
    duplicates: int  #: samples dropped because an earlier one had the same stamp


def order_stamps(stamps: np.ndarray) -> Ordering:
    """Sort by stamp (stable) and drop exact duplicate stamps (the first one is kept)."""
    stamps = np.asarray(stamps)
    if stamps.size == 0:
        return Ordering(np.zeros(0, dtype=np.intp), 0, 0)
    running_max = np.maximum.accumulate(stamps)
    reordered = int(np.count_nonzero(stamps[1:] < running_max[:-1]))
    order = np.argsort(stamps, kind="stable")
    sorted_stamps = stamps[order]
    dup = np.zeros(order.size, dtype=bool)
    dup[1:] = sorted_stamps[1:] == sorted_stamps[:-1]
    return Ordering(order[~dup], reordered, int(dup.sum()))


# --------------------------------------------------------------------------- association
def associate(
    t_ref_s: np.ndarray, t_other_s: np.ndarray, max_dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pair two sorted streams one-to-one by nearest stamp, within ``max_dt_s``.

    Candidate pairs (``|dt| <= max_dt_s``) are taken in order of increasing ``|dt|`` (ties:
    earlier reference, then earlier other); each sample is used at most once. This is the rule
    of TUM's ``associate.py``. Returns index arrays ``(i_ref, i_other)`` sorted by ``i_ref``.
    """
    t_ref_s = np.asarray(t_ref_s, dtype=np.float64)
    t_other_s = np.asarray(t_other_s, dtype=np.float64)
    if t_ref_s.size == 0 or t_other_s.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    lo = np.searchsorted(t_other_s, t_ref_s - max_dt_s, side="left")
    hi = np.searchsorted(t_other_s, t_ref_s + max_dt_s, side="right")
    counts = hi - lo
    ref_idx = np.repeat(np.arange(t_ref_s.size), counts)
    offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    other_idx = np.repeat(lo, counts) + offsets
    dt = np.abs(t_ref_s[ref_idx] - t_other_s[other_idx])
    within = dt <= max_dt_s
    ref_idx, other_idx, dt = ref_idx[within], other_idx[within], dt[within]
    order = np.lexsort((other_idx, ref_idx, dt))
    used_ref = np.zeros(t_ref_s.size, dtype=bool)
    used_other = np.zeros(t_other_s.size, dtype=bool)
    pairs: list[tuple[int, int]] = []
    for k in order:
        i, j = int(ref_idx[k]), int(other_idx[k])
        if not used_ref[i] and not used_other[j]:
            used_ref[i] = used_other[j] = True
            pairs.append((i, j))
    pairs.sort()
    if not pairs:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    arr = np.asarray(pairs, dtype=np.intp)
    return arr[:, 0], arr[:, 1]


# --------------------------------------------------------------------------- IMU merge
@dataclass(frozen=True)
class ImuMergeCounts:
    """What merging a gyro and an accel stream kept and dropped."""

    time_base: str
    base_found: int
    base_used: int
    base_dropped_start: int  #: base samples before the other stream's first sample
    base_dropped_end: int  #: base samples after the other stream's last sample
    base_dropped_gap: int  #: base samples whose bracketing other samples are too far apart
    other_found: int
    other_used: int  #: other samples inside the span of the kept base samples (bracketing ones)
    other_unused_start: int
    other_unused_end: int


def merge_accel_gyro(
    t_gyro_s: np.ndarray,
    gyro_rad_s: np.ndarray,
    t_accel_s: np.ndarray,
    accel_m_s2: np.ndarray,
    *,
    time_base: str = "gyro",
    max_gap_s: float = 0.05,
) -> tuple[ImuSeries, ImuMergeCounts]:
    """Put separate accel and gyro streams (sorted, unique stamps) on one time base.

    The base stream's samples are kept as they are; the other stream is interpolated linearly
    at the base stamps. Base samples outside the other stream's span, or whose two bracketing
    other samples are more than ``max_gap_s`` apart, are dropped and counted.
    """
    if time_base == "gyro":
        t_base, base, t_other, other = t_gyro_s, gyro_rad_s, t_accel_s, accel_m_s2
    else:
        t_base, base, t_other, other = t_accel_s, accel_m_s2, t_gyro_s, gyro_rad_s
    t_base = np.asarray(t_base, dtype=np.float64)
    t_other = np.asarray(t_other, dtype=np.float64)
    if t_other.size == 0 or t_base.size == 0:  # nothing to pair: every sample is dropped
        counts = ImuMergeCounts(
            time_base,
            int(t_base.size),
            0,
            int(t_base.size),
            0,
            0,
            int(t_other.size),
            0,
            int(t_other.size),
            0,
        )
        return ImuSeries(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))), counts
    start = t_base < t_other[0]
    end = t_base > t_other[-1]
    inside = ~(start | end)
    right = np.clip(np.searchsorted(t_other, t_base, side="left"), 0, t_other.size - 1)
    left = np.clip(right - 1, 0, t_other.size - 1)
    exact = t_other[right] == t_base
    left = np.where(exact, right, left)
    gap = (t_other[right] - t_other[left]) > max_gap_s
    gap &= inside
    keep = inside & ~gap
    span = np.where(right > left, t_other[right] - t_other[left], 1.0)
    alpha = np.where(right > left, (t_base - t_other[left]) / span, 0.0)[:, None]
    other_at_base = (1.0 - alpha) * other[left] + alpha * other[right]
    if keep.any():
        first_used = int(left[keep].min())
        last_used = int(right[keep].max())
        other_used = last_used - first_used + 1
        unused_start, unused_end = first_used, t_other.size - 1 - last_used
    else:
        other_used, unused_start, unused_end = 0, t_other.size, 0
    counts = ImuMergeCounts(
        time_base=time_base,
        base_found=int(t_base.size),
        base_used=int(keep.sum()),
        base_dropped_start=int(start.sum()),
        base_dropped_end=int(end.sum()),
        base_dropped_gap=int(gap.sum()),
        other_found=int(t_other.size),
        other_used=other_used,
        other_unused_start=unused_start,
        other_unused_end=unused_end,
    )
    base_kept, other_kept = np.asarray(base)[keep], other_at_base[keep]
    gyro, accel = (base_kept, other_kept) if time_base == "gyro" else (other_kept, base_kept)
    return ImuSeries(t_base[keep], gyro, accel), counts


# --------------------------------------------------------------------------- poses
def interpolate_poses(
    t_src_s: np.ndarray, poses: np.ndarray, t_query_s: np.ndarray, max_gap_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Poses at ``t_query_s``: translation linear, rotation along the geodesic (slerp).

    Only queries inside the source span whose two bracketing samples are at most ``max_gap_s``
    apart get a pose. Returns ``(mask over queries, M×4×4 poses for the masked queries)``.
    """
    from scipy.spatial.transform import Rotation

    t_src_s = np.asarray(t_src_s, dtype=np.float64)
    t_query_s = np.asarray(t_query_s, dtype=np.float64)
    if t_src_s.size == 0 or t_query_s.size == 0:
        return np.zeros(t_query_s.size, dtype=bool), np.zeros((0, 4, 4))
    inside = (t_query_s >= t_src_s[0]) & (t_query_s <= t_src_s[-1])
    right = np.clip(np.searchsorted(t_src_s, t_query_s, side="left"), 0, t_src_s.size - 1)
    left = np.where(t_src_s[right] == t_query_s, right, np.clip(right - 1, 0, None))
    ok = inside & ((t_src_s[right] - t_src_s[left]) <= max_gap_s)
    left, right, tq = left[ok], right[ok], t_query_s[ok]
    span = t_src_s[right] - t_src_s[left]
    alpha = np.divide(tq - t_src_s[left], span, out=np.zeros_like(tq), where=span > 0)
    out = np.tile(np.eye(4), (tq.size, 1, 1))
    if tq.size:
        r_left = Rotation.from_matrix(poses[left, :3, :3])
        r_right = Rotation.from_matrix(poses[right, :3, :3])
        delta = (r_left.inv() * r_right).as_rotvec()
        out[:, :3, :3] = (r_left * Rotation.from_rotvec(alpha[:, None] * delta)).as_matrix()
        out[:, :3, 3] = (1.0 - alpha[:, None]) * poses[left, :3, 3] + alpha[:, None] * poses[
            right, :3, 3
        ]
    return ok, out


# --------------------------------------------------------------------------- depth units
#: Units offered when the stated one gives an implausible median depth (metres per value).
CANDIDATE_UNITS_M: tuple[tuple[str, float], ...] = (
    ("metres (1 m)", 1.0),
    ("millimetres (0.001 m)", 1e-3),
    ("TUM (1/5000 m)", 2e-4),
    ("0.1 mm (1e-4 m)", 1e-4),
)


def check_depth_units(
    raw_samples: Sequence[np.ndarray],
    unit_m: float,
    *,
    where: str,
    unit_source: str,
    fix: str = "set the depth units in the conversion config",
) -> float | None:
    """The median valid depth (value × unit, values > 0 and finite) of a few sampled frames
    must be plausible for a body-worn camera; returns the median (None without valid pixels).

    Raises :class:`DepthUnitsError` naming the median found and the units that would make it
    plausible.
    """
    valid = [np.asarray(s, dtype=np.float64) for s in raw_samples]
    values = np.concatenate([np.zeros(0)] + [v[np.isfinite(v) & (v > 0)].ravel() for v in valid])
    if values.size == 0:
        return None
    median_raw = float(np.median(values))
    median_m = median_raw * unit_m
    lo, hi = PLAUSIBLE_MEDIAN_DEPTH_M
    if lo <= median_m <= hi:
        return median_m
    fits = [
        f"{name} → {median_raw * unit:.3g} m"
        for name, unit in CANDIDATE_UNITS_M
        if lo <= median_raw * unit <= hi
    ]
    hint = ("; with " + " or ".join(fits) + " it would be plausible") if fits else ""
    raise DepthUnitsError(
        f"{where}: with {unit_m:g} m per depth value ({unit_source}) the median valid depth of "
        f"{len(raw_samples)} sampled frame(s) is {median_m:.4g} m, outside the plausible "
        f"{lo}–{hi} m{hint}; {fix}"
    )
