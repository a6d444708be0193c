"""The front end's per-pixel, per-voxel and per-row loops written with numpy (the
formulation before the compiled kernels of :mod:`graph_slam.frontend.kernels`): the reference
they must equal to rounding (tests/test_frontend_kernels.py)."""

from __future__ import annotations

import time

import numpy as np

from graph_slam.errors import RecordError
from graph_slam.frontend.cloud import voxel_groups, voxel_index
from graph_slam.frontend.config import CloudConfig, ProjectiveConfig
from graph_slam.frontend.objective import Rows, kernel_weights
from graph_slam.frontend.projective import DepthFrame
from graph_slam.session.checks import check_pose
from graph_slam.session.records import CameraIntrinsics, RgbdFrame


def organized_points(
    depth_m: np.ndarray, camera: tuple[float, float, float, float], config: CloudConfig
) -> tuple[np.ndarray, np.ndarray]:
    """The back-projected points of a depth image as 3 component planes (3×h×w; invalid
    pixels hold zeros) and the mask of valid, in-range pixels."""
    fx, fy, cx, cy = camera
    h, w = depth_m.shape
    z = depth_m.astype(np.float64)
    valid = (z >= config.min_depth_m) & (z <= config.max_depth_m)
    z[~valid] = 0.0
    planes = np.empty((3, h, w))
    np.multiply(z, ((np.arange(w) - cx) / fx)[None, :], out=planes[0])
    np.multiply(z, ((np.arange(h) - cy) / fy)[:, None], out=planes[1])
    planes[2] = z
    return planes, valid


def _cross(a, b):
    """Cross product of two vectors given as 3 component planes each."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def organized_normals(
    planes: np.ndarray,
    valid: np.ndarray,
    max_jump_ratio: float,
    intensity: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Per-pixel (unnormalised, area-weighted) normals of an organised cloud (3 component
    planes, 3×h×w) for the interior pixels (3×(h−2)×(w−2)): the cross product of central
    differences of the neighbouring pixels, oriented towards the camera; the mask where they
    are defined (the four neighbours valid, their depths within ``max_jump_ratio · z`` of each
    other). With an intensity image (h×w), also the 3D intensity gradient in the tangent plane
    (``d·∂P/∂u = ∂I/∂u``, ``d·∂P/∂v = ∂I/∂v``, ``d·n = 0``). Component planes throughout:
    numpy's ``cross`` on h×w×3 arrays was about 2× slower (it copies and casts)."""
    h, w = valid.shape
    if h < 3 or w < 3:
        empty = np.zeros((3, max(h - 2, 0), max(w - 2, 0)))
        return empty, np.zeros(empty.shape[1:], bool), None if intensity is None else empty
    du = [c[1:-1, 2:] - c[1:-1, :-2] for c in planes]
    dv = [c[2:, 1:-1] - c[:-2, 1:-1] for c in planes]
    center = [c[1:-1, 1:-1] for c in planes]
    limit = max_jump_ratio * center[2]
    ok = (
        valid[1:-1, 1:-1]
        & valid[1:-1, 2:]
        & valid[1:-1, :-2]
        & valid[2:, 1:-1]
        & valid[:-2, 1:-1]
        & (np.abs(du[2]) <= limit)
        & (np.abs(dv[2]) <= limit)
    )
    n = _cross(dv, du)  # u right, v down, z forward: dv × du points towards the camera
    sign = np.where(_dot(n, center) > 0, -1.0, 1.0) * ok
    n = np.stack([c * sign for c in n])
    ok &= (n[0] != 0) | (n[1] != 0) | (n[2] != 0)
    grads = None
    if intensity is not None:
        di_u = intensity[1:-1, 2:] - intensity[1:-1, :-2]
        di_v = intensity[2:, 1:-1] - intensity[:-2, 1:-1]
        # rows (du, dv, n): the inverse's columns are (dv×n, n×du, du×dv) / det
        dv_n, n_du = _cross(dv, n), _cross(n, du)
        det = _dot(du, dv_n)
        safe = ok & (np.abs(det) > 1e-30)
        scale = np.where(safe, 1.0 / np.where(safe, det, 1.0), 0.0)
        grads = np.stack([(di_u * dv_n[j] + di_v * n_du[j]) * scale for j in range(3)])
    return n, ok, grads


