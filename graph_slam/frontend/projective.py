"""The real-time front end without nearest-neighbour searches: organised normals, projective
data association, colored ICP's objective by Gauss-Newton (loops compiled).

``prepare_depth(frame, intrinsics, config, cloud_config, grid_T_cloud)`` turns a frame into a
:class:`DepthFrame`, once:

* the depth image decimated by ``pixel_step`` is back-projected as an *organised* image;
* per pixel, the tangents are central differences of the neighbouring pixels' points,
  ``∂P/∂u ≈ P(u+1) − P(u−1)`` and ``∂P/∂v``; the normal is their cross product and the
  intensity gradient in the tangent plane solves ``d·∂P/∂u = ∂I/∂u``, ``d·∂P/∂v = ∂I/∂v``,
  ``d·n = 0`` (pixels next to a depth jump, or a missing neighbour, get none);
* voxel means on the house's fixed-origin grid (the keys of
  :func:`graph_slam.frontend.cloud.voxel_index`, ``grid_T_cloud`` as for the other presets):
  mean point, colour, intensity gradient, and the normal of the summed (area-weighted) cross
  products — an unbiased sum, since the two differences share no pixel; voxels without a
  normal are dropped;
* the map ``pixel → voxel row`` (−1: none), which makes the frame a target.

``register_depth(source, target, config, guess)``: Gauss-Newton on colored ICP's objective
(point-to-plane and intensity rows, ``λ`` / ``1 − λ``, Tukey kernel: the accurate preset's,
Open3D's, Park et al. 2017) with **projective data association**: each source voxel mean,
moved by the current estimate, is projected into the target's decimated image; its
correspondence is the target voxel of the pixel it lands on, kept when within
``max_correspondence_m`` and when the normals agree within ``max_normal_angle_deg``
(KinectFusion, DVO). Every pass is O(N), its loops compiled
(:mod:`graph_slam.frontend.kernels`); the quality report and the information are the accurate
path's (:mod:`graph_slam.frontend.registration`), from the last iteration's rows. See
docs/frontend.md, "The real-time preset".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from graph_slam.errors import RecordError, RegistrationFailure
from graph_slam.frontend import kernels
from graph_slam.frontend.config import CloudConfig, ProjectiveConfig
from graph_slam.frontend.objective import (
    Rows,
    analyse,
    exp_left,
    rows_information,
    unit_system,
)
from graph_slam.frontend.result import (
    RegistrationResult,
    conclude,
    gate_correspondences,
    registration_failure,
    start_pose,
)
from graph_slam.session.checks import check_pose
from graph_slam.session.records import CameraIntrinsics, RgbdFrame

_NO_COLOR = np.zeros((1, 1, 3), np.uint8)  # the kernels' placeholder for "no colour image"
_NO_INTENSITY = np.zeros((0, 0))
_NO_VALUES, _NO_POINTS = np.zeros(0), np.zeros((0, 3))


@dataclass(frozen=True, eq=False)
class DepthFrame:
    """A frame prepared for projective registration, as source and as target.

    ``points_m``, ``normals`` (unit, towards the camera), ``intensity`` (mean of RGB in [0, 1];
    None for depth only) and ``gradients`` (3D intensity gradients in the tangent plane):
    per voxel, M rows, in the frame's own camera frame. ``pixel_voxel``: h×w (the decimated
    image) row of the voxel each pixel fell in, −1 for none; ``pixel_points_m``: the valid
    pixels' points (the decimated cloud, e.g. for the floor fit). ``fx, fy, cx, cy``: the decimated
    image's intrinsics. ``timing_s``: ``cloud`` (organised points), ``normals`` (normals and
    gradients), ``voxel``.
    """

    points_m: np.ndarray
    normals: np.ndarray
    intensity: np.ndarray | None
    gradients: np.ndarray | None
    pixel_voxel: np.ndarray
    pixel_points_m: np.ndarray  # the valid pixels' points (the frame's cloud), K×3
    camera: tuple[float, float, float, float]  # fx, fy, cx, cy of the decimated image
    grid_T_cloud: np.ndarray
    voxel_m: float
    timing_s: dict[str, float] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.points_m.shape[0])


def organized_points(
    depth_m: np.ndarray, camera: tuple[float, float, float, float], config: CloudConfig
) -> tuple[np.ndarray, np.ndarray]:
    """The back-projected points of a depth image as 3 component planes (3×h×w; invalid
    pixels hold zeros) and the mask of valid, in-range pixels."""
    planes, valid, _, _, _ = kernels.organize(
        depth_m, 1, *camera, config.min_depth_m, config.max_depth_m, _NO_COLOR, False
    )
    return planes, valid


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
    (``d·∂P/∂u = ∂I/∂u``, ``d·∂P/∂v = ∂I/∂v``, ``d·n = 0``; zero where undefined)."""
    has = intensity is not None
    normals, defined, grads = kernels.pixel_normals(
        planes, valid, float(max_jump_ratio), intensity if has else _NO_INTENSITY, has
    )
    return normals, defined, grads if has else None


