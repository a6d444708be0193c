"""The online terrain's compiled per-frame pass (graph_slam.terrain.grid.kernels) against the numpy
functions it replaced in the live grid: map_pixels + map_cloud + depth_range_image +
point_terms. Same points, ranges and terms to rounding (bounds per field below; cells and
ranges exactly), on the seeded synthetic box course seen from a stride pose, with and without a pose
covariance and the depth-edge term, at two pixel steps.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_frontend_projective import A, frame_at
from test_frontend_registration import K

from graph_slam.errors import MappingError
from graph_slam.terrain.grid.depth_edges import depth_range_image
from graph_slam.terrain.grid.kernels import frame_point_terms
from graph_slam.terrain.grid.online import DepthNoiseModel, OnlineTerrainConfig, point_terms
from graph_slam.terrain.maps.builder import map_cloud, map_pixels

#: the box course's camera at 0.6 m, 41° down, as a stride pose (origin 0.3 m behind it)
STRIDE_T_CAMERA = A.copy()
STRIDE_T_CAMERA[0, 3] += 0.3


def _covariance(seed: int) -> np.ndarray:
    m = np.random.default_rng(seed).normal(scale=0.01, size=(6, 6))
    return m @ m.T + 1e-6 * np.eye(6)


def _numpy(cfg, frame, limits, pose, cov):
    pixels = map_pixels(frame, cfg.pixel_step, *limits)
    points, _ = map_cloud(frame, K, cfg.pixel_step, *limits, pixels)
    ranges = None
    if cfg.depth_noise.edge_factor > 0:
        v, u = pixels
        step = cfg.pixel_step
        ranges = depth_range_image(frame.depth_m, step)[v // step, u // step]
    return points, ranges, point_terms(cfg, points, pose, cov, ranges)


@pytest.mark.parametrize("step", [1, 3])
@pytest.mark.parametrize("edge_factor", [1.0, 0.0])
@pytest.mark.parametrize("with_cov", [True, False])
def test_frame_terms_equal_the_numpy_functions(step, edge_factor, with_cov) -> None:
    cfg = OnlineTerrainConfig(pixel_step=step, depth_noise=DepthNoiseModel(edge_factor=edge_factor))
    frame = frame_at(A, seed=4)
    limits = (0.3, 1.6)  # cuts the far floor: the range test is exercised
    cov = _covariance(1) if with_cov else None
    points, ranges, terms = frame_point_terms(cfg, frame.depth_m, K, limits, STRIDE_T_CAMERA, cov)
    ref_points, ref_ranges, ref = _numpy(cfg, frame, limits, STRIDE_T_CAMERA, cov)
    np.testing.assert_allclose(points, ref_points, rtol=1e-12, atol=0)
    if edge_factor > 0:
        np.testing.assert_array_equal(ranges, ref_ranges)
        assert np.count_nonzero(ranges > cfg.depth_noise.edge_threshold_m) > 20  # box edges
    else:
        assert ranges is None
    np.testing.assert_array_equal(terms.flat, ref.flat)
    assert 0 < len(terms.flat) < len(points)  # some points off the grid
    # z near 0 (the floor) differs in the last bit of the metre: an absolute bound there
    np.testing.assert_allclose(terms.z_m, ref.z_m, rtol=1e-12, atol=1e-12)
    for name in ("var_depth_m2", "var_pose_m2"):
        np.testing.assert_allclose(getattr(terms, name), getattr(ref, name), rtol=1e-9, atol=1e-18)


def test_a_non_finite_pose_is_a_mapping_error() -> None:
    pose = STRIDE_T_CAMERA.copy()
    pose[0, 3] = np.nan
    with pytest.raises(MappingError, match="stride_T_camera"):
        frame_point_terms(OnlineTerrainConfig(), frame_at(A).depth_m, K, (0.2, 2.0), pose, None)
