"""Typed configuration of the Open3D registration: the pyramid (:class:`LevelConfig`), ICP,
the robust kernel and the quality gates (:class:`RegistrationConfig`), the depth-only settings
(:class:`DepthOnlyConfig`), what the real-time front ends share with it
(:class:`ConstraintAnalysisConfig`), and its presets: :func:`thesis_registration`,
:func:`colored_registration` (the default), :func:`refined_colored_registration` and
:func:`fast_point_to_plane`."""

from __future__ import annotations

import itertools
from typing import Literal

from pydantic import Field, model_validator

from graph_slam.config import ConfigModel

Method = Literal["point_to_plane", "colored"]
Kernel = Literal["none", "huber", "tukey", "cauchy"]


class LevelConfig(ConfigModel):
    """One level of the coarse-to-fine pyramid."""

    voxel_m: float = Field(gt=0, description="voxel edge of the fixed-origin grid")
    max_correspondence_m: float = Field(gt=0, description="ICP correspondence distance")
    max_iterations: int = Field(30, gt=0, le=1000)


def _levels(voxels_m: tuple[float, ...], iterations: tuple[int, ...], corr_factor: float):
    return tuple(
        LevelConfig(voxel_m=v, max_correspondence_m=corr_factor * v, max_iterations=n)
        for v, n in zip(voxels_m, iterations, strict=True)
    )


#: The thesis's levels: Open3D's colored-ICP tutorial (4, 2, 1 cm; 50, 30, 14 iterations).
THESIS_LEVELS = _levels((0.04, 0.02, 0.01), (50, 30, 14), 1.0)


class RefineConfig(ConfigModel):
    """Optional last stage: Gauss-Newton on the same objective with per-point noise weights.

    Open3D's ICP weighs every correspondence alike; depth noise grows as ``z²`` (structured
    light and stereo), so far points get ``(z_near/z_far)⁴`` too much weight. This stage divides
    each geometric residual by ``depth_sigma_at_1m_m · z²`` (``z``: the source point's depth)
    and each photometric residual by ``color_sigma``, with a Tukey kernel at ``kernel_sigmas``.
    """

    voxel_m: float = Field(0.005, gt=0, description="its own, finer level of the pyramid")
    max_correspondence_m: float = Field(0.03, gt=0)
    max_iterations: int = Field(30, gt=0, le=1000)
    depth_sigma_at_1m_m: float = Field(0.003, gt=0, description="σ_z = this · (z / 1 m)²")
    color_sigma: float = Field(0.03, gt=0, description="intensity noise (intensity in [0, 1])")
    kernel_sigmas: float = Field(6.0, gt=0, description="Tukey k in units of σ")
    min_step: float = Field(1e-5, gt=0, description="stop when |Δξ| (rad, m) falls below this")


class ConstraintAnalysisConfig(ConfigModel):
    """The degeneracy test's settings, shared by every registration config
    (:class:`graph_slam.frontend.degeneracy.DegeneracyReport`, docs/frontend.md)."""

    degeneracy_threshold: float = Field(
        0.01,
        gt=0,
        description="normalised Hessian eigenvalue below which a direction is under-constrained",
    )
    degeneracy_min_alignment: float = Field(
        0.5,
        gt=0,
        le=1,
        description="a point-to-plane row holds a direction only when its unit-free Jacobian "
        "along it is at least this (a normal within ~60° of a translation): the noise of a "
        "plane's normals cannot make its free directions look constrained",
    )
    degeneracy_min_share: float = Field(
        0.03,
        ge=0,
        lt=1,
        description="a direction is constrained only when the rows that hold it significantly "
        "carry at least this share of the correspondences' weight (a box face: 5-8 %; the "
        "far, noisy points of a plain floor: about 1 %)",
    )
    degeneracy_min_gradient: float = Field(
        0.25,
        gt=0,
        description="a photometric row holds a direction only when the texture's intensity "
        "gradient along it is at least this (intensity in [0, 1] per metre)",
    )


class DepthOnlyConfig(ConfigModel):
    """Point-to-plane ICP for a depth-only sensor (a ToF camera such as the Pico Flexx, 1 cm
    noise at 1 m): the settings that replace the RGB-D ones when the session has no colour.

    Tuned on the simulated Pico Flexx box course (docs/frontend.md, "Depth-only sensors"):
    the RGB-D Tukey kernel (0.5 voxel = 1 cm at the 2 cm level) cuts the ToF's inliers, the
    4 cm normals of a 1 cm-noise surface tilt, and the information of the pairs that remain
    was 80 times over-confident (χ²/dof median 79)."""

    kernel_scale: float = Field(
        3.0, gt=0, description="Tukey k as a multiple of the level's voxel (RGB-D: 0.5)"
    )
    normal_radius_factor: float = Field(
        4.0, gt=0, description="normal radius / voxel_m (RGB-D: 2): smoother ToF normals"
    )
    information_scale: float = Field(
        0.035,
        gt=0,
        description="replaces RegistrationConfig.information_scale: χ²/dof median 1.01 on 50 "
        "simulated Pico Flexx pairs with the two settings above (1.20 on another session; "
        "0.025 gave 0.72, 0.14 gave 5.6)",
    )


