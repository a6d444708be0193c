"""The thigh's sagittal angle and angular velocity from a thigh IMU, causally (one sample in,
one estimate out), in an unknown mounting orientation.

Two stages, both causal:

1. :class:`SagittalAxisLearner`: the sagittal (flexion) axis in the sensor frame is the principal
   axis of the angular velocity, as in the offline detector
   (:func:`kinematics.gait_events.sagittal_axis`), but learned from the samples seen so far: the
   learner buffers samples until it has seen a whole cycle (the projected rate beyond ±35 % of
   its peak for at least 0.12 s three times in alternating directions, the larger peak at least
   ``min_swing_peak_rad_s``); the axis sign makes flexion positive, chosen by the gait's
   asymmetry (the mid-swing flexion-velocity peak is 1.3-1.9 times the stance extension
   velocity; a partial cycle can fake it, hence the whole-cycle rule). The zero angle is the
   gravity direction of the quiet samples before the first motion (the standing posture), or
   the mean of the buffer when there were none; :func:`initial_angle` gives the angle at the
   buffer's start from the gyro integral matched to gravity. The learner never looks at a
   sample after the one being processed.
2. :class:`ThighAngleFilter`: a filterpy :class:`~filterpy.kalman.KalmanFilter` with the state
   ``[angle_rad, rate_rad_s, gyro_bias_rad_s]`` (sagittal angle from the standing posture,
   flexion +; its rate; the gyro bias about the axis). The angle is propagated with the rate
   (white angular-acceleration noise); the gyro projected on the axis measures rate + bias;
   the gravity direction projected in the sagittal plane measures the angle, with a σ that
   grows with the accelerometer's departure from 1 g (the thigh's own acceleration).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinematics.errors import GaitInputError

GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class ThighAttitudeConfig:
    """Noise and learning parameters of the thigh-angle filter (SI units, radians)."""

    gyro_sigma_rad_s: float = 0.03
    """White noise of the gyro (per sample)."""
    angular_accel_sigma_rad_s2: float = 60.0
    """Process noise: the thigh's angular acceleration (swing reaches ~30-40 rad/s²)."""
    bias_walk_rad_s_per_sqrt_s: float = 0.002
    """Random walk of the gyro bias."""
    accel_angle_sigma_rad: float = 0.25
    """σ of the angle from gravity while the accelerometer reads 1 g (walking adds ~0.1-0.3 rad
    of linear-acceleration error)."""
    accel_angle_sigma_per_m_s2: float = 0.15
    """Extra σ (rad) of the gravity angle per m/s² of departure from 1 g."""
    quiet_gyro_rad_s: float = 0.25
    """A sample with a smaller angular-rate norm is quiet (standing) for the zero-angle and the
    initial bias."""
    min_swing_peak_rad_s: float = 0.8
    """The axis is fixed once the projected angular velocity has reached this peak (a prosthesis
    side's thigh swings at 1.2 rad/s at most at 0.6 m/s, reduced swing flexion; standing sway
    stays below 0.2 rad/s)."""
    min_moving_s: float = 0.4
    """... and at least this much time of motion has been seen."""
    max_peak_ratio: float = 0.88
    """The sign is fixed once the smaller of the two projected peaks (flexion, extension) is
    below this fraction of the larger (reference: 0.53 at 0.6 m/s, 0.78 at 1.8 m/s)."""
    min_counter_peak_rad_s: float = 0.5
    """... and the other direction has reached this (one swing and one stance seen)."""
    segment_fraction: float = 0.35
    """The axis is fixed once the projected rate has gone beyond ±this fraction of its peak
    three times in alternating directions (a whole cycle seen: a partial one can fake the
    asymmetry; the fraction skips the small loading-response bump after a foot strike)."""
    max_learn_s: float = 8.0
    """Longest buffer kept while learning (older samples are dropped)."""
    min_wait_moving_s: float = 3.2
    """Once the buffer spans ``max_learn_s`` without a whole cycle, the axis is fixed from what
    it holds, but only after the motion in it spans this long (two strides at the slowest
    adult cadence, 1.6 s): a long standing start fills the buffer, and is no reason to give
    up at the first swing."""


@dataclass(frozen=True)
class SagittalAxis:
    """The learned sagittal frame in the sensor frame: ``axis`` (flexion +), the zero-angle
    gravity direction ``zero_up`` (unit, ⟂ axis), the initial gyro bias about the axis."""

    axis: np.ndarray
    zero_up: np.ndarray
    gyro_bias_rad_s: float
    learned_at_s: float
    variance_share: float


