"""The terrain-following walker: the prosthetic leg walks on stairs, ramps, curbs and boxes.

:class:`TerrainMotion` has the interface of :class:`graph_slam.sim.motion.GaitMotion` (thigh
pose, joint angles, events, IMU) but plans where the foot lands
(:mod:`graph_slam.sim.footholds`) and moves the leg by inverse kinematics instead of playing
the level-walking curves:

* **Stance (strike → toe-off): the foot is pinned on its foothold.** Its pitch relative to the
  surface rolls over the heel, lies flat on the tread or slope, then rolls over the toe up to
  toe-off (quintic smoothsteps: the ankle point is C2 and at rest at the strike and at
  toe-off); the pivot (heel, then toe) does not move at all. The ankle stays between the
  activity's dorsiflexion cap and plantarflexion floor (the heel rises earlier, or less;
  :mod:`graph_slam.sim.walker_ankle`). The hip's height is the leg's length at a target knee
  flexion over the ankle (the level curve, Schwartz 2008, or the activity's knots,
  :mod:`graph_slam.sim.gaits`); its x a C2 spline through one posture per strike.
* **Swing (toe-off → strike)**: the hip's height bridges the two stances (quintic Hermite,
  C2) and rises to the mean of their apexes (the other leg's mid-stance); the ankle moves
  relative to the hip on a quintic Hermite from the stance's ankle motion at toe-off to rest
  at the strike (in the world), follows 30 % of that rise, and is lifted by
  ``c · 64 s³(1-s)³``; ``c`` is raised until every convex edge
  the swing passes over (nosings, box and curb edges, a ramp's top) is cleared by the sole by
  ``clearance_m`` and the foot touches no surface. Going down stairs the forward motion ends
  at 75 % of the swing (over the nosing, then straight down). The ankle angle blends between
  its toe-off and strike values within the cap and the floor
  (:mod:`graph_slam.sim.walker_ankle`); the foot's pitch follows from it.
* **Joint angles** by two-link IK of thigh and shank from the hip to the ankle; the ankle
  angle follows from the foot's pitch. The encoders report these angles, so the leg model's
  forward kinematics from the pinned foot reproduces the camera pose exactly.

The other leg is not modelled (in the level walker it only shaped the hip path); the hip path
here is designed instead. Simplifications are listed in docs/simulator.md.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from scipy.interpolate import CubicSpline

from graph_slam.errors import SimulationError
from graph_slam.sim.config import MotionConfig
from graph_slam.sim.footholds import (
    Foothold,
    FootholdPlanner,
    stride_label,
)
from graph_slam.sim.gaits import GAIT
from graph_slam.sim.shapes import bump, rot_x, rot_y, rot_z, smoothstep
from graph_slam.sim.surface import Surfaces
from graph_slam.sim.thigh_motion import ThighMotion
from graph_slam.sim.walker_ankle import FootAndAnkle
from graph_slam.sim.walker_ankle import leg_ik as _ik
from graph_slam.sim.walker_ankle import rotate_sagittal as _rotate
from graph_slam.sim.walker_swing import SwingPlanning
from kinematics import gait_curves
from kinematics.leg_params import LegParams

#: The walker refuses a plan whose leg leaves these (the URDF's knee limit is 120°).
KNEE_MAX_RAD = math.radians(125.0)
THIGH_RANGE_RAD = (math.radians(-45.0), math.radians(95.0))


class TerrainMotion(SwingPlanning, FootAndAnkle, ThighMotion):
    """The prosthetic leg walking over a scene's surfaces (see the module text).

    Session time 0 is ``lead_in_s`` before the first recorded strike (at world x = 0; its
    heel lands on the surface there); the session ends ``lead_out_s`` after the strike that
    completes stride ``strides``.
    """

    clearance_m: float = 0.03

    def __init__(
        self,
        speed_m_s: float,
        strides: int,
        seed: int,
        surfaces: Surfaces,
        leg: LegParams | None = None,
        cfg: MotionConfig | None = None,
    ) -> None:
        self.cfg = cfg or MotionConfig()
        self.leg = leg or LegParams()
        self.speed_m_s = float(speed_m_s)
        self.strides = int(strides)
        self.surfaces = surfaces
        c = self.cfg
        rng = np.random.default_rng([seed, 11])
        self.nominal_stride_s = gait_curves.stride_time_s(speed_m_s)
        self._sf = gait_curves.stance_fraction(speed_m_s)
        n = strides + 4  # footholds: one before the first recorded strike, two after the last
        self._level_stride_m = gait_curves.stride_length_m(speed_m_s)
        planner = FootholdPlanner(surfaces, self.leg.foot_length_m, self._level_stride_m)
        self.footholds: list[Foothold] = planner.plan(n)
        self.segments = planner.segs
        self.labels = [
            stride_label(a, b, self.segments)
            for a, b in zip(self.footholds[:-1], self.footholds[1:], strict=True)
        ]
        arrive = ["level", *self.labels]  # how each foothold was reached
        self._arrive = [GAIT[label] for label in arrive]
        self._leave = [GAIT[label] for label in self.labels] + [GAIT["level"]]
        durations = np.array(
            [self.nominal_stride_s * g.time_factor for g in self._leave[: n - 1]]
        ) * np.clip(1.0 + c.stride_time_cv * rng.standard_normal(n - 1), 0.8, 1.2)
        self._strike_u = np.concatenate([[0.0], np.cumsum(durations)])
        self._toe_off_u = np.append(
            self._strike_u[:-1] + self._sf * durations,
            self._strike_u[-1] + self._sf * self.nominal_stride_s,
        )
        self._y_m = c.lateral_step_sigma_m * rng.standard_normal(n)
        self._y_m -= self._y_m[1]
        amp = np.clip(1.0 + 0.25 * rng.standard_normal((n, 3)), 0.3, 1.7)
        self._sway_lateral_m = c.swing_lateral_m * amp[:, 0]
        self._sway_roll_rad = math.radians(c.swing_roll_deg) * amp[:, 1]
        self._sway_yaw_rad = math.radians(c.swing_yaw_deg) * amp[:, 2]
        self._hip_x = self._hip_x_spline()
        self._swing_ends: dict[int, tuple] = {}
        self._lift = np.zeros(n - 1)
        self._plan_swings()
        self.u0 = self._strike_u[1] - c.lead_in_s
        self.duration_s = float(self._strike_u[strides + 1] + c.lead_out_s - self.u0)
        self._check_reach()

    # ------------------------------------------------------------ stance foot
    # ------------------------------------------------------------ hip
    def _hip_x_spline(self) -> CubicSpline:
        """Hip x: a C2 spline through one posture per strike (behind the landing ankle)."""
        t, x = [], []
        for k in range(len(self.footholds)):
            g = self._arrive[k]
            back = g.hip_back_m
            if g.back_per_stride > 0.0:
                prev = self.footholds[max(k - 1, 0)].heel_x_m
                stride = self.footholds[k].heel_x_m - prev if k > 0 else self._level_stride_m
                back = -g.back_per_stride * stride
            t.append(self._strike_u[k])
            x.append(self._flat_ankle(k)[0] + back)
        return CubicSpline(np.array(t), np.array(x))

    def _knee_target(self, k: int, tau: np.ndarray) -> np.ndarray:
        """Stance knee flexion (rad) of stance ``k`` at stance fraction ``tau``."""
        g = self._leave[k] if self._leave[k].knee_deg else self._arrive[k]
        if g.knee_deg:
            knots = np.array(g.knee_deg)
            spline = CubicSpline(knots[:, 0], knots[:, 1], bc_type=((1, 0.0), (1, 0.0)))
            return np.radians(spline(np.clip(tau, 0.0, 1.0)))
        a = self._arrive[k]
        knee = gait_curves.joint_angles(np.clip(tau, 0.0, 1.0) * self._sf, self.speed_m_s)["knee"]
        extra = a.knee_extra_deg[0] * (1.0 - smoothstep(tau / 0.6))
        extra = extra + self._leave[k].knee_extra_deg[1] * bump(tau)
        a, b, eps = knee + np.radians(extra), math.radians(6.0), math.radians(3.0)
        return 0.5 * (a + b + np.sqrt((a - b) ** 2 + eps * eps))  # a smooth max(a, 6°)

    def _leg_span2(self, k: int, tau: np.ndarray) -> np.ndarray:
        """Squared hip–ankle distance at the target knee flexion of stance ``k``."""
        T, S = self.leg.thigh_length_m, self.leg.shank_length_m
        return T * T + S * S + 2 * T * S * np.cos(self._knee_target(k, tau))

    def _stance_hip_z(self, k: int, u: np.ndarray) -> np.ndarray:
        """Stance hip height: the leg's length at the target knee flexion over the ankle."""
        tau = (u - self._strike_u[k]) / (self._toe_off_u[k] - self._strike_u[k])
        ankle = self._stance_foot(k, tau)[0]
        d2 = self._leg_span2(k, tau)
        dx = self._hip_x(u) - ankle[:, 0]
        if np.any(dx * dx >= d2):
            raise SimulationError(f"stance {k}: the hip is out of the leg's reach")
        return ankle[:, 1] + np.sqrt(d2 - dx * dx)

    def _stance_apex(self, k: int) -> float:
        """The highest hip of stance ``k``."""
        u = np.linspace(self._strike_u[k], self._toe_off_u[k], 41)
        return float(self._stance_hip_z(k, u).max())

    def _hip_z_state(self, k: int, t: float, side: int, h: float = 2e-4) -> np.ndarray:
        """Hip z, rate and acceleration at the end ``t`` of stance ``k`` (one-sided)."""
        u = t + side * h * np.arange(3)
        z = self._stance_hip_z(k, u)
        return np.array([z[0], side * (-3 * z[0] + 4 * z[1] - z[2]) / (2 * h),
                         (z[0] - 2 * z[1] + z[2]) / h**2])  # fmt: skip

    def _hip(self, u: np.ndarray) -> np.ndarray:
        """Hip (n, 2): stance from the leg, swing a quintic Hermite (C2) between stances."""
        u = np.atleast_1d(u)
        k = self._index(u)
        stance = u < self._toe_off_u[k]
        z = np.zeros(u.size)
        for kk in np.unique(k):
            st, sw = (k == kk) & stance, (k == kk) & ~stance
            if st.any():
                z[st] = self._stance_hip_z(kk, u[st])
            if sw.any():
                z[sw] = self._swing_hip_z(kk, u[sw])
        return np.column_stack([self._hip_x(u), z])

    def _swing_hip_z(self, k: int, u: np.ndarray) -> np.ndarray:
        if k not in self._swing_ends:
            t0, t1 = self._toe_off_u[k], self._strike_u[k + 1]
            start, end = self._hip_z_state(k, t0, -1), self._hip_z_state(k + 1, t1, +1)
            # the other leg's mid-stance: the hip as high as the mean of our two apexes
            apex = 0.5 * (self._stance_apex(k) + self._stance_apex(k + 1))
            mid = float(_quintic(np.array([0.5]), t1 - t0, start, end)[0])
            self._swing_ends[k] = (start, end, max(0.0, apex - mid))
        start, end, rise = self._swing_ends[k]
        t0, t1 = self._toe_off_u[k], self._strike_u[k + 1]
        T = t1 - t0
        sc = np.clip((u - t0) / T, 0.0, 1.0)
        return _quintic(sc, T, start, end) + rise * bump(sc)

    def _hip_derivatives(self, t: float, h: float = 2e-4) -> tuple[np.ndarray, np.ndarray]:
        """Hip velocity and acceleration (2,) at a stance end ``t`` (central differences of
        the C2 path)."""
        p = self._hip(np.array([t - h, t, t + h]))
        return (p[2] - p[0]) / (2 * h), (p[2] - 2 * p[1] + p[0]) / h**2

    # ------------------------------------------------------------ swing
    # ------------------------------------------------------------ evaluation
    def _index(self, u: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self._strike_u, u, side="right") - 1, 0,
                       self._strike_u.size - 2)  # fmt: skip

    def _sagittal(self, u: np.ndarray):
        """Hip (n, 2), ankle (n, 2), foot pitch, thigh, knee, stride index and stance flag at
        model times ``u``."""
        k = self._index(u)
        stance = u < self._toe_off_u[k]
        hip, ankle, gamma = self._hip_and_ankle(u, k, stance)
        thigh, knee = _ik(hip, ankle, self.leg)
        for kk in np.unique(k):
            sw = (k == kk) & ~stance
            if sw.any():
                gamma[sw] = self._swing_pitch(kk, u[sw], thigh[sw], knee[sw])
        return hip, ankle, gamma, thigh, knee, k, stance

    def _check_reach(self) -> None:
        u = np.arange(self.u0, self.u0 + self.duration_s, 1e-3)
        k = self._index(u)
        hip, ankle, _ = self._hip_and_ankle(u, k, u < self._toe_off_u[k])
        reach = np.linalg.norm(hip - ankle, axis=1) / (
            self.leg.thigh_length_m + self.leg.shank_length_m
        )
        thigh, knee = _ik(hip, ankle, self.leg)
        bad = (knee > KNEE_MAX_RAD) | (thigh < THIGH_RANGE_RAD[0]) | (thigh > THIGH_RANGE_RAD[1])
        if bad.any():
            k = int(self._index(u[bad][:1])[0])
            raise SimulationError(
                f"stride {k} ({self.labels[k]}): the leg leaves the human range (knee up to "
                f"{math.degrees(knee.max()):.0f} deg, thigh {math.degrees(thigh.min()):.0f}.."
                f"{math.degrees(thigh.max()):.0f} deg); the scene's layout asks too much"
            )
        if reach.max() > math.cos(math.radians(1.0)):
            i = int(reach.argmax())
            k = int(self._index(u[i : i + 1])[0])
            raise SimulationError(
                f"the leg cannot reach the foot at t = {u[i] - self.u0:.3f} s "
                f"(stride {k}, {self.labels[k]})"
            )

    def _hip_and_ankle(self, u: np.ndarray, k: np.ndarray, stance: np.ndarray):
        """Hip (n, 2), ankle (n, 2) and the stance foot's pitch (0 in swing) at ``u``."""
        ankle = np.zeros((u.size, 2))
        gamma = np.zeros(u.size)
        for kk in np.unique(k):
            sel = k == kk
            st, sw = sel & stance, sel & ~stance
            if st.any():
                tau = (u[st] - self._strike_u[kk]) / (self._toe_off_u[kk] - self._strike_u[kk])
                ankle[st], gamma[st], _ = self._stance_foot(kk, tau)
            if sw.any():
                s = (u[sw] - self._toe_off_u[kk]) / (self._strike_u[kk + 1] - self._toe_off_u[kk])
                ankle[sw] = self._swing_ankle(kk, s, self._lift[kk])
        return self._hip(u), ankle, gamma

    # ------------------------------------------------------------ public
    @cached_property
    def foot_strikes_s(self) -> np.ndarray:
        """True foot strikes of the prosthetic leg (session time), strides + 1 of them."""
        return self._strike_u[1 : self.strides + 2] - self.u0

    @cached_property
    def toe_offs_s(self) -> np.ndarray:
        """True toe-offs (session time), one per stride."""
        return self._toe_off_u[1 : self.strides + 1] - self.u0

    @property
    def stride_labels(self) -> list[str]:
        """Terrain label of each recorded stride (strike k to strike k + 1)."""
        return self.labels[1 : self.strides + 1]

    @property
    def stride_footholds(self) -> list[Foothold]:
        """The foothold of each recorded strike (strides + 1)."""
        return self.footholds[1 : self.strides + 2]

    def stance_mask(self, t_s) -> np.ndarray:
        u = self._model_time(t_s)
        return u < self._toe_off_u[self._index(u)]

    def pinned_mask(self, t_s) -> np.ndarray:
        """The whole stance is pinned (the pivot never moves)."""
        return self.stance_mask(t_s)

    def joint_angles(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """True knee flexion and ankle dorsiflexion of the prosthetic leg (rad)."""
        _, _, gamma, thigh, knee, *_ = self._sagittal(self._model_time(t_s))
        return knee, gamma - thigh + knee

    def thigh_angle(self, t_s) -> np.ndarray:
        """Thigh inclination from the vertical (rad, flexion +): the hip angle with no pelvis."""
        return self._sagittal(self._model_time(t_s))[3]

    def world_T_thigh(self, t_s) -> np.ndarray:
        u = self._model_time(t_s)
        hip, _, _, thigh, _, k, stance = self._sagittal(u)
        S, TO = self._strike_u, self._toe_off_u
        k1 = k + 1
        v = np.where(stance, 0.0, (u - np.minimum(TO[k], u)) / (S[k1] - TO[k]))
        b = bump(v)
        y = self._y_m[k] + smoothstep(v) * (self._y_m[k1] - self._y_m[k])
        y = y + self._sway_lateral_m[k] * b
        pose = np.tile(np.eye(4), (u.size, 1, 1))
        pose[:, :3, :3] = (
            rot_z(-self._sway_yaw_rad[k] * b) @ rot_x(-self._sway_roll_rad[k] * b)
            @ rot_y(-thigh)
        )  # fmt: skip
        pose[:, 0, 3], pose[:, 1, 3], pose[:, 2, 3] = hip[:, 0], y, hip[:, 1]
        return pose

    def world_T_heel(self, t_s) -> np.ndarray:
        """(n, 4, 4) pose of the prosthetic foot's heel frame (x toe-ward along the sole)."""
        u = self._model_time(t_s)
        hip, ankle, gamma, thigh, _, _, _ = self._sagittal(u)
        pose = self.world_T_thigh(t_s)
        sag_R = pose[:, :3, :3] @ rot_y(thigh)
        hx, hz = _rotate(gamma, -self.leg.heel_behind_ankle_m, -self.leg.ankle_height_m)
        rel = np.column_stack([ankle[:, 0] + hx - hip[:, 0], np.zeros(u.size),
                               ankle[:, 1] + hz - hip[:, 1]])  # fmt: skip
        heel = np.tile(np.eye(4), (u.size, 1, 1))
        heel[:, :3, :3] = sag_R @ rot_y(-gamma)
        heel[:, :3, 3] = pose[:, :3, 3] + np.einsum("nij,nj->ni", sag_R, rel)
        return heel

    def world_toe(self, t_s) -> np.ndarray:
        """(n, 3) world position of the toe (the sole's front end)."""
        heel = self.world_T_heel(t_s)
        return heel[:, :3, 3] + heel[:, :3, 0] * self.leg.foot_length_m

    @property
    def mean_speed_m_s(self) -> float:
        """Horizontal speed the plan produced (first to last recorded strike)."""
        x = [f.heel_x_m for f in self.stride_footholds]
        return float((x[-1] - x[0]) / (self.foot_strikes_s[-1] - self.foot_strikes_s[0]))


def _quintic(s: np.ndarray, T: float, start, end) -> np.ndarray:
    """Quintic Hermite on [0, 1] from (value, rate, acceleration) ``start`` to ``end``
    (rates per second; ``T`` the duration in seconds)."""
    p0, v0, c0 = start
    p1, v1, c1 = end
    s2, s3, s4, s5 = s * s, s**3, s**4, s**5
    return (
        (1 - 10 * s3 + 15 * s4 - 6 * s5) * p0 + (s - 6 * s3 + 8 * s4 - 3 * s5) * T * v0
        + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * T * T * c0 + (10 * s3 - 15 * s4 + 6 * s5) * p1
        + (-4 * s3 + 7 * s4 - 3 * s5) * T * v1 + 0.5 * (s3 - 2 * s4 + s5) * T * T * c1
    )  # fmt: skip
