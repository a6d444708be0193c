"""The terrain walker's swing (:class:`graph_slam.sim.walker.TerrainMotion`, whose module text
describes it): the ankle's path from toe-off to strike, its lift raised until every edge the
swing passes over is cleared by ``clearance_m`` and the sole touches no surface, and the
clearances the plan achieved."""

from __future__ import annotations

import math

import numpy as np

from graph_slam.errors import SimulationError
from graph_slam.sim.footholds import crossed_edges
from graph_slam.sim.shapes import bump, smoothstep
from graph_slam.sim.walker_ankle import leg_ik as _ik
from graph_slam.sim.walker_ankle import rotate_sagittal as _rotate

#: The sole may touch the surface within this (m) as it lands and leaves (numerical).
GROUND_TOLERANCE_M = 2e-4
#: The share of the hip's rise in our swing (the other leg's mid-stance) the foot does not follow.
HIP_RISE_SHARE = 0.7
#: Edges this close to the foothold left or landed on are not held to the clearance margin.
EDGE_KEEPOUT_M = 0.03


class SwingPlanning:
    """The swing's methods of :class:`~graph_slam.sim.walker.TerrainMotion` (its state: the
    footholds, the hip path and the stance feet are the walker's)."""

    def _swing_ankle(self, k: int, s: np.ndarray, lift: float) -> np.ndarray:
        """Swing ankle at swing fraction ``s``: relative to the hip, a quintic Hermite from
        where the stance left it to where the next stance starts (the foot at rest at both
        ends: the relative rate and acceleration are minus the hip's), plus the lift."""
        t0, t1 = self._toe_off_u[k], self._strike_u[k + 1]
        T = t1 - t0
        a0 = self._stance_foot(k, np.array([1.0]))[0][0]
        a1 = self._stance_foot(k + 1, np.array([0.0]))[0][0]
        ends = []
        for kk, t, a, side in ((k, t0, a0, -1), (k + 1, t1, a1, +1)):
            h = self._hip(np.array([t]))[0]
            hv, ha = self._hip_derivatives(t)
            av, aa = self._stance_ankle_derivatives(kk, t, side)
            ends.append((a - h, (av - hv) * T, (aa - ha) * T * T))
        (p0, v0, c0), (p1, v1, c1) = ends
        sc = np.clip(s, 0.0, 1.0)[:, None]
        s2, s3, s4, s5 = sc * sc, sc**3, sc**4, sc**5
        rel = (
            (1 - 10 * s3 + 15 * s4 - 6 * s5) * p0 + (sc - 6 * s3 + 8 * s4 - 3 * s5) * v0
            + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * c0 + (10 * s3 - 15 * s4 + 6 * s5) * p1
            + (-4 * s3 + 7 * s4 - 3 * s5) * v1 + 0.5 * (s3 - 2 * s4 + s5) * c1
        )  # fmt: skip
        out = self._hip(t0 + sc[:, 0] * T) + rel
        drop = self.footholds[k].heel_z_m - self.footholds[k + 1].heel_z_m
        if drop > 0.05 and self.labels[k] == "stairs_down":  # over the nosing, then down
            w = smoothstep((sc[:, 0] - 0.45) / 0.3)
            out[:, 0] += (a1[0] - out[:, 0]) * w
        hip_rise = self._swing_ends[k][2]  # the hip's rise in our swing does not lift the foot
        out[:, 1] += (lift - HIP_RISE_SHARE * hip_rise) * bump(sc[:, 0])
        return out

    def _swing_clearance(
        self, k: int, lift: float, every_edge: bool = False
    ) -> tuple[float, float]:
        """(least clearance over the crossed edges − margin, least sole height above the
        surface) of swing ``k`` with lift amplitude ``lift``."""
        u = np.linspace(self._toe_off_u[k], self._strike_u[k + 1], 481)[1:-1]
        s = (u - self._toe_off_u[k]) / (self._strike_u[k + 1] - self._toe_off_u[k])
        ankle = self._swing_ankle(k, s, lift)
        hip = self._hip(u)
        thigh, knee = _ik(hip, ankle, self.leg)
        gamma = self._swing_pitch(k, u, thigh, knee)
        sole = self._sole_points(ankle, gamma)  # (n, m, 2)
        edges = (
            crossed_edges(self.footholds[k], self.footholds[k + 1], self.segments)
            if every_edge else self.swing_edges(k)
        )  # fmt: skip
        worst = np.inf
        for xe, ze in edges:
            xs, zs = sole[:, :, 0], sole[:, :, 1]
            over = (xs.min(axis=1) <= xe) & (xs.max(axis=1) >= xe)
            if not over.any():
                continue
            z_at = np.array([np.interp(xe, xs[i], zs[i]) for i in np.flatnonzero(over)])
            worst = min(worst, float(z_at.min() - ze))
        ground = self.surfaces.height_at(sole[:, :, 0], np.zeros(sole.shape[:2]))
        return worst - self.clearance_m, float((sole[:, :, 1] - ground).min())

    def swing_edges(self, k: int) -> list[tuple[float, float]]:
        """(x, z) of the edges swing ``k`` must clear by ``clearance_m``: those it passes
        over, except within ``EDGE_KEEPOUT_M`` of the toe it leaves from or the heel it
        lands on (there it is only checked not to touch the surface)."""
        a, b = self.footholds[k], self.footholds[k + 1]
        toe0 = a.heel_x_m + self.leg.foot_length_m * math.cos(a.slope_rad)
        return [
            (x, z) for x, z in crossed_edges(a, b, self.segments)
            if toe0 + EDGE_KEEPOUT_M <= x <= b.heel_x_m - EDGE_KEEPOUT_M
        ]  # fmt: skip

    def edge_clearances_m(self) -> list[float | None]:
        """Per recorded stride, the least vertical clearance of the sole over every edge its
        swing crossed (m; also those beside the feet, see :meth:`swing_edges`), None where
        it crossed none."""
        out = []
        for k in range(1, self.strides + 1):
            gap, _ = self._swing_clearance(k, self._lift[k], every_edge=True)
            out.append(None if not np.isfinite(gap) else gap + self.clearance_m)
        return out

    def _plan_swings(self) -> None:
        for k in range(len(self.footholds) - 1):
            lift = self._leave[k].lift_m
            if k > self.strides + 1:  # after the session: no clearance search
                self._lift[k] = lift
                break
            for _ in range(40):
                edge_gap, ground_gap = self._swing_clearance(k, lift)
                if edge_gap >= 0.0 and ground_gap >= -GROUND_TOLERANCE_M:
                    break
                lift += max(0.01, -min(edge_gap, ground_gap))
            else:
                raise SimulationError(
                    f"swing {k} ({self.labels[k]}): no lift clears the terrain "
                    f"(edge gap {edge_gap:.3f} m, ground gap {ground_gap:.3f} m)"
                )
            self._lift[k] = lift

    def _sole_points(self, ankle: np.ndarray, gamma: np.ndarray, m: int = 9) -> np.ndarray:
        leg = self.leg
        fx = np.linspace(-leg.heel_behind_ankle_m, leg.foot_length_m - leg.heel_behind_ankle_m, m)
        px, pz = _rotate(gamma[:, None], fx[None, :], -leg.ankle_height_m)
        return np.stack([ankle[:, 0:1] + px, ankle[:, 1:2] + pz], axis=-1)
