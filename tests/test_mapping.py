"""graph_slam.terrain: fusion on a fixed grid, the elevation grid of a step, boxes within 2 mm."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.errors import MappingError
from graph_slam.terrain import (
    SKIP_REASONS,
    ElevationConfig,
    MappingConfig,
    ObstacleConfig,
    build_stride_map,
    elevation_grid,
    extract_obstacles,
    fuse_clouds,
)

# Thesis Table 3.1 (depth x, width y, height z), metres, placed beside the walking line.
BOXES = {
    "Box1": ((0.60, -0.30), (0.20320, 0.26670, 0.19050)),
    "Box2": ((1.20, -0.35), (0.26670, 0.35560, 0.07620)),
    "Box3": ((1.90, -0.40), (0.33655, 0.43815, 0.06350)),
}


def _pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def _box_points(
    rng: np.random.Generator,
    centre_xy: tuple[float, float],
    size: tuple[float, float, float],
    yaw_rad: float = 0.0,
    n: int = 30_000,
) -> tuple[np.ndarray, np.ndarray]:
    """Top and four side faces of a box (yawed about z), and a mask for its floor footprint."""
    d, w, h = size
    top = np.column_stack(
        [rng.uniform(-d / 2, d / 2, n), rng.uniform(-w / 2, w / 2, n), np.full(n, h)]
    )
    u = rng.uniform(-0.5, 0.5, (4, n // 4))
    z = rng.uniform(0, h, (4, n // 4))
    sides = [
        np.column_stack([np.full(n // 4, -d / 2), w * u[0], z[0]]),
        np.column_stack([np.full(n // 4, d / 2), w * u[1], z[1]]),
        np.column_stack([d * u[2], np.full(n // 4, -w / 2), z[2]]),
        np.column_stack([d * u[3], np.full(n // 4, w / 2), z[3]]),
    ]
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    rotation = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    points = np.concatenate([top, *sides]) @ rotation.T + [*centre_xy, 0]
    return points, rotation


def _floor(rng, x_range=(-0.2, 2.4), y_range=(-0.8, 0.5), n=120_000) -> np.ndarray:
    return np.column_stack([rng.uniform(*x_range, n), rng.uniform(*y_range, n), np.zeros(n)])


def _scene(
    rng: np.random.Generator,
    boxes: list[tuple[tuple[float, float], tuple[float, float, float], float]],
    noise_m: float = 0.0005,
    floor: np.ndarray | None = None,
) -> np.ndarray:
    """Floor with holes under the boxes, each box's top and four side faces, densely sampled."""
    floor = _floor(rng) if floor is None else floor
    keep = np.ones(len(floor), bool)
    parts = []
    for centre, size, yaw in boxes:
        points, rotation = _box_points(rng, centre, size, yaw)
        local = (floor[:, :2] - centre) @ rotation[:2, :2]
        keep &= ~((np.abs(local[:, 0]) < size[0] / 2) & (np.abs(local[:, 1]) < size[1] / 2))
        parts.append(points)
    cloud = np.concatenate([floor[keep], *parts])
    return cloud + rng.normal(0, noise_m, cloud.shape)


def _box_scene(rng: np.random.Generator, noise_m: float = 0.0005) -> np.ndarray:
    """The three boxes of Table 3.1 beside the walking line, square to it."""
    return _scene(rng, [(c, s, 0.0) for c, s in BOXES.values()], noise_m)


def test_obstacles_of_known_boxes_within_2mm():
    rng = np.random.default_rng(7)
    result = extract_obstacles(_box_scene(rng))
    assert abs(result.floor.normal[2] - 1) < 1e-4 and abs(result.floor.offset_m) < 1e-3
    assert len(result.obstacles) == 3
    for obstacle, ((cx, _), (d, w, h)) in zip(result.obstacles, BOXES.values(), strict=True):
        np.testing.assert_allclose(obstacle.size_m, [d, w, h], atol=0.002)
        assert abs(obstacle.leading_edge_x_m - (cx - d / 2)) < 0.002
        assert abs(obstacle.yaw_rad) < np.deg2rad(0.3)
        # seen whole: floor all round, nothing beyond the map near it
        assert obstacle.complete and obstacle.skip_reason is None
        assert obstacle.top_fill_fraction > 0.95 and obstacle.floor_seen_fraction > 0.95
    assert result.complete == result.obstacles


