"""The terrain for the controller: an elevation grid in the stride frame, updated every frame.

Frames and units: the grid lies in the **stride frame** (x forward along the foot, y left,
z up against gravity; origin at the heel contact point at the stride's foot strike), metres,
seconds. Cell ``(i, j)`` covers ``x in [x0 + i*cell, x0 + (i+1)*cell)`` and
``y in [y0 + j*cell, y0 + (j+1)*cell)`` with ``(x0, y0) = (x_range_m[0], y_range_m[0])``.

**Update** (:meth:`OnlineElevationMap.update`, one frame): every ``pixel_step``-th depth pixel
within range becomes a point ``p_c`` (camera frame), placed in the stride frame by the frame's
online ``stride_T_camera``; its height ``z`` gets two variances:

* depth noise, independent between points: the sensor's range σ(z_c) = ``sigma_at_1m_m`` ·
  z_c^``exponent`` + ``sigma_floor_m`` along the pixel's ray ``p_c / z_c``, projected on the
  stride z axis: ``σ_d² = (R[2] · p_c / z_c)² (σ(z_c)² + σ_e²)``, with the depth-edge term
  ``σ_e²`` of a possible flying pixel (:class:`DepthNoiseModel`);
* pose, common to the frame: the camera's marginal covariance Σ (6×6, camera local, rotation
  first, ``T exp(ξ)``) pushed through the point's Jacobian, z row only:
  ``J = [p_c × R[2], R[2]]`` (from ``δp = R(-[p_c]× δθ + δt)``), ``σ_p² = J Σ Jᵀ``.

Each point weighs ``w = 1 / (σ_d² + σ_p²)``; a cell keeps ``W = Σ w``, ``Σ w z``,
``Σ w z²``, ``A = Σ w² σ_d²``, ``B = Σ w σ_p`` and ``D = Σ w σ_d²``. Its height is
``h = Σ w z / W``; its variance ``A / W² + (B / W)² + e``: the depth noise averages out, the
pose errors are taken as fully correlated (one pose error shifts every point of a frame, and
successive online poses drift together), so they do not; ``e = max(0, Σ w z² / W - h² -
D / W)`` is the cell's spread beyond the depth noise (a cell across a box edge, flying pixels
at a depth jump: its height is then no one surface's). Sums are additive: the map after frames 1..n is the batch fusion
(:func:`fuse_frames`) of the same frames and poses, to rounding.

**Re-fusion**: the map keeps the stride's subsampled clouds; :meth:`OnlineElevationMap.refuse`
builds the stride's map again from its smoothed poses (the batch path).

**Carry** (:func:`graph_slam.terrain.grid.carry.carry_map`): at a foot strike the previous stride's cells ahead of the new
heel are moved into the new stride frame through ``new_T_old`` and enter the new map as prior
points whose variance is grown by that pose's covariance (docs/terrain.md).

The read-only snapshot a controller gets, heights and variances from these sums:
:class:`~graph_slam.terrain.grid.view.TerrainView`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.errors import MappingError
from graph_slam.terrain.grid.view import TerrainView


class DepthNoiseModel(ConfigModel):
    """Range noise of the depth camera: σ(z) = sigma_at_1m_m · z^exponent + sigma_floor_m
    (the sensor profile's ``noise`` block; defaults: the D455 of models/sensors/d455.yaml),
    plus the depth-edge term: a pixel whose neighbourhood spans a depth range R above
    ``edge_threshold_m`` (a depth discontinuity: a box's outline against the floor behind it)
    may be a *flying pixel*, a mixture of both surfaces anywhere between them along its ray;
    its range variance gets ``edge_factor · R² / 3`` (the second moment of an error uniform on
    [0, R]). R is the range of the valid depths at the pixel and at ±1, ±2 pixels along u and
    v of the full-resolution image (:mod:`graph_slam.terrain.grid.depth_edges`)."""

    sigma_at_1m_m: float = Field(0.0019, ge=0)
    exponent: float = Field(2.0, ge=0, le=3)
    sigma_floor_m: float = Field(0.0003, ge=0)
    edge_threshold_m: float = Field(
        0.03, gt=0, description="a neighbourhood depth range above this marks a depth edge"
    )
    edge_factor: float = Field(
        1.0,
        ge=0,
        description="scale of the depth-edge variance R²/3 (0: no edge term, the model before)",
    )

    def sigma_m(self, z_m: np.ndarray) -> np.ndarray:
        return self.sigma_at_1m_m * np.power(z_m, self.exponent) + self.sigma_floor_m

    def edge_variance_m2(self, range_m: np.ndarray) -> np.ndarray:
        """Range variance of a pixel at a depth edge (0 below the threshold)."""
        r = np.asarray(range_m, dtype=np.float64)
        return np.where(r > self.edge_threshold_m, self.edge_factor * r**2 / 3.0, 0.0)


class OnlineTerrainConfig(ConfigModel):
    """The per-frame elevation grid of the pipelines (see the module docstring)."""

    enabled: bool = Field(True, description="update the grid at every frame")
    cell_m: float = Field(0.02, gt=0, description="cell edge (m)")
    x_range_m: tuple[float, float] = Field(
        (-0.2, 1.8), description="stride x covered: from behind the heel to ahead of the foot"
    )
    y_range_m: tuple[float, float] = (-0.6, 0.6)
    pixel_step: int = Field(4, ge=1, le=16, description="every n-th depth pixel in u and v")
    min_depth_m: float = Field(0.2, ge=0)
    max_depth_m: float = Field(2.0, gt=0, description="farther depth is too noisy for the map")
    depth_noise: DepthNoiseModel = DepthNoiseModel()
    fallback_pose_sigma: tuple[float, float] = Field(
        (0.005, 0.005),
        description="(rotation rad, translation m) σ of the camera pose when the estimator gives "
        "no covariance (the baseline; the graph with backend.covariances off)",
    )
    max_pose_sigma_m: float | None = Field(
        0.02,
        gt=0,
        description="hold a frame back from the grid while its pose is not yet trustworthy: "
        "the median over its points of the height σ its pose covariance alone gives (the "
        "σ_p of the module text, from the estimator's marginal) above this. Checked from a "
        "stride's first frame until one passes; the frames after it are fused. Frames "
        "without an estimator's covariance (the baseline) are not checked. 0.02: a stride "
        "anchored on a plane starts at 1-3 mm, one on the IMU's up (0.01 rad) near 15 mm, "
        "a session's first strike at ~100 mm (docs/terrain.md). None: every frame is fused",
    )
    carry: bool = Field(
        True,
        description="at a foot strike carry the previous stride's cells ahead of the new heel "
        "into the new stride's map (False: start from nothing, the thesis behaviour)",
    )
    carry_min_x_m: float = Field(0.0, description="carry cells with new-frame x at least this")
    toe_x_m: float = Field(
        0.2, description="toe's x in the stride frame (heel at 0): obstacle distances are from it"
    )
    keep_clouds: bool = Field(
        True,
        description="keep the stride's clouds for the re-fusion from the smoothed poses; "
        "false: the stride's final grid is its online one (the real-time preset)",
    )
    keep_stride_grids: int | None = Field(
        None,
        ge=1,
        description="the results keep the grids (StrideOutput.online_grid, smoothed_grid) "
        "of at most this many of the latest strides, older ones released (a controller "
        "running for hours: ~0.4 MB a stride); None: every stride's (evaluation)",
    )

    @model_validator(mode="after")
    def _ranges(self) -> OnlineTerrainConfig:
        for name in ("x_range_m", "y_range_m"):
            lo, hi = getattr(self, name)
            if not hi > lo:
                raise ValueError(f"{name}: the upper bound must exceed the lower, got {lo}, {hi}")
        return self

    @property
    def shape(self) -> tuple[int, int]:
        nx = round((self.x_range_m[1] - self.x_range_m[0]) / self.cell_m)
        ny = round((self.y_range_m[1] - self.y_range_m[0]) / self.cell_m)
        return nx, ny


def fallback_covariance(sigma: tuple[float, float]) -> np.ndarray:
    """A diagonal 6×6 pose covariance (rotation first) from (rotation σ, translation σ)."""
    return np.diag([sigma[0] ** 2] * 3 + [sigma[1] ** 2] * 3)


def z_variance(points_local: np.ndarray, rotation: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Variance of the z coordinate of ``T p`` for points ``p`` (N×3, the frame of the pose's
    right perturbation) under a 6×6 covariance (rotation first): ``J Σ Jᵀ`` with the z row
    ``J = [p × R[2], R[2]]``. With ``p × r = A p`` (``A = -[r]×``) it is the quadratic
    ``pᵀ Q p + g·p + c``: 3×3 work per point."""
    q, g, c = z_variance_terms(rotation, cov)
    p = np.asarray(points_local, dtype=np.float64)
    return np.einsum("ni,ni->n", p @ q, p) + p @ g + c


def z_variance_terms(rotation: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``Q``, ``g``, ``c`` of :func:`z_variance`'s quadratic ``pᵀ Q p + g·p + c``."""
    r = rotation[2]
    a = -np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return a.T @ cov[:3, :3] @ a, 2.0 * a.T @ cov[:3, 3:] @ r, float(r @ cov[3:, 3:] @ r)


@dataclass(frozen=True, eq=False)
class PointTerms:
    """Per-point contributions to the cell sums (only the points inside the grid)."""

    flat: np.ndarray
    z_m: np.ndarray
    var_depth_m2: np.ndarray
    var_pose_m2: np.ndarray

    @staticmethod
    def concat(terms: Sequence[PointTerms]) -> PointTerms:
        return PointTerms(*(np.concatenate([getattr(t, f) for t in terms]) for f in _TERM_FIELDS))


_TERM_FIELDS = ("flat", "z_m", "var_depth_m2", "var_pose_m2")


def cell_index(cfg: OnlineTerrainConfig, xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat cell index of each (x, y) and whether it lies on the grid."""
    nx, ny = cfg.shape
    i = np.floor((xy_m[:, 0] - cfg.x_range_m[0]) / cfg.cell_m).astype(np.int64)
    j = np.floor((xy_m[:, 1] - cfg.y_range_m[0]) / cfg.cell_m).astype(np.int64)
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    return i * ny + j, inside


def point_terms(
    cfg: OnlineTerrainConfig,
    points_camera_m: np.ndarray,
    stride_T_camera: np.ndarray,
    cov,
    depth_range_m: np.ndarray | None = None,
) -> PointTerms:
    """One frame's points in the stride frame with their depth and pose variances;
    ``depth_range_m`` (per point, :mod:`graph_slam.terrain.grid.depth_edges`; None: no edge term)
    adds the
    depth-edge variance along the ray."""
    pts = np.asarray(points_camera_m, dtype=np.float64)
    rotation, t = stride_T_camera[:3, :3], stride_T_camera[:3, 3]
    p = pts @ rotation.T + t
    flat, inside = cell_index(cfg, p[:, :2])
    pts, p, flat = pts[inside], p[inside], flat[inside]
    z_c = pts[:, 2]
    ray_z = (pts @ rotation[2]) / z_c
    noise = cfg.depth_noise
    var_range = noise.sigma_m(z_c) ** 2
    if depth_range_m is not None and noise.edge_factor > 0:
        var_range = var_range + noise.edge_variance_m2(np.asarray(depth_range_m)[inside])
    var_depth = ray_z**2 * var_range
    var_pose = z_variance(pts, rotation, cov) if cov is not None else np.zeros(len(pts))
    return PointTerms(flat, p[:, 2], var_depth, var_pose)


def checked_pose(stride_T_camera) -> np.ndarray:
    """``stride_T_camera`` as a float 4×4; a :class:`MappingError` unless finite 4×4."""
    pose = np.asarray(stride_T_camera, dtype=np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise MappingError(f"online terrain: stride_T_camera must be a finite 4×4, got {pose}")
    return pose


@dataclass(frozen=True, eq=False)
class CellSums:
    """The additive per-cell sums (flat arrays of nx·ny; see the module docstring)."""

    w: np.ndarray
    wz: np.ndarray
    a: np.ndarray
    b: np.ndarray
    count: np.ndarray
    last_t_s: np.ndarray
    wz2: np.ndarray
    d: np.ndarray

    @staticmethod
    def empty(n: int) -> CellSums:
        z = np.zeros(n)
        return CellSums(z, z, z, z, np.zeros(n, np.int64), np.full(n, np.nan), z, z)

    def plus(self, terms: PointTerms, t_s: float | np.ndarray) -> CellSums:
        """New sums with the points added (self unchanged: views keep their arrays)."""
        from graph_slam.terrain.grid.sums_kernel import cell_terms

        n = len(self.w)
        touched, w, wz, a, b, wz2, d = cell_terms(
            np.ascontiguousarray(terms.flat, np.int64),
            np.ascontiguousarray(terms.z_m, np.float64),
            np.ascontiguousarray(terms.var_depth_m2, np.float64),
            np.ascontiguousarray(terms.var_pose_m2, np.float64),
            n,
        )
        last = self.last_t_s.copy()
        if np.ndim(t_s) == 0:
            last[touched > 0] = float(t_s)
        else:  # batch: the latest time of any point in the cell
            np.fmax.at(last, terms.flat, np.asarray(t_s, dtype=np.float64))
        return CellSums(
            self.w + w,
            self.wz + wz,
            self.a + a,
            self.b + b,
            self.count + touched,
            last,
            self.wz2 + wz2,
            self.d + d,
        )


class OnlineElevationMap:
    """One stride's elevation grid, updated frame by frame (see the module docstring)."""

    def __init__(
        self, config: OnlineTerrainConfig, stride_index: int = 0, prior: CellSums | None = None
    ) -> None:
        self.cfg = config
        self.stride_index = stride_index
        nx, ny = config.shape
        self.prior = prior if prior is not None else CellSums.empty(nx * ny)
        self.sums = self.prior
        self.t_s = float("nan")
        self.clouds: list[tuple[float, np.ndarray, np.ndarray | None]] = []
        """Per fused frame: its time, camera-frame points (float32) and depth ranges."""

    def update(
        self,
        points_camera_m,
        stride_T_camera,
        covariance,
        t_s: float,
        depth_range_m: np.ndarray | None = None,
    ) -> TerrainView:
        """Fuse one frame's camera-frame points placed by its ``stride_T_camera`` (4×4) with
        its 6×6 pose covariance (None: depth noise only) and, per point, the depth range of
        its pixel's neighbourhood (None: no depth-edge term)."""
        pose = checked_pose(stride_T_camera)
        if depth_range_m is not None and len(depth_range_m) != len(points_camera_m):
            raise MappingError(
                f"online terrain: {len(depth_range_m)} depth ranges for "
                f"{len(points_camera_m)} points"
            )
        terms = point_terms(self.cfg, points_camera_m, pose, covariance, depth_range_m)
        return self.fuse(terms, t_s, points_camera_m, depth_range_m)

    def fuse(
        self, terms: PointTerms, t_s: float, points_camera_m, depth_range_m=None
    ) -> TerrainView:
        """Add one frame's point terms (:func:`point_terms`, or the compiled
        :func:`graph_slam.terrain.grid.kernels.frame_point_terms`); its camera-frame points and depth ranges are kept for the
        re-fusion when ``keep_clouds``."""
        self.sums = self.sums.plus(terms, t_s)
        self.t_s = float(t_s)
        self.keep_cloud(t_s, points_camera_m, depth_range_m)
        return self.view()

    def keep_cloud(self, t_s: float, points_camera_m, depth_range_m=None) -> None:
        """Keep a frame's cloud for the re-fusion (``keep_clouds``), fused now or not."""
        if self.cfg.keep_clouds:
            ranges = None if depth_range_m is None else np.asarray(depth_range_m, np.float32)
            self.clouds.append((float(t_s), np.asarray(points_camera_m, np.float32), ranges))

    def view(self) -> TerrainView:
        """The current grid, read-only (later updates do not change it)."""
        return TerrainView(
            self.stride_index,
            self.t_s,
            np.array([self.cfg.x_range_m[0], self.cfg.y_range_m[0]]),
            self.cfg.cell_m,
            self.sums,
            self.cfg.shape,
            self.cfg.toe_x_m,
        )

    def refuse(self, stride_T_camera: np.ndarray, covariances) -> TerrainView:
        """The stride's map again from other (smoothed) poses, from the carried prior and the
        kept clouds (frames whose pose is NaN are left out)."""
        poses = np.asarray(stride_T_camera, dtype=np.float64)
        if len(poses) != len(self.clouds):
            raise MappingError(
                f"online terrain: {len(poses)} poses for {len(self.clouds)} kept clouds"
            )
        keep = [i for i in range(len(poses)) if np.isfinite(poses[i]).all()]
        covs = [None if covariances is None else covariances[i] for i in keep]
        sums = fuse_frames(
            self.cfg,
            [self.clouds[i][1] for i in keep],
            poses[keep],
            covs,
            [self.clouds[i][0] for i in keep],
            self.prior,
            [self.clouds[i][2] for i in keep],
        )
        t = self.clouds[-1][0] if self.clouds else float("nan")
        return TerrainView(
            self.stride_index,
            t,
            np.array([self.cfg.x_range_m[0], self.cfg.y_range_m[0]]),
            self.cfg.cell_m,
            sums,
            self.cfg.shape,
            self.cfg.toe_x_m,
        )


def fuse_frames(
    cfg: OnlineTerrainConfig,
    clouds_camera_m: Sequence[np.ndarray],
    stride_T_camera: np.ndarray,
    covariances: Sequence[np.ndarray | None],
    t_s: Sequence[float],
    prior: CellSums | None = None,
    depth_ranges_m: Sequence[np.ndarray | None] | None = None,
) -> CellSums:
    """The batch fusion: every frame's points in one pass (equal to the frame-by-frame
    updates of :class:`OnlineElevationMap`, to rounding)."""
    nx, ny = cfg.shape
    base = prior if prior is not None else CellSums.empty(nx * ny)
    if not len(clouds_camera_m):
        return base
    ranges = depth_ranges_m if depth_ranges_m is not None else [None] * len(clouds_camera_m)
    terms = [
        point_terms(cfg, c, np.asarray(p, np.float64), cov, r)
        for c, p, cov, r in zip(clouds_camera_m, stride_T_camera, covariances, ranges, strict=True)
    ]
    times = np.concatenate([np.full(len(t.flat), tt) for t, tt in zip(terms, t_s, strict=True)])
    return base.plus(PointTerms.concat(terms), times)
