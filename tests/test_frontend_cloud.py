"""Depth → cloud, the fixed-origin voxel grid, normals and the local map."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.errors import ConfigError, RecordError
from graph_slam.frontend import (
    Cloud,
    CloudConfig,
    LocalMap,
    RegistrationConfig,
    build_pyramid,
    depth_to_cloud,
    estimate_normals,
    voxel_downsample,
)
from graph_slam.frontend.cloud import voxel_pyramid
from graph_slam.session.records import CameraIntrinsics, RgbdFrame

K = CameraIntrinsics(4, 3, 100.0, 120.0, 1.5, 1.0)


def test_depth_to_cloud_back_projects_and_counts_every_pixel() -> None:
    depth = np.array(
        [[0.0, 1.0, 2.0, 0.05], [1.0, 4.0, 1.5, 0.0], [2.5, 0.0, 1.0, 3.5]], dtype=np.float32
    )
    color = np.arange(36, dtype=np.uint8).reshape(3, 4, 3)
    cloud, counts = depth_to_cloud(
        RgbdFrame(0.0, depth, color), K, CloudConfig(min_depth_m=0.1, max_depth_m=3.0)
    )
    assert (counts.pixels, counts.no_depth, counts.too_near, counts.too_far) == (12, 3, 1, 2)
    assert counts.kept == len(cloud) == 6
    # pixel (u=2, v=0) at 2 m: x = (2 - 1.5) * 2 / 100, y = (0 - 1) * 2 / 120
    row = np.flatnonzero(np.isclose(cloud.points_m[:, 2], 2.0))[0]
    np.testing.assert_allclose(cloud.points_m[row], [0.01, -2.0 / 120.0, 2.0])
    np.testing.assert_allclose(cloud.colors[row], color[0, 2] / 255.0)


def test_depth_to_cloud_refuses_a_frame_of_another_size() -> None:
    frame = RgbdFrame(0.0, np.ones((2, 2), np.float32))
    with pytest.raises(RecordError, match="does not match the intrinsics"):
        depth_to_cloud(frame, K)


def test_cloud_range_config_is_checked() -> None:
    with pytest.raises(ValueError, match="max_depth_m"):
        CloudConfig(min_depth_m=2.0, max_depth_m=1.0)


def test_voxel_means_on_a_grid_anchored_at_the_origin() -> None:
    points = np.array([[0.001, 0.001, 0.001], [0.009, 0.003, 0.005], [0.011, 0.0, 0.0]])
    down = voxel_downsample(Cloud(points), 0.01)
    got = down.points_m[np.argsort(down.points_m[:, 0])]
    np.testing.assert_allclose(got, [[0.005, 0.002, 0.003], [0.011, 0.0, 0.0]])


def test_voxel_grid_does_not_move_when_the_cloud_grows() -> None:
    """Open3D's voxel_down_sample anchors at the cloud's minimum; this grid must not."""
    rng = np.random.default_rng(3)
    points = rng.uniform(0.0, 0.5, (3000, 3))
    base = voxel_downsample(Cloud(points), 0.02).points_m
    grown = voxel_downsample(Cloud(np.vstack([points, [[-0.737, -0.511, -0.333]]])), 0.02)
    kept = grown.points_m[grown.points_m[:, 0] > -0.5]
    np.testing.assert_allclose(np.sort(kept, axis=0), np.sort(base, axis=0))


def test_voxelising_in_another_frame_buckets_there_and_returns_own_frame_points() -> None:
    points = np.array([[0.004, 0.0, 0.0], [0.012, 0.0, 0.0]])
    grid_T_cloud = np.eye(4)
    grid_T_cloud[0, 3] = 0.01  # in the grid frame: 0.014 and 0.022, two voxels of 2 cm
    down = voxel_downsample(Cloud(points), 0.02, grid_T_cloud)
    np.testing.assert_allclose(np.sort(down.points_m[:, 0]), [0.004, 0.012])
    own = voxel_downsample(Cloud(points), 0.02)  # in its own frame: one voxel
    np.testing.assert_allclose(own.points_m, [[0.008, 0.0, 0.0]])


def test_pyramid_levels_merged_from_the_finest_equal_direct_voxelisation() -> None:
    rng = np.random.default_rng(5)
    cloud = Cloud(rng.uniform(-1, 2, (20000, 3)), rng.uniform(0, 1, (20000, 3)))
    pose = np.eye(4)
    pose[:3, 3] = [0.013, -0.021, 0.005]
    levels = voxel_pyramid(cloud, (0.04, 0.03, 0.01), pose)  # 0.03 is not a multiple: direct
    for voxel_m, level in zip((0.04, 0.03, 0.01), levels, strict=True):
        direct = voxel_pyramid(cloud, (voxel_m,), pose)[0]
        order_a, order_b = np.lexsort(level.points_m.T), np.lexsort(direct.points_m.T)
        np.testing.assert_allclose(level.points_m[order_a], direct.points_m[order_b], atol=1e-12)
        np.testing.assert_allclose(level.colors[order_a], direct.colors[order_b], atol=1e-12)


def test_points_beyond_the_key_range_are_refused() -> None:
    with pytest.raises(RecordError, match="voxel key"):
        voxel_downsample(Cloud(np.array([[1e5, 0.0, 0.0]])), 0.01)


def test_normals_are_unit_and_face_the_camera() -> None:
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.5, 0.5, (2000, 2))
    plane = np.column_stack([xy, 1.0 + 0.2 * xy[:, 0]])  # tilted plane 1 m in front
    cloud, dropped = estimate_normals(Cloud(plane), radius_m=0.1)
    assert dropped == 0
    np.testing.assert_allclose(np.linalg.norm(cloud.normals, axis=1), 1.0, atol=1e-9)
    assert np.all(np.einsum("ij,ij->i", cloud.normals, -plane) > 0)
    expected = np.array([0.2, 0.0, -1.0]) / np.linalg.norm([0.2, 0.0, -1.0])
    np.testing.assert_allclose(cloud.normals, np.tile(expected, (2000, 1)), atol=1e-6)


def test_normals_are_undefined_on_a_line_and_dropped_with_a_count() -> None:
    rng = np.random.default_rng(6)
    xy = rng.uniform(-0.5, 0.5, (2000, 2))
    plane = np.column_stack([xy, np.full(2000, 1.0)])
    row = np.column_stack([np.linspace(-0.5, 0.5, 30), np.full(30, 2.0), np.full(30, 3.0)])
    cloud, dropped = estimate_normals(Cloud(np.vstack([plane, row])), radius_m=0.1)
    assert dropped == 30 and len(cloud) == 2000  # a single image row far away: no surface
    np.testing.assert_allclose(np.abs(cloud.normals[:, 2]), 1.0, atol=1e-9)


def test_pyramid_has_one_level_per_config_level_coarse_to_fine() -> None:
    rng = np.random.default_rng(2)
    xy = rng.uniform(-0.5, 0.5, (20000, 2))
    cloud = Cloud(np.column_stack([xy, 1.0 + 0.1 * np.sin(3 * xy[:, 0])]))
    pyramid = build_pyramid(cloud, RegistrationConfig(method="point_to_plane"))
    assert pyramid.voxel_m == (0.04, 0.02, 0.01)
    sizes = [len(level) for level in pyramid.levels]
    assert sizes == sorted(sizes) and all(lv.normals is not None for lv in pyramid.levels)
    assert len(pyramid.dropped) == 3 and sum(pyramid.dropped) < 0.05 * sizes[-1]


def test_local_map_averages_in_the_map_frame() -> None:
    points = np.array([[0.001, 0.002, 1.003], [0.5, 0.5, 1.5]])
    colors = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    local_map = LocalMap(0.01)
    local_map.insert(Cloud(points, colors), np.eye(4))
    local_map.insert(Cloud(points + 0.004, colors * 0.5), np.eye(4))
    assert len(local_map) == 2 and local_map.frames_inserted == 2
    cloud = local_map.cloud()
    order = np.argsort(cloud.points_m[:, 0])
    np.testing.assert_allclose(cloud.points_m[order], points + 0.002)
    np.testing.assert_allclose(cloud.colors[order], colors * 0.75)
    map_T_camera = np.eye(4)
    map_T_camera[:3, 3] = [1.0, 0.0, 0.0]
    local_map.insert(Cloud(points[:1], colors[:1]), map_T_camera)
    assert len(local_map) == 3
    assert np.isclose(local_map.cloud().points_m[:, 0], 1.001).any()


def test_local_map_refuses_a_cloud_without_colours_and_a_bad_pose() -> None:
    local_map = LocalMap(0.01)
    with pytest.raises(ConfigError, match="colours"):
        local_map.insert(Cloud(np.zeros((1, 3))), np.eye(4))
    with pytest.raises(RecordError, match="map_T_cloud"):
        local_map.insert(Cloud(np.zeros((1, 3)), np.zeros((1, 3))), 2.0 * np.eye(4))
