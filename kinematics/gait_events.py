"""Gait events (foot strike, toe-off) from a load cell or from a thigh IMU, and gait phase.

Load cell (:func:`detect_from_load_cell`): a hysteresis comparator on the axial load; foot
strike when the load rises through the upper threshold, toe-off when it falls through the
lower one; contacts or swings shorter than a minimum are chatter and are dropped (counted).

Thigh IMU in an unknown mounting orientation (:func:`detect_from_thigh_imu`):

1. resample to a uniform grid, low-pass the gyro (zero-phase Butterworth, 8 Hz);
2. the sagittal axis is the principal axis of the angular velocity (walking is mostly
   flexion/extension of the thigh); its sign is chosen so that the signal matches the
   reference thigh angular velocity (flexion +) better than its negative does;
3. swing peaks (the large flexion-velocity peak of mid-swing) mark each stride; their
   spacing gives the local stride time T and, through the adult stride-time/speed relation,
   the walking speed whose reference thigh-velocity curve (:mod:`kinematics.gait_curves`) is
   the template;
4. each foot strike is located by aligning the template with the measured signal over the
   phases -0.30 .. +0.25 around it (terminal-swing deceleration, loading plateau, onset of
   stance extension) by normalised cross-correlation (insensitive to gain and bias); toe-off
   likewise over the phases around the template's toe-off. Alignments with a correlation below
   ``min_correlation`` are rejected (not walking: standing, shuffling, gait initiation);
5. foot strikes closer than the plausible minimum stride time are merged, with a warning,
   and counted.

When the accelerometer shows heel-strike shocks (:mod:`kinematics.gait_impact`), the axis
sign is the one whose strikes carry the shocks (a toe-off has none), and each strike is moved
to its shock's onset minus the impact lag (the template's shape bias is then gone).

Gait phase (:func:`gait_phase`): linear in time between consecutive foot strikes of a walking
bout (0 at a strike, 1 at the next); NaN outside walking.
"""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from kinematics.errors import GaitDetectionError, GaitInputError
from kinematics.imu import IMU_COLUMNS, LEGACY_IMU_COLUMNS, ImuSeries

logger = logging.getLogger(__name__)

EVENT_KINDS: tuple[str, ...] = ("foot_strike", "toe_off")
MIN_RATE_HZ, MAX_RATE_HZ = 50.0, 1000.0
MAX_GYRO_RAD_S = 35.0  # 2000 deg/s: the largest common MEMS range
MAX_ACCEL_M_S2 = 16 * 9.81


@dataclass(frozen=True)
class GaitEventConfig:
    """Parameters of the gait-event detectors (SI units)."""

    min_stride_s: float = 0.7
    """Plausible minimum stride time: closer foot strikes are merged (walking at 1.8 m/s has
    about 0.9 s strides)."""
    max_stride_s: float = 2.5
    """Longest stride still counted as continuous walking."""
    lowpass_hz: float = 8.0
    work_rate_hz: float = 100.0
    min_swing_peak_rad_s: float = 0.8
    """Smallest mid-swing thigh flexion velocity counted as a step (reference: 1.5 rad/s at
    0.6 m/s, 3-4 rad/s at 1.2-1.8 m/s)."""
    min_correlation: float = 0.8
    """Minimum normalised correlation of an event's template alignment."""
    strike_window: tuple[float, float] = (-0.30, 0.25)
    """Phases around the foot strike used to align it."""
    toe_off_window: tuple[float, float] = (-0.20, 0.12)
    """Phases around toe-off used to align it."""
    search_fraction: float = 0.15
    """Alignment search range, ± this fraction of the stride around the predicted time."""
    amplitude_ratio: tuple[float, float] = (0.35, 3.0)
    """Allowed ratio of the measured to the template angular-velocity spread in a window."""
    min_window_fraction: float = 0.6
    """At the ends of a recording, use an alignment window cut to at least this fraction."""
    use_impacts: bool = True
    """Place the strikes on the accelerometer's heel-strike shocks and check the axis sign with
    them when the shocks are there (:mod:`kinematics.gait_impact`); False: the template only."""
    # load cell
    min_contact_s: float = 0.15
    min_swing_s: float = 0.15


