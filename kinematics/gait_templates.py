"""Events along one sign of the sagittal axis, by template alignment (steps 1 and 3-4 of
:mod:`kinematics.gait_events`): the signal resampled and low-passed, mid-swing peaks, the local
stride time and speed, and the reference thigh-velocity template aligned to each foot strike and
toe-off by normalised cross-correlation."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from kinematics.gait_event_config import GaitEventConfig
from kinematics.gait_io import validate_imu
from kinematics.imu import ImuSeries


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


def prepare_signal(imu: ImuSeries, cfg: GaitEventConfig) -> tuple[np.ndarray, np.ndarray, float]:
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


def detect_with_axis(t: np.ndarray, omega: np.ndarray, cfg: GaitEventConfig) -> dict:
    """Foot strikes and toe-offs with the flexion velocity ``omega`` (one sign of the axis),
    the candidates rejected, and the whole-cycle template score that decides the sign."""
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
        scores.append(_align_swing(t, omega, tp, stride, cfg, candidates, result))
    _accept_strikes(t, t_peaks, strides, candidates, cfg, result)
    result["score"] = float(np.mean(scores)) if scores else 0.0
    result["toe_offs"] = sorted(set(np.round(result["toe_offs"], 6)))
    return result


def _align_swing(
    t: np.ndarray,
    omega: np.ndarray,
    tp: float,
    stride: float,
    cfg: GaitEventConfig,
    candidates: list[tuple[float, float]],
    result: dict,
) -> float:
    """Align the template around the swing peak at ``tp``: the two strike candidates (the
    strike ending this swing and the one starting its cycle) go to ``candidates``, the toe-off
    to ``result`` (or its rejection count); returns the whole-cycle correlation."""
    from kinematics.gait_curves import stance_fraction

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
    return cycle_corr


def _accept_strikes(
    t: np.ndarray,
    t_peaks: np.ndarray,
    strides: np.ndarray,
    candidates: list[tuple[float, float]],
    cfg: GaitEventConfig,
    result: dict,
) -> None:
    """The strikes among the candidates: one per group of close candidates (the best
    correlated), after a swing, correlated enough; the others counted as rejected."""
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
