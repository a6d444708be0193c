"""The terrain features' σ from the physics of the grid: the points of a step's face in the
cell holding its edge, and a tilt of the frame over the distance between where two surfaces'
heights lie; and a curb down whose lower surface is seen in two pieces. Synthetic grids of
cell means (the layout and helpers of ``tests/test_terrain_features.py``), seeded noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graph_slam.terrain.features.config import FeatureConfig
from graph_slam.terrain.features.extract import extract_features
from tests.test_terrain_features import CELL, NX, X0, Y0, grid, seen_counts

NOTHING_HIDDEN = lambda x, y: np.zeros(x.shape, bool)  # noqa: E731


def _curb_up_seen_face_on(through: float, face_share: float, seed: int):
    """A 12 cm curb up, its edge ``through`` of the way through cell 40, seen face-on: every
    cell holds 192 points of its surfaces and the edge's cell as many more again on the face
    (heights spread over the rise: their mean half of it) as make ``face_share`` of its
    points."""
    edge = X0 + 40 * CELL + through * CELL
    h, var = grid(lambda x, y: np.where(x >= edge, 0.12, 0.0), 0.001, seed=seed)
    count = seen_counts(NOTHING_HIDDEN).astype(np.float64)
    surface = count[40].copy()
    face = surface * face_share / (1.0 - face_share)
    h[40] = (surface * h[40] + face * 0.06) / (surface + face)
    count[40] = surface + face
    return edge, h, var, count


@pytest.mark.parametrize(("through", "seed"), [(0.2, 41), (0.5, 42), (0.85, 43)])
def test_an_edge_seen_face_on_carries_where_it_lies_in_its_cell(through, seed):
    """The face's points pull the edge's cell to half the rise, so the edge comes out
    r·(1/2 - through) of a cell late (r the face's share, 0.75: up to 3/8 cell), the same in
    every row: its σ carries ``face_cell_sigma`` (1/√12) × r of a cell, common to the rows
    (within 0.3 mm), and the error lies within √3 of that (the uniform's bound). Without the
    face's points (even counts) the term is nil."""
    r = 0.75
    edge, h, var, count = _curb_up_seen_face_on(through, r, seed)
    got = extract_features(h, var, (X0, Y0), CELL, count=count).curbs[0].edge
    off = FeatureConfig(face_cell_sigma=0.0)
    bare = extract_features(h, var, (X0, Y0), CELL, count=count, config=off).curbs[0].edge
    err = got.x_m - edge
    assert err == pytest.approx(r * (0.5 - through) * CELL, abs=0.001), err
    face_sigma = math.sqrt(got.sigma_m**2 - bare.sigma_m**2)
    assert face_sigma == pytest.approx(r * CELL / math.sqrt(12), abs=0.0003)
    assert abs(err) <= math.sqrt(3) * face_sigma + 0.0005
    hf, vf = grid(lambda x, y: np.where(x >= edge, 0.12, 0.0), 0.001, seed=seed)
    even = seen_counts(NOTHING_HIDDEN)
    plain = extract_features(hf, vf, (X0, Y0), CELL, count=even).curbs[0].edge
    plain_off = extract_features(hf, vf, (X0, Y0), CELL, count=even, config=off).curbs[0].edge
    assert plain.sigma_m == pytest.approx(plain_off.sigma_m, abs=1e-12)


@pytest.mark.parametrize("tilt", [0.005, -0.004])
def test_a_box_height_carries_the_tilt_over_its_top_to_its_floor(tilt):
    """A 19 cm box 0.9-1.1 m ahead in a frame tilted along x: the floor's height lies where
    its cells lie (about the grid's middle, 0.8 m), the top's at 1.0 m, so the height comes out
    the tilt × that distance off (about 1 mm at 5 mrad); its σ carries the stride tilt's over
    the same distance (error/σ within 0.5-1.5), where the averaged cells alone say under
    0.2 mm."""

    def box(x, y):
        top = (x >= 0.903) & (x < 1.1062) & (np.abs(y) < 0.2)
        return np.where(top, 0.1905, 0.0) + tilt * x

    h, var = grid(box, 0.001, seed=44)
    cfg = FeatureConfig(stride_tilt_sigma_rad=abs(tilt))
    (b,) = extract_features(h, var, (X0, Y0), CELL, config=cfg).boxes
    (plain,) = extract_features(
        h, var, (X0, Y0), CELL, config=FeatureConfig(stride_tilt_sigma_rad=0.0)
    ).boxes
    err = b.height_m - 0.1905
    floor_x = X0 + NX * CELL / 2  # the floor's cells, less the box's few, about the middle
    assert err == pytest.approx(tilt * (1.005 - floor_x), abs=0.0004), err
    assert 0.5 <= abs(err) / b.height_sigma_m <= 1.5, (err, b.height_sigma_m)
    assert plain.height_sigma_m < 0.0002


def _curb_down_in_two_pieces(gap_from: float, gap_to: float, seed: int):
    """A 12 cm curb down at 0.408 m whose lower floor is not seen over [gap_from, gap_to)
    (the edge's own shadow between the cells carried from the previous stride and those the
    views from the top reach)."""
    edge = 0.408
    h, var = grid(
        lambda x, y: np.where(x >= edge, -0.12, 0.0),
        0.001,
        seed=seed,
        unknown=lambda x, y: (x >= gap_from) & (x < gap_to),
    )
    return edge, h, var


@pytest.mark.parametrize("seed", [45, 46])
def test_a_curb_down_whose_lower_floor_is_seen_in_two_pieces(seed):
    """The lower floor seen 0.41-0.68 m, then not for 12 cm (6 cells), then on from 0.80 m:
    one surface at one height across the gap, a curb (edge within 8 mm, height within 3 mm),
    where its near piece alone (27 cm) is short of a curb's 45 cm. A gap over
    ``max_gap_cells`` + 1 (32 cm) is not bridged: no curb."""
    edge, h, var = _curb_down_in_two_pieces(0.68, 0.80, seed)
    f = extract_features(h, var, (X0, Y0), CELL)
    assert len(f.curbs) == 1 and not f.stairs and not f.boxes, f
    (curb,) = f.curbs
    assert abs(curb.edge.x_m - edge) <= 0.008
    assert abs(curb.height_m + 0.12) <= 0.003
    _, h2, var2 = _curb_down_in_two_pieces(0.68, 1.00, seed)
    assert not extract_features(h2, var2, (X0, Y0), CELL).curbs