@dataclass(frozen=True)
class DetectedEvents:
    """What a detector found: the events and how (method, merged and rejected candidates).

    Not a session record: ``graph_slam.session.records.GaitEvents`` is the validated stream of
    events a session holds (time, kind and source per event)."""

    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    method: str
    merged_strikes: int = 0
    """Foot strikes merged because they were closer than ``min_stride_s``."""
    rejected: int = 0
    """Candidate events dropped (low correlation, chatter)."""
    sagittal_axis: np.ndarray | None = None
    """IMU method: unit axis in the sensor frame about which thigh flexion is positive."""
    details: dict[str, float] = field(default_factory=dict)

    def rows(self) -> list[tuple[float, str]]:
        """(t_s, kind) sorted by time."""
        out = [(float(t), "foot_strike") for t in self.foot_strikes_s]
        out += [(float(t), "toe_off") for t in self.toe_offs_s]
        return sorted(out)


# --- I/O -------------------------------------------------------------------------------------
def read_imu_csv(path: str | Path) -> ImuSeries:
    """Read an IMU CSV strictly: header :data:`~kinematics.imu.IMU_COLUMNS` (the session
    format's ``imu.csv``) or the unit-less :data:`~kinematics.imu.LEGACY_IMU_COLUMNS`, any
    column order; s, rad/s, m/s².

    Errors (:class:`GaitInputError`) name the file, the line, the column (as the file names
    it) and the rule.
    """
    path = Path(path)
    try:
        fh = path.open(newline="", encoding="utf-8")
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read IMU CSV ({err.strerror})") from None
    try:
        with fh:
            return _read_imu_rows(path, csv.reader(fh))
    except UnicodeDecodeError as err:
        raise GaitInputError(
            f"{path}: not a UTF-8 text CSV (byte {err.start} cannot be decoded); expected "
            f"header {','.join(IMU_COLUMNS)}"
        ) from None


def _read_imu_rows(path: Path, reader) -> ImuSeries:
    """The header and rows of :func:`read_imu_csv` (``reader``: a csv.reader)."""
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise GaitInputError(f"{path}: empty file (need header {','.join(IMU_COLUMNS)})") from None
    # the schema the header is closest to names what is missing
    columns = max((IMU_COLUMNS, LEGACY_IMU_COLUMNS), key=lambda cols: len(set(cols) & set(header)))
    missing = [c for c in columns if c not in header]
    extra = [c for c in header if c not in columns]
    if missing or extra or len(header) != len(columns):
        raise GaitInputError(
            f"{path}: line 1: header must be exactly {','.join(IMU_COLUMNS)} (or the "
            f"legacy {','.join(LEGACY_IMU_COLUMNS)}), any order; missing {missing}, "
            f"unexpected {extra}"
        )
    index = [header.index(c) for c in columns]
    rows: list[list[float]] = []
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not x.strip() for x in row):
            continue
        if len(row) != len(header):
            raise GaitInputError(
                f"{path}: line {line_no}: has {len(row)} fields, the header has {len(header)}"
            )
        values = []
        for col, j in zip(columns, index, strict=True):
            text = row[j].strip()
            try:
                value = float(text)
            except ValueError:
                raise GaitInputError(
                    f"{path}: line {line_no}, column {col}: {text!r} is not a number"
                ) from None
            if not math.isfinite(value):
                raise GaitInputError(
                    f"{path}: line {line_no}, column {col}: {text!r} is not finite "
                    "(NaN/inf samples are not allowed; drop or mark them upstream)"
                )
            values.append(value)
        rows.append(values)
    data = np.asarray(rows, dtype=float).reshape(-1, len(columns))
    imu = ImuSeries(
        t_s=data[:, 0], gyro_rad_s=data[:, 1:4], accel_m_s2=data[:, 4:7], source=str(path)
    )
    validate_imu(imu, first_line=2, columns=columns)
    return imu