class RegistrationConfig(ConstraintAnalysisConfig):
    """ICP registration and the gates that decide success, degeneracy or failure."""

    method: Method = Field("colored", description="point_to_plane (depth only) or colored (RGB-D)")
    levels: tuple[LevelConfig, ...] = Field(THESIS_LEVELS, description="coarse to fine")
    kernel: Kernel = Field("tukey", description="robust kernel (Open3D RobustKernel)")
    kernel_scale: float = Field(
        0.5, gt=0, description="kernel parameter k as a multiple of the level's voxel_m"
    )
    lambda_geometric: float = Field(
        0.968, ge=0, le=1, description="colored ICP: weight of the geometric term (Park 2017)"
    )
    kernel_noise_sigmas: float | None = Field(
        None,
        gt=0,
        description="noise-aware kernel: when this × the residuals' robust σ (MAD, at the "
        "finest level's solution) exceeds the finest level's k, that level is run again with "
        "it. None (default) = off: 5.5 helped simulated pairs with doubled depth noise "
        "(1.19 → 0.87 mm) but hurt the real TUM pairs (2.96 → 4.02 mm; docs/frontend.md)",
    )
    normal_radius_factor: float = Field(2.0, gt=0, description="normal radius / voxel_m")
    normal_max_nn: int = Field(30, ge=3)
    relative_fitness: float = Field(1e-6, ge=0, description="Open3D ICP stopping criterion")
    relative_rmse: float = Field(1e-6, ge=0, description="Open3D ICP stopping criterion")
    # --- quality gates (on the finest level, at the solution)
    min_points: int = Field(20, ge=3, description="fewer points in a cloud = empty")
    min_correspondences: int = Field(100, ge=6)
    min_fitness: float = Field(0.3, ge=0, le=1, description="inlier fraction of the source")
    max_final_step_m: float = Field(
        0.002,
        gt=0,
        description="a Gauss-Newton step at the solution longer than this = not converged",
    )
    max_final_step_rad: float = Field(0.004, gt=0)
    check_convergence: bool = Field(
        True,
        description="raise NOT_CONVERGED when the step at the solution exceeds the limits above; "
        "False returns Open3D's result as it is (the step is still reported: final_step_m)",
    )
    information_scale: float = Field(
        0.14,
        gt=0,
        description="multiplies JᵀWJ/σ² (correspondences are not independent): calibrated on "
        "the simulator's box course, textured and not, so that the χ² of the relative pose "
        "against the truth is near its degrees of freedom (χ²/dof median 0.57 and 1.79; "
        "docs/frontend.md)",
    )
    information_floor_m: float = Field(
        0.0,
        ge=0,
        description="covariance floor: σ per translation axis added to the solver's covariance "
        "in the constrained directions (errors the residuals do not show); 0 (default, the "
        "simulator) = none. A real camera: REAL_CAMERA_FLOOR_M (with_real_camera_floor)",
    )
    information_floor_rad: float = Field(
        0.0,
        ge=0,
        description="covariance floor: σ per rotation axis; 0 = none. A real camera: "
        "REAL_CAMERA_FLOOR_RAD",
    )
    fail_on_degenerate: bool = Field(
        False, description="raise RegistrationError(DEGENERATE) instead of returning the result"
    )
    information_min_sigma_m: float = Field(
        0.001, gt=0, description="floor of the residual sigma used to scale the information"
    )
    refine: RefineConfig | None = Field(
        None, description="noise-weighted refinement after the levels (None = off)"
    )

    @model_validator(mode="after")
    def _check_levels(self) -> RegistrationConfig:
        if not self.levels:
            raise ValueError("levels: at least one level is required")
        voxels = [level.voxel_m for level in self.levels]
        if any(b > a for a, b in itertools.pairwise(voxels)):
            raise ValueError(f"levels: voxel_m must not increase (coarse to fine), got {voxels}")
        return self

    @property
    def pyramid_voxels_m(self) -> tuple[float, ...]:
        """Voxel edge of every target pyramid level: the ICP levels, then the refinement's."""
        voxels = tuple(level.voxel_m for level in self.levels)
        return voxels if self.refine is None else (*voxels, self.refine.voxel_m)


def thesis_registration() -> RegistrationConfig:
    """The thesis (Chapter 3.4): colored ICP on 3 levels, Open3D's defaults (no robust kernel)."""
    return RegistrationConfig(method="colored", levels=THESIS_LEVELS, kernel="none")


def colored_registration() -> RegistrationConfig:
    """The default: the thesis's levels with a Tukey kernel (k = 0.5 voxel)."""
    return RegistrationConfig()


def refined_colored_registration() -> RegistrationConfig:
    """The default levels, then the depth-noise-weighted refinement at 5 mm (RGB-D)."""
    return RegistrationConfig(refine=RefineConfig())


def fast_point_to_plane(voxel_m: float = 0.02) -> RegistrationConfig:
    """Depth only, one level: point-to-plane ICP at ``voxel_m`` (2 cm), Tukey kernel."""
    return RegistrationConfig(
        method="point_to_plane",
        levels=(LevelConfig(voxel_m=voxel_m, max_correspondence_m=2 * voxel_m, max_iterations=30),),
        kernel="tukey",
        kernel_scale=1.0,
    )
