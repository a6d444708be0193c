"""The compact PLY maps compare writes: the fused voxels averaged, weighted by their point
counts, on a coarser grid of the same origin (CompareConfig.map_file_voxel_m)."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.errors import ConfigError
from graph_slam.report.views import file_cloud
from graph_slam.terrain.maps.fusion import FusedMap


def _fused() -> FusedMap:
    keys = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 1], [2, 0, 0]])
    points = (keys + 0.5) * 0.005
    colors = np.array([[0, 0, 0], [255, 255, 255], [255, 0, 0], [0, 0, 255]], np.uint8)
    return FusedMap(points, colors, np.array([1, 3, 4, 2]), keys, 0.005, np.zeros(3), 1, 0)


def test_voxels_averaged_by_their_counts_on_the_coarser_grid():
    cloud = file_cloud(_fused(), 0.01)
    # 1 cm cells: keys // 2 -> (0,0,0) holds the first three voxels, (1,0,0) the last
    assert cloud.points_m.shape == (2, 3)
    expected = (np.array([[0.5, 0.5, 0.5]]) * 1 + [[1.5, 0.5, 0.5]] * np.array(3)
                + [[1.5, 1.5, 1.5]] * np.array(4)) / 8 * 0.005  # fmt: skip
    np.testing.assert_allclose(cloud.points_m[0], expected[0], atol=1e-15)
    np.testing.assert_allclose(cloud.points_m[1], [2.5 * 0.005, 0.0025, 0.0025], atol=1e-15)
    np.testing.assert_allclose(cloud.colors[0], [7 / 8, 3 / 8, 3 / 8], atol=1e-12)
    np.testing.assert_allclose(cloud.colors[1], [0, 0, 1], atol=1e-12)


def test_as_fused_at_zero_and_a_voxel_that_is_no_multiple_is_refused():
    fused = _fused()
    np.testing.assert_array_equal(file_cloud(fused, 0.0).points_m, fused.points_m)
    with pytest.raises(ConfigError, match="map_file_voxel_m"):
        file_cloud(fused, 0.0075)
