"""The first foot strikes of a walk, before the sensor's axis is learned (causal, any mounting).

The online gait estimator (:mod:`kinematics.gait_phase`) learns the thigh's sagittal axis from
a whole gait cycle; the strikes of that cycle would come out only then, 0.2-1 s after they
happened. :class:`FirstStrikes` emits them as they happen, from evidence that needs no axis and
no sign (each is unchanged by any rotation of the sensor):

* the **standing posture**: ``standing_s`` of quiet samples (gyro norm below ``quiet_rad_s``)
  give the gravity direction at rest ``up0`` and the gyro bias; from the last quiet sample on,
  the gyro is integrated into the sensor's rotation since standing, so the current direction of
  ``up0``'s sensor axis, and the thigh's **tilt** (angle from its standing direction, and the
  tilt's horizontal direction) are known exactly, whatever the mounting and the heading;
* **walking**: the running RMS of the gyro norm above ``walk_on_rms_rad_s``;
* a **shock**: the impact envelope (:class:`kinematics.gait_impact.ImpactEnvelope`, the norm of
  the high-passed specific force) rises ``min_strength`` times above its median since walking
  started; the burst is followed to its peak, and the onset is the rise through
  ``threshold_fraction`` of that peak, the strike ``lag_s`` before it (as the estimator places
  its later strikes);
* the shock is **this leg's** strike, not the other leg's felt through the pelvis, when the thigh
  is well forward at it: tilted at least ``min_tilt_rad`` from standing, having **swung** into
  that tilt (at least ``min_swing_rad`` more towards it than at any time in the last
  ``swing_window_s``), and further than it has been on the opposite side since standing (by
  ``min_side_ratio``, over the last ``side_window_s``). At its own contact the thigh is flexed 18-27° (adult reference curves,
  0.6-1.8 m/s) at the end of its swing; at the other leg's contact it is extended, and on a
  first step from standing by less than 10-15° reached by a slow stance lean.

A strike is emitted once (``detected_t_s`` is the sample that confirmed it); the estimator
keeps these strikes when it has learned the axis (a strike its replay of the learning buffer
finds within ``merge_s`` of one is the same strike) and counts those its replay does not
confirm (``first_strikes_unconfirmed``).
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from kinematics.gait_impact import ImpactConfig, ImpactEnvelope


@dataclass(frozen=True)
class FirstStrikeConfig:
    """Parameters of :class:`FirstStrikes` (SI units, radians)."""

    enabled: bool = True
    quiet_rad_s: float = 0.25
    """A sample with a smaller gyro norm is quiet (standing)."""
    standing_s: float = 0.5
    """Quiet this long: a standing posture (the tilt's zero)."""
    posture_s: float = 1.0
    """The posture is the running mean of the quiet samples' specific force over about this
    long (the last posture before walking, not that of a long stand's start); the gyro bias
    is their mean over the whole quiet run (standing sway, ~0.05 rad/s, averages out)."""
    walk_on_rms_rad_s: float = 0.5
    rms_window_s: float = 0.25
    min_walk_s: float = 0.3
    """The envelope's median (over the walking so far, at most its last 2000 samples) is
    taken over at least this much walking before a shock counts."""
    min_strength: float = 50.0
    """A shock rises this many times above the envelope's median since walking started."""
    min_tilt_rad: float = math.radians(10.0)
    min_swing_rad: float = math.radians(12.0)
    swing_window_s: float = 0.6
    min_side_ratio: float = 1.0
    side_window_s: float = 2.5
    """The opposite side is looked at over this long before the shock (a turn later turns the
    tilt's direction with the heading)."""
    follow_s: float = 0.04
    """A burst's peak is the envelope's largest value over this long after it rose through
    ``min_strength`` (its ripples peak 20-60 ms after contact)."""
    refractory_s: float = 0.6
    """No second strike this soon after one."""
    merge_s: float = 0.3


@dataclass
class _Burst:
    start_s: float
    peak: float


class FirstStrikes:
    """See the module docstring: :meth:`update` per sample, returns (strike, detected) or None."""

    def __init__(self, config: FirstStrikeConfig | None = None, impact: ImpactConfig | None = None):
        self.cfg = config or FirstStrikeConfig()
        self.impact = impact or ImpactConfig()
        self.envelope = ImpactEnvelope(self.impact)
        self.strikes_s: list[float] = []
        self._t: float | None = None
        self._quiet_s = 0.0
        self._gyro_sum = np.zeros(3)  # over the quiet run: the sway averages out
        self._quiet_n = 0
        self._up_mean = np.zeros(3)  # accel over the last ~posture_s of quiet
        self._up0: np.ndarray | None = None
        self._bias = np.zeros(3)
        self._R = np.eye(3)  # standing sensor frame <- current sensor frame
        self._ms = 0.0
        self._walk_s = 0.0
        self._envs: deque[float] = deque(maxlen=2000)
        self._hist: deque[tuple[float, float, np.ndarray]] = deque(maxlen=4000)
        self._burst: _Burst | None = None

    def update(self, t_s: float, gyro: np.ndarray, accel: np.ndarray) -> tuple[float, float] | None:
        dt = 0.0 if self._t is None else t_s - self._t
        self._t = t_s
        env = self.envelope.update(t_s, accel)
        if not self.cfg.enabled:
            return None
        self._posture(dt, gyro, accel)
        if self._up0 is None:
            return None
        self._ms += min(1.0, dt / self.cfg.rms_window_s) * (float(gyro @ gyro) - self._ms)
        walking = math.sqrt(self._ms) > self.cfg.walk_on_rms_rad_s
        self._walk_s = self._walk_s + dt if walking else 0.0
        # the tilt: the sensor axis that pointed up at standing, now (in the standing frame)
        self._hist.append((t_s, env, np.cross(self._up0, self._R @ self._up0)))
        if not walking:
            self._envs.clear()
            self._burst = None
            return None
        self._envs.append(env)
        return self._shock(t_s, env)

    # --- posture -------------------------------------------------------------------------
    def _posture(self, dt: float, gyro: np.ndarray, accel: np.ndarray) -> None:
        """Standing: collect the quiet samples; the sensor's rotation since the last one."""
        if float(np.linalg.norm(gyro)) < self.cfg.quiet_rad_s:
            w = 1.0 if self._quiet_n == 0 else min(1.0, dt / self.cfg.posture_s)
            self._up_mean += w * (np.asarray(accel, dtype=float) - self._up_mean)
            self._gyro_sum += gyro
            self._quiet_n += 1
            self._quiet_s += dt
            if self._quiet_s >= self.cfg.standing_s:
                self._bias = self._gyro_sum / self._quiet_n
                self._up0 = self._up_mean / max(float(np.linalg.norm(self._up_mean)), 1e-9)
                self._R = np.eye(3)
                self._hist.clear()
                self.strikes_s.clear()
                return
        else:
            self._quiet_s = 0.0
            self._gyro_sum[:] = 0.0
            self._quiet_n = 0
        if self._up0 is not None and dt > 0:
            self._R = self._R @ _exp(np.asarray(gyro, dtype=float) - self._bias, dt)

    # --- shocks --------------------------------------------------------------------------
    def _shock(self, t_s: float, env: float) -> tuple[float, float] | None:
        cfg = self.cfg
        if self._burst is None:
            if self._walk_s < cfg.min_walk_s:
                return None
            floor = max(float(np.median(self._envs)), 1e-12)
            recent = self.strikes_s and t_s - self.strikes_s[-1] < cfg.refractory_s
            if env >= cfg.min_strength * floor and not recent:
                self._burst = _Burst(t_s, env)
            return None
        burst = self._burst
        burst.peak = max(burst.peak, env)
        if t_s - burst.start_s < cfg.follow_s:
            return None
        self._burst = None
        onset = self._onset(self.impact.threshold_fraction * burst.peak, burst.start_s - 0.05)
        if onset is None or not self._forward_swing(onset):
            return None
        strike = onset[0] - self.impact.lag_s
        self.strikes_s.append(strike)
        return strike, t_s

    def _onset(self, level: float, from_s: float) -> tuple[float, np.ndarray] | None:
        """The first rise through ``level`` after ``from_s`` (interpolated), with the tilt
        vector there."""
        h = [x for x in self._hist if x[0] >= from_s]
        for (t0, e0, _), (t1, e1, v1) in itertools.pairwise(h):
            if e0 < level <= e1:
                return t0 + (level - e0) / (e1 - e0) * (t1 - t0), v1
        return None

    def _forward_swing(self, onset: tuple[float, np.ndarray]) -> bool:
        """The thigh is tilted at least ``min_tilt_rad`` at the onset, swung into that tilt
        within ``swing_window_s``, and further than on the opposite side over ``side_window_s``."""
        cfg = self.cfg
        t_on, v = onset
        tilt = math.asin(min(float(np.linalg.norm(v)), 1.0))
        if tilt < cfg.min_tilt_rad:
            return False
        d = v / np.linalg.norm(v)
        past = [
            (t, float(w @ d)) for t, _, w in self._hist if t_on - cfg.side_window_s <= t <= t_on
        ]
        swing = [p for t, p in past if t >= t_on - cfg.swing_window_s]
        if not swing or math.asin(min(max(v @ d - min(swing), 0.0), 1.0)) < cfg.min_swing_rad:
            return False
        opposite = max([-p for _, p in past] + [0.0])
        return tilt >= cfg.min_side_ratio * math.asin(min(opposite, 1.0))


def _exp(omega: np.ndarray, dt: float) -> np.ndarray:
    """Rotation matrix of the rotation vector ``omega * dt`` (Rodrigues)."""
    v = omega * dt
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * (kx @ kx)