def _segments(t_s: np.ndarray, rate: np.ndarray, deadband: float, min_run_s: float) -> int:
    """Number of alternating runs of one sign in ``rate`` beyond ±``deadband`` that last at
    least ``min_run_s`` (three: one direction, the other, the first again — a whole cycle; the
    short loading-response bump after a foot strike does not count)."""
    beyond = np.abs(rate) > deadband
    signs, times = np.sign(rate[beyond]), t_s[beyond]
    if signs.size == 0:
        return 0
    cuts = np.flatnonzero(np.diff(signs)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [signs.size]]) - 1
    long_runs = [
        signs[a] for a, b in zip(starts, ends, strict=True) if times[b] - times[a] >= min_run_s
    ]
    if not long_runs:
        return 0
    return int(1 + np.count_nonzero(np.diff(long_runs)))


def flipped(axis: SagittalAxis) -> SagittalAxis:
    """The same sagittal frame with the opposite flexion sense."""
    return SagittalAxis(
        axis=-axis.axis,
        zero_up=axis.zero_up,
        gyro_bias_rad_s=-axis.gyro_bias_rad_s,
        learned_at_s=axis.learned_at_s,
        variance_share=axis.variance_share,
    )


def initial_angle(
    axis: SagittalAxis,
    t_s: np.ndarray,
    gyro_rad_s: np.ndarray,
    accel_m_s2: np.ndarray,
    config: ThighAttitudeConfig | None = None,
) -> float:
    """The sagittal angle at ``t_s[0]`` from a buffer of samples: the gyro integral over the
    buffer is exact up to its start value, the gravity angle is right on average (each sample
    weighted by its σ): start value = weighted mean of (gravity angle - gyro integral). Much
    better than the first sample's gravity angle, which the thigh's own acceleration corrupts."""
    cfg = config or ThighAttitudeConfig()
    t = np.asarray(t_s, dtype=float)
    g = np.asarray(gyro_rad_s, dtype=float) @ axis.axis - axis.gyro_bias_rad_s
    a = np.asarray(accel_m_s2, dtype=float)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(t))])
    e2 = np.cross(axis.axis, axis.zero_up)
    grav = -np.arctan2(a @ e2, a @ axis.zero_up)
    diff = np.unwrap(grav - integral)
    sigma = cfg.accel_angle_sigma_rad + cfg.accel_angle_sigma_per_m_s2 * np.abs(
        np.linalg.norm(a, axis=1) - GRAVITY_M_S2
    )
    w = 1.0 / sigma**2
    return float(math.remainder(float(np.sum(w * diff) / np.sum(w)), 2 * math.pi))


class SagittalAxisLearner:
    """Buffers samples until the sagittal axis can be fixed (see the module docstring)."""

    def __init__(self, config: ThighAttitudeConfig | None = None) -> None:
        self.cfg = config or ThighAttitudeConfig()
        self.t: list[float] = []
        self.gyro: list[np.ndarray] = []
        self.accel: list[np.ndarray] = []
        self._moving_s = 0.0

    def add(self, t_s: float, gyro: np.ndarray, accel: np.ndarray) -> SagittalAxis | None:
        """Add one sample; return the axis once it is learned (else None)."""
        if self.t:
            dt = t_s - self.t[-1]
            if np.linalg.norm(gyro) > self.cfg.quiet_gyro_rad_s:
                self._moving_s += dt
        self.t.append(t_s)
        self.gyro.append(gyro)
        self.accel.append(accel)
        while self.t[-1] - self.t[0] > self.cfg.max_learn_s:
            self.t.pop(0)
            self.gyro.pop(0)
            self.accel.pop(0)
        if self._moving_s < self.cfg.min_moving_s:
            return None
        return self._try_fix()

    def _try_fix(self) -> SagittalAxis | None:
        g = np.asarray(self.gyro)
        a = np.asarray(self.accel)
        quiet = np.linalg.norm(g, axis=1) <= self.cfg.quiet_gyro_rad_s
        bias = g[quiet].mean(axis=0) if quiet.sum() >= 20 else np.zeros(3)
        gc = g - bias
        # rotation about the thigh's long axis (the mean specific force: turns, internal and
        # external rotation) is not flexion: removed before the principal axis
        long_axis = a.mean(axis=0) / max(float(np.linalg.norm(a.mean(axis=0))), 1e-9)
        gc = gc - np.outer(gc @ long_axis, long_axis)
        cov = gc.T @ gc / len(gc)
        eigval, eigvec = np.linalg.eigh(cov)
        axis = eigvec[:, -1]
        w = gc @ axis
        pos, neg = float(w.max()), float(-w.min())
        peak = max(pos, neg)
        if peak < self.cfg.min_swing_peak_rad_s:
            return None
        # a buffer full of standing is no reason to give up on a whole cycle at the first swing
        first_moving = self.t[int(np.argmax(~quiet))]
        full = (
            self.t[-1] - self.t[0] >= self.cfg.max_learn_s * 0.99
            and self.t[-1] - first_moving >= self.cfg.min_wait_moving_s
        )
        if not full and (
            _segments(np.asarray(self.t), w, self.cfg.segment_fraction * peak, 0.12) < 3
            or min(pos, neg) < self.cfg.min_counter_peak_rad_s
            or min(pos, neg) > self.cfg.max_peak_ratio * peak
        ):
            return None  # not both directions yet, or no clear asymmetry: wait
        if neg > pos:
            axis = -axis
        up = a[quiet].mean(axis=0) if quiet.sum() >= 20 else a.mean(axis=0)
        up = up - (up @ axis) * axis
        norm = float(np.linalg.norm(up))
        if norm < 1e-6:
            return None
        return SagittalAxis(
            axis=axis,
            zero_up=up / norm,
            gyro_bias_rad_s=float(bias @ axis),
            learned_at_s=self.t[-1],
            variance_share=float(eigval[-1] / max(eigval.sum(), 1e-30)),
        )


