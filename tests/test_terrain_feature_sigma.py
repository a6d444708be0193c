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
from graph_slam.terrain.features.kinds import _common_m2, _face_correlation, _tread
from graph_slam.terrain.features.model import EdgeLine
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


def _line(x_m: float, sigma_m: float) -> EdgeLine:
    return EdgeLine(x_m, 0.0, 0.0, sigma_m, 1e-3, (-0.3, 0.3), 30)


@pytest.mark.parametrize(("delta", "seed"), [(0.0, 51), (0.3, 52), (0.5, 53), (0.85, 54)])
def test_two_face_on_nosings_correlate_by_the_treads_fraction_of_a_cell(delta, seed):
    """Two edges seen face-on a tread apart: each is off by r (1/2 - f) of a cell, f where it
    lies in its cell (uniform), the second at f + δ (mod 1). Monte Carlo over f (200 000
    draws): their correlation is 1 - 6 δ (1 - δ) (within 0.01), the tread known exactly; a
    tread known to 1 cell or more leaves them independent (within 0.01)."""
    f = np.random.default_rng(seed).uniform(0.0, 1.0, 200_000)
    a, b = 0.5 - f, 0.5 - np.mod(f + delta, 1.0)
    rho = float(np.corrcoef(a, b)[0, 1])
    assert _face_correlation(14 + delta, 0.0) == pytest.approx(rho, abs=0.01)
    assert _face_correlation(14 + delta, 0.0) == pytest.approx(
        1 - 6 * delta * (1 - delta), abs=0.01
    )
    assert abs(_face_correlation(14 + delta, 1.0)) < 0.01


def test_a_tread_between_nosings_carried_together_loses_the_carrys_shift():
    """Two nosings carried from the previous stride by one relative stride pose move by the
    same shift: their carried terms (3 mm) cancel in the tread, which keeps only the rest of
    their σ (1 and 2 mm: √5 mm, to 1e-12); one carried and one seen: all of both."""
    carried = FeatureConfig().carried_edge_sigma_m
    a = {"line": _line(0.27, math.hypot(0.001, carried)), "carried_m": carried}
    b = {"line": _line(0.55, math.hypot(0.002, carried)), "carried_m": carried}
    _, sigma = _tread(a["line"], b["line"], 0.0, _common_m2(a, b, CELL))
    assert sigma == pytest.approx(math.sqrt(5e-6), abs=1e-12)
    seen = {"line": _line(0.55, 0.002)}
    _, sigma = _tread(a["line"], seen["line"], 0.0, _common_m2(a, seen, CELL))
    assert sigma == pytest.approx(math.sqrt(0.001**2 + carried**2 + 0.002**2), abs=1e-12)


@pytest.mark.parametrize(("tread_cells", "cancels"), [(14.0, True), (14.5, False)])
def test_a_tread_between_face_on_nosings_at_the_same_place_in_their_cells(tread_cells, cancels):
    """Two nosings seen face-on, their σ the face terms alone (5 mm): a tread of a whole
    number of cells puts both at the same place in their cells and the face terms cancel
    (σ 0, to 1e-9); half a cell on they anticorrelate -1/2 (σ² = 3 · 25 mm², to 1e-9). Known
    to 1 mm each besides, where the second lies is blurred: σ between the two."""
    face = 0.005
    a = {"line": _line(0.5, face), "face_m": face}
    b = {"line": _line(0.5 + tread_cells * CELL, face), "face_m": face}
    _, sigma = _tread(a["line"], b["line"], 0.0, _common_m2(a, b, CELL))
    assert sigma == pytest.approx(0.0 if cancels else math.sqrt(3) * face, abs=1e-9)
    a["line"], b["line"] = (_line(L.x_m, math.hypot(0.001, face)) for L in (a["line"], b["line"]))
    _, blurred = _tread(a["line"], b["line"], 0.0, _common_m2(a, b, CELL))
    independent = math.sqrt(2) * math.hypot(0.001, face)
    lo, hi = sorted((math.hypot(math.sqrt(2e-6), sigma), independent))
    assert lo < blurred < hi if cancels else blurred > independent


def test_the_carried_edge_sigma_is_the_relative_stride_poses_error():
    """The default carried-edge σ is the RMS horizontal error of the estimated relative
    stride pose over the simulated terrain walker's strikes (3.0 mm), not the 9 mm the carry
    left before its cells were shared by area."""
    assert FeatureConfig().carried_edge_sigma_m == pytest.approx(0.003)