def test_a_yawed_box_is_measured_along_its_own_sides():
    """Box3 turned 20° against the walk: its own depth and width within 2 mm (its bounding
    extents would be 17 and 11 cm larger), the yaw within 0.3°, the nearest corner as the
    leading edge."""
    rng = np.random.default_rng(12)
    centre, size = (1.2, -0.4), BOXES["Box3"][1]
    yaw = np.deg2rad(20.0)
    result = extract_obstacles(_scene(rng, [(centre, size, yaw)]))
    (box,) = result.obstacles
    np.testing.assert_allclose(box.size_m, size, atol=0.002)
    assert box.yaw_rad == pytest.approx(yaw, abs=np.deg2rad(0.3))
    corners = box.corners_xy_m()
    half = np.array([size[0], size[1]]) / 2
    c, s = np.cos(yaw), np.sin(yaw)
    true_corners = np.array([[sx, sy] for sx, sy in [(-1, -1), (1, -1), (1, 1), (-1, 1)]]) * half
    true_corners = true_corners @ np.array([[c, s], [-s, c]]) + centre
    np.testing.assert_allclose(corners, true_corners, atol=0.003)
    assert box.leading_edge_x_m == pytest.approx(true_corners[:, 0].min(), abs=0.002)
    assert box.complete


def test_partial_boxes_are_kept_with_the_reason_they_are_not_measured():
    """Four ways a stride map holds only part of a box; a whole box beside them is measured.

    * cut by the map's edge: the map (floor and box) ends at x = 2.0 through Box3;
    * touching another box: Box1 with a 10 cm cube 2.5 cm from its side;
    * top incomplete: Box2 with the far 60 % of its top unseen (sides and floor all there);
    * no floor seen around it: a box in a 6 cm wide unobserved ring, floor beyond it.
    """
    rng = np.random.default_rng(13)
    whole = ((0.6, 0.25), (0.2, 0.2, 0.1), 0.0)
    cut = ((1.9, -0.4), BOXES["Box3"][1], 0.0)
    pair = [
        ((0.6, -0.3), BOXES["Box1"][1], 0.0),
        ((0.6, -0.3 - 0.1334 - 0.025 - 0.05), (0.1,) * 3, 0.0),
    ]
    ringed = ((1.4, 0.25), (0.2, 0.2, 0.08), 0.0)
    cloud = _scene(rng, [whole, cut, *pair, ringed])
    # Box2's top: only its near 40 % seen.
    box2, _ = _box_points(rng, (1.2, -0.35), BOXES["Box2"][1])
    box2 = box2[~((box2[:, 2] > 0.07) & (box2[:, 0] > 1.2 - 0.2667 / 2 + 0.4 * 0.2667))]
    floor_under_box2 = (np.abs(cloud[:, 0] - 1.2) < 0.1334) & (np.abs(cloud[:, 1] + 0.35) < 0.178)
    cloud = np.concatenate([cloud[~floor_under_box2 | (cloud[:, 2] > 0.01)], box2])
    # The ring around the ringed box: no floor within 6 cm of it.
    ring = (
        (np.abs(cloud[:, 0] - 1.4) < 0.16)
        & (np.abs(cloud[:, 1] - 0.25) < 0.16)
        & (cloud[:, 2] < 0.005)
    )
    cloud = cloud[~ring & (cloud[:, 0] < 2.0)]

    result = extract_obstacles(cloud)
    by_centre = {
        name: min(result.obstacles, key=lambda o: np.linalg.norm(o.center_xy_m - xy))
        for name, xy in [
            ("whole", (0.6, 0.25)),
            ("cut", (1.85, -0.4)),
            ("box1", (0.6, -0.3)),
            ("box2", (1.15, -0.35)),
            ("ringed", (1.4, 0.25)),
        ]
    }
    assert len(result.obstacles) == 6
    assert by_centre["whole"].complete
    np.testing.assert_allclose(by_centre["whole"].size_m, [0.2, 0.2, 0.1], atol=0.002)
    assert by_centre["cut"].skip_reason == "edge_of_map"
    assert by_centre["box1"].skip_reason == "adjacent"
    assert by_centre["box2"].skip_reason == "top_incomplete"
    assert by_centre["ringed"].skip_reason == "floor_not_seen"
    assert by_centre["ringed"].floor_seen_fraction < 0.1
    for o in result.obstacles:
        assert (o.skip_reason is None) == o.complete
        assert o.skip_reason is None or (o.skip_reason in SKIP_REASONS and o.skip_detail)
    assert result.complete == (by_centre["whole"],)
    # The coverage grid: the area beyond x = 2.0 is outside the map, the ring is a hole in it.
    assert result.coverage.is_outside(
        np.array([[2.3, 0.0], [1.0, 0.0], [1.4, 0.25 + 0.13]])
    ).tolist() == [
        True,
        False,
        False,
    ]