def validate_imu(
    imu: ImuSeries, first_line: int | None = None, columns: Sequence[str] = IMU_COLUMNS
) -> float:
    """Check an IMU series (shapes, finite, time, rate 50-1000 Hz, ranges); return its rate.

    ``first_line``: file line of sample 0, to name lines in messages (else sample indices);
    ``columns``: the names of t, gyro x/y/z, accel x/y/z in messages.
    """

    def where(k: int) -> str:
        return f"line {k + first_line}" if first_line is not None else f"sample {k}"

    src = imu.source
    t, g, a = (np.asarray(x, dtype=float) for x in (imu.t_s, imu.gyro_rad_s, imu.accel_m_s2))
    if t.ndim != 1 or g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise GaitInputError(f"{src}: need t_s (N,), gyro (N, 3), accel (N, 3)")
    if t.size < 2:
        raise GaitInputError(f"{src}: need at least 2 samples, got {t.size}")
    for first, arr in ((0, t[:, None]), (1, g), (4, a)):
        bad = ~np.isfinite(arr)
        if bad.any():
            k, j = np.argwhere(bad)[0]
            col = columns[first + j]
            raise GaitInputError(f"{src}: {where(int(k))}, column {col}: not finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise GaitInputError(f"{src}: {where(k)}, column t_s: time must increase strictly")
    rate = 1.0 / float(np.median(dt))
    if not MIN_RATE_HZ * 0.95 <= rate <= MAX_RATE_HZ * 1.05:
        raise GaitInputError(
            f"{src}: column t_s: median sample rate {rate:.1f} Hz is outside "
            f"{MIN_RATE_HZ:.0f}-{MAX_RATE_HZ:.0f} Hz (are the times in seconds?)"
        )
    gaps = np.flatnonzero(dt > 5.0 / rate)
    if gaps.size:
        k = int(gaps[0]) + 1
        raise GaitInputError(
            f"{src}: {where(k)}, column t_s: gap of {dt[k - 1]:.3f} s (more than 5 sample "
            "periods); split the recording at gaps"
        )
    for first, arr, limit, unit in (
        (1, g, MAX_GYRO_RAD_S, "rad/s"),
        (4, a, MAX_ACCEL_M_S2, "m/s²"),
    ):
        big = np.abs(arr) > limit
        if big.any():
            k, j = np.argwhere(big)[0]
            raise GaitInputError(
                f"{src}: {where(int(k))}, column {columns[first + j]}: {arr[k, j]:.4g} exceeds the "
                f"plausible range ±{limit:.4g} {unit} (units must be rad/s and m/s²)"
            )
    return rate


def write_imu_csv(path: str | Path, imu: ImuSeries) -> Path:
    """Write an IMU series with the header :data:`~kinematics.imu.IMU_COLUMNS` (the session
    format's ``imu.csv``), as :func:`read_imu_csv` reads it."""
    path = Path(path)
    data = np.column_stack([imu.t_s, imu.gyro_rad_s, imu.accel_m_s2])
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(IMU_COLUMNS) + "\n")
        for row in data:
            fh.write(f"{row[0]:.6f}," + ",".join(f"{x:.6g}" for x in row[1:]) + "\n")
    return path


def write_events_csv(path: str | Path, events: DetectedEvents) -> Path:
    """Write ``t_s,kind`` rows sorted by time."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write("t_s,kind\n")
        for t, kind in events.rows():
            fh.write(f"{t:.6f},{kind}\n")
    return path


def read_events_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``t_s,kind`` rows: ``{"foot_strike": times, "toe_off": times}``."""
    path = Path(path)
    out: dict[str, list[float]] = {k: [] for k in EVENT_KINDS}
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read events CSV ({err.strerror})") from None
    if not lines or lines[0].strip() != "t_s,kind":
        raise GaitInputError(f"{path}: line 1: header must be 't_s,kind'")
    for line_no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        t_text, _, kind = line.partition(",")
        kind = kind.strip()
        if kind not in out:
            raise GaitInputError(
                f"{path}: line {line_no}, column kind: {kind!r} is not one of {EVENT_KINDS}"
            )
        try:
            t = float(t_text)
        except ValueError:
            raise GaitInputError(
                f"{path}: line {line_no}, column t_s: {t_text!r} is not a number"
            ) from None
        if not math.isfinite(t):
            raise GaitInputError(f"{path}: line {line_no}, column t_s: not finite")
        out[kind].append(t)
    return {k: np.asarray(v) for k, v in out.items()}