def prepare_depth_reference(
    frame: RgbdFrame,
    intrinsics: CameraIntrinsics,
    config: ProjectiveConfig,
    cloud_config: CloudConfig | None = None,
    grid_T_cloud: np.ndarray | None = None,
    use_color: bool = True,
) -> DepthFrame:
    """Prepare ``frame`` once (see the module doc): organised points, normals and intensity
    gradients, voxel means on the grid fixed in frame ``grid`` (``grid_T_cloud``: the frame's
    own by default), and the pixel → voxel map."""
    cloud_config = cloud_config or CloudConfig()
    grid_T_cloud = np.eye(4) if grid_T_cloud is None else np.asarray(grid_T_cloud, dtype=float)
    check_pose("prepare_depth", "grid_T_cloud", grid_T_cloud)
    if frame.depth_m.shape != intrinsics.shape_hw:
        raise RecordError(
            f"RgbdFrame[{frame.index}].depth_m: shape {frame.depth_m.shape} does not match the "
            f"intrinsics {intrinsics.shape_hw} (height, width)"
        )
    step = config.pixel_step_for(intrinsics)
    t0 = time.perf_counter()
    depth = frame.depth_m[::step, ::step]
    h, w = depth.shape
    camera = (
        intrinsics.fx_px / step,
        intrinsics.fy_px / step,
        intrinsics.cx_px / step,
        intrinsics.cy_px / step,
    )
    planes, valid = organized_points(depth, camera, cloud_config)
    rows = np.flatnonzero(valid)
    pts = np.column_stack([c.ravel()[rows] for c in planes])
    intensity = None
    if use_color and config.photometric and frame.color_rgb is not None:
        color = frame.color_rgb[::step, ::step]
        intensity = color.sum(axis=2, dtype=np.float64) * (1.0 / (3.0 * 255.0))
    t1 = time.perf_counter()
    ns = config.normal_step  # normals at every ns-th pixel, differences over ±ns pixels
    normals, defined, grads = organized_normals(
        planes[:, ::ns, ::ns],
        valid[::ns, ::ns],
        config.max_jump_ratio * ns,
        None if intensity is None else intensity[::ns, ::ns],
    )
    t2 = time.perf_counter()
    in_grid = pts @ grid_T_cloud[:3, :3].T + grid_T_cloud[:3, 3]
    _, inverse, m = voxel_groups(voxel_index(in_grid, config.voxel_m))
    count = np.bincount(inverse, minlength=m).astype(float)
    mean = np.column_stack([np.bincount(inverse, pts[:, j], m) for j in range(3)]) / count[:, None]
    pixel_voxel = np.full(h * w, -1, dtype=np.int64)
    pixel_voxel[rows] = inverse
    # the interior pixels with a normal: their voxel, and their normal (and gradient) sums
    inner = np.flatnonzero(defined)
    inner_w = defined.shape[1]
    full = (inner // inner_w + 1) * ns * w + (inner % inner_w + 1) * ns
    vox = pixel_voxel[full]

    def sums(values: np.ndarray) -> np.ndarray:
        return np.column_stack([np.bincount(vox, values[j].ravel()[inner], m) for j in range(3)])

    nsum = sums(normals)
    norm = np.sqrt(np.einsum("ij,ij->i", nsum, nsum))
    n_defined = np.bincount(vox, minlength=m)
    keep = (n_defined >= config.min_pixel_normals) & (norm > 0)
    new_row = np.full(m, -1, dtype=np.int64)
    new_row[keep] = np.arange(int(keep.sum()))
    pixel_voxel[rows] = new_row[inverse]
    voxel_intensity = voxel_grads = None
    if intensity is not None:
        voxel_intensity = np.bincount(inverse, intensity.ravel()[rows], m)[keep] / count[keep]
        voxel_grads = sums(grads)[keep] / n_defined[keep][:, None]
    timing = {"cloud": t1 - t0, "normals": t2 - t1, "voxel": time.perf_counter() - t2}
    return DepthFrame(
        points_m=mean[keep],
        normals=nsum[keep] / norm[keep][:, None],
        intensity=voxel_intensity,
        gradients=voxel_grads,
        pixel_voxel=pixel_voxel.reshape(h, w),
        pixel_points_m=pts,
        camera=camera,
        grid_T_cloud=grid_T_cloud,
        voxel_m=config.voxel_m,
        timing_s=timing,
    )


def associate_reference(
    source: DepthFrame, target: DepthFrame, target_T_source: np.ndarray, config: ProjectiveConfig
) -> np.ndarray:
    """K×2 (source row, target row): each source voxel mean moved by ``target_T_source`` and
    projected into the target's image; the target voxel of that pixel, kept within
    ``max_correspondence_m`` and ``max_normal_angle_deg``."""
    rot, trans = target_T_source[:3, :3], target_T_source[:3, 3]
    q = source.points_m @ rot.T + trans
    fx, fy, cx, cy = target.camera
    h, w = target.pixel_voxel.shape
    z = q[:, 2]
    front = z > 1e-6
    zs = np.where(front, z, 1.0)
    u = np.rint(fx * q[:, 0] / zs + cx)
    v = np.rint(fy * q[:, 1] / zs + cy)
    inside = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    src = np.flatnonzero(inside)
    tgt = target.pixel_voxel[v[src].astype(np.intp), u[src].astype(np.intp)]
    hit = tgt >= 0
    src, tgt = src[hit], tgt[hit]
    gap = q[src] - target.points_m[tgt]
    near = np.einsum("ij,ij->i", gap, gap) <= config.max_correspondence_m**2
    cos = np.einsum("ij,ij->i", source.normals[src] @ rot.T, target.normals[tgt])
    agree = cos >= np.cos(np.deg2rad(config.max_normal_angle_deg))
    keep = near & agree
    return np.column_stack([src[keep], tgt[keep]])


def rows_reference(
    source: DepthFrame,
    target: DepthFrame,
    corr: np.ndarray,
    target_T_source: np.ndarray,
    config: ProjectiveConfig,
) -> Rows:
    """Colored ICP's rows (as :func:`graph_slam.frontend.objective.cloud_rows`, which takes
    clouds): point-to-plane ``√λ · n·(q − p)`` and, with intensities on both frames,
    ``√(1−λ) · (I_s − (I_t + d·(q_proj − p)))``; Jacobian for a left perturbation about the
    target origin; Tukey weights at ``kernel_scale · voxel_m``."""
    rot, trans = target_T_source[:3, :3], target_T_source[:3, 3]
    q = source.points_m[corr[:, 0]] @ rot.T + trans
    p = target.points_m[corr[:, 1]]
    n = target.normals[corr[:, 1]]
    color = source.intensity is not None and target.intensity is not None
    geo = np.sqrt(config.lambda_geometric) if color else 1.0
    dist = np.einsum("ij,ij->i", q - p, n)
    count = len(q)
    jac = np.empty((2 * count if color else count, 6))
    _cross_rows(q, n, jac[:count, :3])
    jac[:count, 3:] = n
    jac[:count] *= geo
    r = geo * dist
    pho = np.sqrt(1.0 - config.lambda_geometric)
    if color:
        d = target.gradients[corr[:, 1]]
        q_proj = q - dist[:, None] * n
        i_t = target.intensity[corr[:, 1]] + np.einsum("ij,ij->i", d, q_proj - p)
        r_pho = pho * (source.intensity[corr[:, 0]] - i_t)
        d_m = -(d - np.einsum("ij,ij->i", d, n)[:, None] * n)  # -(I - n nᵀ) d
        _cross_rows(q, d_m, jac[count:, :3])
        jac[count:, 3:] = d_m
        jac[count:] *= pho
        r = np.concatenate([r, r_pho])
    k = config.kernel_scale * config.voxel_m
    w = kernel_weights(r, "tukey", k)
    return Rows(r, jac, w, q, np.full(len(q), geo), len(q), pho if color else 0.0)


def _cross_rows(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """Row-wise ``a × b`` (N×3) into ``out`` (numpy's ``cross`` copies and is slower)."""
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def displacement_norms(lever: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """N×6: ``|ω × l + t|`` for each row's lever ``l`` (N×3) and each column ``(ω, t)`` of
    ``vectors`` (6×6), written out per component (``np.cross`` over N×6×3 took 4× longer)."""
    w, t = vectors[:3], vectors[3:]
    lx, ly, lz = lever[:, 0:1], lever[:, 1:2], lever[:, 2:3]
    dx = w[1] * lz - w[2] * ly + t[0]
    dy = w[2] * lx - w[0] * lz + t[1]
    dz = w[0] * ly - w[1] * lx + t[2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def significant_reference(
    rows, along: np.ndarray, vectors, center, length: float, norm: float, config
) -> tuple[np.ndarray, np.ndarray]:
    """Per eigen-direction ``v`` of an objective's ``rows`` (:class:`graph_slam.frontend.
    objective.Rows`; ``along``: each row's Jacobian in ``(L·ω, t)`` times the
    eigenvectors), the normalised stiffness of the rows that hold it significantly:
    point-to-plane rows whose normal is aligned with the point's displacement ``δ`` under
    ``v`` (``|n·δ| ≥ degeneracy_min_alignment · |δ|``), photometric rows whose intensity
    gradient along ``δ`` is at least ``degeneracy_min_gradient`` per metre of it; and the
    share of the geometric rows' weight those rows carry (a photometric row counts as much as
    a geometric one)."""
    n_geo = rows.n_geo
    contrib = rows.w[:, None] * along**2
    # |δ|: how far each point moves under the unit-free motion v (rotation about c over L)
    moved = displacement_norms((rows.q - center) / length, vectors)
    geo = np.abs(along[:n_geo]) >= (
        config.degeneracy_min_alignment * rows.geo_scale[:, None] * moved
    )
    total = np.sum(contrib[:n_geo] * geo, axis=0)
    count = rows.w[:n_geo] @ geo
    if len(rows.r) > n_geo and rows.pho_scale > 0:
        pho = np.abs(along[n_geo:]) >= config.degeneracy_min_gradient * rows.pho_scale * moved
        total = total + np.sum(contrib[n_geo:] * pho, axis=0)
        count = count + rows.w[n_geo:] @ pho
    return total / norm, count / max(float(rows.w[:n_geo].sum()), 1e-300)
