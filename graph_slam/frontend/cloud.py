"""Depth image → point cloud → voxel pyramid with normals.

Clouds are numpy arrays in a named frame (the caller's: usually ``camera``, optical). The voxel
grid has a **fixed origin**: the origin of the frame the points are bucketed in (``grid_T_cloud``
maps the cloud into that frame). Open3D's ``voxel_down_sample`` anchors its grid at each cloud's
minimum point instead, so two clouds of the same surface are sampled on different grids (see
docs/frontend.md). Each voxel keeps the mean of its points (and colours).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from graph_slam.errors import RecordError
from graph_slam.frontend.config import CloudConfig, RegistrationConfig
from graph_slam.session.records import CameraIntrinsics, Cloud, RgbdFrame

_KEY_BITS = 21  # bits per axis of a voxel key: ±2^20 voxels (±10 km at 1 cm)
_KEY_OFFSET = 1 << (_KEY_BITS - 1)


@dataclass(frozen=True)
class CloudCounts:
    """What :func:`depth_to_cloud` did with every pixel (they add up to ``pixels``)."""

    pixels: int
    no_depth: int
    too_near: int
    too_far: int
    kept: int


def depth_to_cloud(
    frame: RgbdFrame,
    intrinsics: CameraIntrinsics,
    config: CloudConfig | None = None,
    pixel_step: int = 1,
) -> tuple[Cloud, CloudCounts]:
    """Back-project the valid, in-range depth pixels into the camera (optical) frame.

    ``pixel_step`` > 1 decimates the organised image first (every n-th row and column, from
    pixel (0, 0)); the counts are then of the pixels kept by the decimation."""
    config = config or CloudConfig()
    depth = frame.depth_m
    if depth.shape != intrinsics.shape_hw:
        raise RecordError(
            f"RgbdFrame[{frame.index}].depth_m: shape {depth.shape} does not match the "
            f"intrinsics {intrinsics.shape_hw} (height, width)"
        )
    if pixel_step < 1:
        raise RecordError(f"depth_to_cloud: pixel_step must be >= 1, got {pixel_step}")
    color = frame.color_rgb
    if pixel_step > 1:
        depth = depth[::pixel_step, ::pixel_step]
        color = None if color is None else color[::pixel_step, ::pixel_step]
    valid = depth > 0
    near = valid & (depth < config.min_depth_m)
    far = valid & (depth > config.max_depth_m)
    keep = valid & ~near & ~far
    v, u = np.nonzero(keep)
    z = depth[v, u].astype(np.float64)
    colors = None if color is None else color[v, u] / 255.0
    if pixel_step > 1:
        v, u = v * pixel_step, u * pixel_step
    points = np.column_stack(
        [
            (u - intrinsics.cx_px) * z / intrinsics.fx_px,
            (v - intrinsics.cy_px) * z / intrinsics.fy_px,
            z,
        ]
    )
    counts = CloudCounts(
        pixels=int(depth.size),
        no_depth=int(depth.size - np.count_nonzero(valid)),
        too_near=int(np.count_nonzero(near)),
        too_far=int(np.count_nonzero(far)),
        kept=int(z.size),
    )
    return Cloud(points, colors), counts


def voxel_index(points_m: np.ndarray, voxel_m: float) -> np.ndarray:
    """N×3 integer voxel index of each point on the grid with origin 0 and edge ``voxel_m``."""
    index = np.floor(points_m / voxel_m).astype(np.int64)
    if index.size and np.abs(index).max() >= _KEY_OFFSET:
        raise RecordError(
            f"cloud: a point lies more than {_KEY_OFFSET} voxels of {voxel_m} m from the grid "
            "origin; the voxel key cannot hold it"
        )
    return index


def _pack(index: np.ndarray) -> np.ndarray:
    index = index + _KEY_OFFSET
    return (index[:, 0] << (2 * _KEY_BITS)) | (index[:, 1] << _KEY_BITS) | index[:, 2]


def voxel_groups(index: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Group points by voxel (N×3 ``index``): the first point of each voxel (sorted by voxel),
    each point's voxel number and the number of voxels (for ``np.bincount`` sums)."""
    keys, first, inverse = np.unique(_pack(index), return_index=True, return_inverse=True)
    return first, inverse.ravel(), int(keys.size)


