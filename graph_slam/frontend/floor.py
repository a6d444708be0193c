"""The floor plane in one depth frame: the camera's tilt against level ground.

At a foot strike the stride frame's z axis is "up against gravity". The IMU gives it from the
gyro-rotated accelerometer mean over the previous stride, but an accelerometer cannot tell its
own bias from a tilt: the turn-on bias of a consumer MEMS IMU (σ 0.05 m/s²) alone tilts that
estimate by up to ~0.5°, and the camera, 0.5–0.6 m above the heel, then sits 5 mm off at the
stride's first frame — the largest single error of the smoothed stride trajectory on the
simulator (see docs/backend.md). On level ground the floor in view gives the same direction
from thousands of depth points, to a few hundredths of a degree.

:func:`fit_floor` finds the dominant plane whose normal lies within ``max_angle_rad`` of a hint
(the IMU's up), by seeded RANSAC and a least-squares refit on its inliers. It never guesses: no
such plane, too few inliers or too small an extent is a :class:`FloorFit` with ``ok`` False and
the reason. Whether the ground *is* level is the caller's assumption (the gate against the IMU
is the only check): on a ramp the plane is the ramp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.errors import ConfigError


class FloorConfig(ConfigModel):
    """RANSAC floor fit used for the stride anchor's tilt (graph variants)."""

    enabled: bool = Field(True, description="fuse the floor normal into the stride-start up vector")
    distance_m: float = Field(0.01, gt=0, description="RANSAC inlier distance to the plane")
    iterations: int = Field(200, ge=10, description="RANSAC hypotheses")
    sample_points: int = Field(4000, ge=100, description="points the hypotheses are scored on")
    prescore_points: int = Field(
        1000,
        ge=10,
        description="pre-emptive RANSAC: every hypothesis is scored on this many of the sample "
        "points first, and only the best prescore_keep on all of them (the fit at a stride's "
        "first frame took 12-15 ms, the whole real-time frame budget)",
    )
    prescore_keep: int = Field(10, ge=1, description="hypotheses kept after the pre-scoring")
    max_points: int = Field(
        8000,
        ge=100,
        description="the fit uses at most this many of the points, evenly strided (on all "
        "of a 424×240 frame's points it took 5 ms of a foot strike's frame; the normal's "
        "statistical σ from 8000 points stays below sigma_min_rad)",
    )
    min_inliers: int = Field(500, ge=3, description="fewer inliers (of the points used): no floor")
    min_extent_m: float = Field(
        0.3, gt=0, description="the inliers' smaller in-plane spread (2σ) must reach this"
    )
    max_angle_rad: float = Field(
        math.radians(3.0),
        gt=0,
        le=math.pi / 2,
        description="the plane's normal must lie within this of the IMU's up vector "
        "(plus 3σ of that vector when it is uncertain)",
    )
    sigma_min_rad: float = Field(
        0.002,
        gt=0,
        description="σ floor of the normal's direction (depth bias, unevenness); the "
        "statistical σ from the fit is usually far smaller",
    )
    seed: int = Field(0, ge=0, description="RANSAC random generator seed")
    assume_level: bool = Field(
        False,
        description="the level-ground anchor: fuse any plane within max_angle_rad (+3σ of "
        "the IMU's up) as if the ground were level; false: fuse only a plane consistent with "
        "level (graph_slam.strides.anchor), keep the IMU's up and record the slope otherwise",
    )
    slope_search_rad: float = Field(
        math.radians(15.0),
        gt=0,
        le=math.pi / 2,
        description="the plane is searched this far from the IMU's up (its slope is recorded)",
    )
    level_gate_sigmas: float = Field(
        3.0, gt=0, description="a plane is level when within this many combined σ of up"
    )
    level_gate_min_rad: float = Field(
        math.radians(2.0),
        ge=0,
        description="the level gate is never tighter than this (the IMU's σ is a model)",
    )
    first_strike_heel_m: float = Field(
        0.05,
        gt=0,
        description="at a session's first strike (no IMU up to gate against) a plane is taken "
        "as the ground only when the stance heel (from the encoders) lies within this of it: "
        "on stairs ahead a plane through the nosings, 30° off, was fused as the floor",
    )
    contact_heel_m: float = Field(
        0.01,
        gt=0,
        description="the plane sets the stance contact's slope (its own, or level where fused) "
        "only when the stance heel (from the encoders) lies within this of it: a ramp seen "
        "ahead of a heel on the level floor, or the floor ahead of a heel still on the ramp, "
        "is not the ground under the foot (the previous stride's contact slope, flag "
        "heel_off_plane)",
    )
    first_strike_search_rad: float = Field(
        math.radians(60.0),
        gt=0,
        le=math.pi / 2,
        description="at a first strike with the heel known the plane is searched this far from "
        "the IMU's up (10-45° off there); the camera must stand above it by this angle's cosine "
        "times the heel's distance",
    )


@dataclass(frozen=True)
class FloorFit:
    """A floor plane ``n·p + d = 0`` in the camera frame, ``n`` pointing up (to the camera)."""

    ok: bool
    reason: str
    normal: np.ndarray | None = None
    offset_m: float = float("nan")
    n_inliers: int = 0
    rms_m: float = float("nan")
    sigma_rad: float = float("nan")
    angle_to_hint_rad: float = float("nan")

    @property
    def height_m(self) -> float:
        """The camera's height above the plane."""
        return self.offset_m


