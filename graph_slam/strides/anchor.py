"""The stride anchor's up vector at a foot strike: the IMU's, fused with the ground in view
only when that ground is level.

The stride frame is gravity-aligned: its z axis is "up" from the IMU (the gyro-rotated
accelerometer mean over the last stride, :class:`graph_slam.strides.gravity.GravityEstimator`).
An accelerometer cannot tell its own bias from a tilt, so on level ground the plane under and
ahead of the foot (fitted in the first frame's depth, :func:`graph_slam.frontend.floor.fit_floor`)
sharpens it. That plane is fused **only when it is consistent with level ground**: its normal
within ``level_gate_sigmas`` combined σ (IMU and plane, at least ``level_gate_min_rad``) of the
IMU's up. Otherwise (a ramp, a tread seen at an angle) the anchor keeps the IMU's up alone and
records the plane's slope. :class:`StrideAnchor` returns which case applied:

* ``floor``: the plane is level within its σ (at a session's first strike without the
  encoders' σ, below, whose up has under a second of history and is 10-40° off, any plane
  found is taken as level when the
  stance heel, from the encoders, lies on it: a plane that does not pass under the foot is
  not the ground the foot stands on — on stairs ahead, the plane through the nosings, 31°
  off, was fused as the floor and tilted the whole session; with the heel to decide, the
  plane is searched within ``first_strike_search_rad`` of that poor up); fused by inverse
  variance;
* ``treads``: no plane passed the floor fit (a tread is 0.28 m deep), but several small level
  planes did (:func:`graph_slam.frontend.treads.fit_level_planes`: the treads of a flight, the
  landing), and their common normal is level within its σ: fused by inverse variance (not at a
  session's first strike, whose IMU up cannot test it);
* ``slope``: a plane was found but is tilted against the IMU's up: IMU alone, slope recorded;
* ``slope_level``: as ``slope`` (its slope for the contact), but level planes beside the
  sloped one (the platform at a ramp's top, the floor at its foot), common normal level within
  its σ, fused into the up as the treads are;
* ``imu``: no plane (no depth, too few points, none near up) or the floor is off: IMU alone;
* ``none``: no IMU up vector either (the back end's own default anchor).

**A session's first strike** comes with under a second of IMU history (the recording starts
mid-swing): the accelerometer's mean over that window holds the swinging thigh's own
acceleration and was 19-65° off the true up on the terrain walker (the floor, where one is
seen under the heel, corrects it; on a flight of stairs seen from below none is). With a leg
model (``gravity_first_strike_kinematics``, on by default) the up vector there is the
encoders' instead (:meth:`graph_slam.strides.kinematics.LegKinematics.heel_strike_up`: the
foot at the model's nominal heel-strike pitch, the sagittal plane vertical), 3.7-7.5° off on
the same strikes; it also centres the plane search. With its σ
(``gravity_first_strike_kinematics_sigma_rad``, 0.1 rad) the strike is then anchored like a
later one: the floor tested for level against it, the treads searched (on stairs-ascent the
treads fixed the up to 0.1°); without (None), the kinematics' heel-strike covariance and the
heel rule above. Flag ``up:kinematics``. The accelerometer's mean with the
first stride's velocity change removed was 0.1-2° off on most strikes but 110° on one (the
first stride's graph, begun without an anchor, can be far off): not used.

``graph.floor.assume_level: true`` restores the level-ground anchor (any plane within
``max_angle_rad`` + 3σ of the IMU's up is fused): the comparison of the two on one session.

The signed slope is the plane's pitch along the camera's heading (+ rising ahead), the angle
the contact factors of the stance need (the toe lies on the slope, not on level ground).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from graph_slam.frontend.floor import FloorConfig, FloorFit, fit_floor, fuse_up
from graph_slam.frontend.treads import LevelPlanes, TreadsConfig, fit_level_planes
from graph_slam.strides.up_fusion import GraphUp, fuse_with_graph

log = logging.getLogger(__name__)

ANCHOR_CASES = ("floor", "treads", "slope", "slope_level", "imu", "none")


@dataclass(frozen=True)
class AnchorUp:
    """The new stride's up vector (IMU frame at ``t_s``) and how it was decided."""

    t_s: float
    up_in_imu: np.ndarray | None
    sigma_rad: float | None
    case: str
    slope_rad: float = float("nan")
    """The ground plane's signed pitch along the heading (NaN: no plane)."""
    tilt_rad: float = float("nan")
    """The plane's normal against the IMU's up (NaN: no plane)."""
    fit: FloorFit | None = None
    imu_sigma_unknown: bool = False
    """The IMU's up had no σ (its window was short: a session's first strike)."""
    graph: str = ""
    """How the graph's own up entered (:mod:`graph_slam.strides.up_fusion`): ``fused``,
    ``gated`` (disagreed with the accelerometer's: not used) or empty (none asked or none
    available)."""
    heel_off_m: float = float("nan")
    """The stance heel's distance from the plane (NaN: not checked, no heel known)."""
    heel_limit_m: float = float("inf")
    previous_slope_rad: float = 0.0
    """The previous stride's contact slope: the ground under a heel the plane misses."""
    treads: LevelPlanes | None = None
    """The small level planes searched where no floor passed (None: not searched)."""
    up_source: str = "imu"
    """Where the up vector before any plane came from: ``imu`` (the accelerometer) or
    ``kinematics`` (the encoders, at a session's first strike)."""

    @property
    def assumed(self) -> bool:
        """A plane taken as level without an IMU σ to test it (a session's first strike)."""
        return self.case == "floor" and self.imu_sigma_unknown

    @property
    def heel_on_plane(self) -> bool:
        """The plane passes under the stance heel (or no heel was known to test it)."""
        return not self.heel_off_m > self.heel_limit_m

    @property
    def contact_slope_rad(self) -> float:
        """The slope the stance contact factors use: the plane's where it was not fused
        (a slope) and level where it was, when it passes under the heel; where it does not
        (a ramp that starts ahead of the foot, the level floor ahead of a heel still on the
        ramp), the previous stride's contact slope."""
        if self.case in ("slope", "slope_level", "floor") and not self.heel_on_plane:
            return self.previous_slope_rad
        return self.slope_rad if self.case in ("slope", "slope_level") else 0.0

    @property
    def flags(self) -> tuple[str, ...]:
        out = [f"anchor:{self.case}"]
        if self.fit is not None:
            out.insert(0, f"floor:{self.fit.reason}")
        if math.isfinite(self.slope_rad):
            out.append(f"slope_deg:{math.degrees(self.slope_rad):.2f}")
        if self.treads is not None:
            t = self.treads
            out.append(f"treads:{t.n_planes}" if t.ok else f"treads:{t.reason.split(':')[0]}")
        if self.graph:
            out.append(f"up_graph:{self.graph}")
        if self.up_source != "imu":
            out.append(f"up:{self.up_source}")
        if self.case in ("slope", "slope_level", "floor") and not self.heel_on_plane:
            out.append(f"heel_off_plane:{self.heel_off_m:.3f}")
        return tuple(out)