@dataclass(frozen=True)
class ThighState:
    """One estimate of the thigh filter: sagittal angle (from the standing posture, flexion +),
    rate, gyro bias about the axis, and the σ of each."""

    t_s: float
    angle_rad: float
    rate_rad_s: float
    gyro_bias_rad_s: float
    angle_sigma_rad: float
    rate_sigma_rad_s: float


class ThighAngleFilter:
    """Kalman filter (filterpy) of the sagittal angle, rate and gyro bias about a known axis."""

    def __init__(
        self,
        axis: SagittalAxis,
        t0_s: float,
        config: ThighAttitudeConfig | None = None,
        initial_angle_rad: float | None = None,
    ):
        from filterpy.kalman import KalmanFilter

        self.cfg = config or ThighAttitudeConfig()
        self.axis = axis
        self._e2 = np.cross(axis.axis, axis.zero_up)
        kf = KalmanFilter(dim_x=3, dim_z=2)
        kf.x = np.array([0.0, 0.0, axis.gyro_bias_rad_s])
        kf.P = np.diag([0.3**2, 1.0**2, 0.05**2])
        kf.H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
        self.kf = kf
        self.t_s = t0_s
        self._first = initial_angle_rad is None
        if initial_angle_rad is not None:
            kf.x[0] = initial_angle_rad
            kf.P[0, 0] = 0.05**2

    def flip(self) -> None:
        """Reverse the flexion sense: the axis, the angle, the rate and the bias change sign."""
        self.axis = flipped(self.axis)
        self._e2 = -self._e2
        self.kf.x = -self.kf.x

    def gravity_angle(self, accel: np.ndarray) -> float:
        """Sagittal angle measured by gravity: the thigh flexing by θ about the axis turns the
        sensor-frame gravity by -θ."""
        return -math.atan2(float(accel @ self._e2), float(accel @ self.axis.zero_up))

    def update(self, t_s: float, gyro: np.ndarray, accel: np.ndarray) -> ThighState:
        cfg, kf = self.cfg, self.kf
        dt = t_s - self.t_s
        if dt < 0:
            raise GaitInputError(f"t_s={t_s}: time must not decrease (previous {self.t_s})")
        self.t_s = t_s
        angle_meas = self.gravity_angle(accel)
        if self._first:
            kf.x[0] = angle_meas
            self._first = False
        if dt > 0:
            kf.F = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            qa = cfg.angular_accel_sigma_rad_s2**2
            kf.Q = np.array(
                [
                    [qa * dt**4 / 4, qa * dt**3 / 2, 0.0],
                    [qa * dt**3 / 2, qa * dt**2, 0.0],
                    [0.0, 0.0, cfg.bias_walk_rad_s_per_sqrt_s**2 * dt],
                ]
            )
            kf.predict()
        off_g = abs(float(np.linalg.norm(accel)) - GRAVITY_M_S2)
        sigma_a = cfg.accel_angle_sigma_rad + cfg.accel_angle_sigma_per_m_s2 * off_g
        kf.R = np.diag([sigma_a**2, cfg.gyro_sigma_rad_s**2])
        # unwrap the gravity angle next to the prediction
        angle_meas = kf.x[0] + math.remainder(angle_meas - kf.x[0], 2 * math.pi)
        kf.update(np.array([angle_meas, float(gyro @ self.axis.axis)]))
        return ThighState(
            t_s=t_s,
            angle_rad=float(kf.x[0]),
            rate_rad_s=float(kf.x[1]),
            gyro_bias_rad_s=float(kf.x[2]),
            angle_sigma_rad=float(math.sqrt(kf.P[0, 0])),
            rate_sigma_rad_s=float(math.sqrt(kf.P[1, 1])),
        )
