"""Level evidence from several small level planes in one depth frame (stair treads).

On a flight of stairs no single plane in view passes :func:`graph_slam.frontend.floor.fit_floor`'s
extent test: a tread is 0.28 m deep (its inliers' smaller in-plane spread, 2σ, is about
0.1 m against the floor's 0.3 m), and the planes through several nosings are 30° off level.
Yet every tread is a level plane, and the treads in view are parallel planes at different
heights. :func:`fit_level_planes` extracts up to ``max_planes`` planes near the up hint one
after the other (seeded RANSAC and a least-squares refit, as the floor fit, each plane's
inliers removed before the next), keeps those wide enough across (the larger in-plane spread)
and deep enough, and fits **one normal to all of them** (each plane keeps its own offset): the
pooled scatter of every plane's inliers about their own centroid. The width of a tread fixes
the roll, its depth (and the number of treads) the pitch along the heading.

Whether the planes *are* level is the caller's test (:class:`graph_slam.strides.anchor.StrideAnchor`
fuses them only within the level gate of the IMU's up); a plane that disagrees with the joint
normal by more than ``consistency_rad`` is dropped and the normal refitted (a ramp's edge or
a box top that is not level is not a tread).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.frontend.floor import FloorConfig, fit_floor


class TreadsConfig(ConfigModel):
    """Level evidence from several small level planes (stair treads) for the stride anchor."""

    enabled: bool = Field(
        True,
        description="where no floor passes the floor fit, look for several small level planes "
        "(stair treads) and fuse their common normal when it is level within its σ",
    )
    max_planes: int = Field(4, ge=1, description="planes extracted one after the other")
    min_inliers: int = Field(300, ge=3, description="fewer inliers: not a plane")
    min_depth_m: float = Field(
        0.06, gt=0, description="a plane's smaller in-plane spread (2σ) must reach this"
    )
    min_width_m: float = Field(
        0.3, gt=0, description="a plane's larger in-plane spread (2σ) must reach this"
    )
    search_rad: float = Field(
        math.radians(5.0),
        gt=0,
        le=math.pi / 2,
        description="the planes are searched this far from the up hint (plus the caller's 3σ)",
    )
    distance_m: float = Field(
        0.005,
        gt=0,
        description="a plane's points for its normal lie within this of it (the floor fit's "
        "1 cm band takes in the foot of a riser and tilts a 0.28 m tread by up to 1.8°)",
    )
    edge_trim: float = Field(
        0.15,
        ge=0,
        lt=0.5,
        description="the fraction of a plane's points left out at either edge along its short "
        "axis (the nosing and the riser's foot)",
    )
    consistency_rad: float = Field(
        math.radians(1.0),
        gt=0,
        description="a plane whose own normal is farther than this from the joint normal "
        "(and 3 of its own σ) is dropped",
    )
    off_slope_m: float = Field(
        0.02,
        gt=0,
        description="beside a sloped plane (a ramp) the level planes are searched among the "
        "points farther than this from it",
    )
    sigma_min_rad: float = Field(
        0.002,
        gt=0,
        description="σ floor of the joint normal (as the floor's: depth bias, unevenness)",
    )


@dataclass(frozen=True)
class LevelPlanes:
    """A common normal (camera frame, toward the camera) of ``n_planes`` parallel planes."""

    ok: bool
    reason: str
    normal: np.ndarray | None = None
    offsets_m: tuple[float, ...] = ()
    n_inliers: int = 0
    rms_m: float = float("nan")
    sigma_rad: float = float("nan")
    angle_to_hint_rad: float = float("nan")

    @property
    def n_planes(self) -> int:
        return len(self.offsets_m)


@dataclass(frozen=True)
class _Plane:
    normal: np.ndarray
    inliers: np.ndarray
    sigma_rad: float


def _spreads(inliers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    centred = inliers - inliers.mean(axis=0)
    evals, evecs = np.linalg.eigh(centred.T @ centred)
    return evals, evecs


def _extract(pts: np.ndarray, hint: np.ndarray, floor: FloorConfig, cfg: TreadsConfig,
             max_angle: float) -> list[_Plane]:  # fmt: skip
    """Planes near ``hint``, one after the other, each one's inliers (within the floor fit's
    ``distance_m``) removed before the next; each keeps its inliers within ``cfg.distance_m``
    less the ``edge_trim`` fraction at either edge along its short axis (module text)."""
    single = floor.model_copy(
        update={"min_inliers": cfg.min_inliers, "min_extent_m": cfg.min_depth_m}
    )
    planes: list[_Plane] = []
    left = pts
    for k in range(cfg.max_planes):
        if left.shape[0] < cfg.min_inliers:
            break
        fit = fit_floor(left, hint, single.model_copy(update={"seed": floor.seed + k}), max_angle)
        if not fit.ok:
            break
        residual = np.abs(left @ fit.normal + fit.offset_m)
        plane = _refined(left, fit.normal, fit.offset_m, cfg, hint)
        if plane is not None:
            planes.append(plane)
        left = left[residual >= floor.distance_m]
    return planes


def _refined(pts, normal, offset, cfg: TreadsConfig, hint: np.ndarray) -> _Plane | None:
    """Three refits on the points within ``cfg.distance_m`` of the plane, less its edges."""
    plane = None
    for _ in range(3):
        plane = _trimmed(pts[np.abs(pts @ normal + offset) < cfg.distance_m], cfg, hint)
        if plane is None:
            return None
        normal = plane.normal
        offset = -float(normal @ plane.inliers.mean(axis=0))
    return plane


def _trimmed(inliers: np.ndarray, cfg: TreadsConfig, hint: np.ndarray) -> _Plane | None:
    """A plane wide and deep enough, refitted without its edges along the short axis (where a
    riser's foot or a nosing's round-over lies within the band and tilts it), or None."""
    if inliers.shape[0] < cfg.min_inliers:
        return None
    evals, evecs = _spreads(inliers)
    n = inliers.shape[0]
    if 2.0 * math.sqrt(max(float(evals[2]), 0.0) / n) < cfg.min_width_m:
        return None
    if 2.0 * math.sqrt(max(float(evals[1]), 0.0) / n) < cfg.min_depth_m:
        return None
    along = (inliers - inliers.mean(axis=0)) @ evecs[:, 1]
    lo, hi = np.quantile(along, [cfg.edge_trim, 1.0 - cfg.edge_trim])
    kept = inliers[(along > lo) & (along < hi)]
    evals, evecs = _spreads(kept)
    normal = evecs[:, 0] * (1.0 if evecs[:, 0] @ hint >= 0 else -1.0)
    rms = math.sqrt(max(float(evals[0]), 0.0) / kept.shape[0])
    return _Plane(normal, kept, rms / math.sqrt(max(float(evals[1]), 1e-12)))


def _joint(planes: list[_Plane], hint: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The common normal of ``planes`` (pooled scatter about each plane's centroid), its
    statistical σ (pitch and roll: the larger) and the residual rms."""
    centred = np.vstack([p.inliers - p.inliers.mean(axis=0) for p in planes])
    evals, evecs = np.linalg.eigh(centred.T @ centred)
    normal = evecs[:, 0] * (1.0 if evecs[:, 0] @ hint >= 0 else -1.0)
    rms = float(np.sqrt(np.mean((centred @ normal) ** 2)))
    return normal, rms / math.sqrt(max(float(evals[1]), 1e-12)), rms


