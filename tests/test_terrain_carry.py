"""The carried terrain's horizontal landing position: a grid moved by a shift of a fraction of
a cell keeps its box edges and stair nosings where the shift puts them, and its heights match
the moved surface's cell means (the area each new cell takes from the old ones)."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.terrain.features.extract import features_of_view
from graph_slam.terrain.grid.carry import carry_map
from graph_slam.terrain.grid.online import CellSums, OnlineTerrainConfig, PointTerms
from graph_slam.terrain.grid.view import TerrainView

CFG = OnlineTerrainConfig()
LEAD, TRAIL, HEIGHT = 1.003, 1.2062, 0.1905  # a Box1 across the walk, y in [-0.4, -0.133)


def box_surface(x, y):
    return np.where((x >= LEAD) & (x < TRAIL) & (y >= -0.4) & (y < -0.1333), HEIGHT, 0.0)


def cell_means(surface, shift_xy=(0.0, 0.0)):
    """Cell means (16×16 samples) of ``surface`` seen from a frame moved by ``shift_xy``."""
    nx, ny = CFG.shape
    sub = (np.arange(16) + 0.5) / 16 * CFG.cell_m
    xs = CFG.x_range_m[0] + (np.arange(nx)[:, None] * CFG.cell_m + sub).ravel()
    ys = CFG.y_range_m[0] + (np.arange(ny)[:, None] * CFG.cell_m + sub).ravel()
    xx, yy = np.meshgrid(xs - shift_xy[0], ys - shift_xy[1], indexing="ij")
    return surface(xx, yy).reshape(nx, 16, ny, 16).mean(axis=(1, 3))


def view_of(heights, var=1e-6):
    n = heights.size
    terms = PointTerms(np.arange(n), heights.ravel(), np.full(n, var), np.zeros(n))
    sums = CellSums.empty(n).plus(terms, 0.0)
    origin = np.array([CFG.x_range_m[0], CFG.y_range_m[0]])
    return TerrainView(1, 0.0, origin, CFG.cell_m, sums, CFG.shape, CFG.toe_x_m)


def test_carried_box_lands_where_the_shift_puts_it():
    old = view_of(cell_means(box_surface))
    shift = np.array([-0.537, 0.0113])  # the new heel 53.7 cm ahead: not a whole cell
    new_T_old = np.eye(4)
    new_T_old[:2, 3] = shift
    carried = carry_map(CFG, old, new_T_old, np.zeros((6, 6)))
    origin = np.array([CFG.x_range_m[0], CFG.y_range_m[0]])
    view = TerrainView(2, 0.0, origin, CFG.cell_m, carried, CFG.shape, CFG.toe_x_m)
    truth = cell_means(box_surface, shift)
    known = view.known & (truth == truth)
    # whole cells only (those the old grid covered entirely after the move)
    inner = known.copy()
    inner[:2] = inner[-2:] = False
    inner[:, :2] = inner[:, -2:] = False
    rmse = float(np.sqrt(np.mean((view.height_m[inner] - truth[inner]) ** 2)))
    assert rmse <= 0.005, rmse
    (box,) = features_of_view(view).boxes
    assert abs(box.leading.x_m - (LEAD + shift[0])) <= 0.003
    assert abs(box.depth_m - (TRAIL - LEAD)) <= 0.006
    assert abs(box.height_m - HEIGHT) <= 0.003


NOSINGS, RISE = (0.83, 1.11, 1.39), 0.17  # a flight up, as the stride before saw it


def stairs_surface(x, y):
    return RISE * sum((x >= n).astype(float) for n in NOSINGS) + 0.0 * y


def view_of_samples(surface, sigma_m=0.002, seed=5):
    """A grid fused from 8×8 samples a cell of ``surface`` with depth noise: a cell across a
    nosing holds both treads (its variance mostly the spread), as a fused grid does."""
    rng = np.random.default_rng(seed)
    nx, ny = CFG.shape
    sub = (np.arange(8) + 0.5) / 8 * CFG.cell_m
    xs = CFG.x_range_m[0] + (np.arange(nx)[:, None] * CFG.cell_m + sub).ravel()
    ys = CFG.y_range_m[0] + (np.arange(ny)[:, None] * CFG.cell_m + sub).ravel()
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    z = surface(xx, yy) + rng.normal(0.0, sigma_m, xx.shape)
    i = np.floor((xx - CFG.x_range_m[0]) / CFG.cell_m).astype(np.int64)
    j = np.floor((yy - CFG.y_range_m[0]) / CFG.cell_m).astype(np.int64)
    terms = PointTerms(
        (i * ny + j).ravel(), z.ravel(), np.full(z.size, sigma_m**2), np.full(z.size, 1e-6)
    )
    sums = CellSums.empty(nx * ny).plus(terms, 0.0)
    origin = np.array([CFG.x_range_m[0], CFG.y_range_m[0]])
    return TerrainView(1, 0.0, origin, CFG.cell_m, sums, CFG.shape, CFG.toe_x_m)


@pytest.mark.parametrize("frac", [0.1, 0.3, 0.5, 0.7, 0.9])
def test_carried_nosings_land_where_the_shift_puts_them(frac):
    """A cell across a nosing has a large variance (the two treads' spread); its shares are
    parts of the new cells' areas and must count by area, not by variance: weighted by
    variance, the level cells beside it took the new cells and the nosings moved to a cell
    boundary (up to 8 mm off, by the shift's fraction of a cell)."""
    old = view_of_samples(stairs_surface)
    old_nosings = [s.nosing.x_m for s in features_of_view(old).stairs[0].steps]
    assert np.allclose(old_nosings, NOSINGS, atol=0.0015), old_nosings
    shift = -(28 + frac) * CFG.cell_m
    new_T_old = np.eye(4)
    new_T_old[0, 3] = shift
    new_T_old[2, 3] = -0.34
    carried = carry_map(CFG, old, new_T_old, np.zeros((6, 6)))
    origin = np.array([CFG.x_range_m[0], CFG.y_range_m[0]])
    view = TerrainView(2, 0.0, origin, CFG.cell_m, carried, CFG.shape, CFG.toe_x_m)
    (stairs,) = features_of_view(view).stairs
    got = np.array([s.nosing.x_m for s in stairs.steps])
    want = np.array(NOSINGS) + shift
    assert got.shape == want.shape
    assert np.max(np.abs(got - want)) <= 0.0015, (got - want) * 1e3
    # the cells across a nosing keep their mixture as spread, not as depth noise (a depth-noise
    # σ over 2 cm reads as a cell held by flying pixels only)
    s = carried
    known = s.w > 0
    noise = np.sqrt(s.a[known]) / s.w[known]
    assert noise.max() < 0.002, noise.max()
    # every carried cell, those across a nosing too, holds the moved surface's cell mean
    truth = cell_means(lambda x, y: stairs_surface(x, y) - 0.34, (shift, 0.0))
    inner = view.known.copy()
    inner[:, :2] = inner[:, -2:] = False
    err = view.height_m[inner] - truth[inner]
    assert np.sqrt(np.mean(err**2)) <= 0.003, np.sqrt(np.mean(err**2))


@pytest.mark.parametrize("frac", [0.2, 0.6])
def test_an_edge_held_by_two_cells_is_carried_as_one_step(frac):
    """A riser on a cell boundary puts its points in the cells on both sides: two mixed cells
    side by side (here 6 and 11 cm of a 17 cm step). Carried, they hold one step where their
    fractions together put it (on the boundary), not two half-steps smeared over three cells."""
    nx, ny = CFG.shape
    heights = np.zeros((nx, ny))
    for edge in NOSINGS:  # on cell boundaries: the cells before and after it hold the riser
        k = round((edge - CFG.x_range_m[0]) / CFG.cell_m)
        heights[k:] += RISE
        heights[k - 1] += 0.35 * RISE
        heights[k] -= 0.35 * RISE
    old = view_of(heights, var=4e-6)
    shift = -(28 + frac) * CFG.cell_m
    new_T_old = np.eye(4)
    new_T_old[0, 3] = shift
    view = TerrainView(
        2, 0.0, old.origin_xy_m, CFG.cell_m, carry_map(CFG, old, new_T_old, np.zeros((6, 6))),
        CFG.shape, CFG.toe_x_m,
    )  # fmt: skip
    edges = np.round((np.array(NOSINGS) - CFG.x_range_m[0]) / CFG.cell_m) * CFG.cell_m
    truth = cell_means(
        lambda x, y: RISE * sum((x >= CFG.x_range_m[0] + e).astype(float) for e in edges) + 0 * y,
        (shift, 0.0),
    )
    inner = view.known.copy()
    inner[:, :2] = inner[:, -2:] = False
    err = view.height_m[inner] - truth[inner]
    assert np.sqrt(np.mean(err**2)) <= 0.004, np.sqrt(np.mean(err**2))