@dataclass(frozen=True, eq=False)
class OrganisedDepth:
    """The part of :func:`prepare_depth` that depends on the frame alone — the organised
    points, normals and intensity gradients, not the grid — so it can be done before the
    frame's guess is known (the live loop does it on the thread that decodes the frame).
    ``depth_m`` / ``color_rgb``: the frame's own arrays it was made from (:meth:`fits`)."""

    depth_m: np.ndarray
    color_rgb: np.ndarray | None
    color: bool  # the intensity was used
    step: int
    camera: tuple[float, float, float, float]
    valid: np.ndarray
    pts: np.ndarray
    rows: np.ndarray
    intensity: np.ndarray
    normals: np.ndarray
    defined: np.ndarray
    grads: np.ndarray
    timing_s: dict[str, float]

    def fits(self, frame: RgbdFrame, color: bool) -> bool:
        """Made from this frame's arrays (the same objects), with the intensity or not."""
        return (
            self.depth_m is frame.depth_m
            and self.color == color
            and (not color or self.color_rgb is frame.color_rgb)
        )


def uses_color(frame: RgbdFrame, config: ProjectiveConfig, use_color: bool) -> bool:
    """Whether :func:`prepare_depth` uses the frame's intensity."""
    return use_color and config.photometric and frame.color_rgb is not None


def organise_depth(
    frame: RgbdFrame,
    intrinsics: CameraIntrinsics,
    config: ProjectiveConfig,
    cloud_config: CloudConfig | None = None,
    use_color: bool = True,
) -> OrganisedDepth:
    """The frame-only part of :func:`prepare_depth` (:class:`OrganisedDepth`)."""
    cloud_config = cloud_config or CloudConfig()
    if frame.depth_m.shape != intrinsics.shape_hw:
        raise RecordError(
            f"RgbdFrame[{frame.index}].depth_m: shape {frame.depth_m.shape} does not match the "
            f"intrinsics {intrinsics.shape_hw} (height, width)"
        )
    step = config.pixel_step_for(intrinsics)
    t0 = time.perf_counter()
    camera = (
        intrinsics.fx_px / step,
        intrinsics.fy_px / step,
        intrinsics.cx_px / step,
        intrinsics.cy_px / step,
    )
    color = uses_color(frame, config, use_color)
    planes, valid, pts, rows, intensity = kernels.organize(
        frame.depth_m, step, *camera, cloud_config.min_depth_m, cloud_config.max_depth_m,
        frame.color_rgb if color else _NO_COLOR, color,
    )  # fmt: skip
    t1 = time.perf_counter()
    ns = config.normal_step  # normals at every ns-th pixel, differences over ±ns pixels
    sub = intensity[::ns, ::ns] if color else _NO_INTENSITY
    normals, defined, grads = kernels.pixel_normals(
        planes[:, ::ns, ::ns], valid[::ns, ::ns], config.max_jump_ratio * ns, sub, color
    )
    timing = {"cloud": t1 - t0, "normals": time.perf_counter() - t1}
    return OrganisedDepth(frame.depth_m, frame.color_rgb, color, step, camera, valid, pts, rows,
                          intensity, normals, defined, grads, timing)  # fmt: skip


def prepare_depth(
    frame: RgbdFrame,
    intrinsics: CameraIntrinsics,
    config: ProjectiveConfig,
    cloud_config: CloudConfig | None = None,
    grid_T_cloud: np.ndarray | None = None,
    use_color: bool = True,
    organised: OrganisedDepth | None = None,
) -> DepthFrame:
    """Prepare ``frame`` once (see the module doc): organised points, normals and intensity
    gradients, voxel means on the grid fixed in frame ``grid`` (``grid_T_cloud``: the frame's
    own by default), and the pixel → voxel map. The loops are compiled
    (:mod:`graph_slam.frontend.kernels`). ``organised``: the frame-only part already done
    (:func:`organise_depth`; used when it :meth:`~OrganisedDepth.fits` the frame, the same
    arrays as it would compute; else computed here)."""
    grid_T_cloud = np.eye(4) if grid_T_cloud is None else np.asarray(grid_T_cloud, dtype=float)
    check_pose("prepare_depth", "grid_T_cloud", grid_T_cloud)
    color = uses_color(frame, config, use_color)
    ahead = organised is not None and organised.fits(frame, color)
    if not ahead:
        organised = organise_depth(frame, intrinsics, config, cloud_config, use_color)
    o = organised
    t2 = time.perf_counter()
    points, unit, voxel_intensity, voxel_grads, pixel_voxel, outside = kernels.voxel_means(
        o.pts, o.rows, o.valid.shape, grid_T_cloud, config.voxel_m, o.normals, o.defined,
        o.grads, o.intensity, color, config.normal_step, config.min_pixel_normals,
    )  # fmt: skip
    if outside:
        raise RecordError(
            f"RgbdFrame[{frame.index}]: a point lies more than {kernels.KEY_OFFSET} voxels of "
            f"{config.voxel_m} m from the grid origin; the voxel key cannot hold it"
        )
    timing = {"cloud": 0.0, "normals": 0.0} if ahead else dict(o.timing_s)
    timing["voxel"] = time.perf_counter() - t2
    return DepthFrame(
        points_m=points,
        normals=unit,
        intensity=voxel_intensity if color else None,
        gradients=voxel_grads if color else None,
        pixel_voxel=pixel_voxel,
        pixel_points_m=o.pts,
        camera=o.camera,
        grid_T_cloud=grid_T_cloud,
        voxel_m=config.voxel_m,
        timing_s=timing,
    )


