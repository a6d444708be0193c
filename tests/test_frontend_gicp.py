"""The real-time front end (GICP, small_gicp): known answers, the information matrix against a
numerical Hessian of the GICP cost, reuse of a prepared target, failures, the preset in the
pipeline config.

Scenes are the registration tests' (test_frontend_registration.py): 128×96 frames of a
textured floor and two yawed boxes, 1 mm depth noise at 1 m. Seeded; tolerances stated per test.
"""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.spatial import cKDTree
from test_frontend_registration import A, K, camera_pose, cloud_at, errors, pair

from graph_slam.config import config_from_dict
from graph_slam.errors import ConfigError, RegistrationError, RegistrationFailure
from graph_slam.frontend import Cloud, depth_to_cloud, voxel_downsample
from graph_slam.frontend.config import GicpConfig, gicp_registration, realtime_registration
from graph_slam.frontend.gicp import (
    PLANE_EPSILON,
    GicpFrame,
    prepare_frame,
    register_gicp,
    register_prepared,
)
from graph_slam.frontend.result import RegistrationStatus
from graph_slam.pipelines.config import PipelineConfig
from tests.numerics import numerical_hessian

#: 1 cm voxels on the 128×96 test frames (the preset's 2 cm are for 424×240 and up), every
#: pixel, tight convergence.
CFG = GicpConfig(
    voxel_m=0.01,
    max_correspondence_m=0.03,
    rotation_epsilon_rad=1e-6,
    translation_epsilon_m=1e-6,
    max_iterations=50,
)
SMALL = camera_pose(0.012, 0.004, 0.505, 41.0, 0.6)


