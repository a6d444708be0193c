"""GICP (small_gicp, the ``realtime-gicp`` preset) on one fixed-grid scale, each frame prepared once.

``prepare_frame(cloud, config, grid_T_cloud)`` turns a frame's cloud into a
:class:`GicpFrame`: voxel means on a grid with a fixed origin (small_gicp's
``voxelgrid_sampling`` buckets by ``floor(p / voxel)`` in the frame it is given, i.e. its grid
is fixed at that frame's origin), per-point covariances (``estimate_covariances``: k
neighbours, regularised to the plane shape ``diag(1e-3, 1, 1)``) and a ``KdTree``. The frame is
the *source* of its own registration and, unchanged, the *target* of the next frame's:
:func:`register_prepared` calls small_gicp's ``align(target, source, target_tree, …,
registration_type="GICP")`` and builds the house's :class:`RegistrationResult` from the
solver's own final Hessian, without another pass over the points for the information.

The grid: a frame is voxelised on the previous frame's grid carried through the initial guess
(``grid_T_cloud = previous.grid_T_cloud · guess``), so consecutive frames are sampled on the
same grid (exactly so when the guess is right); along a chain of frames the grid stays fixed in
the first frame's camera frame. See docs/frontend.md, "The real-time preset".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from graph_slam.errors import RegistrationFailure
from graph_slam.frontend.cloud import Cloud, voxel_downsample
from graph_slam.frontend.config import GicpConfig
from graph_slam.frontend.degeneracy import DegeneracyReport, project_information
from graph_slam.frontend.objective import analyse, cloud_rows, exp_left, rows_information
from graph_slam.frontend.result import (
    RegistrationResult,
    conclude,
    fail_if_degenerate,
    gate_correspondences,
    registration_failure,
    start_pose,
)
from graph_slam.session.checks import check_pose
from kinematics.conversions import adjoint_rot_first, skew

#: small_gicp regularises every covariance to ``diag(1e-3, 1, 1)`` in its eigenbasis: a
#: correspondence between two parallel surface patches has variance ``2 · 1e-3 · κ`` along
#: the normal in GICP's model, κ the residual scale.
PLANE_EPSILON = 1e-3


@dataclass(frozen=True, eq=False)
class GicpFrame:
    """A frame ready to register and to be registered against.

    ``points_m``: voxel means in the cloud's own frame (N×3); ``cloud``: the same points with
    their covariances (``small_gicp.PointCloud``); ``tree``: its ``small_gicp.KdTree``;
    ``grid_T_cloud``: the frame whose origin anchors the voxel grid. ``cloud`` and ``tree``
    are None when there are fewer than ``config.min_points`` points (registration then raises
    ``EMPTY_SOURCE`` / ``EMPTY_TARGET``). ``timing_s``: ``voxel``, ``covariances`` (with the
    tree).
    """

    points_m: np.ndarray
    cloud: object | None
    tree: object | None
    grid_T_cloud: np.ndarray
    voxel_m: float
    colored: Cloud | None = None  # points, colours, normals: the photometric stage's
    gradients: np.ndarray | None = None  # N×3 intensity gradients (tangent plane)
    timing_s: dict[str, float] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points_m)


def prepare_frame(
    cloud: Cloud | np.ndarray, config: GicpConfig, grid_T_cloud: np.ndarray | None = None
) -> GicpFrame:
    """Voxelise ``cloud`` (its own frame) on the grid fixed in frame ``grid``
    (``grid_T_cloud``; the cloud's own frame by default), then covariances and a k-d tree."""
    import small_gicp

    points = cloud.points_m if isinstance(cloud, Cloud) else np.asarray(cloud, dtype=float)
    colors = cloud.colors if isinstance(cloud, Cloud) and config.photometric else None
    grid_T_cloud = np.eye(4) if grid_T_cloud is None else np.asarray(grid_T_cloud, dtype=float)
    check_pose("prepare_frame", "grid_T_cloud", grid_T_cloud)
    rot, trans = grid_T_cloud[:3, :3], grid_T_cloud[:3, 3]
    t0 = time.perf_counter()
    if colors is not None:  # the house's fixed grid keeps the colour means
        down = voxel_downsample(Cloud(points, colors), config.voxel_m, grid_T_cloud)
        means, colors = down.points_m, down.colors
    elif len(points):
        in_grid = points @ rot.T + trans
        # one thread: the multi-threaded sampling is not deterministic (small_gicp's note)
        means = small_gicp.voxelgrid_sampling(in_grid, config.voxel_m, 1).points()[:, :3]
        means = (means - trans) @ rot  # back to the cloud's frame (a mean commutes with it)
    else:
        means = np.zeros((0, 3))
    t1 = time.perf_counter()
    sg_cloud = tree = colored = gradients = None
    if len(means) >= config.min_points:
        sg_cloud = small_gicp.PointCloud(means)
        tree = small_gicp.KdTree(sg_cloud, config.num_threads)
        k, threads = config.covariance_neighbors, config.num_threads
        if colors is None:
            small_gicp.estimate_covariances(sg_cloud, tree, k, threads)
        else:
            small_gicp.estimate_normals_covariances(sg_cloud, tree, k, threads)
            normals = sg_cloud.normals()[:, :3]
            normals[np.einsum("ij,ij->i", normals, means) > 0] *= -1.0  # towards the camera
            nbr, _ = tree.batch_knn_search(means, config.color_neighbors, threads)
            gradients = intensity_gradients(means, colors.mean(axis=1), normals, nbr)
            colored = Cloud(means, colors, normals)
    timing = {"voxel": t1 - t0, "covariances": time.perf_counter() - t1}
    return GicpFrame(
        means, sg_cloud, tree, grid_T_cloud, config.voxel_m, colored, gradients, timing
    )


def intensity_gradients(
    points: np.ndarray, intensity: np.ndarray, normals: np.ndarray, neighbors: np.ndarray
) -> np.ndarray:
    """Intensity gradient in each point's tangent plane, by least squares over its k nearest
    neighbours (``neighbors``: N×k indices, the point itself first), with a weighted
    ``d·n = 0`` row: Open3D colored ICP's estimate (as
    :func:`graph_slam.frontend.neighbourhood.color_gradients`, from a k-NN query)."""
    nbr = neighbors[:, 1:].astype(np.intp)
    diff = points[nbr] - points[:, None, :]
    proj = diff - np.einsum("mkj,mj->mk", diff, normals)[..., None] * normals[:, None, :]
    b = intensity[nbr] - intensity[:, None]
    count = float(nbr.shape[1])
    ata = np.einsum("mki,mkj->mij", proj, proj) + count**2 * np.einsum(
        "mi,mj->mij", normals, normals
    )
    atb = np.einsum("mki,mk->mi", proj, b)
    return np.linalg.solve(ata + 1e-12 * np.eye(3), atb[..., None])[..., 0]


def _degeneracy(
    hessian_right: np.ndarray,
    target_T_source: np.ndarray,
    source_points_m: np.ndarray,
    threshold: float,
) -> DegeneracyReport:
    """The solver's Hessian made unit-free as :class:`DegeneracyReport` defines it: a motion
    of the source about the centroid ``c`` of its points (target frame), coordinates
    ``(L·ω, t)``, divided by the trace of its translation block (``Σ tr Mᵢ``, as the ICP
    report divides by the summed weights ``Σ wᵢ |nᵢ|²``): a unit translation's stiffness is
    then the share of the correspondences' weight that holds it."""
    ad = adjoint_rot_first(target_T_source)  # left twist (target origin) = Ad · right twist
    ad_inv = np.linalg.inv(ad)
    hess_left = ad_inv.T @ hessian_right @ ad_inv
    moved = source_points_m @ target_T_source[:3, :3].T + target_T_source[:3, 3]
    center = moved.mean(axis=0)
    length = max(float(np.sqrt(np.mean(np.sum((moved - center) ** 2, axis=1)))), 1e-6)
    to_unit = np.eye(6)  # origin twist = to_unit · (L·ω, t about the centre)
    to_unit[3:, :3] = skew(center)
    to_unit[:, :3] /= length
    hess_n = to_unit.T @ hess_left @ to_unit / max(float(np.trace(hess_left[3:, 3:])), 1e-300)
    values, vectors = np.linalg.eigh(0.5 * (hess_n + hess_n.T))
    return DegeneracyReport(values, vectors, center, length, threshold)


_fail = registration_failure


def _photometric(
    source: GicpFrame, target: GicpFrame, target_T_source: np.ndarray, config: GicpConfig
) -> RegistrationResult:
    """Gauss-Newton on colored ICP's objective (the accurate preset's, Open3D's: point-to-plane
    and intensity rows, ``λ`` and ``1 − λ``, Tukey kernel) from GICP's result, nearest
    neighbours re-associated each iteration with the target's k-d tree; steps restricted to
    the well-constrained directions. The quality report is the accurate path's
    (:func:`graph_slam.frontend.registration.register`), from the last iteration's rows."""
    src, tgt = source.colored, target.colored
    k = config.kernel_scale * config.voxel_m
    lam = config.lambda_geometric

    def rows_at(corr: np.ndarray, pose: np.ndarray):
        return cloud_rows(src, tgt, corr, pose, geo_scale=np.sqrt(lam), pho_scale=np.sqrt(1.0 - lam),
                     kernel="tukey", k=k, gradients=target.gradients)  # fmt: skip

    corr = np.zeros((0, 2), dtype=int)
    for _ in range(config.refine_iterations):
        moved = src.points_m @ target_T_source[:3, :3].T + target_T_source[:3, 3]
        nearest, sq_dist = target.tree.batch_knn_search(moved, 1, config.num_threads)
        found = np.flatnonzero(sq_dist[:, 0] <= config.photometric_max_correspondence_m**2)
        corr = np.column_stack([found, nearest[found, 0].astype(np.intp)])
        gate_correspondences(config, len(corr) / len(src), len(corr))
        step = analyse(rows_at(corr, target_T_source), config, significance=False).step_origin
        target_T_source = exp_left(step) @ target_T_source
        if np.linalg.norm(step) < config.refine_min_step:
            break
    rows = rows_at(corr, target_T_source)
    analysis = analyse(rows, config)
    information, sigma = rows_information(
        rows, target_T_source, config.information_min_sigma_m, analysis.degeneracy,
        config.information_scale,
    )  # fmt: skip
    gap = rows.q - tgt.points_m[corr[:, 1]]
    return conclude(
        target_T_source, analysis, information, sigma, len(corr) / len(src), len(corr),
        float(np.sqrt(np.mean(np.sum(gap**2, axis=1)))), config,
    )  # fmt: skip


def register_prepared(
    source: GicpFrame,
    target: GicpFrame,
    config: GicpConfig,
    initial_target_T_source: np.ndarray | None = None,
) -> RegistrationResult:
    """GICP of ``source`` to ``target`` (both prepared) from ``initial_target_T_source``.

    The information is small_gicp's final Gauss-Newton Hessian ``H = Σ JᵀMJ`` (it is already
    in the house's tangent space: rotation first, right perturbation in the source frame, see
    docs/frontend.md), divided by the residual scale ``κ = Σ rᵀMr / (3 · inliers)``, floored so
    that the implied σ along a surface normal, ``√(2·1e-3·κ)``, is at least
    ``information_min_sigma_m``. Raises :class:`RegistrationError` on failure.
    """
    import small_gicp

    if source.cloud is None or target.cloud is None:
        raise _fail(
            RegistrationFailure.EMPTY_SOURCE
            if source.cloud is None
            else RegistrationFailure.EMPTY_TARGET,
            "a frame without its prepared cloud",
        )
    init = start_pose("register_prepared", source, target, config, initial_target_T_source)
    t0 = time.perf_counter()
    result = small_gicp.align(
        target.cloud,
        source.cloud,
        target.tree,
        init_T_target_source=init,
        registration_type="GICP",
        max_correspondence_distance=config.max_correspondence_m,
        num_threads=config.num_threads,
        max_iterations=config.max_iterations,
        rotation_epsilon=config.rotation_epsilon_rad,
        translation_epsilon=config.translation_epsilon_m,
    )
    t1 = time.perf_counter()
    target_T_source = np.asarray(result.T_target_source)
    count = int(result.num_inliers)
    fitness = count / len(source)
    hessian = np.asarray(result.H)
    if count == 0:
        raise _fail(
            RegistrationFailure.NO_OVERLAP,
            f"no correspondence within {config.max_correspondence_m} m",
            0.0,
            0,
        )
    if not (np.isfinite(target_T_source).all() and np.isfinite(hessian).all()):
        raise _fail(
            RegistrationFailure.NUMERICAL, "non-finite transform or Hessian", fitness, count
        )
    gate_correspondences(config, fitness, count)
    # the solver's last step (Gauss-Newton, at the last linearisation)
    step = -np.linalg.lstsq(hessian, np.asarray(result.b).ravel(), rcond=1e-12)[0]
    step_m, step_rad = float(np.linalg.norm(step[3:])), float(np.linalg.norm(step[:3]))
    photometric = source.colored is not None and target.colored is not None
    if config.check_convergence and not result.converged and not photometric:
        raise _fail(
            RegistrationFailure.NOT_CONVERGED,
            f"no convergence in {config.max_iterations} iterations (last step "
            f"{step_m * 1e3:.2f} mm, {np.degrees(step_rad):.3f} deg)",
            fitness,
            count,
        )
    if photometric:  # the photometric stage's own convergence gate decides
        result = _photometric(source, target, target_T_source, config)  # gates: conclude
        t2 = time.perf_counter()
        return replace(result, timing_s={"icp": t2 - t0, "information": 0.0})
    kappa_min = config.information_min_sigma_m**2 / (2.0 * PLANE_EPSILON)
    kappa = max(2.0 * float(result.error) / (3.0 * count), kappa_min)
    degeneracy = _degeneracy(hessian, target_T_source, source.points_m, config.degeneracy_threshold)
    information = project_information(
        config.information_scale * 0.5 * (hessian + hessian.T) / kappa, degeneracy, target_T_source
    )
    # point-to-point inlier RMSE (the back end's gate reads it): one nearest-neighbour query
    moved = source.points_m @ target_T_source[:3, :3].T + target_T_source[:3, 3]
    _, sq_dist = target.tree.batch_knn_search(moved, 1, config.num_threads)
    sq_dist = sq_dist[:, 0]
    sq_dist = sq_dist[sq_dist <= config.max_correspondence_m**2]
    inlier_rmse_m = float(np.sqrt(sq_dist.mean())) if sq_dist.size else float("nan")
    fail_if_degenerate(config, degeneracy, fitness, count)
    return RegistrationResult(
        target_T_source=target_T_source,
        fitness=fitness,
        inlier_rmse_m=inlier_rmse_m,
        correspondences=count,
        information=information,
        degeneracy=degeneracy,
        residual_sigma=float(np.sqrt(2.0 * PLANE_EPSILON * kappa)),
        final_step_m=step_m,
        final_step_rad=step_rad,
        timing_s={"icp": t1 - t0, "information": time.perf_counter() - t1},
    )


def register_gicp(
    source: Cloud | GicpFrame,
    target: Cloud | GicpFrame,
    config: GicpConfig | None = None,
    initial_target_T_source: np.ndarray | None = None,
) -> RegistrationResult:
    """:func:`register_prepared` for clouds or prepared frames: a target cloud is prepared on
    its own grid, a source cloud on the target's grid through the initial guess."""
    config = config or GicpConfig()
    init = np.eye(4) if initial_target_T_source is None else np.asarray(initial_target_T_source)
    if not isinstance(target, GicpFrame):
        target = prepare_frame(target, config)
    if not isinstance(source, GicpFrame):
        source = prepare_frame(source, config, target.grid_T_cloud @ init)
    return register_prepared(source, target, config, init)