def associate(
    source: DepthFrame, target: DepthFrame, target_T_source: np.ndarray, config: ProjectiveConfig
) -> np.ndarray:
    """K×2 (source row, target row): each source voxel mean moved by ``target_T_source`` and
    projected into the target's image; the target voxel of that pixel, kept within
    ``max_correspondence_m`` and ``max_normal_angle_deg``."""
    return associated_rows(source, target, target_T_source, config)[0]


def associated_rows(
    source: DepthFrame, target: DepthFrame, target_T_source: np.ndarray, config: ProjectiveConfig
) -> tuple[np.ndarray, Rows]:
    """The correspondences (:func:`associate`) and colored ICP's rows at them (as
    :func:`graph_slam.frontend.objective.cloud_rows`, which takes clouds): point-to-plane
    ``√λ · n·(q − p)`` and, with intensities on both frames, ``√(1−λ) · (I_s − (I_t +
    d·(q_proj − p)))``; Jacobian for a left perturbation about the target origin; Tukey
    weights at ``kernel_scale · voxel_m``. One compiled pass
    (:func:`graph_slam.frontend.kernels.projective_rows`)."""
    color = source.intensity is not None and target.intensity is not None
    geo = float(np.sqrt(config.lambda_geometric)) if color else 1.0
    pho = float(np.sqrt(1.0 - config.lambda_geometric)) if color else 0.0
    corr, r, jac, q = kernels.projective_rows(
        source.points_m, source.normals,
        source.intensity if color else _NO_VALUES, target.points_m, target.normals,
        target.intensity if color else _NO_VALUES, target.gradients if color else _NO_POINTS,
        target.pixel_voxel, target.camera, np.ascontiguousarray(target_T_source, dtype=float),
        config.max_correspondence_m, float(np.cos(np.deg2rad(config.max_normal_angle_deg))),
        color, geo, pho,
    )  # fmt: skip
    w = kernels.tukey_weights(r, float(config.kernel_scale * config.voxel_m))
    return corr, Rows(r, jac, w, q, np.full(len(q), geo), len(q), pho)


_fail = registration_failure


def _gate(config: ProjectiveConfig, corr: np.ndarray, n_source: int) -> None:
    count, fitness = len(corr), len(corr) / n_source
    if count == 0:
        raise _fail(
            RegistrationFailure.NO_OVERLAP,
            f"no source point projects onto a target voxel within {config.max_correspondence_m} m",
            0.0,
            0,
        )
    gate_correspondences(config, fitness, count)


def register_depth(
    source: DepthFrame,
    target: DepthFrame,
    config: ProjectiveConfig,
    initial_target_T_source: np.ndarray | None = None,
) -> RegistrationResult:
    """Gauss-Newton on colored ICP's objective (point-to-plane only without colours) with
    projective association, re-associated every iteration, steps restricted to the
    well-constrained directions (the accurate path's ``analyse``). The information is
    ``JᵀWJ / σ²`` at the solution in the house's convention (rotation first, right
    perturbation in the source frame), σ the weighted rms residual floored at
    ``information_min_sigma_m``. Raises :class:`RegistrationError` on failure."""
    init = start_pose("register_depth", source, target, config, initial_target_T_source)
    t0 = time.perf_counter()
    target_T_source = init
    for iteration in range(config.max_iterations + 1):
        corr, rows = associated_rows(source, target, target_T_source, config)
        _gate(config, corr, len(source))
        system = unit_system(rows)
        step = system.step(config.degeneracy_threshold)
        # converged: this pose is the solution, its rows the final ones (the step, below
        # min_step, is reported and not taken); else at most max_iterations steps
        if np.linalg.norm(step) < config.min_step:
            break
        if iteration == config.max_iterations:
            break
        target_T_source = exp_left(step) @ target_T_source
        if not np.isfinite(target_T_source).all():
            raise _fail(RegistrationFailure.NUMERICAL, "non-finite transform")
    # the solution's report, with the significance test (its system: the last iteration's)
    analysis = analyse(rows, config, system=system)
    t1 = time.perf_counter()
    information, sigma = rows_information(
        rows, target_T_source, config.information_min_sigma_m, analysis.degeneracy,
        config.information_scale, floor_m=config.information_floor_m,
        floor_rad=config.information_floor_rad,
    )  # fmt: skip
    gap = rows.q - target.points_m[corr[:, 1]]
    return conclude(
        target_T_source, analysis, information, sigma, len(corr) / len(source), len(corr),
        float(np.sqrt(np.mean(np.sum(gap**2, axis=1)))), config,
        {"icp": t1 - t0, "information": time.perf_counter() - t1},
    )  # fmt: skip