def plane_hypotheses(
    triples: np.ndarray, up: np.ndarray, min_norm: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC hypotheses: the planes ``n·p + d = 0`` through point triples (K×3×3), unit normals
    on the side of ``up``. A triple whose cross product has norm ``<= min_norm`` (collinear)
    gives NaN. Shared by this floor fit and ``terrain.obstacles.fit_floor``."""
    p0, p1, p2 = triples[:, 0], triples[:, 1], triples[:, 2]
    normals = np.cross(p1 - p0, p2 - p0)
    norms = np.linalg.norm(normals, axis=1)
    norms[norms <= min_norm] = np.nan
    normals = normals / norms[:, None]
    normals *= np.where(normals @ up < 0, -1.0, 1.0)[:, None]
    return normals, -np.einsum("kd,kd->k", normals, p0)


def fit_floor(
    points_m: np.ndarray,
    up_hint: np.ndarray,
    config: FloorConfig | None = None,
    max_angle_rad: float | None = None,
) -> FloorFit:
    """Fit the floor to ``points_m`` (N×3, camera frame) near the direction ``up_hint``.

    Returns a :class:`FloorFit`; ``ok`` False with a reason when there is no such plane.
    ``max_angle_rad`` overrides ``config.max_angle_rad`` (e.g. widened by the hint's σ).
    """
    cfg = config or FloorConfig()
    pts = np.asarray(points_m)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ConfigError(f"fit_floor: points_m must be N×3, got shape {pts.shape}")
    hint = np.asarray(up_hint, float)
    if hint.shape != (3,) or not np.isfinite(hint).all() or np.linalg.norm(hint) == 0:
        raise ConfigError(f"fit_floor: up_hint must be a finite non-zero 3-vector, got {hint}")
    hint = hint / np.linalg.norm(hint)
    pts = np.asarray(pts[:: max(1, -(-pts.shape[0] // cfg.max_points))], float)  # strided
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.shape[0] < cfg.min_inliers:
        return FloorFit(False, f"too_few_points: {pts.shape[0]} < {cfg.min_inliers}")
    max_angle = cfg.max_angle_rad if max_angle_rad is None else max_angle_rad
    cos_max = math.cos(max_angle)
    rng = np.random.default_rng(cfg.seed)
    # with replacement: a repeated point costs nothing, a permutation of all points did
    sample = pts[rng.integers(0, pts.shape[0], size=min(cfg.sample_points, pts.shape[0]))]
    tri = rng.integers(0, sample.shape[0], size=(cfg.iterations, 3))
    normals, offsets = plane_hypotheses(sample[tri], hint, min_norm=1e-9)
    valid = np.isfinite(normals).all(axis=1)
    valid[valid] = normals[valid] @ hint >= cos_max
    if not valid.any():
        return FloorFit(False, "no_plane_near_up: no 3-point hypothesis within the angle gate")
    n_h, d_h = normals[valid], offsets[valid]
    if len(n_h) > cfg.prescore_keep:  # pre-emptive: every hypothesis on the first points
        pre = sample[: cfg.prescore_points]
        pre_scores = (np.abs(pre @ n_h.T + d_h) < cfg.distance_m).sum(axis=0)
        top = np.argsort(-pre_scores, kind="stable")[: cfg.prescore_keep]
        n_h, d_h = n_h[top], d_h[top]
    scores = (np.abs(sample @ n_h.T + d_h) < cfg.distance_m).sum(axis=0)
    best = int(np.argmax(scores))
    normal, offset = n_h[best], d_h[best]
    for _ in range(3):  # least-squares refits
        inl = pts[np.abs(pts @ normal + offset) < cfg.distance_m]
        if inl.shape[0] < cfg.min_inliers:
            return FloorFit(False, f"too_few_inliers: {inl.shape[0]} < {cfg.min_inliers}")
        centre = inl.mean(axis=0)
        scatter = (inl - centre).T @ (inl - centre)
        evals, evecs = np.linalg.eigh(scatter)
        normal = evecs[:, 0] * (1.0 if evecs[:, 0] @ hint >= 0 else -1.0)
        offset = -float(normal @ centre)
    angle = math.acos(min(1.0, float(normal @ hint)))
    if angle > max_angle:
        return FloorFit(
            False, f"off_up: refined normal {math.degrees(angle):.2f}° from the up vector"
        )
    spread = 2.0 * np.sqrt(evals[1] / inl.shape[0])
    if spread < cfg.min_extent_m:
        return FloorFit(False, f"small_extent: {spread:.3f} m < {cfg.min_extent_m} m")
    residual = inl @ normal + offset
    rms = float(np.sqrt(np.mean(residual**2)))
    # direction σ of a least-squares plane: rms / sqrt(scatter eigenvalue) about each axis
    sigma_fit = rms / math.sqrt(float(evals[1]))
    return FloorFit(
        True,
        "ok",
        normal=normal,
        offset_m=offset,
        n_inliers=int(inl.shape[0]),
        rms_m=rms,
        sigma_rad=max(sigma_fit, cfg.sigma_min_rad),
        angle_to_hint_rad=angle,
    )


def fuse_up(
    up_a: np.ndarray, sigma_a_rad: float, up_b: np.ndarray, sigma_b_rad: float
) -> tuple[np.ndarray, float]:
    """Inverse-variance mean of two unit directions with isotropic σ (small angles)."""
    a = np.asarray(up_a, float) / np.linalg.norm(up_a)
    b = np.asarray(up_b, float) / np.linalg.norm(up_b)
    wa, wb = 1.0 / sigma_a_rad**2, 1.0 / sigma_b_rad**2
    m = wa * a + wb * b
    return m / np.linalg.norm(m), 1.0 / math.sqrt(wa + wb)
