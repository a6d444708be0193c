"""Typed configuration of the real-time front ends, each frame prepared once on a fixed-origin
voxel grid (:class:`PreparedFrameConfig`): small_gicp's GICP (:class:`GicpConfig`,
:func:`gicp_registration`; :mod:`graph_slam.frontend.gicp`) and the projective front end
(:class:`ProjectiveConfig`, :func:`realtime_registration`, the real-time preset;
:mod:`graph_slam.frontend.projective`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from graph_slam.frontend.registration_config import ConstraintAnalysisConfig


class PreparedFrameConfig(ConstraintAnalysisConfig):
    """What the real-time front ends share: a frame prepared once on a fixed-origin voxel grid
    from a decimated depth image, colored ICP's objective, and the accurate path's quality
    gates (as :class:`RegistrationConfig`'s)."""

    pixel_step: int | None = Field(
        None,
        ge=1,
        le=16,
        description="use every n-th depth row and column; None: the step that leaves about "
        "target_pixels pixels",
    )
    target_pixels: int = Field(25_000, ge=100, description="see pixel_step")
    voxel_m: float = Field(0.02, gt=0, description="voxel edge of the fixed-origin grid")
    lambda_geometric: float = Field(0.968, ge=0, le=1, description="as RegistrationConfig's")
    kernel_scale: float = Field(0.5, gt=0, description="Tukey k as a multiple of voxel_m")
    min_points: int = Field(20, ge=3, description="fewer prepared points in a frame = empty")
    min_correspondences: int = Field(100, ge=6)
    min_fitness: float = Field(0.3, ge=0, le=1, description="inlier fraction of the source")
    max_final_step_m: float = Field(
        0.002, gt=0, description="a longer Gauss-Newton step at the solution = not converged"
    )
    max_final_step_rad: float = Field(0.004, gt=0)
    check_convergence: bool = Field(True)
    information_scale: float = Field(
        1.0,
        gt=0,
        description="multiplies the information (1.0: GICP's is not calibrated; the projective "
        "preset's is, below)",
    )
    fail_on_degenerate: bool = Field(False)
    information_min_sigma_m: float = Field(
        0.001,
        gt=0,
        description="floor of the residual sigma (along the surface normal) that scales the "
        "information",
    )

    def pixel_step_for(self, intrinsics) -> int:
        """The depth decimation step for a camera (``pixel_step``, or the automatic one)."""
        if self.pixel_step is not None:
            return self.pixel_step
        pixels = intrinsics.width_px * intrinsics.height_px
        return max(1, round((pixels / self.target_pixels) ** 0.5))


class GicpConfig(PreparedFrameConfig):
    """The real-time front end: GICP (small_gicp) on one fixed-grid voxel scale.

    Every frame is prepared once (:func:`graph_slam.frontend.gicp.prepare_frame`): the
    depth image decimated by ``pixel_step``, voxel means on a fixed grid, per-point covariances
    from ``covariance_neighbors`` neighbours, a k-d tree; it is the source of this frame's
    registration and, unchanged, the target of the next one. One scale: the initial guess
    (the graph's IMU prediction, or constant velocity) must be within about
    ``max_correspondence_m``.
    """

    method: Literal["gicp"] = Field("gicp", description="selects this config type")
    target_pixels: int = Field(100_000, ge=100, description="see pixel_step")
    covariance_neighbors: int = Field(10, ge=5, le=100, description="k of each covariance")
    max_correspondence_m: float = Field(
        0.08, gt=0, description="GICP correspondence distance (reach of the initial guess)"
    )
    max_iterations: int = Field(20, gt=0, le=1000)
    rotation_epsilon_rad: float = Field(
        2e-3, gt=0, description="GICP converged when a step rotates less than this and ..."
    )
    translation_epsilon_m: float = Field(1e-3, gt=0, description="... moves less than this")
    num_threads: int = Field(1, ge=1, le=64, description="small_gicp's OpenMP threads")
    # --- photometric refinement (RGB-D): colored ICP's objective after GICP
    photometric: bool = Field(
        True,
        description="when both frames have colours, refine GICP's result on colored ICP's "
        "objective (point-to-plane + intensity, Park 2017): geometry alone leaves a floor's "
        "slide free",
    )
    photometric_max_correspondence_m: float = Field(0.04, gt=0)
    color_neighbors: int = Field(8, ge=4, le=50, description="k of each intensity gradient")
    refine_iterations: int = Field(5, ge=1, le=100)
    refine_min_step: float = Field(1e-4, gt=0, description="stop when |Δξ| (rad, m) is below")
    check_convergence: bool = Field(
        True,
        description="raise NOT_CONVERGED when max_iterations ran out before the epsilons (the "
        "photometric stage: when its last step is longer than max_final_step_*)",
    )


def gicp_registration() -> GicpConfig:
    """GICP (small_gicp) on 2 cm voxels of about 100k depth pixels (every pixel at 424×240,
    every 2nd at 848×480), then the photometric stage; one thread (the first real-time
    preset, kept as ``realtime-gicp``)."""
    return GicpConfig()


class ProjectiveConfig(PreparedFrameConfig):
    """The real-time front end without nearest-neighbour searches
    (:mod:`graph_slam.frontend.projective`).

    Every frame is prepared once from its organised depth image: normals and intensity
    gradients from neighbouring pixels, averaged per voxel of the fixed-origin grid; the
    registration associates projectively (a source voxel mean projected into the target's
    image takes that pixel's voxel) and runs Gauss-Newton on colored ICP's objective
    (point-to-plane only without colours). One scale: the initial guess (the graph's IMU
    prediction) must be within about ``max_correspondence_m``.
    """

    method: Literal["projective"] = Field("projective", description="selects this config type")
    target_pixels: int = Field(25_000, ge=100, description="see pixel_step")
    normal_step: int = Field(
        1,
        ge=1,
        le=8,
        description="pixel normals (and intensity gradients) at every n-th pixel of the "
        "decimated image, from its neighbours ±n pixels away",
    )
    max_jump_ratio: float = Field(
        0.025,
        gt=0,
        description="no pixel normal where two neighbours one pixel apart would differ in depth "
        "by more than this × z (scaled by the distance between the neighbours used)",
    )
    min_pixel_normals: int = Field(
        2, ge=1, description="a voxel with fewer pixel normals is dropped (no defined normal)"
    )
    max_correspondence_m: float = Field(
        0.04, gt=0, description="a correspondence's point-to-point distance (the guess's reach)"
    )
    max_normal_angle_deg: float = Field(
        45.0, gt=0, le=180, description="a correspondence's normals agree within this"
    )
    max_iterations: int = Field(
        30, gt=0, le=1000, description="a cap: from the IMU guess 2–4 iterations are typical"
    )
    min_step: float = Field(1e-4, gt=0, description="stop when |Δξ| (rad, m) is below this")
    information_scale: float = Field(
        0.22,
        gt=0,
        description="multiplies JᵀWJ/σ² (calibrated on the simulator's box course, textured "
        "and not: χ²/dof median 0.56 and 1.47; docs/frontend.md)",
    )
    information_floor_m: float = Field(
        0.0, ge=0, description="covariance floor per translation axis, as RegistrationConfig's"
    )
    information_floor_rad: float = Field(
        0.0, ge=0, description="covariance floor per rotation axis, as RegistrationConfig's"
    )
    photometric: bool = Field(
        True,
        description="with colours on both frames, colored ICP's objective (point-to-plane + "
        "intensity, Park 2017); otherwise point-to-plane",
    )


def realtime_registration() -> ProjectiveConfig:
    """The real-time preset: organised normals, projective association, colored ICP's
    objective on 2 cm voxels of about 25k depth pixels (every 2nd pixel at 424×240, every 4th
    at 848×480); no nearest-neighbour search."""
    return ProjectiveConfig()
