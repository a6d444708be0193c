"""The carried terrain's horizontal landing position: a grid moved by a shift of a fraction of
a cell keeps its box edges where the shift puts them, and its heights match the moved surface's
cell means (the area each new cell takes from the old ones)."""

from __future__ import annotations

import numpy as np

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
