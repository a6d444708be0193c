"""Synthetic thigh-IMU recordings for the online gait estimator: walking bouts with a speed per
stride (speed changes), separated by standing (stop-and-go, standing only), with true events.

Like :func:`kinematics.gait_synth.thigh_imu_from_reference` (which it generalises): each bout
starts from standing at mid-stance (phase 0.3), blends into the reference curves by phase 0.55,
walks its strides, and blends back to standing between phase N + 0.3 and N + 0.5 (before the
toe-off that would follow). Stride k of a bout lasts the adult stride time of its speed
(:func:`kinematics.gait_curves.stride_time_s`, ± ``stride_time_jitter``); the thigh angle is the
reference curve at the speed interpolated between stride centres. True foot strikes are the
integer phases of each bout; true toe-offs the phases k + stance fraction (k = 0 .. N - 1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from kinematics.gait_curves import stride_time_s
from kinematics.gait_patterns import ABLE_BODIED, GaitPattern, shock
from kinematics.gait_synth import (
    ImuNoise,
    _imu_from_pose_functions,
    _invert,
    _rx,
    _ry,
    _rz,
    _smoothstep,
)
from kinematics.imu import ImuSeries


@dataclass(frozen=True)
class Scenario:
    """A synthetic recording and its truth (``walking_intervals_s``: (start, end) per bout)."""

    imu: ImuSeries
    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    walking_intervals_s: list[tuple[float, float]]
    load_n: np.ndarray | None = None
    """The prosthesis's axial load at the IMU's sample times (N; 750 N in contact, ramps of
    40 ms, noise σ 8 N; loaded while standing)."""
    knee_rad: np.ndarray | None = None
    """The knee flexion of the pattern at the IMU's sample times (0 while standing)."""


@dataclass(frozen=True)
class _Bout:
    knots_t: np.ndarray
    knots_phase: np.ndarray
    speeds: np.ndarray
    phase_fn: CubicSpline

    def speed_at(self, phase: np.ndarray) -> np.ndarray:
        centres = np.arange(self.speeds.size) + 0.5
        return np.interp(phase, centres, self.speeds)


def _bouts(
    speeds_per_bout: Sequence[Sequence[float]],
    stand_s: float,
    rng: np.random.Generator,
    jitter: float,
) -> tuple[list[_Bout], float]:
    out, t0 = [], stand_s
    for speeds in speeds_per_bout:
        v = np.asarray(speeds, dtype=float)
        n = v.size
        knots_phase = np.concatenate([[0.3], np.arange(1, n + 1), [n + 0.5]])
        stride = np.array([stride_time_s(float(s)) for s in v]) * (
            1 + jitter * rng.standard_normal(n)
        )
        seg = np.diff(knots_phase) * np.concatenate([stride, [stride[-1]]])
        knots_t = t0 + np.concatenate([[0.0], np.cumsum(seg)])
        out.append(_Bout(knots_t, knots_phase, v, CubicSpline(knots_t, knots_phase)))
        t0 = knots_t[-1] + stand_s
    return out, t0