def test_obstacles_on_a_fused_5mm_voxel_map_within_2_5mm():
    """Voxel averaging moves edge cells inwards by up to a voxel fraction: 2.5 mm at 5 mm voxels."""
    cloud = _box_scene(np.random.default_rng(11))
    fused = fuse_clouds([cloud], np.eye(4)[None], voxel_m=0.005)
    result = extract_obstacles(fused.points_m)
    sizes = np.array([o.size_m for o in result.obstacles])
    np.testing.assert_allclose(sizes, [b[1] for b in BOXES.values()], atol=0.0025)


def test_obstacles_on_a_tilted_raised_floor():
    """The floor 3 cm below the stride origin and tilted 5° about y: heights stay above it."""
    rng = np.random.default_rng(8)
    cloud = _box_scene(rng)
    floor_to_stride = _pose([0, np.deg2rad(5), 0], [0, 0, -0.03])
    cloud = cloud @ floor_to_stride[:3, :3].T + floor_to_stride[:3, 3]
    result = extract_obstacles(cloud, ObstacleConfig(seed=3))
    assert len(result.obstacles) == 3
    heights = [o.height_m for o in result.obstacles]
    np.testing.assert_allclose(heights, [b[1][2] for b in BOXES.values()], atol=0.002)


def test_no_floor_is_an_error():
    wall = np.column_stack([np.zeros(100), np.linspace(0, 1, 100), np.linspace(0, 1, 100) ** 2])
    with pytest.raises(MappingError, match="near-horizontal"):
        extract_obstacles(wall)


def test_elevation_grid_of_a_known_step():
    """Floor at 0 for x < 0.5, a 0.15 m step beyond: cell heights and edge variance."""
    xs, ys = np.meshgrid(np.arange(0.0025, 1.0, 0.005), np.arange(-0.2975, 0.3, 0.005))
    x, y = xs.ravel(), ys.ravel()
    z = np.where(x < 0.5, 0.0, 0.15)
    grid = elevation_grid(
        np.column_stack([x, y, z]),
        ElevationConfig(cell_m=0.02, x_range_m=(0, 1), y_range_m=(-0.3, 0.3)),
    )
    assert grid.shape == (50, 30)
    np.testing.assert_allclose(grid.height_m[:25], 0.0, atol=1e-12)
    np.testing.assert_allclose(grid.height_m[25:], 0.15, atol=1e-12)
    np.testing.assert_array_equal(grid.count, 16)
    np.testing.assert_allclose(grid.variance_m2, 0.0, atol=1e-20)
    assert grid.height_at(0.49, 0.0) == 0.0
    assert grid.height_at(0.51, 0.0) == pytest.approx(0.15, abs=1e-12)
    assert np.isnan(grid.height_at(2.0, 0.0))

    # Cells straddling the edge average both levels; their variance is (h/2)^2.
    shifted = elevation_grid(
        np.column_stack([x, y, np.where(x < 0.49, 0.0, 0.15)]),
        ElevationConfig(cell_m=0.02, x_range_m=(0, 1), y_range_m=(-0.3, 0.3)),
    )
    np.testing.assert_allclose(shifted.height_m[24], 0.075)
    np.testing.assert_allclose(shifted.variance_m2[24], 0.075**2)


def test_elevation_grid_empty_cells_are_nan():
    grid = elevation_grid(
        np.array([[0.05, 0.05, 0.1], [5.0, 0.0, 0.0]]),
        ElevationConfig(cell_m=0.1, x_range_m=(0, 0.5), y_range_m=(0, 0.5)),
    )
    assert grid.count.sum() == 1 and grid.points_outside == 1
    assert grid.height_m[0, 0] == 0.1 and np.isnan(grid.height_m[1, 1])


def test_fusion_of_identical_clouds_with_known_poses():
    """One scene seen from three known poses fuses back to the scene's voxel means."""
    rng = np.random.default_rng(1)
    scene = rng.uniform([0, -0.5, 0], [1.0, 0.5, 0.2], (2000, 3))
    colors = rng.integers(0, 256, (2000, 3), dtype=np.uint8)
    poses = np.stack(
        [_pose([0.1, -0.2, 0.3], [0.1, 0, 0.5]), _pose([-0.3, 0.1, 0], [0.4, 0.1, 0.6]), np.eye(4)]
    )
    # Each camera sees the same world points: camera_p = inv(stride_T_camera) @ stride_p.
    clouds = [(scene - T[:3, 3]) @ T[:3, :3] for T in poses]
    fused = fuse_clouds(clouds, poses, [colors] * 3, voxel_m=0.05)
    single = fuse_clouds([scene], np.eye(4)[None], [colors], voxel_m=0.05)
    assert fused.frames_fused == 3 and fused.frames_skipped == 0
    np.testing.assert_array_equal(fused.voxel_keys, single.voxel_keys)
    np.testing.assert_allclose(fused.points_m, single.points_m, atol=1e-12)
    np.testing.assert_array_equal(fused.counts, 3 * single.counts)
    np.testing.assert_array_equal(fused.colors_rgb, single.colors_rgb)
    # Fixed origin: every mean lies inside its own voxel of the grid anchored at (0, 0, 0).
    np.testing.assert_array_equal(np.floor(fused.points_m / 0.05), fused.voxel_keys)