def off(pose: np.ndarray, dt_m=(0.006, -0.004, 0.003), yaw_deg: float = 1.5) -> np.ndarray:
    """``pose`` moved by ``dt_m`` and yawed about its z axis: a guess 8 mm / 1.5° off."""
    out = pose.copy()
    out[:3, 3] += dt_m
    c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
    out[:3, :3] = out[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return out


# --------------------------------------------------------------------------- known answers
def test_small_motion_is_recovered_from_identity() -> None:
    target, source, truth = pair(A, SMALL, color=False)
    result = register_gicp(source, target, CFG)
    t_mm, r_deg = errors(result.target_T_source, truth)
    assert t_mm < 0.5 and r_deg < 0.05  # measured 0.13 mm, 0.006°
    assert result.fitness > 0.8 and result.correspondences > 5000
    assert result.inlier_rmse_m < 0.01  # point to point between 1 cm voxel means: 7 mm


def test_swing_jump_with_a_guess_8_mm_and_1p5_deg_off() -> None:
    target, source, truth = pair(A, camera_pose(0.045, 0.015, 0.52, 50.0, 2.0), color=False)
    guess = off(truth)
    assert errors(guess, truth)[0] > 7.0
    result = register_gicp(source, target, CFG, guess)
    t_mm, r_deg = errors(result.target_T_source, truth)
    assert t_mm < 1.0 and r_deg < 0.1


def test_the_preset_itself() -> None:
    """The GICP preset (``realtime-gicp``: 2 cm voxels; no decimation at 128×96) on the same
    pair, RGB-D."""
    target, source, truth = pair(A, SMALL)
    config = gicp_registration()
    assert config.pixel_step_for(K) == 1  # 12k pixels, below the preset's 100k
    result = register_gicp(source, target, config)
    t_mm, r_deg = errors(result.target_T_source, truth)
    assert t_mm < 1.0 and r_deg < 0.1


def test_colour_holds_a_textured_floor_that_geometry_leaves_free() -> None:
    """RGB-D: the photometric stage registers a textured floor slid 3 cm sideways, which GICP
    alone reports as degenerate (and cannot recover)."""
    world_T_a = camera_pose(0.0, 0.0, 0.5, 40.0)
    world_T_b = camera_pose(0.004, 0.03, 0.5, 40.0)
    target, source = cloud_at(world_T_a, boxes=()), cloud_at(world_T_b, boxes=(), seed=3)
    truth = np.linalg.solve(world_T_a, world_T_b)
    guess = off(truth, (0.006, -0.004, 0.0), 0.5)
    result = register_gicp(source, target, CFG, guess)
    t_mm, r_deg = errors(result.target_T_source, truth)
    assert t_mm < 1.0 and r_deg < 0.1
    assert result.status is RegistrationStatus.OK
    geometry = register_gicp(Cloud(source.points_m), Cloud(target.points_m), CFG, guess)
    assert geometry.status is RegistrationStatus.DEGENERATE


def test_colour_on_the_box_scene_with_a_guess_off() -> None:
    target, source, truth = pair(A, camera_pose(0.045, 0.015, 0.52, 50.0, 2.0))
    result = register_gicp(source, target, CFG, off(truth))
    t_mm, r_deg = errors(result.target_T_source, truth)
    assert t_mm < 1.0 and r_deg < 0.1
    assert result.is_reliable


# --------------------------------------------------------------------------- information
def _gicp_cost(source: GicpFrame, target: GicpFrame, solution: np.ndarray, max_m: float):
    """``E(ξ) = ½ Σ rᵢᵀ (C_Bᵢ + R C_Aᵢ Rᵀ)⁻¹ rᵢ`` with ``rᵢ = bᵢ − T·Exp(ξ)·aᵢ`` (GTSAM's
    Expmap, right perturbation), correspondences fixed at the solution (nearest neighbour
    within ``max_m``), as small_gicp's GICP factor defines it."""
    a_pts, b_pts = source.points_m, target.points_m
    cov_a = np.array(source.cloud.covs())[:, :3, :3]
    cov_b = np.array(target.cloud.covs())[:, :3, :3]
    moved = a_pts @ solution[:3, :3].T + solution[:3, 3]
    dist, nearest = cKDTree(b_pts).query(moved)
    ia = np.flatnonzero(dist <= max_m)
    ib = nearest[ia]

    def cost(xi: np.ndarray) -> float:
        pose = solution @ gtsam.Pose3.Expmap(xi).matrix()
        rot = pose[:3, :3]
        r = b_pts[ib] - (a_pts[ia] @ rot.T + pose[:3, 3])
        m = np.linalg.inv(cov_b[ib] + rot @ cov_a[ia] @ rot.T)
        return 0.5 * float(np.einsum("ni,nij,nj->", r, m, r))

    return cost, len(ia)


def _numerical_hessian(cost, step: float = 1e-4) -> np.ndarray:
    return numerical_hessian(cost, step)


@pytest.mark.parametrize("floor_sigma", [False, True], ids=["residual_scale", "floored"])
def test_information_is_the_gicp_hessian_in_gtsam_tangent_space(floor_sigma: bool) -> None:
    """information = ∂²E/∂ξ² / κ, ξ = (ω, t) a right perturbation (GTSAM order), κ the
    residual scale ``2E / (3 n)`` or its floor. Measured relative Frobenius error 0.2 %."""
    config = CFG.model_copy(update={"information_min_sigma_m": 0.02 if floor_sigma else 1e-6})
    target_cloud, source_cloud, _ = pair(A, SMALL, color=False)
    target = prepare_frame(target_cloud, config)
    source = prepare_frame(source_cloud, config, target.grid_T_cloud)
    result = register_prepared(source, target, config)
    cost, count = _gicp_cost(source, target, result.target_T_source, config.max_correspondence_m)
    assert abs(count - result.correspondences) <= 0.01 * count
    kappa = 2.0 * cost(np.zeros(6)) / (3.0 * count)
    kappa_floor = config.information_min_sigma_m**2 / (2.0 * PLANE_EPSILON)
    assert (kappa_floor > kappa) is floor_sigma
    expected = _numerical_hessian(cost) / max(kappa, kappa_floor)
    rel = np.linalg.norm(result.information - expected) / np.linalg.norm(expected)
    assert rel < 0.05, rel
    np.testing.assert_allclose(result.information, result.information.T)
    if not result.degeneracy.is_degenerate:  # else zero along the free directions
        assert np.all(np.linalg.eigvalsh(result.information) > 0)
    assert result.residual_sigma == pytest.approx(np.sqrt(2 * PLANE_EPSILON * max(kappa, kappa_floor)), rel=0.01)  # fmt: skip


def test_a_left_perturbation_hessian_would_not_match() -> None:
    """The check above can tell the conventions apart: the same cost perturbed on the left
    (``Exp(ξ)·T``) differs from the information by far more than 5 %."""
    target_cloud, source_cloud, truth = pair(A, SMALL, color=False)
    moved_T_target = off(np.eye(4), (0.8, -0.5, 0.3), 40.0)  # far from identity
    target_cloud = Cloud(target_cloud.points_m @ moved_T_target[:3, :3].T + moved_T_target[:3, 3])
    target = prepare_frame(target_cloud, CFG)
    guess = moved_T_target @ truth
    source = prepare_frame(source_cloud, CFG, target.grid_T_cloud @ guess)
    result = register_prepared(source, target, CFG, guess)
    solution = result.target_T_source
    cost, _ = _gicp_cost(source, target, solution, CFG.max_correspondence_m)

    def cost_left(xi: np.ndarray) -> float:
        # T' = Exp(ξ)·T = T·Exp(Ad_T⁻¹ ξ)
        return cost(np.linalg.solve(gtsam.Pose3(solution).AdjointMap(), xi))

    left, right = _numerical_hessian(cost_left), _numerical_hessian(cost)
    info_dir = result.information / np.linalg.norm(result.information)
    assert np.linalg.norm(info_dir - right / np.linalg.norm(right)) < 0.05
    assert np.linalg.norm(info_dir - left / np.linalg.norm(left)) > 0.2


# --------------------------------------------------------------------------- prepared frames
def test_a_prepared_target_is_reused_unchanged() -> None:
    """Registering against a frame prepared earlier (and already used as a source) gives
    exactly what preparing it again gives."""
    c0, c1, c2 = (cloud_at(p, seed=s, color=False) for s, p in enumerate(
        (A, SMALL, camera_pose(0.02, 0.01, 0.51, 42.0, 1.0))))  # fmt: skip
    p0 = prepare_frame(c0, CFG)
    p1 = prepare_frame(c1, CFG, p0.grid_T_cloud)
    first = register_prepared(p1, p0, CFG)  # p1 as a source
    guess = first.target_T_source
    p2 = prepare_frame(c2, CFG, p1.grid_T_cloud @ guess)
    reused = register_prepared(p2, p1, CFG, guess)  # p1 as the target, as kept
    fresh = register_prepared(p2, prepare_frame(c1, CFG, p0.grid_T_cloud), CFG, guess)
    np.testing.assert_array_equal(reused.target_T_source, fresh.target_T_source)
    np.testing.assert_array_equal(reused.information, fresh.information)
    assert reused.correspondences == fresh.correspondences


def test_voxels_are_on_the_fixed_grid_through_grid_T_cloud() -> None:
    """small_gicp's voxel means equal the house's fixed-origin ``voxel_downsample``."""
    cloud = cloud_at(A, color=False)
    grid_T_cloud = off(np.eye(4), (0.0037, -0.0051, 0.0023), 7.0)
    ours = prepare_frame(cloud, CFG, grid_T_cloud).points_m
    house = voxel_downsample(cloud, CFG.voxel_m, grid_T_cloud).points_m
    assert len(ours) == len(house)
    dist, index = cKDTree(house).query(ours)
    assert dist.max() < 1e-12 and len(set(index)) == len(house)


def test_depth_decimation_keeps_every_nth_pixel() -> None:
    frame = _frame()
    full, counts = depth_to_cloud(frame, K)
    half, half_counts = depth_to_cloud(frame, K, pixel_step=2)
    assert half_counts.pixels == (K.height_px // 2) * (K.width_px // 2)
    assert half_counts.kept < counts.kept
    tree = cKDTree(full.points_m)
    dist, _ = tree.query(half.points_m)
    assert dist.max() < 1e-12  # a subset of the full cloud's points
    np.testing.assert_allclose(half.colors, full.colors[tree.query(half.points_m)[1]])


def _frame():
    from test_frontend_registration import BOXES
    from test_frontend_registration import CFG as SCFG

    from graph_slam.session.synthetic import render_frame

    rng = np.random.default_rng(0)
    phases = np.random.default_rng(99).uniform(0, 2 * np.pi, (3, 4))
    return render_frame(SCFG, A, 0.0, 0, rng, phases, BOXES)


# --------------------------------------------------------------------------- failures
def test_empty_clouds_fail_with_their_reason() -> None:
    cloud = cloud_at(A, color=False)
    empty = Cloud(np.zeros((0, 3)))
    with pytest.raises(RegistrationError) as err:
        register_gicp(empty, cloud, CFG)
    assert err.value.reason is RegistrationFailure.EMPTY_SOURCE
    with pytest.raises(RegistrationError) as err:
        register_gicp(cloud, Cloud(cloud.points_m[:5]), CFG)
    assert err.value.reason is RegistrationFailure.EMPTY_TARGET


def test_no_overlap_fails_instead_of_returning_the_guess() -> None:
    target, source, _ = pair(A, SMALL, color=False)
    far = Cloud(source.points_m + np.array([5.0, 0.0, 0.0]))
    with pytest.raises(RegistrationError) as err:
        register_gicp(far, target, CFG)
    assert err.value.reason is RegistrationFailure.NO_OVERLAP
    assert err.value.correspondences == 0


def test_little_overlap_fails_on_correspondences_or_fitness() -> None:
    target, source, _ = pair(A, SMALL, color=False)
    sliver = Cloud(source.points_m[source.points_m[:, 0] > 0.25])
    with pytest.raises(RegistrationError) as err:
        register_gicp(sliver, target, CFG.model_copy(update={"min_correspondences": 5000}))
    assert err.value.reason is RegistrationFailure.TOO_FEW_CORRESPONDENCES
    shifted = Cloud(source.points_m + np.array([0.4, 0.0, 0.0]))
    with pytest.raises(RegistrationError) as err:
        register_gicp(shifted, target, CFG.model_copy(update={"max_iterations": 3}))
    assert err.value.reason in (RegistrationFailure.LOW_FITNESS, RegistrationFailure.NOT_CONVERGED)


def test_running_out_of_iterations_is_not_converged() -> None:
    target, source, truth = pair(A, camera_pose(0.045, 0.015, 0.52, 50.0, 2.0), color=False)
    config = CFG.model_copy(update={"max_iterations": 1})
    with pytest.raises(RegistrationError) as err:
        register_gicp(source, target, config, off(truth))
    assert err.value.reason is RegistrationFailure.NOT_CONVERGED
    loose = config.model_copy(update={"check_convergence": False})
    assert register_gicp(source, target, loose, off(truth)).final_step_m > 1e-4


def test_flat_floor_sliding_sideways_is_degenerate() -> None:
    """Geometry alone cannot see a floor slide: reported DEGENERATE along the floor (or, with
    ``fail_on_degenerate``, raised), never a confident zero motion."""
    world_T_a = camera_pose(0.0, 0.0, 0.5, 40.0)
    world_T_b = camera_pose(0.0, 0.03, 0.5, 40.0)  # 3 cm sideways
    target, source = cloud_at(world_T_a, boxes=(), color=False), cloud_at(world_T_b, boxes=(), seed=3, color=False)  # fmt: skip
    result = register_gicp(source, target, CFG)
    assert result.status is RegistrationStatus.DEGENERATE
    assert result.degeneracy.weak.sum() >= 2
    sideways = np.linalg.solve(world_T_a, world_T_b)[:3, 3]
    stiffness = result.degeneracy.stiffness(translation=sideways / np.linalg.norm(sideways))
    assert stiffness < CFG.degeneracy_threshold
    with pytest.raises(RegistrationError) as err:
        register_gicp(source, target, CFG.model_copy(update={"fail_on_degenerate": True}))
    assert err.value.reason is RegistrationFailure.DEGENERATE


# --------------------------------------------------------------------------- config
def test_registration_presets_by_name() -> None:
    cfg = config_from_dict(PipelineConfig, {"graph": {"registration": "realtime"}})
    assert cfg.graph.registration == realtime_registration()
    assert PipelineConfig.model_validate(cfg.model_dump(mode="json")) == cfg  # YAML round trip
    accurate = config_from_dict(PipelineConfig, {"graph": {"registration": "accurate"}})
    assert accurate.graph.registration == PipelineConfig(preset="accurate").graph.registration
    assert PipelineConfig().graph.registration == realtime_registration()  # the default
    thesis = config_from_dict(PipelineConfig, {"graph": {"registration": "thesis"}})
    assert len(thesis.graph.registration.levels) == 3
    custom = {"graph": {"registration": {"method": "gicp", "voxel_m": 0.03}}}
    assert config_from_dict(PipelineConfig, custom).graph.registration.voxel_m == 0.03
    with pytest.raises(ConfigError, match="unknown registration preset 'fast'"):
        config_from_dict(PipelineConfig, {"graph": {"registration": "fast"}})
