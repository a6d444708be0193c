"""The terrain walker's foot and ankle: the stance foot's roll with the activity's ankle caps,
and the swing ankle (a mixin of :class:`graph_slam.sim.walker.TerrainMotion`).

* **Stance**: the foot's pitch relative to the tread or slope rolls over the heel, lies flat,
  then rolls over the toe (:mod:`graph_slam.sim.gaits`); the pivot (heel, then toe) does not
  move. Where the shank would bend the ankle past the activity's dorsiflexion cap
  (``Gait.ankle_max_deg``, below the URDF's 20°) the heel rises earlier; where the push-off
  would plantarflex it past the floor (``Gait.ankle_min_deg``, above the URDF's −30°) the
  heel rises less. Both are C2 soft ramps solved as a fixed point (the ankle's place depends
  on the pitch, the hip's on the ankle's).
* **Swing**: the ankle angle blends between its toe-off and strike values (quintic Hermite on
  angle, rate and acceleration), soft-capped just above the stance's cap and floored just
  below its floor; the foot's pitch follows from it.
"""

from __future__ import annotations

import math

import numpy as np

from graph_slam.sim.shapes import smoothstep
from kinematics.leg_params import LegParams

#: The stance ankle saturates at its cap over this width (rad); the swing's cap is this
#: much above the stance's, so the ends of the swing lie where its soft cap is the identity.
ANKLE_CAP_SOFT_RAD = math.radians(4.0)
ANKLE_SWING_SOFT_RAD = math.radians(1.5)
#: Fixed-point iterations of the heel rise that holds the stance ankle within its cap and floor.
ANKLE_CAP_ITERATIONS = 12


def rotate_sagittal(a, x, z):
    """(x, z) rotated by ``a`` (toe up +) in the sagittal plane; arrays broadcast."""
    c, s = np.cos(a), np.sin(a)
    return x * c - z * s, x * s + z * c


def soft_ramp(x: np.ndarray, w: float) -> np.ndarray:
    """C2 ramp: 0 below −w, x above w, a quartic between; ``x − soft_ramp(x − c, w)`` caps x at
    c smoothly and is x itself below c − w."""
    t = np.clip((np.asarray(x) + w) / (2 * w), 0.0, 1.0)
    return np.where(x >= w, x, w * (2 * t**3 - t**4))


def leg_ik(hip: np.ndarray, ankle: np.ndarray, leg: LegParams) -> tuple[np.ndarray, np.ndarray]:
    """Thigh angle from the vertical and knee flexion (rad) putting the ankle at ``ankle``."""
    T, S = leg.thigh_length_m, leg.shank_length_m
    d = ankle - hip
    dist2 = (d**2).sum(axis=1)
    cos_k = np.clip((dist2 - T * T - S * S) / (2 * T * S), -1.0, 1.0)
    knee = np.arccos(cos_k)
    beta = np.arctan2(d[:, 0], -d[:, 1])
    eps = np.arctan2(S * np.sin(knee), T + S * np.cos(knee))
    return beta + eps, knee