def simulate_walks(
    speeds_per_bout: Sequence[Sequence[float]],
    *,
    stand_s: float = 3.0,
    rate_hz: float = 200.0,
    thigh_R_sensor: np.ndarray | None = None,
    noise: ImuNoise | None = None,
    seed: int = 0,
    stride_time_jitter: float = 0.02,
    pattern: GaitPattern = ABLE_BODIED,
    turns: Sequence[tuple[float, float, float]] = (),
) -> Scenario:
    """Stand ``stand_s``, walk bout 1 (one speed per stride), stand, walk bout 2, ..., stand.

    ``speeds_per_bout=[]`` gives standing only (``stand_s`` long). ``pattern``: the gait's
    departure from the reference (:mod:`kinematics.gait_patterns`: prosthetic or sound side,
    treadmill, heel-strike shock). ``turns``: ``(start_s, duration_s, angle_rad)`` each, a
    change of heading (rotation of the whole leg about the vertical, counter-clockwise +)
    smoothly over the interval; the walking direction follows the heading."""
    rng = np.random.default_rng(seed)
    bouts, total = _bouts(speeds_per_bout, stand_s, rng, stride_time_jitter)
    sway_f = rng.uniform(0.15, 0.5, 3)
    sway_p = rng.uniform(0, 2 * np.pi, 3)

    def fields(t: np.ndarray):
        t = np.asarray(t, dtype=float)
        stand = math.radians(2.0) + sum(
            math.radians(0.4) * np.sin(2 * np.pi * f * t + p)
            for f, p in zip(sway_f, sway_p, strict=True)
        )
        sag, add, rot, w_all, ph_all = (
            stand.copy(),
            np.zeros_like(t),
            np.zeros_like(t),
            *(np.zeros_like(t) for _ in range(2)),
        )
        for b in bouts:
            inside = (t > b.knots_t[0]) & (t < b.knots_t[-1])
            if not inside.any():
                continue
            ph = b.phase_fn(t[inside])
            end = b.knots_phase[-1]
            w = np.minimum(
                _smoothstep((ph - 0.3) / 0.25), 1 - _smoothstep((ph - (end - 0.2)) / 0.2)
            )
            # the curve between the speeds of a 0.01 m/s grid, interpolated (a rounded speed
            # would step the angle, and a step is a spurious shock in the accelerometer)
            v = b.speed_at(ph) * 100.0
            lo = np.floor(v)
            frac = v - lo
            curve = np.empty_like(ph)
            for s in np.unique(lo):
                m = lo == s
                a = pattern.thigh(ph[m] % 1.0, float(s) / 100.0)
                c = pattern.thigh(ph[m] % 1.0, min(float(s) + 1.0, 180.0) / 100.0)
                curve[m] = a + frac[m] * (c - a)
            sag[inside] = stand[inside] + w * (curve - stand[inside])
            add[inside] = w * math.radians(3.0) * np.sin(2 * np.pi * ph + 0.5)
            rot[inside] = w * math.radians(5.0) * np.sin(2 * np.pi * ph - 0.8)
            w_all[inside], ph_all[inside] = w * b.speed_at(ph), ph
        return sag, add, rot, w_all, ph_all

    def heading(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return sum((a * _smoothstep((t - t0) / d) for t0, d, a in turns), np.zeros_like(t))

    def world_r_thigh(t: np.ndarray):
        sag, add, rot, _, _ = fields(t)
        return _rz(heading(t)) * _ry(-sag) * _rx(add) * _rz(rot)

    dt = 1.0 / rate_hz
    fine_t = np.arange(0.0, total, dt / 4)
    _, _, _, vel, ph_fine = fields(fine_t)
    pos = np.zeros((fine_t.size, 3))
    if not pattern.treadmill:
        psi = heading(fine_t)
        pos[:, 0] = np.cumsum(vel * np.cos(psi)) * (dt / 4)
        pos[:, 1] = np.cumsum(vel * np.sin(psi)) * (dt / 4)
    pos[:, 2] = 0.9 + 0.02 * (vel / 1.8) * np.cos(4 * np.pi * ph_fine)  # smooth bob
    splines = [CubicSpline(fine_t, pos[:, i]) for i in range(3)]

    def world_p_imu(t: np.ndarray) -> np.ndarray:
        hip = np.stack([s(np.clip(t, fine_t[0], fine_t[-1])) for s in splines], axis=-1)
        return hip + world_r_thigh(t).apply(np.array([0.0, -0.07, -0.25]))

    t = np.arange(0.0, total - dt, dt) + 1e-3
    imu = _imu_from_pose_functions(
        t,
        world_r_thigh,
        world_p_imu,
        up_axis=np.array([0.0, 0.0, 1.0]),
        thigh_R_sensor=np.eye(3) if thigh_R_sensor is None else np.asarray(thigh_R_sensor),
        noise=noise or ImuNoise(),
        rng=rng,
        source=f"simulated walks {[list(b) for b in speeds_per_bout]} (synthetic IMU)",
    )
    strikes, toe_offs = [], []
    for b in bouts:
        strikes += list(b.knots_t[1:-1])
        for k in range(b.speeds.size):
            sf = pattern.stance(float(b.speed_at(np.array([k + 0.6]))[0]))
            toe_offs.append(_invert(b.phase_fn, k + sf, b.knots_t))
    if pattern.impact_m_s2 > 0:
        mount = np.eye(3) if thigh_R_sensor is None else np.asarray(thigh_R_sensor)
        accel = imu.accel_m_s2 + shock(imu.t_s, np.asarray(strikes), pattern.impact_m_s2) @ mount
        imu = ImuSeries(imu.t_s, imu.gyro_rad_s, accel, imu.source)
    load, knee = _prosthesis_signals(imu.t_s, bouts, strikes, toe_offs, pattern, rng)
    return Scenario(
        imu=imu,
        foot_strikes_s=np.asarray(strikes),
        toe_offs_s=np.asarray(toe_offs),
        walking_intervals_s=[(float(b.knots_t[0]), float(b.knots_t[-1])) for b in bouts],
        load_n=load,
        knee_rad=knee,
    )


def _prosthesis_signals(t, bouts, strikes, toe_offs, pattern, rng):
    """Load cell and knee encoder of a walk (see :class:`Scenario`)."""
    from kinematics.gait_patterns import knee_angle

    events = sorted([(s, True) for s in strikes] + [(s, False) for s in toe_offs])
    contact = np.ones(t.size)
    for te, on in events:
        contact[t >= te] = 1.0 if on else 0.0
    ramp = max(1, round(0.04 / float(np.median(np.diff(t)))))
    smooth = np.convolve(contact, np.ones(ramp) / ramp)[: t.size]  # causal 40 ms ramps
    load = 750.0 * smooth + rng.normal(0.0, 8.0, t.size)
    knee = np.zeros(t.size)
    for b in bouts:
        inside = (t > b.knots_t[0]) & (t < b.knots_t[-1])
        if inside.any():
            ph = b.phase_fn(t[inside])
            w = np.minimum(
                _smoothstep((ph - 0.3) / 0.25),
                1 - _smoothstep((ph - (b.knots_phase[-1] - 0.2)) / 0.2),
            )
            knee[inside] = w * knee_angle(pattern, ph % 1.0, float(np.mean(b.speeds)))
    return load, knee


def speed_change(slow_m_s: float = 0.8, fast_m_s: float = 1.6, strides: int = 10) -> list[float]:
    """Speeds per stride: a third slow, a change over 3 strides, the rest fast."""
    n_slow = strides // 3
    ramp = list(np.linspace(slow_m_s, fast_m_s, 5)[1:-1])
    return [slow_m_s] * n_slow + ramp + [fast_m_s] * (strides - n_slow - len(ramp))