@dataclass(frozen=True, eq=False)
class VoxelSums:
    """Per-voxel point (and colour) sums and counts on a fixed grid: the one voxel mean.

    Used by the pyramid (:func:`voxel_pyramid`), the local map (running sums over frames) and
    the terrain fusion. ``index`` is M×3 (sorted by voxel), ``counts`` the (weighted) number of
    points per voxel.
    """

    index: np.ndarray  # M×3 voxel index
    counts: np.ndarray  # M
    point_sums: np.ndarray  # M×3
    color_sums: np.ndarray | None

    @classmethod
    def of(
        cls,
        index: np.ndarray,
        points: np.ndarray,
        colors: np.ndarray | None = None,
        weights: np.ndarray | None = None,
    ) -> VoxelSums:
        """Sum ``points`` (and ``colors``) by voxel ``index`` (N×3); ``weights`` are the
        counts the rows stand for (1 each by default; sums of earlier voxels carry theirs)."""
        first, inverse, n = voxel_groups(index)

        def sums(values: np.ndarray) -> np.ndarray:
            return np.column_stack([np.bincount(inverse, values[:, j], n) for j in range(3)])

        counts = np.bincount(inverse, weights, n).astype(float)
        return cls(index[first], counts, sums(points), None if colors is None else sums(colors))

    @classmethod
    def empty(cls, with_colors: bool) -> VoxelSums:
        zeros = np.zeros((0, 3))
        return cls(np.zeros((0, 3), np.int64), np.zeros(0), zeros, zeros if with_colors else None)

    def __len__(self) -> int:
        return int(self.counts.size)

    def added(self, index: np.ndarray, points: np.ndarray, colors: np.ndarray | None) -> VoxelSums:
        """These sums with more points (N×3 voxel ``index``) added."""
        return VoxelSums.of(
            np.vstack([self.index, index]),
            np.vstack([self.point_sums, points]),
            None if self.color_sums is None else np.vstack([self.color_sums, colors]),
            np.concatenate([self.counts, np.ones(len(points))]),
        )

    def mean_points(self) -> np.ndarray:
        return self.point_sums / self.counts[:, None]

    def mean_colors(self) -> np.ndarray | None:
        return None if self.color_sums is None else self.color_sums / self.counts[:, None]

    def cloud(self) -> Cloud:
        return Cloud(self.mean_points(), self.mean_colors())


def voxel_pyramid(
    cloud: Cloud, voxels_m: tuple[float, ...], grid_T_cloud: np.ndarray | None = None
) -> tuple[Cloud, ...]:
    """:func:`voxel_downsample` at every voxel size, in the order given.

    The finest level is computed from the points; a coarser level whose edge is an integer
    multiple of the finest one merges the finest voxels (exactly the same result, since the
    grids share their origin), any other from the points again.
    """
    if len(cloud) == 0:
        empty = Cloud(np.zeros((0, 3)), None if cloud.colors is None else np.zeros((0, 3)))
        return tuple(empty for _ in voxels_m)
    points = cloud.points_m
    in_grid = (
        points if grid_T_cloud is None else points @ grid_T_cloud[:3, :3].T + grid_T_cloud[:3, 3]
    )
    finest_m = min(voxels_m)
    finest = VoxelSums.of(voxel_index(in_grid, finest_m), points, cloud.colors)
    out = []
    for voxel_m in voxels_m:
        ratio = voxel_m / finest_m
        if voxel_m == finest_m:
            out.append(finest.cloud())
        elif abs(ratio - round(ratio)) < 1e-9:
            merged = VoxelSums.of(
                finest.index // round(ratio), finest.point_sums, finest.color_sums, finest.counts
            )
            out.append(merged.cloud())
        else:
            out.append(voxel_downsample(cloud, voxel_m, grid_T_cloud))
    return tuple(out)