class FootAndAnkle:
    """Stance foot and ankle angles of :class:`~graph_slam.sim.walker.TerrainMotion` (which
    provides the footholds, the gaits, the timing and the hip)."""

    def _flat_ankle(self, k: int) -> np.ndarray:
        f = self.footholds[k]
        dx, dz = rotate_sagittal(f.slope_rad, self.leg.heel_behind_ankle_m, self.leg.ankle_height_m)
        return np.array([f.heel_x_m + dx, f.heel_z_m + dz])

    def _stance_pitch(self, k: int, tau: np.ndarray) -> np.ndarray:
        """Foot pitch relative to the surface (toe up +) over stance fraction ``tau``."""
        a, b = self._arrive[k], self._leave[k]
        heel = math.radians(a.heel_rocker_deg) * (1.0 - smoothstep(tau / a.flat_from))
        toe = -math.radians(b.toe_rocker_deg) * smoothstep((tau - b.toe_from) / (1 - b.toe_from))
        return heel + toe

    def _stance_foot(self, k: int, tau: np.ndarray):
        """Ankle (n, 2), foot pitch γ (n,) and pivot-is-toe flag in stance ``k``.

        Where the shank leans so far that the ankle would pass the activity's dorsiflexion
        cap (``ankle_max_deg``), the heel rises: γ is lowered by a C2 soft ramp so the ankle
        angle saturates at the cap. Where the push-off would plantarflex it past the floor
        (``ankle_min_deg``) the heel rises less (never below flat). A fixed point, as the
        ankle's place depends on γ and the hip's on the ankle's."""
        delta0 = self._stance_pitch(k, tau)
        cap, floor = self._ankle_cap(k), self._ankle_floor(k)
        u = self._strike_u[k] + tau * (self._toe_off_u[k] - self._strike_u[k])
        hip_x = self._hip_x(u)
        d2 = self._leg_span2(k, tau)
        delta = delta0
        for _ in range(ANKLE_CAP_ITERATIONS):
            ankle, gamma, _ = self._pivot_foot(k, delta)
            dx = hip_x - ankle[:, 0]
            hip = np.column_stack([hip_x, ankle[:, 1] + np.sqrt(np.maximum(d2 - dx * dx, 0.0))])
            thigh, knee = leg_ik(hip, ankle, self.leg)
            raw = gamma - delta + delta0 - thigh + knee  # the ankle with the planned pitch
            lower = np.minimum(soft_ramp(floor - raw, ANKLE_CAP_SOFT_RAD), np.maximum(-delta0, 0))
            delta = delta0 - soft_ramp(raw - cap, ANKLE_CAP_SOFT_RAD) + lower
        ankle, gamma, on_toe = self._pivot_foot(k, delta)
        return ankle, gamma, on_toe

    def _ankle_cap(self, k: int) -> float:
        """Dorsiflexion cap (rad) of stance ``k`` and the swing after it: the larger of the
        activities it arrives from and leaves to."""
        return math.radians(max(self._arrive[k].ankle_max_deg, self._leave[k].ankle_max_deg))

    def _ankle_floor(self, k: int) -> float:
        """Plantarflexion floor (rad) of stance ``k`` and the swing after it: the lower of
        the activities it arrives from and leaves to."""
        return math.radians(min(self._arrive[k].ankle_min_deg, self._leave[k].ankle_min_deg))

    def _pivot_foot(self, k: int, delta: np.ndarray):
        """Ankle (n, 2), foot pitch and pivot-is-toe flag for pitch ``delta`` relative to the
        surface of foothold ``k`` (heel pivot toe up, toe pivot heel up)."""
        f = self.footholds[k]
        leg = self.leg
        gamma = f.slope_rad + delta
        hx, hz = rotate_sagittal(gamma, leg.heel_behind_ankle_m, leg.ankle_height_m)
        heel_ankle = np.column_stack([f.heel_x_m + hx, f.heel_z_m + hz])
        tx, tz = rotate_sagittal(f.slope_rad, leg.foot_length_m, 0.0)
        ax, az = rotate_sagittal(
            gamma, leg.heel_behind_ankle_m - leg.foot_length_m, leg.ankle_height_m
        )
        toe_ankle = np.column_stack([f.heel_x_m + tx + ax, f.heel_z_m + tz + az])
        on_toe = delta < 0.0
        return np.where(on_toe[:, None], toe_ankle, heel_ankle), gamma, on_toe

    def _stance_ankle_derivatives(self, k: int, t: float, side: int, h: float = 2e-4):
        """Stance ankle velocity and acceleration (2,) at the end ``t`` of stance ``k``
        (one-sided, ``side`` −1 at toe-off, +1 at the strike): zero where the pitch is at
        rest, not where the heel rises to hold the ankle at its cap."""
        u = t + side * h * np.arange(3)
        tau = (u - self._strike_u[k]) / (self._toe_off_u[k] - self._strike_u[k])
        p = self._stance_foot(k, tau)[0]
        return side * (-3 * p[0] + 4 * p[1] - p[2]) / (2 * h), (p[0] - 2 * p[1] + p[2]) / h**2

    def _swing_pitch(self, k, u, thigh, knee) -> np.ndarray:
        """Foot pitch in swing: the ankle angle blends (quintic Hermite: angle, rate and
        acceleration) between its toe-off and strike values."""
        t0, t1 = self._toe_off_u[k], self._strike_u[k + 1]
        h = 2e-4
        end0 = self._ankle_derivatives(k, t0 - np.array([0.0, h, 2 * h]), -h)
        end1 = self._ankle_derivatives(k + 1, t1 + np.array([0.0, h, 2 * h]), h)
        T = t1 - t0
        s = np.clip((u - t0) / T, 0.0, 1.0)[:, None]
        s2, s3, s4, s5 = s * s, s**3, s**4, s**5
        basis = np.hstack([
            1 - 10 * s3 + 15 * s4 - 6 * s5, (s - 6 * s3 + 8 * s4 - 3 * s5) * T,
            0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * T**2, 10 * s3 - 15 * s4 + 6 * s5,
            (-4 * s3 + 7 * s4 - 3 * s5) * T, 0.5 * (s3 - 2 * s4 + s5) * T**2,
        ])  # fmt: skip
        ankle = basis @ np.concatenate([end0, end1])
        cap = self._ankle_cap(k) + ANKLE_SWING_SOFT_RAD
        ankle = ankle - soft_ramp(ankle - cap, ANKLE_SWING_SOFT_RAD)
        floor = self._ankle_floor(k) - ANKLE_SWING_SOFT_RAD
        ankle = ankle + soft_ramp(floor - ankle, ANKLE_SWING_SOFT_RAD)
        return thigh - knee + ankle

    def _ankle_derivatives(self, k: int, u: np.ndarray, h: float) -> np.ndarray:
        """Ankle angle, rate and acceleration at the end ``u[0]`` of stance ``k`` (one-sided
        differences over ``u``, spaced by ``h`` with its sign)."""
        tau = (u - self._strike_u[k]) / (self._toe_off_u[k] - self._strike_u[k])
        ankle_pt, gamma, _ = self._stance_foot(k, tau)
        thigh, knee = leg_ik(self._hip(u), ankle_pt, self.leg)
        a = gamma - thigh + knee
        return np.array(
            [a[0], (-3 * a[0] + 4 * a[1] - a[2]) / (2 * h), (a[0] - 2 * a[1] + a[2]) / h**2]
        )
