"""Online gait state from a thigh IMU: gait phase, cadence, foot strikes and toe-offs as they
happen (causal: each sample is processed once, in order, and nothing reads ahead).

Per sample (:meth:`OnlineGaitEstimator.update`):

1. input checks: a non-finite sample is dropped, a saturated one is only predicted through, a
   gap longer than ``max_gap_s`` is flagged and predicted through up to ``max_bridge_s``, a
   longer one drops the phase lock (re-acquired after it); each is counted in
   :attr:`OnlineGaitEstimator.counts`; time going backwards is a :class:`GaitInputError`;
2. the thigh's sagittal angle and rate (:mod:`kinematics.thigh_attitude`; the samples buffered
   while the sagittal axis is learned are replayed once it is fixed, and the events found in
   them are emitted then, with that sample's time as their detection time; the strikes among
   them that :mod:`kinematics.gait_first_strike` found from the shock and the thigh's tilt,
   which need no axis, were emitted as they happened);
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
   With impacts the phase reported is the time since the strike over the stride time
   expected, re-timed within the stride by the thigh's landmarks (largest extension,
   mid-swing: :mod:`kinematics.gait_phase_angle`).

:func:`kinematics.gait_online.estimate_online` runs a whole series through the estimator one
sample at a time (a loop; no look-ahead by construction).

The estimator's methods are grouped by stage: :mod:`kinematics.gait_phase_mounting` (axis
learning, sign checks), :mod:`kinematics.gait_phase_filter` (walking, phase EKF),
:mod:`kinematics.gait_phase_events` (events, reported state); this module holds its state and
the per-sample flow.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_first_strike import FirstStrikes
from kinematics.gait_phase_angle import ThighAnglePhase
from kinematics.gait_phase_config import (
    COUNT_NAMES,
    GaitPhaseConfig,
    GaitState,
    OnlineEvent,
)
from kinematics.gait_phase_events import EventEmission
from kinematics.gait_phase_filter import PhaseFilter
from kinematics.gait_phase_impact import StrikeTiming
from kinematics.gait_phase_mounting import MountingCheck
from kinematics.gait_prosthesis import LoadCellEvents, ProsthesisSign
from kinematics.phase_model import phase_reference
from kinematics.thigh_attitude import (
    SagittalAxis,
    SagittalAxisLearner,
    ThighAngleFilter,
)


class OnlineGaitEstimator(MountingCheck, EventEmission, PhaseFilter):
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
        self._held_s = 0.0
        self._relocked = False
        self._shadow: OnlineGaitEstimator | None = None
        self._shadow_until_s = math.inf
        self._sum_mark = (0.0, 0.0, 0, 0)
        self._nis_n = 0
        self._walk_angles: deque[float] = deque(maxlen=4000)  # >= 4 s at up to 1 kHz
        self._walk_dt: deque[float] = deque(maxlen=4000)
        self._walk_n = 0
        self._last_rate: float | None = None
        self._stride_s: float | None = None
        self._norm = (0.0, 0.25)
        self._standing_angle = 0.0
        self._standing_seen = False
        self._next_strike = 0
        self._next_toe_off = 0
        self._last_event_t = {"foot_strike": -math.inf, "toe_off": -math.inf}
        self.timing = StrikeTiming(self.cfg.strike_timing)
        self.first = FirstStrikes(self.cfg.first_strike, self.cfg.strike_timing.impact)
        self.load_cell = LoadCellEvents(self.cfg.prosthesis)
        self.prosthesis_sign = ProsthesisSign(self.cfg.prosthesis)
        self._knee_rad: float | None = None
        self._strides: deque[float] = deque(maxlen=3)
        sp = self.cfg.stride_phase
        self.stride_phase = ThighAnglePhase(sp) if sp is not None else None
        self._buffer_stride_s: float | None = None
        self._armed_for: int | None = None
        self._recent_angles: deque[tuple[float, float]] = deque()
        """(t_s, thigh angle) over the last ``swing_cyc`` stride: where the flexion peak was."""

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
            if t_s - self._t_last > self.cfg.max_bridge_s:
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
            return self._first_strike(t_s, gyro, accel) + self._learn(t_s, gyro, accel, flags)
        self._knee_rad = knee_rad
        out = self._step(t_s, gyro, accel, saturated, flags, detected_t_s=t_s)
        if self._shadow is not None:
            self._check_sign(t_s, gyro, accel)
        return out

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
        self._track_norm(thigh.angle_rad, dt, t_s)
        if self._ekf is None:
            self._acquire(thigh)
            flags |= 16
        else:
            flags |= self._ekf_step(thigh, dt, saturated)
        self._set_state(t_s, thigh, flags)
        return self._events(t_s, detected_t_s)