def fit_level_planes(
    points_m: np.ndarray,
    up_hint: np.ndarray,
    floor: FloorConfig | None = None,
    config: TreadsConfig | None = None,
    max_angle_rad: float | None = None,
) -> LevelPlanes:
    """The common normal of the small level planes in ``points_m`` (N×3, camera frame) near
    ``up_hint`` (module text). ``max_angle_rad`` overrides ``config.search_rad``."""
    floor = floor or FloorConfig()
    cfg = config or TreadsConfig()
    pts = np.asarray(points_m, float)
    pts = pts[:: max(1, -(-pts.shape[0] // floor.max_points))]
    pts = pts[np.isfinite(pts).all(axis=1)]
    hint = np.asarray(up_hint, float) / np.linalg.norm(up_hint)
    max_angle = cfg.search_rad if max_angle_rad is None else max_angle_rad
    planes = _extract(pts, hint, floor, cfg, max_angle)
    if not planes:
        return LevelPlanes(False, "no_level_plane: none wide and deep enough near up")
    normal, sigma, rms = _joint(planes, hint)
    while len(planes) > 1:  # drop the plane farthest from the joint normal, if any is off
        off = [math.acos(min(1.0, float(p.normal @ normal))) for p in planes]
        worst = int(np.argmax(off))
        if off[worst] <= max(cfg.consistency_rad, 3.0 * planes[worst].sigma_rad):
            break
        planes.pop(worst)
        normal, sigma, rms = _joint(planes, hint)
    angle = math.acos(min(1.0, float(normal @ hint)))
    if angle > max_angle:
        return LevelPlanes(False, f"off_up: joint normal {math.degrees(angle):.2f}° from up")
    offsets = tuple(-float(normal @ p.inliers.mean(axis=0)) for p in planes)
    return LevelPlanes(
        True,
        "ok",
        normal=normal,
        offsets_m=offsets,
        n_inliers=int(sum(p.inliers.shape[0] for p in planes)),
        rms_m=rms,
        sigma_rad=max(sigma, cfg.sigma_min_rad),
        angle_to_hint_rad=angle,
    )
