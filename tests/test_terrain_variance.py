"""The cell variance's terms on known answers: the within-cell spread of a cell across a step,
the depth range of a pixel's neighbourhood, and the depth-edge (flying pixel) term against
Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.terrain.grid.depth_edges import depth_range_at, depth_range_image
from graph_slam.terrain.grid.online import (
    DepthNoiseModel,
    OnlineElevationMap,
    OnlineTerrainConfig,
)

# a camera looking straight down from 1 m: a point's ray is the stride -z axis (ray_z = -1),
# camera x = stride x, camera y = -stride y
DOWN = np.diag([1.0, -1.0, -1.0, 1.0])
DOWN[2, 3] = 1.0
CFG = OnlineTerrainConfig(cell_m=0.02, x_range_m=(0.0, 0.04), y_range_m=(0.0, 0.02))


def _points_at(xy_m: np.ndarray, height_m: np.ndarray) -> np.ndarray:
    """Camera-frame points (DOWN) of stride points (x, y, height)."""
    return np.column_stack([xy_m[:, 0], -xy_m[:, 1], 1.0 - height_m])


def test_a_cell_across_a_step_gets_the_step_spread():
    """Cell 0 holds noise-free points at 0 and at H = 0.1 m in equal numbers: its height is
    H/2 and its variance the step's spread H²/4 beyond the depth noise the points are
    expected to have (σ_d², subtracted: a noisy sample's spread would hold it), plus the
    averaged depth noise σ_d²/n; cell 1 (one surface: no spread beyond the noise) only that."""
    noise = DepthNoiseModel(sigma_at_1m_m=0.0, sigma_floor_m=0.001, edge_factor=0.0)
    cfg = CFG.model_copy(update={"depth_noise": noise})
    rng = np.random.default_rng(0)
    n = 200
    xy = np.column_stack([rng.uniform(0.001, 0.019, 2 * n), rng.uniform(0.001, 0.019, 2 * n)])
    h = np.r_[np.zeros(n), np.full(n, 0.1)]
    xy1 = xy + np.array([0.02, 0.0])
    emap = OnlineElevationMap(cfg)
    view = emap.update(np.r_[_points_at(xy, h), _points_at(xy1, np.zeros(2 * n))], DOWN, None, 0.0)
    assert view.height_m[0, 0] == pytest.approx(0.05, abs=1e-12)
    depth_part = 0.001**2 / (2 * n)  # averaged over the cell's points
    expected = 0.1**2 / 4 - 0.001**2 + depth_part
    assert view.variance_m2[0, 0] == pytest.approx(expected, rel=1e-9)
    assert view.variance_m2[1, 0] == pytest.approx(depth_part, rel=1e-6)


def test_depth_range_of_a_pixel_neighbourhood():
    """A 1.0 m / 1.6 m depth step between columns 4 and 5, one invalid pixel: the range is 0.6
    within two pixels of the step along u, 0 elsewhere; invalid depths are left out."""
    depth = np.ones((6, 10))
    depth[:, 5:] = 1.6
    depth[2, 6] = 0.0  # dropped: not a neighbour
    v = np.array([0, 0, 0, 0, 3, 2, 2])
    u = np.array([0, 2, 3, 7, 5, 8, 4])
    np.testing.assert_allclose(depth_range_at(depth, v, u), [0, 0, 0.6, 0, 0.6, 0, 0.6])
    # the whole-image form agrees at every pixel and every step
    for step in (1, 2, 3):
        vv, uu = np.mgrid[0:6:step, 0:10:step]
        np.testing.assert_allclose(
            depth_range_image(depth, step),
            depth_range_at(depth, vv.ravel(), uu.ravel()).reshape(vv.shape),
        )


def test_edge_term_is_honest_for_flying_pixels():
    """One flying pixel per cell, anywhere between its surface and one R behind along the ray
    (uniform): with the edge term its normalised height error has an RMS of 1 (the model's
    R²/3 is that error's second moment about the true height); without it, far above 1."""
    rng = np.random.default_rng(3)
    n = 1000
    r = rng.uniform(0.05, 0.8, n)  # neighbourhood depth range (above the 3 cm threshold)
    err = rng.uniform(0.0, 1.0, n) * r  # along the ray: away from the camera = down
    noise = DepthNoiseModel(sigma_at_1m_m=0.0, sigma_floor_m=0.001)
    normalised = {}
    for factor in (1.0, 0.0):
        cfg = OnlineTerrainConfig(
            cell_m=0.02, x_range_m=(0.0, 0.02), y_range_m=(0.0, 0.02),
            depth_noise=noise.model_copy(update={"edge_factor": factor}),
        )  # fmt: skip
        z = []
        for e, rr in zip(err, r, strict=True):  # one cell, one point per map
            view = OnlineElevationMap(cfg).update(
                [[0.01, -0.01, 1.0 + e]], DOWN, None, 0.0, depth_range_m=[rr]
            )
            z.append(view.height_m[0, 0] / view.sigma_m[0, 0])  # the truth is 0
        normalised[factor] = float(np.sqrt(np.mean(np.square(z))))
    assert normalised[1.0] == pytest.approx(1.0, abs=0.06)
    assert normalised[0.0] > 50
    # below the threshold a pixel is not at an edge
    assert DepthNoiseModel().edge_variance_m2(np.array([0.02, 0.06]))[0] == 0.0


@pytest.mark.parametrize("shape", [(240, 424), (7, 9), (5, 3)])
def test_depth_range_image_agrees_at_the_borders_on_random_depth(shape):
    """The strided-view form equals the per-pixel gather at every step, borders, holes and
    NaN included (seeded random depth)."""
    rng = np.random.default_rng(11)
    depth = rng.uniform(0.5, 3.0, shape).astype(np.float32)
    depth[rng.random(shape) < 0.1] = 0.0
    depth[1, 1] = np.nan
    for step in (1, 2, 3, 4):
        vv, uu = np.mgrid[0 : shape[0] : step, 0 : shape[1] : step]
        np.testing.assert_allclose(
            depth_range_image(depth, step),
            depth_range_at(depth, vv.ravel(), uu.ravel()).reshape(vv.shape),
            atol=1e-6,
        )