class StrideAnchor:
    """The up vector at a foot strike (module text). Built by :func:`make_anchor`."""

    def __init__(
        self,
        gravity,
        floor: FloorConfig,
        camera_T_imu: np.ndarray,
        sigma_rad: float | None,
        min_window_s: float,
        short_sigma_rad: float,
        graph_up: Callable[[float], GraphUp | None] | None = None,
        velocity_change: Callable[[float], tuple[float, np.ndarray] | None] | None = None,
        lateral_bias: Callable[[float], tuple[np.ndarray, float] | None] | None = None,
        lateral_bias_max_sigma: float | None = None,
        treads: TreadsConfig | None = None,
        kinematic_up: Callable[[float], np.ndarray | None] | None = None,
        kinematic_sigma_rad: float | None = None,
    ) -> None:
        self.gravity = gravity
        self.floor = floor
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.sigma_rad = sigma_rad
        self.min_window_s = float(min_window_s)
        self.short_sigma_rad = float(short_sigma_rad)
        self.graph_up = graph_up
        self.velocity_change = velocity_change
        self.lateral_bias = lateral_bias
        self.lateral_bias_max_sigma = lateral_bias_max_sigma
        self.treads = treads
        self.kinematic_up = kinematic_up
        self.kinematic_sigma_rad = kinematic_sigma_rad
        self.last_contact_slope_rad = 0.0
        """The contact slope of the last stride anchored (0 before the first)."""

    def imu_up(self, t_strike_s: float, t_s: float) -> tuple[np.ndarray | None, float | None]:
        """The IMU's up at ``t_s`` over about the last stride, and its σ (None: the first
        strike's short window, which keeps the back end's looser anchor covariance)."""
        window = self.gravity.window_before(t_strike_s)
        change = None if self.velocity_change is None else self.velocity_change(t_s)
        if change is not None and t_s - change[0] < self.min_window_s:
            change = None
        if change is not None:
            window = t_s - change[0]  # the open stride's span, whose velocity change is known
        up = self.gravity.up_at(t_s, window)
        if up is not None and change is not None:
            up = up - change[1] / window  # the window's mean acceleration is not gravity
        if up is not None and self.lateral_bias is not None:
            bias = self.lateral_bias(t_s)
            if bias is not None and bias[1] <= (self.lateral_bias_max_sigma or 0.0):
                up = up - bias[0]  # a known lateral bias is not a roll
        sigma = None
        long_enough = min(window, self.gravity.history_s(t_s)) >= self.min_window_s
        if up is not None and self.sigma_rad is not None and long_enough:
            sigma = self.sigma_rad
        return up, sigma

    def with_graph(self, t_s: float, up: np.ndarray, sigma: float | None):
        """The accelerometer's up fused with the estimator's (``graph_up``; module text of
        :mod:`graph_slam.strides.up_fusion`) when both are known; returns ``(up, σ, how)``."""
        if sigma is None or self.graph_up is None:
            return up, sigma, ""
        estimate = self.graph_up(t_s)
        if estimate is None:
            return up, sigma, ""
        f = fuse_with_graph(up, sigma, estimate)
        if not f.fused:
            log.info("t=%.3f s: the graph's up is %.1fσ from the IMU's: not used", t_s,
                     math.sqrt(f.mahalanobis2))  # fmt: skip
            return up, sigma, "gated"
        return f.up_in_imu, f.sigma_rad, "fused"

    def at_strike(
        self,
        t_strike_s: float,
        t_s: float,
        points_m: np.ndarray | None,
        heel_in_camera_m: np.ndarray | None = None,
    ) -> AnchorUp:
        """The anchor for the stride struck at ``t_strike_s``, at its first frame ``t_s``
        (``points_m``: that frame's cloud, camera frame; None: no depth; ``heel_in_camera_m``:
        the stance heel at ``t_s`` in the camera frame, from the encoders, None: unknown)."""
        up, sigma = self.imu_up(t_strike_s, t_s)
        source = "imu"
        if sigma is None and self.kinematic_up is not None:  # a session's first strike
            kin = self.kinematic_up(t_s)
            if kin is not None:
                up, source, sigma = kin, "kinematics", self.kinematic_sigma_rad
        if up is None:
            return AnchorUp(t_s, None, None, "none")
        up, sigma, how = self.with_graph(t_s, up, sigma)
        if points_m is None or not self.floor.enabled:
            out = AnchorUp(t_s, up, sigma, "imu", graph=how)
        else:
            out = replace(self.with_plane(t_s, up, sigma, points_m, heel_in_camera_m), graph=how)
        out = replace(out, up_source=source)
        self.last_contact_slope_rad = out.contact_slope_rad
        return out

    def with_plane(
        self, t_s: float, up: np.ndarray, sigma: float | None, points_m, heel_in_camera_m=None
    ) -> AnchorUp:
        """Fit the plane near ``up`` and decide the case (module text)."""
        cfg = self.floor
        sigma_imu = sigma if sigma is not None else self.short_sigma_rad
        level_gate = cfg.max_angle_rad + 3.0 * sigma_imu
        search = level_gate if cfg.assume_level else max(level_gate, cfg.slope_search_rad)
        first = not cfg.assume_level and sigma is None and heel_in_camera_m is not None
        if first:  # the heel decides what is ground: the plane may be far off the poor up
            search = max(search, cfg.first_strike_search_rad)
        hint = self.camera_T_imu[:3, :3] @ up
        fit = fit_floor(points_m, hint, cfg, max_angle_rad=search)
        if not fit.ok:
            log.info("t=%.3f s: no floor for the anchor (%s)", t_s, fit.reason)
            if not self._searches_levels(sigma):
                return AnchorUp(t_s, up, sigma, "imu", fit=fit)
            return self.with_treads(t_s, up, sigma, points_m, hint, fit)
        n_imu = self.camera_T_imu[:3, :3].T @ fit.normal
        tilt = fit.angle_to_hint_rad
        slope = self.signed_slope(up, n_imu)
        reason = self._not_ground(fit, heel_in_camera_m) if first else None
        if reason is not None:  # not the ground under the foot (module text)
            log.info("t=%.3f s: first strike's plane refused (%s)", t_s, reason)
            fit = replace(fit, ok=False, reason=reason)
            return AnchorUp(t_s, up, sigma, "imu", fit=fit)
        if cfg.assume_level or sigma is None:
            # a first strike's IMU up (under a second of history) is 10-40° off: nothing
            # tells a slope from that error, so the ground (under the heel) is taken as level
            consistent = True
        else:
            gate = cfg.level_gate_sigmas * math.hypot(sigma_imu, fit.sigma_rad)
            consistent = tilt <= max(gate, cfg.level_gate_min_rad)
        heel_off = float("nan")
        if heel_in_camera_m is not None:
            heel_off = abs(float(fit.normal @ np.asarray(heel_in_camera_m, float)) + fit.offset_m)
        heel = {"heel_off_m": heel_off, "heel_limit_m": cfg.contact_heel_m,
                "previous_slope_rad": self.last_contact_slope_rad}  # fmt: skip
        if not consistent:
            return self.beside_slope(AnchorUp(t_s, up, sigma, "slope", slope, tilt, fit, **heel),
                                     points_m, hint)  # fmt: skip
        fused, sigma_fused = fuse_up(up, sigma_imu, n_imu, fit.sigma_rad)
        return AnchorUp(t_s, fused, sigma_fused, "floor", slope, tilt, fit, sigma is None, **heel)

    def level_planes(self, up, sigma: float, points_m, hint):
        """The small level planes in ``points_m`` (:func:`fit_level_planes`) and, when their
        common normal is within the level gate of the IMU's up, the two fused: returns
        ``(planes, up, σ)`` with ``up`` None where they were not found or not level."""
        cfg, tcfg = self.floor, self.treads
        search = max(tcfg.search_rad, cfg.max_angle_rad + 3.0 * sigma)
        planes = fit_level_planes(points_m, hint, cfg, tcfg, max_angle_rad=search)
        if not planes.ok:
            return planes, None, sigma
        gate = cfg.level_gate_sigmas * math.hypot(sigma, planes.sigma_rad)
        if planes.angle_to_hint_rad > max(gate, cfg.level_gate_min_rad):
            log.info("level planes %.2f° off the IMU's up: not used",
                     math.degrees(planes.angle_to_hint_rad))  # fmt: skip
            return planes, None, sigma
        n_imu = self.camera_T_imu[:3, :3].T @ planes.normal
        fused, sigma_fused = fuse_up(up, sigma, n_imu, planes.sigma_rad)
        return planes, fused, sigma_fused

    def _searches_levels(self, sigma: float | None) -> bool:
        on = self.treads is not None and self.treads.enabled
        return on and not self.floor.assume_level and sigma is not None

    def with_treads(self, t_s: float, up, sigma: float, points_m, hint, fit: FloorFit) -> AnchorUp:
        """Where no floor passed: the common normal of the small level planes in view (stair
        treads), fused like a level floor when within the level gate of the IMU's up
        (``treads``), else the IMU's up alone (``imu``). A tread is level: the contact is too."""
        planes, fused, sigma_fused = self.level_planes(up, sigma, points_m, hint)
        if fused is None:
            return AnchorUp(t_s, up, sigma, "imu", fit=fit, treads=planes)
        n_imu = self.camera_T_imu[:3, :3].T @ planes.normal
        slope, tilt = self.signed_slope(up, n_imu), planes.angle_to_hint_rad
        return AnchorUp(t_s, fused, sigma_fused, "treads", slope, tilt, fit, treads=planes)

    def beside_slope(self, anchor: AnchorUp, points_m, hint) -> AnchorUp:
        """A sloped plane (a ramp) keeps its slope for the contact; level planes beside it,
        farther than ``treads.off_slope_m`` from it (the platform at a ramp's top, the floor
        at its foot), fix the up (``slope_level``) when level within the gate."""
        if not self._searches_levels(anchor.sigma_rad):
            return anchor
        fit = anchor.fit
        pts = np.asarray(points_m, float)
        pts = pts[np.isfinite(pts).all(axis=1)]
        rest = pts[np.abs(pts @ fit.normal + fit.offset_m) >= self.treads.off_slope_m]
        planes, fused, sigma_fused = self.level_planes(anchor.up_in_imu, anchor.sigma_rad,
                                                       rest, hint)  # fmt: skip
        if fused is None:
            return replace(anchor, treads=planes)
        slope = self.signed_slope(fused, self.camera_T_imu[:3, :3].T @ fit.normal)  # vs level
        return replace(anchor, up_in_imu=fused, sigma_rad=sigma_fused, case="slope_level",
                       slope_rad=slope, treads=planes)  # fmt: skip

    def _not_ground(self, fit: FloorFit, heel_in_camera_m) -> str | None:
        """Why a first strike's plane is not the ground the heel stands on (None: it is): the
        heel must lie on it, and the camera stand above it by at least the search cone's
        cosine times the heel's distance (a riser or a wall through the heel is no floor)."""
        heel = np.asarray(heel_in_camera_m, float)
        off = abs(float(fit.normal @ heel) + fit.offset_m)
        if off > self.floor.first_strike_heel_m:
            return f"not_under_heel: the heel {off:.3f} m off the plane"
        least = math.cos(self.floor.first_strike_search_rad) * float(np.linalg.norm(heel))
        if fit.offset_m < least:
            return f"not_under_camera: the camera {fit.offset_m:.3f} m above it (< {least:.3f})"
        return None

    def signed_slope(self, up_imu: np.ndarray, normal_imu: np.ndarray) -> float:
        """The plane's pitch along the camera's heading (+ rising ahead), radians."""
        u = np.asarray(up_imu, float) / np.linalg.norm(up_imu)
        n = np.asarray(normal_imu, float) / np.linalg.norm(normal_imu)
        view = self.camera_T_imu[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # optical axis, IMU
        ahead = view - (view @ u) * u
        if np.linalg.norm(ahead) < 1e-6:
            return float("nan")
        ahead /= np.linalg.norm(ahead)
        return float(math.atan2(-(n @ ahead), n @ u))


def make_anchor(
    config,
    camera_T_imu: np.ndarray,
    gravity,
    graph_up=None,
    velocity_change=None,
    lateral_bias=None,
    kinematic_up=None,
) -> StrideAnchor:
    """The stride anchor of a graph pipeline from its :class:`PipelineConfig`; ``graph_up``
    (e.g. :meth:`graph_slam.backend.StrideSLAM.up_estimate`) is used when
    ``gravity_from_graph`` is on, ``velocity_change``
    (:meth:`graph_slam.backend.StrideSLAM.velocity_change`) when
    ``gravity_mean_acceleration`` is, ``lateral_bias``
    (:meth:`graph_slam.backend.StrideSLAM.lateral_bias`) when
    ``gravity_lateral_bias_max_sigma_m_s2`` is set, ``kinematic_up``
    (:meth:`graph_slam.strides.kinematics.LegKinematics.heel_strike_up`) at a session's first
    strike when ``gravity_first_strike_kinematics`` is."""
    return StrideAnchor(
        gravity,
        config.graph.floor,
        camera_T_imu,
        config.gravity_sigma_rad,
        config.gravity_min_window_s,
        config.gravity_short_sigma_rad,
        graph_up if config.gravity_from_graph else None,
        velocity_change if config.gravity_mean_acceleration else None,
        lateral_bias if config.gravity_lateral_bias_max_sigma_m_s2 is not None else None,
        config.gravity_lateral_bias_max_sigma_m_s2,
        config.graph.treads,
        kinematic_up if config.gravity_first_strike_kinematics else None,
        config.gravity_first_strike_kinematics_sigma_rad,
    )
