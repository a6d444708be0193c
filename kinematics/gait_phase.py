"""Online gait state from a thigh IMU: gait phase, cadence, foot strikes and toe-offs as they
happen (causal: each sample is processed once, in order, and nothing reads ahead).

Per sample (:meth:`OnlineGaitEstimator.update`):

1. input checks: a non-finite sample is dropped, a saturated one is only predicted through, a
   gap longer than ``max_gap_s`` drops the phase lock (re-acquired after it); each is counted in
   :attr:`OnlineGaitEstimator.counts`; time going backwards is a :class:`GaitInputError`;
2. the thigh's sagittal angle and rate (:mod:`kinematics.thigh_attitude`; the samples buffered
   while the sagittal axis is learned are replayed once it is fixed, and the events found in
   them are emitted then, with that sample's time as their detection time);
3. walking or standing, from the running RMS of the thigh rate (hysteresis) and a stop test in
   stance (the thigh rate below a quarter of the model's for 60 ms); standing freezes the phase
   (no prediction, no events) and the next walk re-acquires it;
4. a filterpy :class:`~filterpy.kalman.ExtendedKalmanFilter` on ``x = [phase_cyc, rate_cyc_s]``
   (constant-rate process with white rate noise) with the measurement model of
   :mod:`kinematics.phase_model`: the thigh angle and rate normalised by the wearer's own running
   offset and scale (the mean and standard deviation of the angle over the last walking cycle,
   blended with the reference's values until a cycle is available);
5. a foot strike when the phase crosses an integer, a toe-off when it crosses k + the reference
   stance fraction at the current cadence; each with its detection time (this sample) and its
   estimated time ``t - (φ - φ_event) / r``. With heel-strike shocks in the accelerometer the
   strike is the shock's onset in a window around that prediction, and the phase's strike
   bias is learned from them (:mod:`kinematics.gait_phase_impact`); with a prosthesis's load
   cell its events are emitted and give that bias (:mod:`kinematics.gait_prosthesis`); the
   axis sign is re-examined from where the shocks fall, or from the load cell or knee encoder.

:func:`kinematics.gait_online.estimate_online` runs a whole series through the estimator one
sample at a time (a loop; no look-ahead by construction).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_phase_config import (
    COUNT_NAMES,
    GaitPhaseConfig,
    GaitState,
    OnlineEvent,
)
from kinematics.gait_phase_impact import StrikeTiming, impact_strikes_in_buffer
from kinematics.gait_prosthesis import LoadCellEvents, ProsthesisSign
from kinematics.phase_model import measurement, measurement_jacobian, phase_reference
from kinematics.thigh_attitude import (
    SagittalAxis,
    SagittalAxisLearner,
    ThighAngleFilter,
    ThighState,
    flipped,
    initial_angle,
)


class OnlineGaitEstimator:
    """Causal gait phase and events from a thigh IMU (see the module docstring)."""

    def __init__(
        self,
        config: GaitPhaseConfig | None = None,
        sagittal_axis: SagittalAxis | None = None,
        initial_angle_rad: float | None = None,
    ) -> None:
        self.cfg = config or GaitPhaseConfig()
        self.ref = phase_reference()
        self.learner = SagittalAxisLearner(self.cfg.attitude)
        self.thigh: ThighAngleFilter | None = None
        self._axis = sagittal_axis
        self._initial_angle = initial_angle_rad
        self.counts = dict.fromkeys(COUNT_NAMES, 0)
        self.events: list[OnlineEvent] = []
        self.state: GaitState | None = None
        self._t_last: float | None = None
        self._ekf = None
        self._walking = False
        self._ms = 0.0  # running mean of rate² (window rms_window_s)
        self._still_s = 0.0
        self._nis = 0.0
        self._nis_sum = 0.0
        self._stall_s = 0.0
        self._shadow: OnlineGaitEstimator | None = None
        self._shadow_until_s = math.inf
        self._sum_mark = (0.0, 0.0, 0, 0)
        self._nis_n = 0
        self._walk_angles: deque[float] = deque(maxlen=4000)  # >= 4 s at up to 1 kHz
        self._walk_dt: deque[float] = deque(maxlen=4000)
        self._last_rate: float | None = None
        self._stride_s: float | None = None
        self._norm = (0.0, 0.25)
        self._standing_angle = 0.0
        self._standing_seen = False
        self._next_strike = 0
        self._next_toe_off = 0
        self._last_event_t = {"foot_strike": -math.inf, "toe_off": -math.inf}
        self.timing = StrikeTiming(self.cfg.strike_timing)
        self.load_cell = LoadCellEvents(self.cfg.prosthesis)
        self.prosthesis_sign = ProsthesisSign(self.cfg.prosthesis)
        self._knee_rad: float | None = None
        self._strides: deque[float] = deque(maxlen=3)
        self._buffer_stride_s: float | None = None
        self._armed_for: int | None = None

    # --- public ------------------------------------------------------------------------------
    def update(
        self,
        t_s: float,
        gyro_rad_s: np.ndarray,
        accel_m_s2: np.ndarray,
        load_n: float | None = None,
        knee_rad: float | None = None,
    ) -> list[OnlineEvent]:
        """Process one sample; return the events emitted at it (usually none).

        ``load_n`` (axial load, N, compression +) and ``knee_rad`` (knee flexion) are the
        prosthesis's own sensors at this sample when it has them
        (:mod:`kinematics.gait_prosthesis`): the load cell then gives the events and the thigh
        IMU's strike bias, and both check the IMU's flexion sign. NaN or None: not available."""
        out = self._update_imu(t_s, gyro_rad_s, accel_m_s2, knee_rad)
        load_event = self.load_cell.update(float(t_s), load_n)
        if load_event is not None:
            out = out + self._load_cell_event(*load_event, float(t_s))
        return out

    def _update_imu(self, t_s, gyro_rad_s, accel_m_s2, knee_rad) -> list[OnlineEvent]:
        t_s = float(t_s)
        gyro = np.asarray(gyro_rad_s, dtype=float).reshape(3)
        accel = np.asarray(accel_m_s2, dtype=float).reshape(3)
        self.counts["samples"] += 1
        if not (math.isfinite(t_s) and np.all(np.isfinite(gyro)) and np.all(np.isfinite(accel))):
            self.counts["nonfinite"] += 1
            self._set_state(t_s, None, flags=1)
            return []
        if self._t_last is not None and t_s <= self._t_last:
            raise GaitInputError(
                f"sample {self.counts['samples'] - 1}, column t_s: time must increase strictly "
                f"({t_s} after {self._t_last})"
            )
        flags = 0
        if self._t_last is not None and t_s - self._t_last > self.cfg.max_gap_s:
            self.counts["gaps"] += 1
            flags |= 4
            self._lose_lock()
            if self.thigh is not None:
                self.thigh._first = True
        self._t_last = t_s
        saturated = bool(
            np.any(np.abs(gyro) >= self.cfg.gyro_range_rad_s)
            or np.any(np.abs(accel) >= self.cfg.accel_range_m_s2)
        )
        if saturated:
            self.counts["saturated"] += 1
            flags |= 2
        if self.thigh is None:
            return self._learn(t_s, gyro, accel, flags)
        self._knee_rad = knee_rad
        out = self._step(t_s, gyro, accel, saturated, flags, detected_t_s=t_s)
        if self._shadow is not None:
            self._check_sign(t_s, gyro, accel)
        return out

    # --- stages ------------------------------------------------------------------------------
    def _learn(self, t_s, gyro, accel, flags) -> list[OnlineEvent]:
        if self._axis is not None:
            self.thigh = ThighAngleFilter(
                self._axis, t_s, self.cfg.attitude, initial_angle_rad=self._initial_angle
            )
            return self._step(t_s, gyro, accel, False, flags, detected_t_s=t_s)
        axis = self.learner.add(t_s, gyro, accel)
        if axis is None:
            self._set_state(t_s, None, flags)
            return []
        # Replay the buffer with both signs of the axis and keep the one whose phase model fits
        # better (lower mean NIS): the peak asymmetry of a partial cycle can mislead.
        buffered = list(zip(self.learner.t, self.learner.gyro, self.learner.accel, strict=True))
        trials = []
        t_b, g_b, a_b = (
            np.asarray(x) for x in (self.learner.t, self.learner.gyro, self.learner.accel)
        )
        for candidate in (axis, flipped(axis)):
            angle0 = initial_angle(candidate, t_b, g_b, a_b, self.cfg.attitude)
            trial = OnlineGaitEstimator(self.cfg, sagittal_axis=candidate, initial_angle_rad=angle0)
            for tb, gb, ab in buffered:
                trial.update(tb, gb, ab)
            trials.append(trial)
        best = min(trials, key=lambda tr: tr.fit_cost()) if self.cfg.sign_by_fit else trials[0]
        self._adopt(best)
        if self.cfg.sign_check_s > 0:
            self._shadow = trials[1] if best is trials[0] else trials[0]
            self._shadow_until_s = t_s + self.cfg.sign_check_s
            shadow = self._shadow
            self._sum_mark = (self._nis_sum, shadow._nis_sum, self._nis_n, shadow._nis_n)
        for name in ("reacquired", "phase_jumps", "saturated"):
            self.counts[name] += best.counts[name]
        self.counts["axis_flipped"] += int(best is trials[1])
        # events found in the buffer are emitted now: they carry this sample's time, and the
        # strikes among them are placed on their impacts (the whole buffer is past by now)
        strikes = impact_strikes_in_buffer(
            t_b, a_b, np.array([e.t_s for e in best.events if e.kind == "foot_strike"]),
            self.cfg.strike_timing,
        )  # fmt: skip
        it = iter(strikes)
        self.events = [
            OnlineEvent(
                e.kind, next(it) if e.kind == "foot_strike" else e.t_s, t_s, e.phase_sigma_cyc
            )
            for e in best.events
        ]
        missed = self._strike_before_lock(t_b, g_b, a_b, t_s)
        if missed is not None:
            self.events = sorted(
                [*self.events, OnlineEvent("foot_strike", missed, t_s, math.nan)],
                key=lambda e: e.t_s,
            )
        fs = [e.t_s for e in self.events if e.kind == "foot_strike"]
        if fs:
            self._last_event_t["foot_strike"] = fs[-1]
            self._learn_bursts(t_b, a_b, fs)
        self._buffer_stride_s = _last_cycle_s(t_b, g_b @ self.thigh.axis.axis)
        self.state = GaitState(**{**self.state.__dict__, "flags": self.state.flags | flags})
        return list(self.events)

    def _strike_before_lock(self, t_b, g_b, a_b, t_s: float) -> float | None:
        """A strike in the learning buffer that the replay did not emit (the phase locks a
        little after walking starts): the strongest impact burst of the buffer that lies
        0.35 s or more from every emitted strike, taken when the thigh is flexed at it (ahead
        of its mean angle over the buffer's motion: at contact the foot is in front of the
        body; at toe-off, behind)."""
        from kinematics.gait_impact import envelope, onset_near

        cfg = self.cfg.strike_timing.impact
        axis = self.thigh.axis if self.thigh is not None else None
        if axis is None or len(t_b) < 10:
            return None
        env = envelope(t_b, a_b, cfg)
        floor = max(float(np.median(env)), 1e-12)
        emitted = [e.t_s for e in self.events if e.kind == "foot_strike"]
        free = np.array([all(abs(t - e) >= 0.35 for e in emitted) for t in t_b])
        free &= t_b <= t_s - 0.1
        if not free.any() or env[free].max() < cfg.min_strength * floor:
            return None
        k = int(np.flatnonzero(free)[np.argmax(env[free])])
        onset = onset_near(
            t_b, env, float(t_b[k]), float(env[k]), replace(cfg, window_s=(-0.3, 0.0))
        )
        if not math.isfinite(onset):
            return None
        rate = g_b @ axis.axis - axis.gyro_bias_rad_s
        angle = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t_b))])
        moving = np.abs(rate) > 0.5
        if moving.sum() < 10 or np.interp(onset, t_b, angle) <= angle[moving].mean():
            return None
        return onset - cfg.lag_s

    def _learn_bursts(self, t_b, a_b, strikes_s) -> None:
        """The bursts of the strikes found in the learning buffer start the typical peak."""
        from kinematics.gait_impact import envelope

        cfg = self.cfg.strike_timing
        env = envelope(t_b, a_b, cfg.impact)
        self.timing.peaks.clear()
        for ts in strikes_s:
            m = (t_b >= ts + cfg.window_s[0]) & (t_b <= ts + cfg.window_s[1])
            if m.any():
                self.timing.peaks.append(float(env[m].max()))

    def _adopt(self, other: OnlineGaitEstimator) -> None:
        keep = {"cfg", "learner", "counts", "events", "_shadow", "_shadow_until_s", "_sum_mark"}
        keep |= {"load_cell", "prosthesis_sign"}
        self.__dict__.update({k: v for k, v in other.__dict__.items() if k not in keep})

    def _check_sign(self, t_s, gyro, accel) -> None:
        """Keep the other axis sign running for ``sign_check_s`` after the axis is fixed; switch
        to it (counted as ``axis_flipped``) when its phase model fits clearly better since then."""
        shadow = self._shadow
        shadow.update(t_s, gyro, accel)
        if t_s < self._shadow_until_s:
            return
        self._shadow = None

        own = (self._nis_sum - self._sum_mark[0]) / max(self._nis_n - self._sum_mark[2], 1)
        other = (shadow._nis_sum - self._sum_mark[1]) / max(shadow._nis_n - self._sum_mark[3], 1)
        if other < own - self.cfg.sign_switch_margin:
            self._adopt(shadow)
            self.counts["axis_flipped"] += 1

    def fit_cost(self) -> float:
        """Mean NIS of the phase EKF's updates so far, plus 2 per re-acquisition beyond the
        first (how badly the reference curves explain the signal)."""
        return self._nis_sum / max(self._nis_n, 1) + 2.0 * max(self.counts["reacquired"] - 1, 0)

    def _step(self, t_s, gyro, accel, saturated, flags, detected_t_s) -> list[OnlineEvent]:
        thigh = self._thigh_update(t_s, gyro, accel, saturated)
        self.timing.sample(t_s, accel)
        if self.state is not None and math.isfinite(self.state.t_s):
            contact = self.load_cell.contact if self.load_cell.alive(t_s) else None
            self.prosthesis_sign.add(
                thigh.rate_rad_s, t_s - self.state.t_s, contact, self._knee_rad
            )
        self._recheck_sign()
        dt = thigh.t_s - (self.state.t_s if self.state is not None else thigh.t_s)
        dt = dt if math.isfinite(dt) and dt > 0 else 0.0
        walking = self._walking_now(thigh, dt)
        if not walking:
            if self._walking:
                self._lose_lock()
            if self._still_s >= self.cfg.standing_posture_s:  # a real stand, not a pause
                self._standing_angle = thigh.angle_rad
                self._standing_seen = True
            self._set_state(t_s, thigh, flags)
            return []
        self._walking = True
        self._track_norm(thigh.angle_rad, dt)
        if self._ekf is None:
            self._acquire(thigh)
            flags |= 16
        else:
            flags |= self._ekf_step(thigh, dt, saturated)
        self._set_state(t_s, thigh, flags)
        return self._events(t_s, detected_t_s)

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

    def _track_norm(self, angle_rad: float, dt: float) -> None:
        """Running offset and scale of the angle: its mean and standard deviation over the last
        cycle of walking samples, or the reference's values (relative to the standing posture)
        until 3/4 of a cycle has been seen."""
        self._walk_angles.append(angle_rad)
        self._walk_dt.append(dt)
        if len(self._walk_angles) % 10 and self._ekf is not None:
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
        n = int(np.searchsorted(span, cycle_s)) + 1
        recent = np.asarray(self._walk_angles)[-n:]
        self._norm = (float(recent.mean()), max(float(recent.std()), 0.02))

    def _z(self, thigh: ThighState) -> np.ndarray:
        m, s = self._norm
        return np.array([(thigh.angle_rad - m) / s, thigh.rate_rad_s / s])

    def _acquire(self, thigh: ThighState) -> None:
        """Start the EKF at the phase on the reference loop nearest the measurement."""
        from filterpy.kalman import ExtendedKalmanFilter

        cfg = self.cfg
        rate = self._rate_prior()
        a, b = self.ref.coefficients(rate)
        grid = np.arange(200) / 200.0
        z = self._z(thigh)
        cost = [
            ((z - measurement(np.array([p, rate]), a, b)) / [cfg.angle_sigma, cfg.rate_sigma])
            @ ((z - measurement(np.array([p, rate]), a, b)) / [cfg.angle_sigma, cfg.rate_sigma])
            for p in grid
        ]
        phase = float(grid[int(np.argmin(cost))])
        ekf = ExtendedKalmanFilter(dim_x=2, dim_z=2)
        ekf.x = np.array([phase, rate])
        ekf.P = np.diag([0.1**2, 0.2**2])
        ekf.R = np.diag([cfg.angle_sigma**2, cfg.rate_sigma**2])
        self._ekf = ekf
        self._nis = 2.0
        # an event the lock has just passed (a re-acquisition near it) is still emitted, once:
        # the spacing rule drops it if it was emitted before the lock was lost
        grace = self.cfg.acquire_grace_cyc
        self._next_strike = math.floor(phase) + (0 if phase % 1.0 < grace else 1)
        sf = self.ref.at_rate("stance_fraction", rate)
        self._next_toe_off = math.floor(phase) + (1 if phase % 1.0 >= sf + grace else 0)
        self.counts["reacquired"] += 1

    def _rate_prior(self) -> float:
        """The last cadence estimate, else that of 1.2 m/s."""
        return self._last_rate if self._last_rate is not None else float(self.ref.rates_cyc_s[12])

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
        ekf.x[1] = float(np.clip(ekf.x[1], 0.3, 2.0))
        # the gait phase does not run backwards: an update that would move it behind the
        # previous estimate holds it there (the innovation then grows and, if the model keeps
        # failing, the NIS test re-acquires)
        ekf.x[0] = max(float(ekf.x[0]), self._phase_floor)
        self._phase_floor = float(ekf.x[0])
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

    def _events(self, t_s: float, detected_t_s: float) -> list[OnlineEvent]:
        ekf = self._ekf
        if ekf is None:
            return []
        rate = max(float(ekf.x[1]), 1e-3)
        phase = float(ekf.x[0]) - self.timing.bias_s * rate  # calibrated (see gait_phase_impact)
        sigma = math.sqrt(float(ekf.P[0, 0]))
        sf = self.ref.at_rate("stance_fraction", rate)
        out = []
        if self.load_cell.alive(t_s):  # the load cell gives the events (_load_cell_event)
            return []
        strike = self._strike_time(t_s, phase, rate)
        if strike is not None:
            out += self._emit("foot_strike", strike, detected_t_s, sigma)
        target = self._next_toe_off + sf
        if phase >= target:
            self._next_toe_off = math.floor(phase - sf) + 1
            t_to = t_s - (phase - target) / rate
            emitted = self._emit("toe_off", t_to, detected_t_s, sigma)
            if emitted:
                self.timing.toe_off(t_to)
            out += emitted
        self.events += out
        return out

    def _strike_time(self, t_s: float, phase: float, rate: float) -> float | None:
        """The foot strike emitted at this sample, if any: the impact onset in the strike's
        window (impact mode), else the calibrated phase crossing the integer, else (impact
        mode, no onset by the window's end) the calibrated prediction."""
        timing = self.timing
        w0, w1 = timing.cfg.window_s
        target = self._next_strike
        pred = t_s + (target - phase) / rate
        win = timing.window
        if win is None and target != self._armed_for and t_s >= pred + w0:
            win = timing.arm(target, pred + w1, pred - timing.bias_s, pred)
            self._armed_for = target
        if win is not None:
            onset = timing.poll()
            if onset is not None or t_s >= win.close_at_s:
                strike = timing.close(onset)
                self.counts["impact_strikes"] += int(onset is not None)
                if win.emitted:
                    return None
                self._next_strike = max(self._next_strike, win.target + 1)
                return strike if strike is not None else win.calibrated_s
            if timing.impact_mode and not win.emitted:
                return None  # wait for the impact, or the window's end
        if phase < target:
            return None
        if win is not None and win.target == target:
            win.emitted = True
        self._next_strike = math.floor(phase) + 1
        return t_s - (phase - target) / rate

    def _emit(self, kind: str, t_event: float, detected_t_s: float, sigma: float):
        if t_event - self._last_event_t[kind] < self.cfg.min_event_spacing_s:
            return []
        if kind == "foot_strike" and 0.6 < t_event - self._last_event_t[kind] < 2.5:
            self._stride_s = t_event - self._last_event_t[kind]
            self._strides.append(self._stride_s)
        self._last_event_t[kind] = t_event
        return [OnlineEvent(kind, t_event, detected_t_s, sigma)]

    def _recheck_sign(self) -> None:
        """Re-examine the axis sign at every sample once a few strides are seen: when the bursts
        at the toe-offs stand above those at the strikes (a strike is a shock, a toe-off is not),
        the axis is the wrong way round: flip it, count it, and start the phase lock again."""
        if self.thigh is None:
            return
        evidence = self.prosthesis_sign.evidence()
        if math.isfinite(evidence):
            wrong = evidence < 0  # the prosthesis's sensors decide when present
        else:
            wrong = self.timing.sign_is_wrong(self.cfg.sign_recheck_strides)
        if not wrong:
            return
        self.counts["axis_flipped"] += 1
        self.counts["sign_disagreement"] += 1
        self.thigh.flip()
        self._standing_angle = -self._standing_angle
        self.timing.forget_bursts()
        self.prosthesis_sign.reset()
        self._lose_lock(forget=True)

    def _load_cell_event(self, kind: str, t_event: float, t_s: float) -> list[OnlineEvent]:
        """An event from the load cell: emitted as is; a strike also gives the thigh IMU's
        strike bias (the EKF's own strike time against it) and moves the next strike on."""
        ekf = self._ekf
        sigma = 0.0
        if ekf is not None and self._walking:
            rate = max(float(ekf.x[1]), 1e-3)
            raw = float(ekf.x[0]) - (t_s - t_event) * rate  # the EKF's phase at the event
            if kind == "foot_strike":
                k = math.floor(raw + 0.5)
                self.timing.reference(t_event, t_event - (raw - k) / rate, source="load cell")
                cal = raw - self.timing.bias_s * rate
                self._next_strike = math.floor(cal + 0.5) + 1
                self._armed_for = None
                self.timing.window = None
            else:
                sf = self.ref.at_rate("stance_fraction", rate)
                cal = raw - self.timing.bias_s * rate
                self._next_toe_off = math.floor(cal - sf + 0.5) + 1
        out = self._emit(kind, t_event, t_s, sigma)
        if kind == "foot_strike" and out:
            self.counts["load_cell_strikes"] += 1
        self.events += out
        return out

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
            self._walk_dt.clear()
            self._stride_s = None
            self._strides.clear()

    def _phase_out(self, t_s: float) -> float:
        """The phase reported: with impacts, linear in time from the last strike over the
        median of the last three strides (the latest before three are known, the EKF's cadence
        before one is) (the phase's definition; the reference curve's shape
        does not bend it); else the EKF's, shifted by the learned strike bias."""
        ekf = self._ekf
        last = self._last_event_t["foot_strike"]
        if self.timing.impact_mode and t_s - last < 2.5:
            if len(self._strides) >= 3:
                stride = float(np.median(self._strides))
            elif self._strides:  # the first strides after a start shorten: the latest
                stride = self._strides[-1]
            elif self._buffer_stride_s is not None:  # the cycle seen while learning the axis
                stride = self._buffer_stride_s
            else:
                stride = 1.0 / max(float(ekf.x[1]), 0.3)
            return float(min((t_s - last) / stride, 0.999))
        return float((ekf.x[0] - self.timing.bias_s * max(float(ekf.x[1]), 1e-3)) % 1.0)

    def _set_state(self, t_s: float, thigh: ThighState | None, flags: int) -> None:
        ekf = self._ekf if self._walking else None
        self.state = GaitState(
            t_s=t_s,
            walking=ekf is not None,
            phase_cyc=self._phase_out(t_s) if ekf is not None else math.nan,
            phase_sigma_cyc=math.sqrt(float(ekf.P[0, 0])) if ekf is not None else math.nan,
            rate_cyc_s=float(ekf.x[1]) if ekf is not None else math.nan,
            angle_rad=thigh.angle_rad if thigh is not None else math.nan,
            rate_rad_s=thigh.rate_rad_s if thigh is not None else math.nan,
            flags=flags,
        )


def _last_cycle_s(t_s: np.ndarray, rate: np.ndarray) -> float | None:
    """The last whole cycle of a flexion rate: between its last two rises through +35 % of
    its peak after falling below -35 % (None when not plausible, 0.7-2.5 s)."""
    level = 0.35 * float(np.max(np.abs(rate))) if rate.size else 0.0
    rises, armed = [], False
    for t, r in zip(t_s, rate, strict=True):
        if r < -level:
            armed = True
        elif r > level and armed:
            rises.append(float(t))
            armed = False
    if len(rises) < 2:
        return None
    cycle = rises[-1] - rises[-2]
    return cycle if 0.7 <= cycle <= 2.5 else None
