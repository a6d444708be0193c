"""What the online gait estimator (:mod:`kinematics.gait_phase`, step 5) reports: foot strikes
and toe-offs as the phase crosses them (the strike placed on its impact when there is one),
the load cell's events when it is alive, and the per-sample state with the phase reported."""

from __future__ import annotations

import math

import numpy as np

from kinematics.gait_phase_config import GaitState, OnlineEvent
from kinematics.thigh_attitude import ThighState


class EventEmission:
    """Event emission and the reported state: part of
    :class:`~kinematics.gait_phase.OnlineGaitEstimator`.

    State: the attributes :class:`~kinematics.gait_phase.OnlineGaitEstimator` sets in its
    ``__init__``; this class only groups its methods.
    """

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
        shock = self._shock_strike(t_s)
        if shock is not None:
            emitted = self._emit("foot_strike", shock, detected_t_s, sigma)
            if emitted:
                self.counts["shock_strikes"] += 1
                self._relocked = True  # the phase's own strike of this cycle is not emitted
            out += emitted
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

    def _shock_strike(self, t_s: float) -> float | None:
        """A strike from its shock alone, when no strike window is open (the phase lost in a
        turn's pause or flat steps): the envelope rises through the onset threshold more than
        0.6 stride after the last strike, and the thigh reached a flexion peak within
        ``swing_cyc`` of a stride before, after flexing by ``min_swing_rad`` (a strike follows the flexion
        peak of its swing). Emitted at the onset minus ``lag_s``."""
        timing, cfg = self.timing, self.timing.cfg
        stride = self._plausible_stride_s()
        angles = self._recent_angles
        if self.state is not None and math.isfinite(self.state.angle_rad):
            angles.append((t_s, self.state.angle_rad))
        while angles and angles[0][0] < t_s - cfg.swing_cyc * stride:
            angles.popleft()
        if timing.window is not None:
            return None
        onset = timing.rise_now()
        if onset is None:
            return None
        if onset - self._last_event_t["foot_strike"] < 0.6 * stride:
            return None
        k = max(range(len(angles)), key=lambda i: angles[i][1], default=None)
        if k is None or k == len(angles) - 1:
            return None  # still flexing (or no history): the peak is not behind
        before = min(a for _, a in list(angles)[: k + 1])
        if angles[k][1] - before < cfg.min_swing_rad:
            return None
        return onset - cfg.impact.lag_s

    def _strike_time(self, t_s: float, phase: float, rate: float) -> float | None:
        """The foot strike emitted at this sample, if any: the impact onset in the strike's
        window (impact mode), else the calibrated phase crossing the integer, else (impact
        mode, no onset by the window's end) the calibrated prediction. The window stays open
        ``window_s[1]`` past the last sample at which the thigh still flexes (a strike follows
        the flexion peak: a prediction made early in a turn must not close it before the
        shock)."""
        timing = self.timing
        w0, w1 = timing.cfg.window_s
        target = self._next_strike
        pred = t_s + (target - phase) / rate
        win = timing.window
        if win is None and target != self._armed_for and t_s >= pred + w0:
            win = timing.arm(target, pred + w1, pred - timing.bias_s, pred)
            self._armed_for = target
        if win is not None:
            if self.state is not None and self.state.rate_rad_s > 0.0:
                # the thigh still flexes: its strike, which follows the flexion peak, is to come
                win.close_at_s = max(win.close_at_s, t_s + w1)
            onset = timing.poll()
            if onset is not None or (t_s >= win.close_at_s and not timing.holding):
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
        if kind == "foot_strike" and self._relocked:
            # the first strike of a re-acquired lock is not the one just emitted again: a
            # cadence does not halve within a stride
            stride = self._plausible_stride_s()
            if t_event - self._last_event_t[kind] < 0.6 * stride:
                return []
            self._relocked = False
        if kind == "foot_strike" and 0.6 < t_event - self._last_event_t[kind] < 2.5:
            self._stride_s = t_event - self._last_event_t[kind]
            self._strides.append(self._stride_s)
        self._last_event_t[kind] = t_event
        if kind == "foot_strike" and self.stride_phase is not None:
            self.stride_phase.strike(t_event)
        return [OnlineEvent(kind, t_event, detected_t_s, sigma)]

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

    def _phase_out(self, t_s: float, angle_rad: float) -> float:
        """The phase reported: with impacts, the time since the last strike over the stride
        time expected, the median of the last three strides (the latest before three are known,
        the cycle seen while learning the axis before one is), re-timed within the stride by
        the thigh's landmarks (:mod:`kinematics.gait_phase_angle`: the time still to come from
        the largest extension or mid-swing to the strike, as in the last strides) (the phase's
        definition is linear in time between strikes; the reference curve's shape does not
        bend it); else the EKF's, shifted by the learned strike bias.

        With impacts but no stride measured yet (the first stride after a start, when the
        learning buffer held no whole cycle) the two estimates at hand err in opposite senses:
        the EKF's own phase follows the reference thigh curve's shape and runs ahead in stance
        on a thigh whose swing and stance differ from it (a prosthesis side: 0.1-0.2 cycle at
        the lock), while the time since the strike over the EKF's cadence lags (the cadence is
        still settling from its prior, low). The phase reported is then their circular mean
        (docs/kinematics.md, "The first strikes and the first stride's phase"), not below 0:
        just after a strike an EKF phase that has not yet crossed its integer would otherwise
        pull the mean back across the wrap, to the end of the last stride (0.9-0.95)."""
        ekf = self._ekf
        last = self._last_event_t["foot_strike"]
        own = float((ekf.x[0] - self.timing.bias_s * max(float(ekf.x[1]), 1e-3)) % 1.0)
        if len(self._strides) >= 3:
            stride = float(np.median(self._strides))
        elif self._strides:  # the first strides after a start shorten: the latest
            stride = self._strides[-1]
        elif self._buffer_stride_s is not None:  # the cycle seen while learning the axis
            stride = self._buffer_stride_s
        else:
            stride = None
        retimed = None
        if self.stride_phase is not None:
            retimed = self.stride_phase.update(t_s, angle_rad, stride or 1.0 / max(ekf.x[1], 0.3))
        if not (self.timing.impact_mode and t_s - last < 2.5):
            return own
        if stride is None and not (self.stride_phase is not None and self.stride_phase.calibrated):
            linear = min((t_s - last) * max(float(ekf.x[1]), 0.3), 0.999)
            mean = linear + 0.5 * math.remainder(own - linear, 1.0)
            return float(min(max(mean, 0.0), 0.999))  # a strike was emitted: not wrapped back
        if retimed is not None and math.isfinite(retimed):
            return float(retimed)
        return float(min((t_s - last) / stride, 0.999))

    def _set_state(self, t_s: float, thigh: ThighState | None, flags: int) -> None:
        ekf = self._ekf if self._walking else None
        angle = thigh.angle_rad if thigh is not None else math.nan
        self.state = GaitState(
            t_s=t_s,
            walking=ekf is not None,
            phase_cyc=self._phase_out(t_s, angle) if ekf is not None else math.nan,
            phase_sigma_cyc=math.sqrt(float(ekf.P[0, 0])) if ekf is not None else math.nan,
            rate_cyc_s=float(ekf.x[1]) if ekf is not None else math.nan,
            angle_rad=angle,
            rate_rad_s=thigh.rate_rad_s if thigh is not None else math.nan,
            flags=flags,
        )