# --- helpers ---------------------------------------------------------------------------------
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
    kept, pairs = _merge_pairs(strikes_s, min_stride_s, source)
    return kept, len(pairs)


def _merge_pairs(
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


@lru_cache(maxsize=64)
def _template(speed_key: int) -> tuple[np.ndarray, np.ndarray]:
    """Reference thigh angular velocity per cycle (rad/cycle) on a phase grid, speed in cm/s."""
    from kinematics.gait_curves import thigh_angle

    phase = np.linspace(0.0, 1.0, 400, endpoint=False)
    return phase, thigh_angle(phase, speed_key / 100.0, derivative=1)


def _speed_for_stride(stride_s: float) -> float:
    from kinematics.gait_curves import stride_time_s, valid_speed_range_m_s

    lo, hi = valid_speed_range_m_s()
    if stride_s >= stride_time_s(lo):
        return lo
    if stride_s <= stride_time_s(hi):
        return hi
    a, b = lo, hi  # stride time decreases with speed
    for _ in range(40):
        mid = 0.5 * (a + b)
        if stride_time_s(mid) > stride_s:
            a = mid
        else:
            b = mid
    return 0.5 * (a + b)


def _template_values(speed: float, phases: np.ndarray) -> np.ndarray:
    phase_grid, omega = _template(round(speed * 100))
    return np.interp(np.mod(phases, 1.0), phase_grid, omega, period=1.0)


def _align(
    t: np.ndarray,
    omega: np.ndarray,
    t_guess: float,
    *,
    stride_s: float,
    speed: float,
    event_phase: float,
    window: tuple[float, float],
    cfg: GaitEventConfig,
) -> tuple[float, float]:
    """Best time for the template phase ``event_phase`` near ``t_guess``; (time, correlation).

    Returns (nan, -1) when too little of the window lies inside the recording.
    """
    n_pts = 120
    rel = np.linspace(window[0], window[1], n_pts)  # phases relative to the event
    tmpl = _template_values(speed, event_phase + rel)
    dt = 1.0 / cfg.work_rate_hz
    search = cfg.search_fraction * stride_s
    shifts = np.arange(-search, search + 0.5 * dt, dt / 2)
    taus = t_guess + shifts
    times = taus[:, None] + rel[None, :] * stride_s  # (candidates, points)
    valid = (times >= t[0]) & (times <= t[-1])
    frac = valid.mean(axis=1)
    ok = frac >= cfg.min_window_fraction
    if not ok.any():
        return math.nan, -1.0
    meas = np.interp(times, t, omega)
    w = valid.astype(float)
    n = w.sum(axis=1, keepdims=True)
    n[n == 0] = 1
    tm = tmpl[None, :]
    mm = (meas * w).sum(1, keepdims=True) / n
    tmm = (tm * w).sum(1, keepdims=True) / n
    dm, dtp = (meas - mm) * w, (tm - tmm) * w
    den = np.sqrt((dm**2).sum(1) * (dtp**2).sum(1))
    # The template is in rad per cycle; in rad/s it is divided by the stride time. A window
    # whose spread is far from the template's is not this gait event (e.g. standing sway).
    ratio = np.sqrt((dm**2).sum(1) / np.maximum((dtp**2).sum(1), 1e-30)) * stride_s
    ok &= (ratio >= cfg.amplitude_ratio[0]) & (ratio <= cfg.amplitude_ratio[1])
    corr = np.where((den > 0) & ok, (dm * dtp).sum(1) / np.where(den > 0, den, 1), -1.0)
    best = int(np.argmax(corr))
    tau = taus[best]
    if 0 < best < len(corr) - 1 and corr[best - 1] > -1 and corr[best + 1] > -1:
        a, b, c = corr[best - 1], corr[best], corr[best + 1]
        den2 = a - 2 * b + c
        if den2 < 0:
            tau += 0.5 * (a - c) / den2 * (dt / 2)
    return float(tau), float(corr[best])


def _prepare_signal(imu: ImuSeries, cfg: GaitEventConfig) -> tuple[np.ndarray, np.ndarray, float]:
    from scipy.signal import butter, sosfiltfilt

    rate = validate_imu(imu)
    gyro = np.asarray(imu.gyro_rad_s, dtype=float)
    t_in = np.asarray(imu.t_s, dtype=float)
    if rate > 2.5 * cfg.lowpass_hz and t_in.size > 30:
        sos = butter(4, cfg.lowpass_hz, fs=rate, output="sos")
        gyro = sosfiltfilt(sos, gyro, axis=0)
    t = np.arange(t_in[0], t_in[-1], 1.0 / cfg.work_rate_hz)
    g = np.column_stack([np.interp(t, t_in, gyro[:, i]) for i in range(3)])
    return t, g, rate


def _swing_peaks(t: np.ndarray, omega: np.ndarray, cfg: GaitEventConfig) -> np.ndarray:
    """Mid-swing flexion-velocity peaks: high, and dominant among their neighbours.

    A peak must exceed ``min_swing_peak_rad_s`` above the signal's median and have at least
    40 % of the largest prominence within ± one maximum stride (this drops the small
    loading-response bump that follows each foot strike).
    """
    from scipy.signal import find_peaks

    distance = max(1, int(0.5 * cfg.min_stride_s * cfg.work_rate_hz))
    peaks, props = find_peaks(
        omega - np.median(omega), height=cfg.min_swing_peak_rad_s, distance=distance, prominence=0.0
    )
    if peaks.size == 0:
        return peaks
    prom = props["prominences"]
    t_pk = t[peaks]
    keep = np.array(
        [
            prom[k] >= 0.4 * prom[np.abs(t_pk - t_pk[k]) <= cfg.max_stride_s].max()
            for k in range(peaks.size)
        ]
    )
    return peaks[keep]


def _local_strides(t_peaks: np.ndarray, cfg: GaitEventConfig) -> np.ndarray:
    """Stride time at each swing peak from the neighbouring plausible intervals."""
    from kinematics.gait_curves import stride_time_s

    d = np.diff(t_peaks)
    plausible = (d >= cfg.min_stride_s) & (d <= cfg.max_stride_s)
    default = float(np.median(d[plausible])) if plausible.any() else stride_time_s(1.2)
    out = np.full(t_peaks.size, default)
    for k in range(t_peaks.size):
        near = []
        if k > 0 and plausible[k - 1]:
            near.append(d[k - 1])
        if k < d.size and plausible[k]:
            near.append(d[k])
        if near:
            out[k] = float(np.mean(near))
    return out


def _detect_with_axis(t: np.ndarray, omega: np.ndarray, cfg: GaitEventConfig) -> dict:
    from kinematics.gait_curves import stance_fraction

    peaks = _swing_peaks(t, omega, cfg)
    result: dict = {
        "strikes": [],
        "strike_corr": [],
        "toe_offs": [],
        "rejected": 0,
        "score": 0.0,
        "n_peaks": int(peaks.size),
    }
    if peaks.size == 0:
        return result
    t_peaks = t[peaks]
    strides = _local_strides(t_peaks, cfg)
    scores = []
    candidates: list[tuple[float, float]] = []
    for tp, stride in zip(t_peaks, strides, strict=True):
        speed = _speed_for_stride(stride)
        phase_grid, tmpl = _template(round(speed * 100))
        swing = phase_grid > 0.4
        phase_peak = float(phase_grid[swing][np.argmax(tmpl[swing])])
        # the strike ending this swing, and the one starting its cycle
        for guess in (tp + (1.0 - phase_peak) * stride, tp - phase_peak * stride):
            tau, corr = _align(
                t,
                omega,
                guess,
                stride_s=stride,
                speed=speed,
                event_phase=0.0,
                window=cfg.strike_window,
                cfg=cfg,
            )
            if math.isfinite(tau):
                candidates.append((tau, corr))
        sf = stance_fraction(speed)
        guess_to = tp - (phase_peak - sf) * stride
        tau, corr = _align(
            t,
            omega,
            guess_to,
            stride_s=stride,
            speed=speed,
            event_phase=sf,
            window=cfg.toe_off_window,
            cfg=cfg,
        )
        if math.isfinite(tau):
            if corr >= cfg.min_correlation:
                result["toe_offs"].append(tau)
            else:
                result["rejected"] += 1
        # whole-cycle agreement around this swing peak: decides the sign of the axis
        _, cycle_corr = _align(
            t,
            omega,
            tp,
            stride_s=stride,
            speed=speed,
            event_phase=phase_peak,
            window=(-0.5, 0.5),
            cfg=cfg,
        )
        scores.append(cycle_corr)
    # de-duplicate strike candidates (each interior strike is found from both neighbours)
    candidates.sort()
    groups: list[list[tuple[float, float]]] = []
    for tau, corr in candidates:
        if groups and tau - groups[-1][-1][0] < 0.25 * cfg.min_stride_s:
            groups[-1].append((tau, corr))
        else:
            groups.append([(tau, corr)])
    for group in groups:
        tau, corr = max(group, key=lambda x: x[1])
        # A foot strike ends a swing: a swing peak must precede it by 0.1-0.6 strides, unless
        # the recording starts too late to show that swing.
        stride = float(np.median(strides))
        lag = tau - t_peaks
        after_swing = bool(np.any((lag >= 0.1 * stride) & (lag <= 0.6 * stride)))
        if not after_swing and tau - t[0] > 0.5 * stride:
            result["rejected"] += 1
            continue
        if corr >= cfg.min_correlation:
            result["strikes"].append(tau)
            result["strike_corr"].append(corr)
        else:
            result["rejected"] += 1
    result["score"] = float(np.mean(scores)) if scores else 0.0
    result["toe_offs"] = sorted(set(np.round(result["toe_offs"], 6)))
    return result


def _long_axis(imu: ImuSeries) -> np.ndarray:
    """The thigh's long axis in the sensor frame: the mean specific force (gravity, on average
    along the thigh, which swings about the vertical)."""
    a = np.asarray(imu.accel_m_s2, dtype=float).mean(axis=0)
    return a / max(float(np.linalg.norm(a)), 1e-9)


def sagittal_axis(
    gyro_rad_s: np.ndarray, long_axis: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """Principal axis of the angular velocity (unsigned) and its share of the variance.

    ``long_axis`` (unit, sensor frame): the rotation about the thigh's long axis (turning,
    internal/external rotation) is removed first, so that turns while walking do not tilt the
    flexion axis; the share is then that of the remaining variance."""
    g = np.asarray(gyro_rad_s, dtype=float)
    if long_axis is not None:
        u = np.asarray(long_axis, dtype=float)
        g = g - np.outer(g @ u, u)
    cov = np.cov((g - np.median(g, axis=0)).T)
    eigval, eigvec = np.linalg.eigh(cov)
    share = float(eigval[-1] / max(eigval.sum(), 1e-30))
    return eigvec[:, -1], share


def detect_from_thigh_imu(imu: ImuSeries, config: GaitEventConfig | None = None) -> DetectedEvents:
    """Foot strikes and toe-offs from a thigh IMU in any mounting orientation.

    See the module docstring for the method. Returns empty event lists (not an error) when no
    walking is found, e.g. when the wearer only stands.
    """
    cfg = config or GaitEventConfig()
    t, gyro, rate = _prepare_signal(imu, cfg)
    if t.size < 3:
        raise GaitDetectionError(f"{imu.source}: recording too short ({t.size} samples)")
    axis, share = sagittal_axis(gyro, _long_axis(imu))
    if share < 0.5:
        logger.warning(
            "%s: the principal rotation axis carries only %.0f%% of the angular-velocity "
            "variance; the sagittal axis may be ill-defined",
            imu.source,
            100 * share,
        )
    omega = gyro @ axis
    # The axis sign that makes the signal look like thigh flexion velocity (template score).
    results = []
    for sign in (1.0, -1.0):
        res = _detect_with_axis(t, sign * omega, cfg)
        res["sign"] = sign
        results.append(res)
    best = max(results, key=lambda r: (r["score"], len(r["strikes"])))
    if cfg.use_impacts:
        best, refined, sign_flag = _impact_sign_and_strikes(imu, t, omega, results, best)
    else:
        from kinematics.gait_impact import ImpactRefinement

        refined = ImpactRefinement(np.asarray(best["strikes"]), 0, 0.0, 0.0)
        best, sign_flag = {**best, "burst_ratio": math.nan}, False
    strikes, merged = merge_close_strikes(refined.strikes_s, cfg.min_stride_s, imu.source)
    toe_offs = np.asarray(best["toe_offs"])
    if toe_offs.size:
        toe_offs, _ = merge_close_strikes(toe_offs, cfg.min_stride_s * 0.5)
    if best["n_peaks"] == 0:
        logger.info(
            "%s: no swing peaks above %.2f rad/s: no walking found",
            imu.source,
            cfg.min_swing_peak_rad_s,
        )
    return DetectedEvents(
        foot_strikes_s=strikes,
        toe_offs_s=toe_offs,
        method="thigh_imu",
        merged_strikes=merged,
        rejected=int(best["rejected"]),
        sagittal_axis=best["sign"] * axis,
        details={
            "axis_variance_share": share,
            "template_score": best["score"],
            "input_rate_hz": rate,
            "swing_peaks": float(best["n_peaks"]),
            "impact_strikes": float(refined.from_impact),
            "impact_strength": refined.strength,
            "template_bias_s": refined.template_bias_s,
            "burst_ratio": best["burst_ratio"],
            "sign_disagreement": float(sign_flag),
        },
    )


def _impact_sign_and_strikes(imu: ImuSeries, t: np.ndarray, omega: np.ndarray, results, best):
    """The axis sign from the impact transients, and the strikes placed on them
    (:mod:`kinematics.gait_impact`).

    When the accelerometer shows impacts, the sign whose strikes carry the bursts (burst ratio
    above ``min_burst_ratio`` while the other sign's is below one) wins; when it differs from
    the template's choice, a warning says so and ``sign_disagreement`` is set. Without impacts,
    or when the ratios do not decide, the template's choice stands."""
    from kinematics.gait_impact import (
        ImpactConfig,
        burst_ratio,
        envelope,
        refine_strikes,
        typical_peak,
    )

    cfg = ImpactConfig()
    t_in = np.asarray(imu.t_s, dtype=float)
    env = envelope(t_in, imu.accel_m_s2, cfg)
    ratios = [
        burst_ratio(t_in, env, np.asarray(r["strikes"]), np.asarray(r["toe_offs"]), cfg)
        for r in results
    ]
    k_best = next(k for k, r in enumerate(results) if r is best)
    k_chosen, disagree = k_best, False
    strong = max(typical_peak(t_in, env, np.asarray(r["strikes"]), cfg)[1] for r in results)
    for k in range(len(results) if strong >= cfg.min_strength else 0):
        other = ratios[1 - k]
        if ratios[k] >= cfg.min_burst_ratio and (not math.isfinite(other) or other < 1.0):
            k_chosen, disagree = k, k != k_best
    if disagree:
        logger.warning(
            "%s: the flexion sign from the impact transients (strikes where the bursts are: "
            "ratio %.1f against %.1f) disagrees with the template fit; taking the impacts'",
            imu.source,
            max(ratios),
            min(ratios),
        )
    chosen = {**results[k_chosen], "burst_ratio": ratios[k_chosen]}
    refined = refine_strikes(t_in, env, np.asarray(chosen["strikes"]), cfg)
    return chosen, refined, disagree


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
    # drop chatter: a state that lasts less than its minimum removes both its transitions
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
    strikes = np.array([x for x, k in transitions if k == "foot_strike"])
    toe_offs = np.array([x for x, k in transitions if k == "toe_off"])
    strikes, pairs = _merge_pairs(strikes, cfg.min_stride_s, source)
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
