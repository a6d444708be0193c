"""Terrain features on synthetic height grids with known answers (ramp, curb, box, floor).

Each grid is the stride-frame layout of the online grid (2 cm cells, x −0.2..1.8 m, y ±0.6 m);
a cell's height is the mean of the analytic surface over it (8×8 samples: a cell across an
edge is a mixture, as a fused cell is), plus seeded noise; its variance the noise's plus the
samples' spread. Tolerances: the issue's targets (rise 3 mm, tread and nosing 8 mm, slope
0.5°, curb and box height 3 mm, box depth 8 mm).

Stairs: ``tests/test_terrain_features_stairs.py``; the grids and their helpers:
``tests/terrain_grid_helpers.py`` (importable from here too).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from graph_slam.terrain.features.extract import extract_features
from graph_slam.terrain.features.model import TerrainFeatures
from tests.terrain_grid_helpers import (  # noqa: F401 (re-exported)
    CELL,
    NOSING_TOL,
    NX,
    NY,
    RISE_TOL,
    SLOPE_TOL,
    TREAD_TOL,
    X0,
    Y0,
    features,
    grid,
    seen_counts,
    stairs_surface,
)


@pytest.mark.parametrize("through", [0.35, 0.70])
def test_a_curb_down_whose_shadow_a_late_view_saw_sparsely(through):
    """A 12 cm curb down, its edge ``through`` of the way through a cell and 4 cm of shadow
    beyond it, as the stance frames saw it (the last cell before the edge holds only the top's
    points); a late viewpoint over the edge put 2 points of the lower surface in each cell of
    the shadow. With ``shadow_sparse_fraction`` 0.25 those cells are the shadow's: the edge
    lies where the last cell's share of points ends (within 1.5 mm); counted as the lower
    surface (0, the default) it lies at that cell's end ((1 - through) of a cell late). Seen
    fully (no shadow), the counts change nothing."""
    from graph_slam.terrain.features.config import FeatureConfig

    edge = X0 + 40 * CELL + through * CELL
    curb = lambda x, y: np.where(x >= edge, -0.12, 0.0)  # noqa: E731

    def shadow(x, y):
        return (x >= edge) & (x < edge + 0.04)

    h, var = grid(curb, 0.001, seed=31, unknown=shadow)
    count = seen_counts(shadow)
    late = np.isnan(h) & (np.arange(NX)[:, None] > 40)
    h[late], var[late], count[late] = -0.12, 1e-6, 2
    on = FeatureConfig(shadow_sparse_fraction=0.25)
    got = extract_features(h, var, (X0, Y0), CELL, count=count, config=on).curbs[0].edge
    assert abs(got.x_m - edge) <= 0.0015, (got.x_m, edge)
    assert got.occluded and 0 < got.sigma_m < 0.005
    plain = extract_features(h, var, (X0, Y0), CELL, count=count).curbs[0].edge  # off
    assert plain.x_m - edge == pytest.approx((1 - through) * CELL, abs=0.0015)
    hf, vf = grid(curb, 0.001, seed=31)
    full = seen_counts(lambda x, y: np.zeros(x.shape, bool))
    seen = extract_features(hf, vf, (X0, Y0), CELL, count=full, config=on).curbs[0].edge
    assert seen.x_m == pytest.approx(features(hf, vf).curbs[0].edge.x_m, abs=1e-9)


@pytest.mark.parametrize(("through", "seed"), [(0.35, 31), (0.70, 32), (0.20, 33)])
def test_a_curb_down_seen_sparsely_beyond_carries_the_span_between_its_readings(through, seed):
    """The curb above: read with the sparse far cells as the lower surface (the default) its
    edge is (1 - through) of a cell late; its σ carries half the span to the reading that
    takes them as not seen (``sparse_span_sigma`` 0.5 of (1 - through) cell, within 1.5 mm),
    so the error stays within 2.5σ. Seen fully, no span: the σ is that of
    ``sparse_span_fraction`` 0 (to 1e-12)."""
    from graph_slam.terrain.features.config import FeatureConfig

    edge = X0 + 40 * CELL + through * CELL
    curb = lambda x, y: np.where(x >= edge, -0.12, 0.0)  # noqa: E731

    def shadow(x, y):
        return (x >= edge) & (x < edge + 0.04)

    h, var = grid(curb, 0.001, seed=seed, unknown=shadow)
    count = seen_counts(shadow)
    late = np.isnan(h) & (np.arange(NX)[:, None] > 40)
    h[late], var[late], count[late] = -0.12, 1e-6, 2
    off = FeatureConfig(sparse_span_fraction=0.0)
    got = extract_features(h, var, (X0, Y0), CELL, count=count).curbs[0].edge
    bare = extract_features(h, var, (X0, Y0), CELL, count=count, config=off).curbs[0].edge
    assert got.x_m == bare.x_m  # the position is the same reading
    span_sigma = math.sqrt(got.sigma_m**2 - bare.sigma_m**2)
    assert span_sigma == pytest.approx(0.5 * (1 - through) * CELL, abs=0.0015)
    assert abs(got.x_m - edge) <= 2.5 * got.sigma_m, (got.x_m - edge, got.sigma_m)
    hf, vf = grid(curb, 0.001, seed=seed)
    full = seen_counts(lambda x, y: np.zeros(x.shape, bool))
    seen = extract_features(hf, vf, (X0, Y0), CELL, count=full).curbs[0].edge
    seen_off = extract_features(hf, vf, (X0, Y0), CELL, count=full, config=off).curbs[0].edge
    assert seen.sigma_m == pytest.approx(seen_off.sigma_m, abs=1e-12)


@pytest.mark.parametrize("slope_deg", [5.0, 8.0, 10.0])
def test_ramp_slope_direction_start(slope_deg):
    g = math.tan(math.radians(slope_deg))
    h, var = grid(lambda x, y: g * np.clip(x - 0.6, 0, None), 0.001, seed=4)
    f = features(h, var)
    assert len(f.ramps) == 1 and not f.stairs and not f.curbs
    (ramp,) = f.ramps
    assert abs(ramp.slope_rad - math.radians(slope_deg)) <= SLOPE_TOL
    assert abs(ramp.uphill_yaw_rad) <= math.radians(2.0)
    assert ramp.start is not None and abs(ramp.start.x_m - 0.6) <= 0.01
    assert 0 < ramp.slope_sigma_rad < SLOPE_TOL


def test_a_ramp_seen_only_up_to_its_top_landing_has_no_start_line():
    """The walker on the slope: the grid holds the ramp and the landing at its top, no level
    ground before it. The landing is no start: the start line is unknown (it was once put at
    the ramp's top, 2.5 m from the true start behind the heel)."""
    g = math.tan(math.radians(8.0))
    h, var = grid(lambda x, y: g * np.clip(x + 1.4, None, 2.5), 0.001, seed=9)
    (ramp,) = features(h, var).ramps
    assert abs(ramp.slope_rad - math.radians(8.0)) <= SLOPE_TOL
    assert ramp.start is None


@pytest.mark.parametrize("height", [0.10, -0.15])
def test_curb_height_and_edge(height):
    h, var = grid(lambda x, y: np.where(x >= 0.711, height, 0.0), 0.001, seed=5)
    f = features(h, var)
    assert len(f.curbs) == 1 and not f.stairs, f
    (curb,) = f.curbs
    assert abs(curb.height_m - height) <= 0.003
    assert abs(curb.edge.x_m - 0.711) <= NOSING_TOL


def test_box_height_leading_edge_depth():
    def box(x, y):
        return np.where((x >= 0.903) & (x < 1.1062) & (y >= -0.4) & (y < -0.1333), 0.1905, 0.0)

    def shadow(x, y):  # the floor behind the box hidden for 6 cm
        return (x >= 1.1062) & (x < 1.166) & (y >= -0.4) & (y < -0.1333)

    f = features(*grid(box, 0.001, seed=6, unknown=shadow))
    assert len(f.boxes) == 1 and not f.stairs and not f.curbs
    (b,) = f.boxes
    assert abs(b.height_m - 0.1905) <= 0.003
    assert abs(b.leading.x_m - 0.903) <= NOSING_TOL
    assert abs(b.depth_m - 0.2032) <= 0.008


def test_level_floor_has_no_feature_and_json_round_trip():
    h, var = grid(lambda x, y: np.zeros_like(x), 0.002, seed=7)
    assert features(h, var).count() == 0
    f = features(*grid(stairs_surface(), 0.001, seed=8))
    back = TerrainFeatures.from_dict(json.loads(json.dumps(f.to_dict())))
    assert back.to_dict() == f.to_dict() and back.stairs[0].steps[1] == f.stairs[0].steps[1]
    assert f.ahead(0.9).stairs[0].n_steps == 4  # the flight reaches beyond 0.9 m
    assert not f.ahead(2.0).stairs
    # the controller's line names the next nosing ahead of the toe (0.793 m from x = 0.6 m)
    assert "next +17.0" in f.summary(0.6) and ", 19." in f.summary(0.6)


def test_sloped_cells_along_one_line_give_no_plane():
    from graph_slam.terrain.features.config import FeatureConfig
    from graph_slam.terrain.features.extract import _ramps
    from graph_slam.terrain.features.model import _Grid

    g = math.tan(math.radians(8.0))
    h, var = grid(lambda x, y: g * np.clip(x - 0.6, 0, None), 0.001, seed=9)
    sloped = np.zeros(h.shape, bool)
    sloped[45:80, 30] = True  # one row of cells: the plane's y slope is undetermined
    cells = _Grid(h, var, np.zeros_like(h), X0, Y0, CELL)
    assert _ramps(cells, sloped, np.zeros(h.shape, int), {}, FeatureConfig()) == []


def test_box_depth_with_flying_pixels_in_its_shadow():
    # behind the box: 4 cm of cells holding only flying pixels (heights in between), then 5 cm
    # not seen, then the floor
    def scene(x, y):
        on = (y >= -0.4) & (y < -0.1333)
        top = np.where((x >= 0.903) & (x < 1.1062) & on, 0.1905, 0.0)
        return np.where((x >= 1.1062) & (x < 1.1462) & on, 0.09, top)

    def shadow(x, y):
        return (x >= 1.1462) & (x < 1.196) & (y >= -0.4) & (y < -0.1333)

    (b,) = features(*grid(scene, 0.001, seed=10, unknown=shadow)).boxes
    assert abs(b.depth_m - 0.2032) <= 0.008
    assert b.leading.occluded is False


def _box_top(x, y):
    on = (y >= -0.4) & (y < -0.1333)
    return np.where((x >= 0.903) & (x < 1.1062) & on, 0.1905, 0.0)


@pytest.mark.parametrize("shadow_m", [0.40, 2.0])
def test_a_box_seen_in_part_is_no_stair(shadow_m):
    """A 19 cm box whose top is seen but the floor behind it is not (a long shadow, or the
    view's end): one up-edge and a 20 cm top is no one-step flight nor a curb, but a box seen
    in part (``far_seen`` False): its leading edge (within 8 mm) and height (3 mm) known, its
    depth the part of the top seen (to the end of its last cell), no trailing edge for the
    clearance; the step-over reference stays on its top past the part seen."""
    from graph_slam.terrain.features.clearance import _edges
    from graph_slam.terrain.features.prediction import step_over_base

    def shadow(x, y):
        return (x >= 1.1062) & (x < 1.1062 + shadow_m) & (y >= -0.4) & (y < -0.1333)

    f = features(*grid(_box_top, 0.001, seed=11, unknown=shadow))
    assert not f.stairs and not f.curbs, f
    (box,) = f.boxes
    assert not box.far_seen
    assert abs(box.height_m - 0.1905) <= 0.003
    assert abs(box.leading.x_at(-0.27) - 0.903) <= NOSING_TOL
    assert 0.15 < box.depth_m <= 0.2032 + CELL and math.isnan(box.depth_sigma_m)  # to a cell's end
    assert [name for name, *_ in _edges(f)] == ["boxes[0].leading"]
    x = np.linspace(0.5, 1.8, 27)
    base = step_over_base(x, box, -0.27, 0.1)
    assert np.allclose(base[x >= 0.903 + NOSING_TOL], box.height_m)
    doc = f.to_dict()
    del doc["boxes"][0]["far_seen"]  # a document from before the field: a whole box
    assert TerrainFeatures.from_dict(doc).boxes[0].far_seen


def test_a_box_trailing_drop_onto_a_short_floor_is_no_stair():
    """The box's leading edge not seen, the floor beyond its trailing edge seen in short pieces
    between holes: one down-edge to a short terrace that goes on at its level is no
    descending flight."""

    def holes(x, y):
        return ((x >= 0.65) & (x < 0.95)) | ((x >= 1.4) & (x < 1.45)) | (x >= 1.6)

    f = features(*grid(_box_top, 0.001, seed=12, unknown=holes))
    assert not f.stairs, f


def test_the_floor_behind_a_box_in_two_pieces_gives_one_box_and_no_curb():
    """Unseen cells wall off the floor behind the box and split it in two along x: the box's
    trailing edge meets two floor terraces. One closes the box; the other is the same box's
    edge, not a curb down."""

    def unseen(x, y):
        behind = x >= 1.1062
        walls = ((y >= -0.42) & (y < -0.4)) | ((y >= -0.1333) & (y < -0.1133))
        split = (y >= -0.28) & (y < -0.26)
        return behind & (walls | split) | ((x >= 1.6) & (x < 1.64))

    f = features(*grid(_box_top, 0.001, seed=14, unknown=unseen))
    assert len(f.boxes) == 1 and not f.curbs and not f.stairs, f
    assert abs(f.boxes[0].depth_m - 0.2032) <= 0.008


def test_a_ramp_slope_sigma_carries_the_pose_tilt():
    """The pose part of the cells' σ growing 2 mm per metre along x (a tilt σ of 2 mrad):
    the slope's σ is at least that; without it, the plane fit's alone (far smaller)."""
    g = math.tan(math.radians(8.0))
    h, var = grid(lambda x, y: g * np.clip(x - 0.6, 0, None), 0.001, seed=17)
    xs = X0 + (np.arange(NX) + 0.5) * CELL
    corr = np.repeat((0.004 + 0.002 * xs)[:, None], NY, axis=1)
    (fit,) = extract_features(h, var, (X0, Y0), CELL).ramps
    (ramp,) = extract_features(h, var + corr**2, (X0, Y0), CELL, corr_sigma_m=corr).ramps
    assert fit.slope_sigma_rad < 0.0005
    cos2 = math.cos(math.radians(8.0)) ** 2
    assert ramp.slope_sigma_rad >= 0.002 * cos2 * 0.95
    assert ramp.slope_sigma_rad <= math.hypot(0.002, fit.slope_sigma_rad * 3)
