"""The phase lock of the online gait estimator (:mod:`kinematics.gait_phase`, steps 3-4): the
thigh-angle update (predict-only when saturated), walking or standing, the running offset and
scale of the angle, and the phase EKF (acquisition, step, stall test, loss of lock)."""

from __future__ import annotations

import math

import numpy as np

from kinematics.phase_model import measurement, measurement_jacobian
from kinematics.thigh_attitude import ThighState


class PhaseFilter:
    """The phase EKF and what feeds it: part of
    :class:`~kinematics.gait_phase.OnlineGaitEstimator`.

    State: the attributes :class:`~kinematics.gait_phase.OnlineGaitEstimator` sets in its
    ``__init__``; this class only groups its methods.
    """

    def _thigh_update(self, t_s, gyro, accel, saturated) -> ThighState:
        assert self.thigh is not None
        if not saturated:
            return self.thigh.update(t_s, gyro, accel)
        # saturated: predict only (the rate keeps its last estimate)
        kf = self.thigh.kf
        dt = t_s - self.thigh.t_s
        self.thigh.t_s = t_s
        kf.x[0] += dt * kf.x[1]
        kf.P[0, 0] += (dt * 2.0) ** 2
        return ThighState(t_s, float(kf.x[0]), float(kf.x[1]), float(kf.x[2]), 0.0, 0.0)

    def _walking_now(self, thigh: ThighState, dt: float) -> bool:
        cfg = self.cfg
        a = min(1.0, dt / cfg.rms_window_s)
        self._ms += a * (thigh.rate_rad_s**2 - self._ms)
        rms = math.sqrt(self._ms)
        self._still_s = self._still_s + dt if abs(thigh.rate_rad_s) < cfg.still_rate_rad_s else 0.0
        if self._walking:
            return rms > cfg.walk_off_rms_rad_s and self._still_s < cfg.still_window_s
        return rms > cfg.walk_on_rms_rad_s

    def _track_norm(self, angle_rad: float, dt: float, t_s: float) -> None:
        """Running offset and scale of the angle: its mean and standard deviation over the last
        cycle of walking samples, or the reference's values (relative to the standing posture)
        until 3/4 of a cycle has been seen."""
        self._walk_angles.append(angle_rad)
        self._walk_dt.append(dt)
        self._walk_n += 1  # the deques' length stops at their maxlen: counted apart
        if self._walk_n % 10 and self._ekf is not None:
            return
        rate = float(self._ekf.x[1]) if self._ekf is not None else self._rate_prior()
        # the window is the last stride (strike to strike) when there is one: a window that
        # follows the instantaneous rate would feed its errors back into the offset
        cycle_s = self._stride_s if self._stride_s is not None else 1.0 / max(rate, 0.3)
        span = np.cumsum(np.asarray(self._walk_dt)[::-1])
        if span[-1] < 0.75 * cycle_s:
            ref_std = self.ref.at_rate("std_rad", rate)
            if self._standing_seen:  # the reference's mean walking angle above standing
                mean = self._standing_angle + self.ref.at_rate("mean_rad", rate)
            else:  # no standing posture seen (the zero is arbitrary): the partial mean
                mean = float(np.mean(self._walk_angles))
            self._norm = (mean, ref_std)
            return
        # the last complete stride (strike to strike) when there is one: a window of the last
        # stride's length ending now covers less or more than a cycle when this stride is
        # longer or shorter, and the missing or doubled part (the swing's flexion peak) shifts
        # the offset by degrees
        since = t_s - self._last_event_t["foot_strike"]
        skip = 0
        if self._stride_s is not None and since < span[-1] - cycle_s:
            skip = int(np.searchsorted(span, since))
        n = int(np.searchsorted(span, cycle_s + since if skip else cycle_s)) + 1
        angles = np.asarray(self._walk_angles)
        recent = angles[-n : len(angles) - skip]
        self._norm = (float(recent.mean()), max(float(recent.std()), 0.02))

    def _z(self, thigh: ThighState) -> np.ndarray:
        m, s = self._norm
        return np.array([(thigh.angle_rad - m) / s, thigh.rate_rad_s / s])

    def _acquire(self, thigh: ThighState) -> None:
        """Start the EKF at the phase on the reference loop nearest the measurement."""
        from filterpy.kalman import ExtendedKalmanFilter

        cfg = self.cfg
        rate = self._rate_prior()
        phase = self._nearest_phase(thigh, rate)
        ekf = ExtendedKalmanFilter(dim_x=2, dim_z=2)
        ekf.x = np.array([phase, rate])
        ekf.P = np.diag([0.1**2, 0.2**2])
        ekf.R = np.diag([cfg.angle_sigma**2, cfg.rate_sigma**2])
        self._ekf = ekf
        self._nis = 2.0
        # an event the lock has just passed (a re-acquisition near it) is still emitted, once:
        # the spacing rule drops it if it was emitted before the lock was lost
        grace = self.cfg.acquire_grace_cyc
        passed = phase % 1.0 < grace or self._skipped_strike(thigh.t_s, phase, rate)
        self._next_strike = math.floor(phase) + (0 if passed else 1)
        sf = self.ref.at_rate("stance_fraction", rate)
        self._next_toe_off = math.floor(phase) + (1 if phase % 1.0 >= sf + grace else 0)
        self.counts["reacquired"] += 1
        self._relocked = True
        self._held_s = 0.0

    def _nearest_phase(self, thigh: ThighState, rate: float) -> float:
        """The phase on the reference loop (at ``rate``) nearest the measurement."""
        cfg = self.cfg
        a, b = self.ref.coefficients(rate)
        grid = np.arange(200) / 200.0
        z = self._z(thigh)
        cost = [
            ((z - measurement(np.array([p, rate]), a, b)) / [cfg.angle_sigma, cfg.rate_sigma])
            @ ((z - measurement(np.array([p, rate]), a, b)) / [cfg.angle_sigma, cfg.rate_sigma])
            for p in grid
        ]
        return float(grid[int(np.argmin(cost))])

    def _rate_prior(self) -> float:
        """The cadence of the last strides in this walk, else the last estimate, else that of
        1.2 m/s (the EKF's own rate is the one a lost lock got wrong)."""
        stride = self._recent_stride_s()
        if stride is not None:
            return float(np.clip(1.0 / stride, 0.3, 2.0))
        return self._last_rate if self._last_rate is not None else float(self.ref.rates_cyc_s[12])

    def _recent_stride_s(self) -> float | None:
        """The median of the last strides, else the cycle seen while learning the axis."""
        if self._strides:
            return float(np.median(self._strides))
        return self._buffer_stride_s

    def _plausible_stride_s(self) -> float:
        """The last strides' median, else the cadence prior's stride, within the adult range
        (the reference curves: 0.92-1.59 s at 1.8-0.6 m/s): a rate held at its lower bound in
        a lost lock (0.3 cycle/s) is no stride."""
        stride = self._recent_stride_s() or 1.0 / self._rate_prior()
        return float(np.clip(stride, 0.9, 1.6))

    def _skipped_strike(self, t_s: float, phase: float, rate: float) -> bool:
        """A re-acquisition in stance (before the toe-off) of a walk whose lock was lost before
        this cycle's strike was emitted (the last strike more than 0.6 stride before it): that
        strike is still emitted (at the phase's estimate, or its impact)."""
        stride = self._recent_stride_s()
        if stride is None or phase % 1.0 >= self.ref.at_rate("stance_fraction", rate):
            return False
        strike_s = t_s - (phase % 1.0) / rate
        return strike_s - self._last_event_t["foot_strike"] > 0.6 * stride

    def _ekf_step(self, thigh: ThighState, dt: float, saturated: bool) -> int:
        cfg, ekf = self.cfg, self._ekf
        flags = 0
        ekf.F = np.array([[1.0, dt], [0.0, 1.0]])
        qp = cfg.phase_walk_cyc_per_sqrt_s**2 * dt
        qr = cfg.rate_walk_cyc_s_per_sqrt_s**2 * dt
        ekf.Q = np.array([[qp + qr * dt**2 / 3, qr * dt / 2], [qr * dt / 2, qr]])
        self._phase_floor = float(ekf.x[0])
        ekf.predict()
        if saturated:
            return flags
        rate = float(np.clip(ekf.x[1], self.ref.rates_cyc_s[0], self.ref.rates_cyc_s[-1]))
        a, b = self.ref.coefficients(rate)
        before = float(ekf.x[0])
        if self._stalled(thigh, a, b, rate, dt):
            self.counts["stops"] += 1
            self._lose_lock(forget=True)
            return flags | 32
        ekf.update(self._z(thigh), measurement_jacobian, measurement, args=(a, b), hx_args=(a, b))
        held = float(ekf.x[0]) < self._phase_floor or float(ekf.x[1]) <= 0.3
        ekf.x[1] = float(np.clip(ekf.x[1], 0.3, 2.0))
        # the gait phase does not run backwards: an update that would move it behind the
        # previous estimate holds it there (the innovation then grows and, if the model keeps
        # failing, the NIS test re-acquires)
        ekf.x[0] = max(float(ekf.x[0]), self._phase_floor)
        if self._held_longer(held, thigh.t_s, dt):
            return flags
        self._phase_floor = float(ekf.x[0])
        if not held:  # a rate held at its bound is the lost lock's, not the walker's
            self._last_rate = float(ekf.x[1])
        if abs(float(ekf.x[0]) - before) > cfg.max_phase_step_cyc:
            self.counts["phase_jumps"] += 1
            flags |= 8
        nis = float(ekf.y @ ekf.SI @ ekf.y)
        self._nis_sum += nis
        self._nis_n += 1
        self._nis += min(1.0, dt / cfg.rms_window_s) * (nis - self._nis)
        if self._nis > cfg.max_nis:
            self._lose_lock(forget=False)
        return flags

    def _held_longer(self, held: bool, t_s: float, dt: float) -> bool:
        """The update has held the phase at its floor (it wanted to run backwards) or the rate
        at its lower bound for ``max_hold_s`` within a walk (a stride measured, a strike in the
        last 2.5 s): the lock is lost (the EKF has settled on a wrong branch of the reference
        loop, as in a turn's short, flat steps); re-acquired at the next sample (counted as
        ``holds``). Before a stride is measured the walk is starting from standing, its first
        steps slower and flatter than the reference: a hold there is not a lost lock."""
        self._held_s = self._held_s + dt if held else 0.0
        in_walk = bool(self._strides) and t_s - self._last_event_t["foot_strike"] < 2.5
        if self._held_s < self.cfg.max_hold_s or not in_walk:
            return False
        self.counts["holds"] += 1
        self._held_s = 0.0
        self._lose_lock(forget=False)
        return True

    def _stalled(self, thigh: ThighState, a: np.ndarray, b: np.ndarray, rate: float, dt: float):
        """A stop in stance: the thigh rate stays below ``stall_ratio`` of the model's (the
        stance extension) for ``stall_s``; the rate filter alone would take a cycle to notice."""
        cfg, x = self.cfg, self._ekf.x
        frac = float(x[0]) % 1.0
        expected = abs(float(measurement(x, a, b)[1]) * self._norm[1])
        in_stance = cfg.stall_from_phase < frac < self.ref.at_rate("stance_fraction", rate)
        if in_stance and abs(thigh.rate_rad_s) < cfg.stall_ratio * expected:
            self._stall_s += dt
        else:
            self._stall_s = 0.0
        return self._stall_s >= cfg.stall_s

    def _lose_lock(self, forget: bool = True) -> None:
        """Drop the phase (re-acquired at the next walking sample); ``forget`` also drops the
        walking history (offset, scale, cadence): after standing or a gap."""
        self._ekf = None
        self.timing.window = None
        self._armed_for = None
        if forget:
            self._walking = False
            self._ms = 0.0
            self._walk_angles.clear()
            self._walk_n = 0
            self._walk_dt.clear()
            self._stride_s = None
            self._strides.clear()
