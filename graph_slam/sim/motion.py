"""Walking motion of the thigh-mounted sensors, from the gait reference curves.

A biped walks along world +x on level ground (world: x forward, y left, z up). Each leg is the
sagittal chain of :class:`kinematics.leg_params.LegParams` (hip → thigh → knee → shank → ankle →
rigid foot with heel and toe), driven by :mod:`kinematics.gait_curves` at the walking speed:
thigh angle from the vertical (hip flexion minus pelvic tilt), knee flexion and ankle
dorsiflexion. The prosthetic leg (the right leg, which carries the camera and the IMU) follows
the curves at phase φ(t); the other leg at φ(t) + 0.5. The other leg only shapes the hip path.

Contact and pinning (no sliding):

* The foot rolls over its heel, lies flat, then rolls over its toe. Its pitch γ (toe up +) is
  the curves' value passed through a C2 "flat band": |γ| below ``flat_foot_deg`` becomes exactly
  0 (foot flat), so the pivot moves from heel to toe while the foot is flat and motionless; the
  ankle angle absorbs the (≤ a few degrees) difference. The encoders report this ankle angle.
* A foot strike of a leg is the moment its heel reaches as low as the other leg's contact (a
  rigid-leg biped cannot keep both feet down); toe-off is the moment its toe rises above it.
  Both are found on a fine grid and refined by linear interpolation.
* The prosthetic foot carries the hip from its strike (phase 0 of the curves) to the other
  foot's strike (phase 0.5): the hip is placed by that leg's chain from its pinned foot, so the
  heel (then the toe) stays exactly where it landed. From the other foot's strike to our next
  strike, the hip follows the other leg's chain (its foot pinned where it landed) plus a quintic
  Hermite correction that matches position, velocity and acceleration of our chain at both
  ends. The hip path is therefore C2 everywhere: the IMU sees shocks at foot flat (the C2
  flattening of the foot pitch, ~2-4 g at the hip, like a real foot slap) but no impulses.
  A rigid-leg biped cannot keep both feet down in double support: in pre-swing and swing our
  foot follows the hip and may dip up to ~2.5 cm below the floor (it is never rendered), and
  the other foot is pinned at z = 0 only where it lands.

Out-of-plane motion, only during the prosthetic leg's swing (zero with zero first and second
derivatives at toe-off and strike, so the stance stays exactly sagittal): a thigh roll
(abduction), a thigh yaw (rotation) and a lateral hip excursion (pelvis sway), plus a lateral
foot placement that varies from stride to stride. Stride-to-stride variability of timing: the
stride times are drawn with coefficient of variation ``stride_time_cv`` and the phase is a C2
cubic spline through them. All randomness is seeded.

The leg at a phase is :func:`graph_slam.sim.leg_state.leg_state`; the C2 shapes and axis
rotations are in :mod:`graph_slam.sim.shapes`; what follows from the thigh pose (sensor frames,
ideal IMU, velocity) is :class:`graph_slam.sim.thigh_motion.ThighMotion`.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from scipy.interpolate import CubicSpline

from graph_slam.errors import SimulationError
from graph_slam.sim.config import MotionConfig
from graph_slam.sim.leg_state import LegState, leg_state
from graph_slam.sim.shapes import bump, flatten_pitch, rot_x, rot_y, rot_z, smoothstep
from graph_slam.sim.thigh_motion import GRAVITY_M_S2, ThighMotion
from kinematics import gait_curves
from kinematics.leg_params import LegParams

__all__ = [
    "GRAVITY_M_S2",
    "GaitMotion",
    "LegState",
    "ThighMotion",
    "bump",
    "flatten_pitch",
    "leg_state",
    "smoothstep",
]


class GaitMotion(ThighMotion):
    """The walking motion: thigh pose, joint angles and gait events at any session time.

    Session time 0 is ``lead_in_s`` before the first foot strike of the prosthetic leg; the
    session ends ``lead_out_s`` after the strike that completes stride ``strides``. World origin:
    the heel contact point of the first strike.
    """

    def __init__(
        self,
        speed_m_s: float,
        strides: int,
        seed: int,
        leg: LegParams | None = None,
        cfg: MotionConfig | None = None,
    ) -> None:
        self.cfg = cfg or MotionConfig()
        self.leg = leg or LegParams()
        self.speed_m_s = float(speed_m_s)
        self.strides = int(strides)
        c = self.cfg
        if c.lead_in_s > 0.3 * gait_curves.stride_time_s(speed_m_s):
            raise SimulationError(f"motion.lead_in_s={c.lead_in_s}: must be below ~0.8 stride")
        rng = np.random.default_rng([seed, 11])
        stride_s = gait_curves.stride_time_s(speed_m_s)
        self.nominal_stride_s = stride_s
        n_cycles = strides + 5
        durations = stride_s * np.clip(
            1.0 + c.stride_time_cv * rng.standard_normal(n_cycles), 0.8, 1.2
        )
        knots_t = np.concatenate([[0.0], np.cumsum(durations)])
        self._phase = CubicSpline(knots_t, np.arange(n_cycles + 1, dtype=float))
        # Events by the curves' definition: strike at phase k, toe-off at k + stance fraction;
        # the other foot strikes at k + 0.5, where the hip is handed over to its chain.
        self._stance_fraction = gait_curves.stance_fraction(speed_m_s)
        u = np.arange(0.0, knots_t[-1], 1.0 / c.grid_hz)
        phase_u = self._phase(u)
        if np.any(np.diff(phase_u) <= 0):
            raise SimulationError("the phase spline is not monotonic (stride_time_cv too large)")
        self._strikes_u = knots_t[1 : strides + 3]
        cycles = np.arange(1, strides + 2)
        self._toe_offs_u = np.interp(cycles + self._stance_fraction, phase_u, u)
        self._handover_u = np.interp(cycles + 0.5, phase_u, u)
        self._pin_feet()
        self._hermite = self._handover_hermite()
        # Lateral placement and swing sway, per stride (seeded).
        n = self._strikes_u.size
        self._y_m = c.lateral_step_sigma_m * rng.standard_normal(n)
        self._y_m -= self._y_m[1]
        amp = np.clip(1.0 + 0.25 * rng.standard_normal((n, 3)), 0.3, 1.7)
        self._sway_lateral_m = c.swing_lateral_m * amp[:, 0]
        self._sway_roll_rad = math.radians(c.swing_roll_deg) * amp[:, 1]
        self._sway_yaw_rad = math.radians(c.swing_yaw_deg) * amp[:, 2]
        # Session time: stride 0 starts at strike index 1 (index 0 only seeds the pinning).
        self.u0 = self._strikes_u[1] - c.lead_in_s
        self.duration_s = float(self._strikes_u[strides + 1] + c.lead_out_s - self.u0)

    # ---------------------------------------------------------------- internals
    def _legs(self, u: np.ndarray) -> tuple[LegState, LegState]:
        phase = self._phase(u)
        return (
            leg_state(phase, self.speed_m_s, self.leg, self.cfg),
            leg_state(phase + 0.5, self.speed_m_s, self.leg, self.cfg),
        )

    def _hip_from_foot(self, q_flat: np.ndarray, s: LegState) -> np.ndarray:
        """Hip (x, z) when the foot's flat-heel point is pinned at ``q_flat`` (rocker rule)."""
        toe_flat = q_flat + np.array([self.leg.foot_length_m, 0.0])
        heel_pivot = (s.foot_pitch_rad >= 0.0)[:, None]
        return np.where(heel_pivot, q_flat - s.heel_xz, toe_flat - s.toe_xz)

    def _flat_heel(self, hip: np.ndarray, s: LegState) -> np.ndarray:
        """Where the heel lies when the foot is flat, given the hip and the current pivot."""
        heel_pivot = (s.foot_pitch_rad >= 0.0)[:, None]
        toe_based = hip + s.toe_xz - np.array([self.leg.foot_length_m, 0.0])
        q = np.where(heel_pivot, hip + s.heel_xz, toe_based)
        q[:, 1] = 0.0
        return q

    def _pin_feet(self) -> None:
        """Pinned flat-heel points: prosthetic foot per strike, other foot per hand-over."""
        n = self._strikes_u.size
        self._q_p = np.zeros((n, 2))
        self._q_o = np.zeros((n - 1, 2))
        for k in range(n):
            if k > 0:
                u = np.array([self._strikes_u[k]])
                p_leg, o_leg = self._legs(u)
                hip_o = self._hip_from_foot(self._q_o[k - 1 : k], o_leg)
                self._q_p[k] = self._flat_heel(hip_o, p_leg)[0]
            if k < n - 1:
                u = np.array([self._handover_u[k]])
                p_leg, o_leg = self._legs(u)
                hip_p = self._hip_from_foot(self._q_p[k : k + 1], p_leg)
                self._q_o[k] = self._flat_heel(hip_p, o_leg)[0]
        x0 = self._q_p[1, 0]
        self._q_p[:, 0] -= x0
        self._q_o[:, 0] -= x0

    def _chain_derivatives(
        self, u: np.ndarray, q_flat: np.ndarray, other: bool, h: float = 1e-4
    ) -> np.ndarray:
        """(n, 3, 2): hip position, velocity, acceleration of one leg's pinned chain at ``u``."""
        legs = [self._legs(u + d)[1 if other else 0] for d in (-h, 0.0, h)]
        x = [self._hip_from_foot(q_flat, leg) for leg in legs]
        return np.stack([x[1], (x[2] - x[0]) / (2 * h), (x[2] - 2 * x[1] + x[0]) / h**2], axis=1)

    def _handover_hermite(self) -> np.ndarray:
        """Per stride, the mismatch (prosthetic chain − other chain) at both ends of the
        other leg's authority (its strike → our next strike): (n, 2, 3, 2)."""
        n = self._handover_u.size
        idx = np.arange(n)
        start = self._chain_derivatives(self._handover_u, self._q_p[idx], False)
        start -= self._chain_derivatives(self._handover_u, self._q_o[idx], True)
        end = self._chain_derivatives(self._strikes_u[1 : n + 1], self._q_p[idx + 1], False)
        end -= self._chain_derivatives(self._strikes_u[1 : n + 1], self._q_o[idx], True)
        return np.stack([start, end], axis=1)

    def _correction(self, k: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Quintic Hermite from the start mismatch to the end mismatch (C2 at both ends)."""
        t0, t1 = self._handover_u[k], self._strikes_u[k + 1]
        T = (t1 - t0)[:, None]
        s = np.clip((u - t0) / (t1 - t0), 0.0, 1.0)[:, None]
        s2, s3, s4, s5 = s * s, s**3, s**4, s**5
        h = self._hermite[k]  # (n, 2, 3, 2)
        return (
            (1 - 10 * s3 + 15 * s4 - 6 * s5) * h[:, 0, 0]
            + (s - 6 * s3 + 8 * s4 - 3 * s5) * T * h[:, 0, 1]
            + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * T**2 * h[:, 0, 2]
            + (10 * s3 - 15 * s4 + 6 * s5) * h[:, 1, 0]
            + (-4 * s3 + 7 * s4 - 3 * s5) * T * h[:, 1, 1]
            + 0.5 * (s3 - 2 * s4 + s5) * T**2 * h[:, 1, 2]
        )

    # ---------------------------------------------------------------- public
    @cached_property
    def foot_strikes_s(self) -> np.ndarray:
        """True foot strikes of the prosthetic leg (session time), strides + 1 of them."""
        return self._strikes_u[1:] - self.u0

    @cached_property
    def toe_offs_s(self) -> np.ndarray:
        """True toe-offs of the prosthetic leg (session time), one per stride."""
        return self._toe_offs_u[1:] - self.u0

    def stance_mask(self, t_s: np.ndarray) -> np.ndarray:
        """True where the prosthetic foot is on the ground (its strike to its toe-off)."""
        u = self._model_time(t_s)
        k = np.clip(np.searchsorted(self._strikes_u, u, side="right") - 1, 0, None)
        k = np.minimum(k, self._toe_offs_u.size - 1)
        return (u >= self._strikes_u[k]) & (u < self._toe_offs_u[k])

    def pinned_mask(self, t_s: np.ndarray) -> np.ndarray:
        """True where the prosthetic foot carries the hip: its strike to the other foot's
        strike. There the foot is exactly pinned (heel, then toe); in pre-swing (the other
        foot's strike to toe-off) it follows the other leg's chain and may move by millimetres.
        """
        u = self._model_time(t_s)
        k = np.clip(np.searchsorted(self._strikes_u, u, side="right") - 1, 0, None)
        k = np.minimum(k, self._handover_u.size - 1)
        return (u >= self._strikes_u[k]) & (u < self._handover_u[k])

    def joint_angles(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True knee flexion and ankle dorsiflexion of the prosthetic leg (rad)."""
        p_leg, _ = self._legs(self._model_time(t_s))
        return p_leg.knee_rad, p_leg.ankle_rad

    def world_T_thigh(self, t_s: np.ndarray) -> np.ndarray:
        """(n, 4, 4) pose of the prosthetic thigh frame (origin at the hip joint centre)."""
        u = self._model_time(t_s)
        p_leg, o_leg = self._legs(u)
        S = self._strikes_u
        TO = np.append(self._toe_offs_u, np.inf)
        M = np.append(self._handover_u, np.inf)
        k = np.clip(np.searchsorted(S, u, side="right") - 1, 0, S.size - 1)
        kc = np.minimum(k, self._handover_u.size - 1)  # the last strike has no swing after it
        k1 = np.minimum(k + 1, S.size - 1)
        hip_p = self._hip_from_foot(self._q_p[k], p_leg)
        hip_o = self._hip_from_foot(self._q_o[kc], o_leg) + self._correction(kc, u)
        before_off = (u < TO[k])[:, None]
        hip_xz = np.where((u < M[k])[:, None], hip_p, hip_o)
        # Out-of-plane motion in swing only.
        swing_s = np.where(np.isfinite(TO[k]), S[k1] - TO[k], 1.0)
        v = np.where(before_off[:, 0], 0.0, (u - np.minimum(TO[k], u)) / swing_s)
        b = bump(v)
        y = self._y_m[k] + smoothstep(v) * (self._y_m[k1] - self._y_m[k])
        y = y + self._sway_lateral_m[k] * b
        roll = -self._sway_roll_rad[k] * b
        yaw = -self._sway_yaw_rad[k] * b
        pose = np.tile(np.eye(4), (u.size, 1, 1))
        pose[:, :3, :3] = rot_z(yaw) @ rot_x(roll) @ rot_y(-p_leg.thigh_rad)
        pose[:, 0, 3] = hip_xz[:, 0]
        pose[:, 1, 3] = y
        pose[:, 2, 3] = hip_xz[:, 1]
        return pose

    def world_T_heel(self, t_s: np.ndarray) -> np.ndarray:
        """(n, 4, 4) pose of the prosthetic foot's heel frame (valid at every time)."""
        u = self._model_time(t_s)
        p_leg, _ = self._legs(u)
        thigh = self.world_T_thigh(t_s)
        gamma = p_leg.foot_pitch_rad
        heel = np.tile(np.eye(4), (u.size, 1, 1))
        heel[:, :3, :3] = thigh[:, :3, :3] @ rot_y(p_leg.thigh_rad - gamma)
        rel = np.zeros((u.size, 3))
        rel[:, 0], rel[:, 2] = p_leg.heel_xz[:, 0], p_leg.heel_xz[:, 1]
        # heel_xz is in the (unrotated) sagittal hip frame: rotate by the thigh's yaw/roll only.
        sag_R = thigh[:, :3, :3] @ rot_y(p_leg.thigh_rad)
        heel[:, :3, 3] = thigh[:, :3, 3] + np.einsum("nij,nj->ni", sag_R, rel)
        return heel

    @property
    def mean_speed_m_s(self) -> float:
        """Forward speed that the leg geometry produced (first to last strike)."""
        q = self._q_p[1 : self.strides + 2, 0]
        return float((q[-1] - q[0]) / (self.foot_strikes_s[-1] - self.foot_strikes_s[0]))
