"""Gait patterns beyond the able-bodied reference, for synthetic thigh-IMU walks: the side of a
transfemoral prosthesis (shorter stance, smaller thigh excursion, a stiff knee in stance, reduced
knee flexion in swing), the sound side (longer stance), treadmill walking (no progression), and
the heel-strike shock the accelerometer sees.

A :class:`GaitPattern` changes the reference curves (:mod:`kinematics.gait_curves`) of
:func:`kinematics.gait_scenarios.simulate_walks`:

* **stance fraction**: the cycle is warped smoothly (a periodic cubic shift of the phase) so
  that the reference's toe-off (its stance fraction at the walking speed) falls at
  ``stance_fraction``; the true toe-offs move with it;
* **thigh**: ``thigh_gain`` scales the thigh angle (a prosthesis user's hip excursion is
  smaller), ``thigh_offset_rad`` adds a constant flexion;
* **knee** (for the encoder signal of :func:`knee_angle`): ``knee_stance_gain`` scales the
  stance-phase flexion (a stiff prosthetic knee: ~0.1), ``knee_swing_gain`` the swing peak;
* **treadmill**: the hip does not progress (the belt moves under the foot);
* **shock**: at each strike the accelerometer gets a burst along the thigh (axial, with an
  anterior part): ``impact_m_s2 · (τ/τr) e^{1-τ/τr} · sin(2π f τ)`` for τ ≥ 0 after contact,
  τr = 30 ms, f = 25 Hz, the shape of the bursts on the real Xsens walk (a peak 30-45 ms after
  contact, 15-20 m/s² above 1 g). ``impact_m_s2 = 0``: no shock (the reference generator's
  smooth signals).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SHOCK_RISE_S = 0.03
SHOCK_HZ = 25.0
SHOCK_DIRECTION_THIGH = np.array([0.4, 0.0, 1.0]) / math.hypot(0.4, 1.0)
"""Burst direction in the thigh frame of the generator (x forward, z along the thigh, up)."""


@dataclass(frozen=True)
class GaitPattern:
    """How a synthetic walk departs from the able-bodied reference (see the module docstring)."""

    name: str = "able-bodied"
    stance_fraction: float | None = None
    """None: the reference's at the walking speed."""
    thigh_gain: float = 1.0
    thigh_offset_rad: float = 0.0
    knee_stance_gain: float = 1.0
    knee_swing_gain: float = 1.0
    treadmill: bool = False
    impact_m_s2: float = 0.0

    def stance(self, speed_m_s: float) -> float:
        from kinematics.gait_curves import stance_fraction

        return (
            self.stance_fraction if self.stance_fraction is not None else stance_fraction(speed_m_s)
        )

    def warp(self, phase: np.ndarray, speed_m_s: float) -> np.ndarray:
        """The reference phase shown at ``phase`` (in [0, 1)): the toe-off moved to
        :meth:`stance`."""
        from scipy.interpolate import CubicSpline

        from kinematics.gait_curves import stance_fraction

        ref, sf = stance_fraction(speed_m_s), self.stance(speed_m_s)
        p = np.asarray(phase, dtype=float) % 1.0
        # a smooth (periodic C2) shift: a kink would put a spurious shock in the accelerometer
        shift = CubicSpline([0.0, sf, 1.0], [0.0, ref - sf, 0.0], bc_type="periodic")
        return p + shift(p)

    def thigh(self, phase: np.ndarray, speed_m_s: float) -> np.ndarray:
        """Thigh angle (rad, flexion +) at ``phase`` of this pattern."""
        from kinematics.gait_curves import thigh_angle

        return self.thigh_gain * thigh_angle(self.warp(phase, speed_m_s), speed_m_s) + (
            self.thigh_offset_rad
        )


ABLE_BODIED = GaitPattern()
PROSTHETIC_SIDE = GaitPattern(
    name="prosthetic side",
    stance_fraction=0.55,
    thigh_gain=0.8,
    thigh_offset_rad=math.radians(3.0),
    knee_stance_gain=0.1,
    knee_swing_gain=0.75,
    impact_m_s2=12.0,
)
SOUND_SIDE = GaitPattern(name="sound side", stance_fraction=0.68, impact_m_s2=15.0)


def knee_angle(pattern: GaitPattern, phase: np.ndarray, speed_m_s: float) -> np.ndarray:
    """Knee flexion (rad) of the pattern: the reference knee with its stance part scaled by
    ``knee_stance_gain`` and its swing part by ``knee_swing_gain``."""
    from kinematics.gait_curves import joint_angles, stance_fraction

    ref = joint_angles(pattern.warp(phase, speed_m_s), speed_m_s)["knee"]
    in_stance = pattern.warp(phase, speed_m_s) < stance_fraction(speed_m_s)
    return np.where(in_stance, pattern.knee_stance_gain, pattern.knee_swing_gain) * ref


def shock(t_s: np.ndarray, strikes_s: np.ndarray, amplitude_m_s2: float) -> np.ndarray:
    """The strikes' bursts (N, 3) in the thigh frame (see the module docstring)."""
    out = np.zeros((np.asarray(t_s).size, 3))
    if amplitude_m_s2 <= 0:
        return out
    for ts in strikes_s:
        tau = np.asarray(t_s, dtype=float) - ts
        m = (tau >= 0) & (tau < 0.25)
        x = tau[m] / SHOCK_RISE_S
        out[m] += np.outer(
            amplitude_m_s2 * x * np.exp(1 - x) * np.sin(2 * math.pi * SHOCK_HZ * tau[m]),
            SHOCK_DIRECTION_THIGH,
        )
    return out
