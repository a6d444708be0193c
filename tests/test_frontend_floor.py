"""The floor plane for the stride anchor's tilt: known-answer fits on synthetic clouds (a tilted
floor with boxes and depth noise), every failure reported with its reason, the fusion of two
up vectors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graph_slam.errors import ConfigError
from graph_slam.frontend.floor import FloorConfig, fit_floor, fuse_up


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(axis, float) * angle).as_matrix()


def floor_scene(rng, camera_R_world, height_m=0.6, noise_m=0.002, boxes=True, wall=False):
    """Points (camera frame) of a level floor 1.2 × 1.5 m ahead of the camera, two boxes on it
    (tops and faces), optionally a wall; z-up world frame with the camera at height_m."""
    pts = [
        np.column_stack(
            [rng.uniform(0.3, 1.8, 20000), rng.uniform(-0.6, 0.6, 20000), np.zeros(20000)]
        )
    ]
    if boxes:
        for x0, w, h in [(0.9, 0.3, 0.19), (1.4, 0.25, 0.08)]:
            top = np.column_stack(
                [rng.uniform(x0, x0 + w, 3000), rng.uniform(-0.1, 0.2, 3000), np.full(3000, h)]
            )
            face = np.column_stack(
                [np.full(2000, x0), rng.uniform(-0.1, 0.2, 2000), rng.uniform(0, h, 2000)]
            )
            pts += [top, face]
    if wall:
        pts.append(
            np.column_stack(
                [np.full(30000, 2.0), rng.uniform(-1, 1, 30000), rng.uniform(0, 2, 30000)]
            )
        )
    world = np.concatenate(pts)
    world[:, 2] -= height_m  # camera at the origin
    cam = world @ camera_R_world.T
    return cam + noise_m * rng.standard_normal(cam.shape)


def camera_looking_down(pitch_rad: float, roll_rad: float = 0.0) -> np.ndarray:
    """camera_R_world for an optical camera (z forward, y down) pitched down, rolled."""
    world_R_optical = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)
    world_R_cam = _rot([0, 1, 0], pitch_rad) @ _rot([1, 0, 0], roll_rad) @ world_R_optical
    return world_R_cam.T


@pytest.mark.parametrize("pitch_deg,roll_deg", [(35.0, 0.0), (45.0, 4.0), (30.0, -2.5)])
def test_fit_floor_recovers_the_up_direction(pitch_deg, roll_deg):
    """Known answer: the normal is the world's up in the camera frame within 0.05° and the
    height within 2 mm, with boxes (parallel tops, vertical faces) and 2 mm depth noise; the
    hint is 2° off."""
    rng = np.random.default_rng(3)
    c_R_w = camera_looking_down(math.radians(pitch_deg), math.radians(roll_deg))
    pts = floor_scene(rng, c_R_w)
    up = c_R_w @ np.array([0.0, 0.0, 1.0])
    hint = _rot([1, 0, 0], math.radians(2.0)) @ up
    fit = fit_floor(pts, hint, FloorConfig())
    assert fit.ok, fit.reason
    assert math.degrees(math.acos(min(1.0, fit.normal @ up))) < 0.05
    assert fit.height_m == pytest.approx(0.6, abs=0.002)
    refit = pts[:: -(-len(pts) // FloorConfig().max_points)]  # the points the fit uses
    assert fit.n_inliers > 0.6 * len(refit)  # the floor's share of the scene
    assert 0 < fit.sigma_rad < 0.01
    assert fit.angle_to_hint_rad == pytest.approx(math.radians(2.0), abs=math.radians(0.1))


def test_fit_floor_failures_have_reasons():
    rng = np.random.default_rng(4)
    c_R_w = camera_looking_down(math.radians(35.0))
    up = c_R_w @ np.array([0.0, 0.0, 1.0])
    pts = floor_scene(rng, c_R_w)
    far = _rot([1, 0, 0], math.radians(20.0)) @ up  # hint 20° off, gate 3°
    fit = fit_floor(pts, far, FloorConfig())
    assert not fit.ok and fit.reason.startswith(("no_plane_near_up", "off_up"))
    assert fit.normal is None
    few = fit_floor(pts[:100], up, FloorConfig())
    assert not few.ok and few.reason.startswith("too_few_points")
    # only a wall in view: no floor, even with the hint pointing anywhere near up
    wall = floor_scene(rng, c_R_w, wall=True)
    wall = wall[np.abs((wall @ c_R_w)[:, 0] - 2.0) < 0.01]
    assert not fit_floor(wall, up, FloorConfig()).ok
    # a narrow strip of floor: too small to trust
    strip = pts[np.abs((pts @ c_R_w)[:, 1]) < 0.05]
    narrow = fit_floor(strip, up, FloorConfig(min_extent_m=0.3))
    assert not narrow.ok and narrow.reason.startswith("small_extent")


def test_fit_floor_prefers_the_floor_over_a_larger_wall():
    """A wall with more points than the floor is outside the angle gate: the floor wins."""
    rng = np.random.default_rng(5)
    c_R_w = camera_looking_down(math.radians(35.0))
    up = c_R_w @ np.array([0.0, 0.0, 1.0])
    fit = fit_floor(floor_scene(rng, c_R_w, boxes=False, wall=True), up, FloorConfig())
    assert fit.ok
    assert math.degrees(math.acos(min(1.0, fit.normal @ up))) < 0.05


def test_fit_floor_is_seeded():
    rng = np.random.default_rng(6)
    c_R_w = camera_looking_down(math.radians(40.0))
    pts = floor_scene(rng, c_R_w)
    up = c_R_w @ np.array([0.0, 0.0, 1.0])
    a, b = fit_floor(pts, up), fit_floor(pts, up)
    assert np.array_equal(a.normal, b.normal)


def test_fit_floor_rejects_bad_input():
    with pytest.raises(ConfigError, match="N×3"):
        fit_floor(np.zeros((10, 2)), np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ConfigError, match="up_hint"):
        fit_floor(np.zeros((10, 3)), np.array([0.0, np.nan, 1.0]))


def test_fuse_up_inverse_variance():
    a = np.array([0.0, 0.0, 1.0])
    b = _rot([1, 0, 0], 0.01) @ a
    up, sigma = fuse_up(a, 0.01, b, 0.01)
    assert math.acos(up @ a) == pytest.approx(0.005, rel=1e-3)  # equal weights: halfway
    assert sigma == pytest.approx(0.01 / math.sqrt(2))
    up, sigma = fuse_up(a, 0.01, b * 9.81, 0.002)  # magnitudes do not matter
    assert math.acos(up @ a) == pytest.approx(0.01 * 25 / 26, rel=1e-3)
    assert sigma == pytest.approx(1 / math.sqrt(1e4 + 2.5e5))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_preemptive_scoring_finds_the_same_floor(seed):
    """The pre-emptive RANSAC (every hypothesis on 1000 points, the best 10 on all) fits the
    same floor as scoring every hypothesis on every sample point, boxes and a wall in view."""
    rng = np.random.default_rng(seed)
    cam_R_world = camera_looking_down(math.radians(40.0), math.radians(2.0))
    pts = floor_scene(rng, cam_R_world, wall=True)
    up = cam_R_world @ np.array([0.0, 0.0, 1.0])
    hint = _rot([1.0, 0.0, 0.0], math.radians(3.0)) @ up
    fast = fit_floor(pts, hint, FloorConfig(seed=seed))
    full = fit_floor(pts, hint, FloorConfig(seed=seed, prescore_keep=10_000))
    assert fast.ok and full.ok
    assert math.degrees(math.acos(min(1.0, float(fast.normal @ full.normal)))) < 0.01
    assert abs(fast.offset_m - full.offset_m) < 1e-4
    assert math.degrees(math.acos(min(1.0, float(fast.normal @ up)))) < 0.1


def test_inlier_counts_match_the_distance_matrix() -> None:
    from graph_slam.terrain.maps.floor import inlier_counts

    rng = np.random.default_rng(4)
    points = rng.normal(size=(3000, 3))
    normals = rng.normal(size=(50, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    offsets = rng.normal(size=50) * 0.2
    expected = (np.abs(points @ normals.T + offsets) < 0.05).sum(axis=0)
    np.testing.assert_array_equal(inlier_counts(points, normals, offsets, 0.05), expected)
