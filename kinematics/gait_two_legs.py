"""A contact reference derived from two thigh IMUs of one walk (no force plate, no shank).

A walk recorded by a sensor on each thigh, with the sensors' orientations (an Xsens export
gives them), carries evidence about each foot strike that no single-thigh detector uses, and
from which a reference strike can be derived with a stated uncertainty:

* **the thigh's inclination** (:func:`thigh_inclination_rad`): the angle of the thigh's long
  axis from the vertical, about its flexion axis, from the orientation (gravity fixes it; no
  integration, no drift). A foot lands in front of the body: at its strike the thigh is flexed,
  after the peak of its swing flexion; its stance then extends it;
* **the other thigh**: the legs alternate and support overlap, so the other leg leaves the
  ground only after this one has landed; its thigh reaches its largest extension just before
  its toe-off (the reference curves of :mod:`kinematics.gait_curves`: 0.5-0.57 of its cycle,
  0-0.07 cycle after this leg's strike at 0.6-1.8 m/s);
* **the impact transient** (:mod:`kinematics.gait_impact`): the strike's shock stands far
  higher in this thigh's accelerometer than in the other's (it is felt there only through
  the pelvis).

:func:`derive_strikes` takes, per stride of one leg (between consecutive peaks of its swing
flexion), the first rise of its impact envelope through ``threshold_fraction`` of the walk's
typical burst between its flexion peak (plus at most ``max_after_flexion_cyc`` of a stride) and the other thigh's
largest extension (plus ``after_extension_cyc``), keeps it when the burst there is at least ``min_side_ratio`` times the
other thigh's, and places the strike ``lag_s`` before it (the onset's lag measured on the
Xsens walk against its shank reference, SD 6 ms). Its **uncertainty**: that spread, the
sample interval, and where a stride holds an earlier, smaller burst (at least
``early_fraction`` of the typical peak, ``min_gap_s`` or more before the onset, after the
flexion peak) the reference is *ambiguous* by that gap: the earlier burst may be the heel's
contact and the larger one the forefoot's (the strides are counted, not dropped).

:func:`physical_checks` tests any set of strikes against the bounds that do not use the
shock at all: each strike after its thigh's flexion peak by at most ``max_after_flexion_cyc`` of a stride,
and before the other thigh's largest extension plus ``after_extension_cyc`` of a stride.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_impact import ImpactConfig, first_rise


@dataclass(frozen=True)
class TwoLegConfig:
    """Bounds of the derived reference (s, rad, fractions)."""

    lowpass_hz: float = 6.0
    """The inclination is low-passed (zero phase) before its peaks are taken."""
    min_prominence_rad: float = math.radians(10.0)
    """A flexion peak or extension trough rises or falls at least this much (a walking thigh:
    30-50°; a turn's shuffle: less)."""
    max_after_flexion_cyc: float = 0.45
    """A strike comes at most this share of the walk's median stride after its thigh's
    flexion peak: the peak lies within the swing, and a swing is shorter than this (stance
    0.55-0.68 of the stride, :mod:`kinematics.gait_patterns`; the reference curves' terminal
    swing after the peak: 0.06-0.11)."""
    after_extension_cyc: float = 0.1
    """The strike comes at most this share of the median stride after the other thigh's
    largest extension: the other foot leaves the ground only after this one has landed
    (double support), and a thigh's largest extension precedes its toe-off by 0.03-0.10 of
    the cycle on the reference curves (0.6-1.8 m/s)."""
    threshold_fraction: float = 0.3
    min_side_ratio: float = 2.0
    """This thigh's burst at least this many times the other thigh's at the same instant."""
    early_fraction: float = 0.1
    min_gap_s: float = 0.06
    lag_s: float = ImpactConfig().lag_s
    lag_sd_s: float = 0.006


@dataclass(frozen=True)
class DerivedStrikes:
    """The derived reference of one leg (see :func:`derive_strikes`)."""

    strikes_s: np.ndarray
    ambiguous_s: np.ndarray
    """Per strike: the gap to an earlier, smaller burst after the flexion peak (0: none)."""
    strides: int
    """Flexion peaks of this thigh (each the swing before a strike)."""
    no_shock: int
    """Flexion peaks with no burst of this leg between the bounds (no reference there)."""
    unreferenced_s: np.ndarray
    """(start, end) of the search interval of each flexion peak without a reference, and of
    the recording before the first flexion peak and after the last interval: a strike there
    can be neither matched nor called extra."""
    uncertainty_s: float
    """1-σ of an unambiguous reference strike: the lag's spread and the sample interval."""


def thigh_inclination_rad(
    global_R_sensor: np.ndarray, accel_m_s2: np.ndarray, gyro_rad_s: np.ndarray
) -> np.ndarray:
    """The thigh's inclination from the vertical about its flexion axis (unsigned sense).

    The long axis is the mean specific force in the sensor frame (on average, gravity along
    the thigh); the flexion axis is the principal axis of the angular velocity orthogonal to
    it. The sense is fixed by :func:`derive_strikes` (flexed at the shocks)."""
    from kinematics.gait_events import sagittal_axis

    r = np.asarray(global_R_sensor, dtype=float)
    if r.ndim != 3 or r.shape[1:] != (3, 3) or r.shape[0] != len(accel_m_s2):
        raise GaitInputError(
            f"global_R_sensor: need one 3x3 matrix per sample, got shape {r.shape}"
        )
    x = np.asarray(accel_m_s2, dtype=float).mean(axis=0)
    x /= max(float(np.linalg.norm(x)), 1e-9)
    lateral, _ = sagittal_axis(gyro_rad_s, x)
    lateral = lateral - (lateral @ x) * x
    lateral /= max(float(np.linalg.norm(lateral)), 1e-9)
    forward = np.cross(lateral, x)
    up_sensor = r[:, 2, :]  # the global vertical in the sensor frame
    return np.arctan2(up_sensor @ forward, up_sensor @ x)


def _lowpass(t_s: np.ndarray, x: np.ndarray, hz: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    rate = 1.0 / float(np.median(np.diff(t_s)))
    return sosfiltfilt(butter(2, hz, fs=rate, output="sos"), x)


def _peaks(x: np.ndarray, prominence: float, t_s: np.ndarray) -> np.ndarray:
    from scipy.signal import find_peaks

    rate = 1.0 / float(np.median(np.diff(t_s)))
    k, _ = find_peaks(x, prominence=prominence, distance=max(1, int(0.5 * rate)))
    return k


@dataclass(frozen=True)
class Leg:
    """One thigh of the walk: times, inclination (rad) and impact envelope, on one clock."""

    t_s: np.ndarray
    inclination_rad: np.ndarray
    envelope: np.ndarray


def _oriented(leg: Leg, cfg: TwoLegConfig) -> tuple[np.ndarray, np.ndarray]:
    """The low-passed inclination, flexion positive: the sense in which the thigh is further
    forward at its own largest bursts (a foot lands in front of the body)."""
    th = _lowpass(leg.t_s, leg.inclination_rad, cfg.lowpass_hz)
    big = leg.envelope >= np.percentile(leg.envelope, 99)
    if np.median(th[big]) < np.median(th):
        th = -th
    return th, _peaks(th, cfg.min_prominence_rad, leg.t_s)


def _typical_burst(t: np.ndarray, env: np.ndarray, flex: np.ndarray) -> float:
    """The median over strides (between flexion peaks) of the envelope's largest value."""
    edges = [*list(flex), t.size - 1]
    maxima = [float(env[a:b].max()) for a, b in itertools.pairwise(edges) if b > a]
    return float(np.median(maxima)) if maxima else math.nan


def derive_strikes(own: Leg, other: Leg, config: TwoLegConfig | None = None) -> DerivedStrikes:
    """The derived reference strikes of ``own`` (see the module docstring)."""
    cfg = config or TwoLegConfig()
    t, env = own.t_s, own.envelope
    _th, flex = _oriented(own, cfg)
    th_o, _ = _oriented(other, cfg)
    env_o = np.interp(t, other.t_s, other.envelope)
    ext = _peaks(-np.interp(t, other.t_s, th_o), cfg.min_prominence_rad, t)
    typical = _typical_burst(t, env, flex)
    out, gaps, empty = [], [], []
    last = -math.inf
    for tf, hi in _search_intervals(t, flex, ext, cfg):
        lo = max(tf, last + 0.3)
        onset = _onset(t, env, env_o, typical, lo, hi, cfg)
        if not math.isfinite(onset):
            empty.append((tf, hi))
            continue
        early = first_rise(t, env, cfg.early_fraction * typical, tf, onset)
        gap = onset - early if math.isfinite(early) and onset - early >= cfg.min_gap_s else 0.0
        out.append(onset - cfg.lag_s)
        gaps.append(gap)
        last = onset
    intervals = _search_intervals(t, flex, ext, cfg)
    if intervals:  # before the first flexion peak and after the last interval: no evidence
        empty = [(float(t[0]), intervals[0][0]), *empty, (intervals[-1][1], float(t[-1]))]
    dt = float(np.median(np.diff(t)))
    sigma = math.hypot(cfg.lag_sd_s, dt / math.sqrt(12.0))
    return DerivedStrikes(
        strikes_s=np.asarray(out),
        ambiguous_s=np.asarray(gaps),
        strides=int(flex.size),
        no_shock=len(empty),
        unreferenced_s=np.asarray(empty).reshape(-1, 2),
        uncertainty_s=sigma,
    )


def _search_intervals(t, flex, ext, cfg: TwoLegConfig) -> list[tuple[float, float]]:
    """Per flexion peak: from it to the earlier of the swing bound and the other thigh's
    next largest extension plus ``after_extension_cyc`` of a stride."""
    tf = t[flex]
    stride = float(np.median(np.diff(tf))) if tf.size > 1 else 1.2
    out = []
    for f in tf:
        later = t[ext][t[ext] > f]
        hi = min(
            f + cfg.max_after_flexion_cyc * stride,
            (later[0] if later.size else math.inf) + cfg.after_extension_cyc * stride,
        )
        out.append((float(f), hi))
    return out


def _onset(t, env, env_o, typical, lo, hi, cfg: TwoLegConfig) -> float:
    """This leg's shock onset in [lo, hi] (nan: none, too weak, or the other leg's)."""
    m = (t >= lo) & (t <= hi)
    if not m.any():
        return math.nan
    onset = first_rise(t, env, cfg.threshold_fraction * typical, lo, hi)
    if not math.isfinite(onset):
        return math.nan
    k = np.flatnonzero((t >= onset) & (t <= onset + 0.1))
    if k.size and env[k].max() < cfg.min_side_ratio * env_o[k][np.argmax(env[k])]:
        return math.nan  # the other leg's shock, felt through the pelvis
    return onset


@dataclass(frozen=True)
class PhysicalCheck:
    """How many strikes keep the bounds that do not use the shock (see the module docstring)."""

    strikes: int
    after_flexion: int
    """Strikes within ``max_after_flexion_cyc`` strides after their thigh's last flexion peak."""
    before_other_extension: int
    """Strikes before the other thigh's first largest extension after that flexion peak, plus
    ``after_extension_cyc`` of a stride."""


def physical_checks(
    strikes_s: np.ndarray, own: Leg, other: Leg, config: TwoLegConfig | None = None
) -> PhysicalCheck:
    """Check strikes of ``own`` against its flexion peaks and the other thigh's extension."""
    cfg = config or TwoLegConfig()
    t = own.t_s
    _th, flex = _oriented(own, cfg)
    th_o, _ = _oriented(other, cfg)
    ext = _peaks(-np.interp(t, other.t_s, th_o), cfg.min_prominence_rad, t)
    tf = t[flex]
    stride = float(np.median(np.diff(tf))) if tf.size > 1 else 1.2
    after = before = 0
    for s in np.asarray(strikes_s, dtype=float):
        prior = tf[tf < s]
        if prior.size == 0:
            continue
        after += int(s - prior[-1] <= cfg.max_after_flexion_cyc * stride)
        nxt = t[ext][t[ext] > prior[-1]]
        before += int(nxt.size > 0 and s <= nxt[0] + cfg.after_extension_cyc * stride)
    return PhysicalCheck(int(np.size(strikes_s)), after, before)


@dataclass(frozen=True)
class ReferenceScore:
    """Strikes against a derived reference (see :func:`score_against`)."""

    errors_s: np.ndarray
    """Per matched reference strike: detected − reference; 0 inside an ambiguous interval,
    else the distance to its nearer end."""
    latencies_s: np.ndarray
    """Per matched reference strike: detection time − reference (when given)."""
    missed: int
    extra: int
    unscored: int
    """Strikes inside an unreferenced span (neither matched nor extra)."""


def score_against(
    strikes_s: np.ndarray,
    reference: DerivedStrikes,
    detected_s: np.ndarray | None = None,
    gate_s: float = 0.25,
) -> ReferenceScore:
    """Match strikes to the derived reference: each reference strike to the nearest unused
    strike within ``gate_s``. An ambiguous reference strike is the interval from its earlier
    burst to it (``ambiguous_s``)."""
    order = np.argsort(np.asarray(strikes_s, dtype=float))
    s = np.asarray(strikes_s, dtype=float)[order]
    det = s if detected_s is None else np.asarray(detected_s, dtype=float)[order]
    spans = reference.unreferenced_s
    inside = np.array([bool(np.any((x >= spans[:, 0]) & (x <= spans[:, 1]))) for x in s])
    inside = inside.reshape(-1).astype(bool)
    scored, det = s[~inside], det[~inside]
    used = np.zeros(scored.size, dtype=bool)
    errors, latencies, missed = [], [], 0
    for ref, gap in zip(reference.strikes_s, reference.ambiguous_s, strict=True):
        d = np.abs(scored - ref)
        d[used] = np.inf
        if d.size == 0 or not np.isfinite(d.min()) or d.min() >= gate_s:
            missed += 1
            continue
        k = int(np.argmin(d))
        used[k] = True
        e = scored[k] - ref
        latencies.append(det[k] - ref)
        errors.append(0.0 if -gap <= e <= 0 else (e + gap if e < -gap else e))
    return ReferenceScore(
        np.asarray(errors), np.asarray(latencies), missed, int((~used).sum()), int(inside.sum())
    )