def voxel_downsample(cloud: Cloud, voxel_m: float, grid_T_cloud: np.ndarray | None = None) -> Cloud:
    """Mean point (and colour) per voxel of a grid fixed in frame ``grid``.

    The points are bucketed by ``floor(grid_T_cloud · p / voxel_m)`` and the means are returned
    in the cloud's own frame; normals are dropped (estimate them on the result).
    """
    return voxel_pyramid(cloud, (voxel_m,), grid_T_cloud)[0]


def estimate_normals(
    cloud: Cloud,
    radius_m: float,
    max_nn: int = 30,
    viewpoint_m: np.ndarray | None = None,
    min_spread: float = 0.05,
    max_thickness: float = 0.5,
) -> tuple[Cloud, int]:
    """Unit normals from the covariance of each point's neighbours (Open3D hybrid search:
    ≤ ``max_nn`` within ``radius_m``), oriented towards ``viewpoint_m`` (the frame's origin by
    default). Returns the cloud of the points whose normal is defined, and how many were
    dropped.

    With eigenvalues ``λ0 ≤ λ1 ≤ λ2`` of the neighbourhood covariance, a normal is defined when
    the neighbours spread in two directions (``λ1 ≥ min_spread · λ2``: not a line, as far,
    sparsely sampled rows of an image are) and lie on a surface (``λ0 ≤ max_thickness · λ1``:
    not an isotropic blob, nor a point with fewer than 3 neighbours). Undefined normals would
    otherwise look like constraints in the degeneracy report.
    """
    import open3d as o3d

    from graph_slam.frontend.neighbourhood import eig3_smallest

    if len(cloud) == 0:
        return Cloud(cloud.points_m, cloud.colors, np.zeros((0, 3))), 0
    points = cloud.points_m
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(points)))
    pcd.estimate_covariances(o3d.geometry.KDTreeSearchParamHybrid(radius=radius_m, max_nn=max_nn))
    # closed form, compiled: numpy's eigh was a sixth of the thesis baseline's time
    values, normals = eig3_smallest(np.ascontiguousarray(np.asarray(pcd.covariances)))
    viewpoint = np.zeros(3) if viewpoint_m is None else np.asarray(viewpoint_m, dtype=float)
    normals[np.einsum("ij,ij->i", normals, viewpoint - points) < 0] *= -1.0
    defined = (values[:, 1] >= min_spread * values[:, 2]) & (
        values[:, 0] <= max_thickness * values[:, 1]
    )
    colors = None if cloud.colors is None else cloud.colors[defined]
    return Cloud(points[defined], colors, normals[defined]), int(np.count_nonzero(~defined))


@dataclass(frozen=True, eq=False)
class Pyramid:
    """A registration target: one voxelised cloud with normals per level, coarse to fine.

    Every level is on the fixed grid of the cloud's own frame. ``dropped`` counts, per level,
    the points dropped because their normal is undefined (see :func:`estimate_normals`);
    ``timing_s`` holds the time spent in the ``voxel`` and ``normals`` stages.
    """

    levels: tuple[Cloud, ...]
    voxel_m: tuple[float, ...]
    dropped: tuple[int, ...] = ()
    timing_s: dict[str, float] = field(default_factory=dict)

    @property
    def finest(self) -> Cloud:
        return self.levels[-1]


def build_pyramid(
    cloud: Cloud, config: RegistrationConfig, viewpoint_m: np.ndarray | None = None
) -> Pyramid:
    """Voxelise ``cloud`` on its own frame's grid at every level (``config.pyramid_voxels_m``:
    the ICP levels, then the refinement's) and estimate normals towards ``viewpoint_m``."""
    t0 = time.perf_counter()
    downs = voxel_pyramid(cloud, config.pyramid_voxels_m)
    t1 = time.perf_counter()
    levels, dropped = zip(
        *(
            estimate_normals(
                down, config.normal_radius_factor * voxel_m, config.normal_max_nn, viewpoint_m
            )
            for down, voxel_m in zip(downs, config.pyramid_voxels_m, strict=True)
        ),
        strict=True,
    )
    timing = {"voxel": t1 - t0, "normals": time.perf_counter() - t1}
    return Pyramid(tuple(levels), config.pyramid_voxels_m, tuple(dropped), timing)