def test_fusion_skips_and_counts_frames_without_pose():
    cloud = np.array([[0.0, 0.0, 1.0]])
    poses = np.stack([np.eye(4), np.full((4, 4), np.nan)])
    fused = fuse_clouds([cloud, cloud + 5], poses, voxel_m=0.1)
    assert (fused.frames_fused, fused.frames_skipped, len(fused)) == (1, 1, 1)
    assert fused.colors_rgb is None
    with pytest.raises(MappingError, match="one pose per cloud"):
        fuse_clouds([cloud], poses)


def test_build_stride_map_from_camera_clouds_and_poses():
    """Two camera views of the box scene, fused with known poses, give the boxes back."""
    scene = _box_scene(np.random.default_rng(5))
    poses = np.stack([_pose([0, 0, 0.1], [0.2, 0, 0.6]), _pose([0, 0, -0.1], [0.5, -0.1, 0.6])])
    clouds = [(scene - T[:3, 3]) @ T[:3, :3] for T in poses]
    stride_map = build_stride_map(clouds, poses)
    assert stride_map.fused.frames_fused == 2 and stride_map.obstacle_error is None
    sizes = np.array([o.size_m for o in stride_map.obstacles.obstacles])
    np.testing.assert_allclose(sizes, [b[1] for b in BOXES.values()], atol=0.0025)
    assert stride_map.elevation.height_at(0.6, -0.3) == pytest.approx(0.1905, abs=0.002)

    # A map without a floor still gets its fused cloud and grid; the reason is kept.
    wall = np.column_stack([np.full(50, 1.0), np.linspace(-0.2, 0.2, 50), np.linspace(0, 0.5, 50)])
    no_floor = build_stride_map([wall], np.eye(4)[None], config=MappingConfig(voxel_m=0.01))
    assert no_floor.obstacles is None and "near-horizontal" in no_floor.obstacle_error
    assert len(no_floor.fused) > 0


def test_a_top_seen_thinly_at_its_far_end_is_not_taken_for_a_shorter_box():
    """Box2's far 45 % seen only as scattered points 2 cm apart (as from 2 m away), on a 5 mm
    voxel map: they fall into pieces too small to be obstacles, but still count against the
    dense part, which alone would pass for a 15 cm deep box."""
    rng = np.random.default_rng(14)
    (cx, cy), (d, w, h) = BOXES["Box2"]
    floor = _floor(rng)
    floor = floor[~((np.abs(floor[:, 0] - cx) < d / 2) & (np.abs(floor[:, 1] - cy) < w / 2))]
    x_split = cx - d / 2 + 0.55 * d
    dense = np.column_stack(
        [rng.uniform(cx - d / 2, x_split, 20_000), rng.uniform(cy - w / 2, cy + w / 2, 20_000)]
    )
    gx, gy = np.meshgrid(
        np.arange(x_split + 0.02, cx + d / 2, 0.02), np.arange(-w / 2 + 0.005, w / 2, 0.02)
    )
    sparse = np.column_stack([gx.ravel(), gy.ravel() + cy])
    top = np.concatenate([dense, sparse])
    cloud = np.concatenate([floor, np.column_stack([top, np.full(len(top), h)])])
    cloud += rng.normal(0, 0.0005, cloud.shape)
    voxel_map = fuse_clouds([cloud], np.eye(4)[None], voxel_m=0.005).points_m
    result = extract_obstacles(voxel_map)
    (box,) = result.obstacles
    assert box.depth_m == pytest.approx(0.55 * d, abs=0.005)  # what the dense part measures
    assert box.skip_reason == "top_incomplete" and not box.complete
    # Joining off (join_gap_cells=0): the scattered points are ignored and the box passes.
    alone = extract_obstacles(voxel_map, ObstacleConfig(join_gap_cells=0))
    assert alone.obstacles[0].complete
