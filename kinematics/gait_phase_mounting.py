"""The mounting of the thigh IMU in the online gait estimator (:mod:`kinematics.gait_phase`,
step 2 and the sign checks): the sagittal axis learned and its sign chosen by replaying the
learning buffer with both signs, the events of that buffer, the other sign kept running for a
while after (switched to when it fits clearly better), and the sign re-examined at every sample
from the impacts or the prosthesis's sensors."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from kinematics.gait_phase_config import GaitState, OnlineEvent
from kinematics.gait_phase_impact import impact_strikes_in_buffer
from kinematics.thigh_attitude import ThighAngleFilter, flipped, initial_angle


class MountingCheck:
    """Axis learning and the mounting-sign self-checks: part of
    :class:`~kinematics.gait_phase.OnlineGaitEstimator`.

    State: the attributes :class:`~kinematics.gait_phase.OnlineGaitEstimator` sets in its
    ``__init__``; this class only groups its methods.
    """

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
            trial = type(self)(self.cfg, sagittal_axis=candidate, initial_angle_rad=angle0)
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
        new = self._buffer_events(best, t_b, g_b, a_b, t_s)
        fs = [e.t_s for e in self.events if e.kind == "foot_strike"]
        if fs:
            self._last_event_t["foot_strike"] = fs[-1]
            self._learn_bursts(t_b, a_b, fs)
        self._buffer_stride_s = _last_cycle_s(t_b, g_b @ self.thigh.axis.axis)
        self.state = GaitState(**{**self.state.__dict__, "flags": self.state.flags | flags})
        return new

    def _buffer_events(self, best, t_b, g_b, a_b, t_s: float) -> list[OnlineEvent]:
        """The events the replay found in the learning buffer, emitted now (they carry this
        sample's time), its strikes placed on their impacts (the whole buffer is past by now),
        less those already emitted as first strikes; ``self.events`` then holds all."""
        strikes = impact_strikes_in_buffer(
            t_b, a_b, np.array([e.t_s for e in best.events if e.kind == "foot_strike"]),
            self.cfg.strike_timing,
        )  # fmt: skip
        it = iter(strikes)
        first = list(self.events)  # the first strikes, emitted before the axis was learned
        replay = [
            OnlineEvent(
                e.kind, next(it) if e.kind == "foot_strike" else e.t_s, t_s, e.phase_sigma_cyc
            )
            for e in best.events
        ]
        self.events = first + replay
        missed = self._strike_before_lock(t_b, g_b, a_b, t_s)
        if missed is not None:
            replay.append(OnlineEvent("foot_strike", missed, t_s, math.nan))
        new = self._merge_first(first, replay, t_b, g_b)
        self.events = sorted(first + new, key=lambda e: e.t_s)
        return new

    def _first_strike(self, t_s, gyro, accel) -> list[OnlineEvent]:
        """Before the axis is learned: a strike from the shock and the thigh's tilt
        (:mod:`kinematics.gait_first_strike`), emitted at once."""
        found = self.first.update(t_s, gyro, accel)
        if found is None:
            return []
        self.counts["first_strikes"] += 1
        event = OnlineEvent("foot_strike", found[0], found[1], math.nan)
        self.events.append(event)
        return [event]

    def _merge_first(self, first, replay, t_b, g_b) -> list[OnlineEvent]:
        """The replay's events less its strikes within ``merge_s`` of a first strike (the same
        strike, already emitted); a first strike the replay does not confirm is counted."""
        merge = self.cfg.first_strike.merge_s
        known = [e.t_s for e in first if e.kind == "foot_strike"]
        found = [e.t_s for e in replay if e.kind == "foot_strike"]
        self.counts["first_strikes_unconfirmed"] += sum(
            all(abs(k - f) > merge for f in found) and not self._flexed_at(t_b, g_b, k)
            for k in known
        )
        return sorted(
            (
                e
                for e in replay
                if e.kind != "foot_strike" or all(abs(e.t_s - k) > merge for k in known)
            ),
            key=lambda e: e.t_s,
        )

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
        return onset - cfg.lag_s if self._flexed_at(t_b, g_b, onset) else None

    def _flexed_at(self, t_b, g_b, t_s: float) -> bool:
        """The thigh is flexed at ``t_s`` (ahead of its mean angle over the buffer's motion:
        at contact the foot is in front of the body; at toe-off, behind)."""
        axis = self.thigh.axis
        rate = g_b @ axis.axis - axis.gyro_bias_rad_s
        angle = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t_b))])
        moving = np.abs(rate) > 0.5
        return bool(moving.sum() >= 10 and np.interp(t_s, t_b, angle) > angle[moving].mean())

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

    def _adopt(self, other: MountingCheck) -> None:
        keep = {"cfg", "learner", "counts", "events", "_shadow", "_shadow_until_s", "_sum_mark"}
        keep |= {"load_cell", "prosthesis_sign", "first"}
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
