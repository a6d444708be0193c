"""Terrain features on synthetic height grids with known answers: stairs (rises, treads,
nosings and their σ, up and down, seen in part, in shadow, smeared, tilted). The grids and
tolerances: ``tests/terrain_grid_helpers.py``."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from graph_slam.terrain.features.extract import extract_features
from tests.terrain_grid_helpers import (
    CELL,
    NOSING_TOL,
    NX,
    RISE_TOL,
    TREAD_TOL,
    X0,
    Y0,
    features,
    grid,
    seen_counts,
    stairs_surface,
)


@pytest.mark.parametrize("noise", [0.0, 0.002])
def test_staircase_rises_treads_nosings(noise):
    f = features(*grid(stairs_surface(), noise, seed=1))
    assert len(f.stairs) == 1 and not f.curbs and not f.boxes
    (st,) = f.stairs
    assert st.n_steps == 4 and st.ascending
    for k, step in enumerate(st.steps):
        assert abs(step.rise_m - 0.17) <= RISE_TOL
        assert abs(step.nosing.x_m - (0.513 + 0.28 * k)) <= NOSING_TOL
        assert abs(step.nosing.yaw_rad) <= math.radians(1.0)
        assert 0 < step.nosing.sigma_m < 0.01 and 0 < step.rise_sigma_m < 0.003
        if k < 3:
            assert abs(step.tread_m - 0.28) <= TREAD_TOL
        else:
            assert math.isnan(step.tread_m)


def test_staircase_partial_view_and_yaw():
    # seen only to x = 1.0 m and on y < 0.3 m: two nosings
    h, var = grid(stairs_surface(yaw_deg=10.0), 0.001, seed=2,
                  unknown=lambda x, y: (x > 1.0) | (y > 0.3))  # fmt: skip
    (st,) = features(h, var).stairs
    assert st.n_steps == 2
    for k, step in enumerate(st.steps):
        assert abs(step.nosing.x_at(0.0) - (0.513 + 0.28 * k)) <= NOSING_TOL
        assert abs(step.nosing.yaw_rad - math.radians(10.0)) <= math.radians(1.5)
        assert abs(step.rise_m - 0.17) <= RISE_TOL
    assert abs(st.steps[0].tread_m - 0.28 * math.cos(math.radians(10))) <= TREAD_TOL


@pytest.mark.parametrize("seed", [11, 13, 14, 15])
def test_a_tread_to_a_nosing_seen_in_a_few_rows_at_the_side(seed):
    """A flight yawed 3°, its second nosing seen only in the 4 rows at the grid's side (y <
    -0.52 m), 3 mm noise: that line's yaw is off by up to 0.8°. The tread is taken where both
    nosings were seen: within 2 mm of the truth and 3σ (its σ holds each line's yaw σ over
    the distance from its point); the next line extrapolated half a metre to the first's
    point is 5-8 mm off with these seeds."""
    yaw = math.radians(3.0)
    h, var = grid(stairs_surface(n=2, yaw_deg=3.0), 0.003, seed=seed,
                  unknown=lambda x, y: (x > 0.75) & (y > -0.52))  # fmt: skip
    (st,) = features(h, var).stairs
    first, second = st.steps
    assert second.nosing.rows == 4 and first.nosing.y_range_m[1] > 0.5
    truth = 0.28 * math.cos(yaw)
    err = first.tread_m - truth
    assert abs(err) <= 0.002, (first.tread_m, err)
    assert abs(err) <= 3 * first.tread_sigma_m, (err, first.tread_sigma_m)
    here, nxt = first.nosing, second.nosing
    extrapolated = (nxt.x_at(here.y_m) - here.x_m) * math.cos(here.yaw_rad)
    assert abs(extrapolated - truth) > 0.005


def test_descending_stairs_with_the_shadow_behind_each_nosing():
    down = stairs_surface(first=0.507, rise=-0.16, tread=0.3, n=3)

    def shadow(x, y):  # 5 cm beyond each nosing not seen from above
        u = (x - 0.507) % 0.3
        return (x > 0.507) & (x < 0.507 + 0.3 * 3) & (u < 0.05)

    (st,) = features(*grid(down, 0.001, seed=3, unknown=shadow)).stairs
    assert st.n_steps == 3 and not st.ascending
    for k, step in enumerate(st.steps):
        assert abs(step.rise_m + 0.16) <= RISE_TOL
        assert abs(step.nosing.x_m - (0.507 + 0.3 * k)) <= NOSING_TOL
        assert step.nosing.occluded


def test_a_tilted_stride_frame_moves_each_rise_by_the_tilt_times_the_tread():
    """The flight seen in a frame tilted 5 mrad up along x: each rise comes out 5 mrad × the
    distance between the middles of the two terraces high (1.4 mm between treads 28 cm
    apart); its σ carries the stride tilt's (``stride_tilt_sigma_rad``) over the distance
    between where their heights lie (their level cells' mean x: about their middles), where
    the averaged cells alone would say under 0.3 mm."""
    from graph_slam.terrain.features.config import FeatureConfig

    tilt = 0.005
    base = stairs_surface()
    h, var = grid(lambda x, y: base(x, y) + tilt * x, 0.001, seed=22)
    with_tilt = FeatureConfig(stride_tilt_sigma_rad=tilt)
    steps = extract_features(h, var, (X0, Y0), CELL, config=with_tilt).stairs[0].steps
    bare = extract_features(h, var, (X0, Y0), CELL, config=FeatureConfig(stride_tilt_sigma_rad=0))
    # the terraces' middles: the floor from the grid's start, the treads, the top to its end
    bounds = [X0] + [0.513 + 0.28 * k for k in range(4)] + [X0 + NX * CELL]
    middles = [(a + b) / 2 for a, b in itertools.pairwise(bounds)]
    assert len(steps) == 4
    for k, (step, plain) in enumerate(zip(steps, bare.stairs[0].steps, strict=True)):
        err = step.rise_m - 0.17
        assert abs(err - tilt * (middles[k + 1] - middles[k])) <= 0.0006, (k, err)
        assert 0.8 <= abs(err) / step.rise_sigma_m <= 1.5
        assert plain.rise_sigma_m < 0.0003


def test_an_edge_seen_only_in_carried_cells_carries_the_carry_sigma():
    """Counts 0 on both sides of every nosing (cells carried from the previous stride): each
    nosing's σ holds ``carried_edge_sigma_m``; with this stride's points there it does not."""
    from graph_slam.terrain.features.config import FeatureConfig

    h, var = grid(stairs_surface(), 0.001, seed=23)
    carried = extract_features(h, var, (X0, Y0), CELL, count=np.zeros(h.shape))
    seen = extract_features(h, var, (X0, Y0), CELL, count=np.full(h.shape, 50.0))
    s_c = FeatureConfig().carried_edge_sigma_m
    for a, b in zip(carried.stairs[0].steps, seen.stairs[0].steps, strict=True):
        assert a.nosing.x_m == pytest.approx(b.nosing.x_m)
        assert s_c <= a.nosing.sigma_m <= math.hypot(s_c, b.nosing.sigma_m) + 1e-9
        assert b.nosing.sigma_m < 0.002


def test_descending_nosings_placed_by_the_points_of_the_last_cell_seen():
    """Nosings 0.35, 0.70 and 0.05 of the way through a cell, the shadow beyond each: without
    the counts the edge is put 0.65 through the last cell seen (up to 7 mm off); with them,
    where the last cell's share of points ends (within 1.5 mm: the samples lie 2.5 mm apart)."""
    first, tread = 0.507, 0.287
    down = stairs_surface(first=first, rise=-0.16, tread=tread, n=3)

    def shadow(x, y):
        u = (x - first) % tread
        return (x > first) & (x < first + tread * 3) & (u < 0.06)

    h, var = grid(down, 0.001, seed=21, unknown=shadow)
    truth = [first + tread * k for k in range(3)]
    plain = extract_features(h, var, (X0, Y0), CELL).stairs[0].steps
    counted = extract_features(h, var, (X0, Y0), CELL, count=seen_counts(shadow)).stairs[0].steps
    plain_err = [abs(s.nosing.x_m - t) for s, t in zip(plain, truth, strict=True)]
    assert max(plain_err) > 0.004  # the fixed guess is off where the nosing is early in its cell
    for step, t in zip(counted, truth, strict=True):
        assert step.nosing.occluded
        assert abs(step.nosing.x_m - t) <= 0.0015, (step.nosing.x_m, t)
        assert 0 < step.nosing.sigma_m < 0.005


@pytest.mark.parametrize("seed", [23, 24])
def test_a_tread_between_two_counted_nosings_takes_their_errors_as_correlated(seed):
    """The flight above: both nosings of a tread have their shadow part from the counts, so
    the tread's variance is σ1² + σ2² - 2ρσ1σ2 with ρ ``shadow_count_common`` (to 1e-12; the
    lines both at y = 0, no lever); placed without the counts (the fixed guess, independent
    per nosing) it is σ1² + σ2². The treads lie within 3σ of the truth (0.287 m)."""
    from graph_slam.terrain.features.config import FeatureConfig

    first, tread = 0.507, 0.287
    down = stairs_surface(first=first, rise=-0.16, tread=tread, n=3)

    def shadow(x, y):
        u = (x - first) % tread
        return (x > first) & (x < first + tread * 3) & (u < 0.06)

    h, var = grid(down, 0.001, seed=seed, unknown=shadow)
    count = seen_counts(shadow)
    rho = FeatureConfig().shadow_count_common
    assert 0 < rho < 1
    for kwargs, r in (({"count": count}, rho), ({}, 0.0)):
        steps = extract_features(h, var, (X0, Y0), CELL, **kwargs).stairs[0].steps
        assert len(steps) == 3
        for here, nxt in itertools.pairwise(steps):
            a, b = here.nosing, nxt.nosing
            assert a.y_m == b.y_m == 0.0
            want = a.sigma_m**2 + b.sigma_m**2 - 2 * r * a.sigma_m * b.sigma_m
            assert here.tread_sigma_m**2 == pytest.approx(want, abs=1e-12)
            assert abs(here.tread_m - tread) <= 3 * here.tread_sigma_m, (here.tread_m, seed)


@pytest.mark.parametrize("rise", [0.17, -0.16])
def test_one_step_seen_with_the_next_riser_beyond_it_is_a_stair(rise):
    """Seen up to 4 cm past the second nosing: the cells there are no terrace of their own,
    but they lie a further rise on, so the first tread is a tread and its nosing a step."""
    h, var = grid(stairs_surface(rise=rise), 0.001, seed=13,
                  unknown=lambda x, y: x > 0.513 + 0.28 + 0.04)  # fmt: skip
    f = features(h, var)
    assert len(f.stairs) == 1 and not f.curbs, f
    (step,) = f.stairs[0].steps
    assert abs(step.rise_m - rise) <= RISE_TOL
    assert abs(step.nosing.x_m - 0.513) <= NOSING_TOL


def test_a_long_smear_behind_each_nosing_still_gives_every_step():
    """Beyond each nosing of a descent: 4 cm not seen, then 14 cm of cells at heights between
    the treads (the fused edge of the lower tread), then the lower tread. Its cells by that
    smear are not level (their window holds it), so the level cells of two treads lie more
    than ``max_gap_cells`` apart; each terrace grows back over the cells still on its surface,
    and every step is found."""
    rise, first, tread = -0.16, 0.52, 0.36
    down = stairs_surface(first=first, rise=rise, tread=tread, n=3)

    def surface(x, y):
        u = (x - first) % tread
        k = np.floor((x - first) / tread)
        smear = (x > first) & (x < first + tread * 3) & (u >= 0.04) & (u < 0.18)
        return np.where(smear, k * rise + rise * (u - 0.04) / 0.14 * 0.8, down(x, y))

    def shadow(x, y):
        u = (x - first) % tread
        return (x > first) & (x < first + tread * 3) & (u < 0.04)

    (st,) = features(*grid(surface, 0.001, seed=15, unknown=shadow)).stairs
    assert st.n_steps == 3
    for k, step in enumerate(st.steps):
        assert abs(step.nosing.x_m - (first + tread * k)) <= NOSING_TOL


def test_flying_pixels_beyond_a_nosing_are_not_the_tread():
    """Beyond each nosing of a descent, the first cell is held only by the depth edge's flying
    pixels (heights near the upper tread's, depth-noise σ 10 cm) and the next 3 cm not at
    all: given the noise σ, those cells are not seen and the nosing is not put a cell late."""
    rise, first, tread = -0.17, 0.52, 0.28
    down = stairs_surface(first=first, rise=rise, tread=tread, n=3)

    def shadow(x, y):
        u = (x - first) % tread
        return (x > first) & (x < first + tread * 3) & (u < 0.05)

    h, var = grid(down, 0.001, seed=16, unknown=shadow)
    noise = np.full(h.shape, 0.001)
    for k in range(3):  # the cell just past nosing k: flying pixels at the upper tread's height
        i = round((first + tread * k - X0) / CELL)
        h[i, :], var[i, :], noise[i, :] = k * rise - 0.004, 0.1**2, 0.1
    args = (h, var, (X0, Y0), CELL)
    seen_all = extract_features(*args).stairs[0].steps
    masked = extract_features(*args, noise_sigma_m=noise).stairs[0].steps
    assert len(masked) == 3
    for k, step in enumerate(masked):
        assert abs(step.nosing.x_m - (first + tread * k)) <= NOSING_TOL
        assert step.nosing.sigma_m >= 0.2 * CELL  # the shadow's start within the last cell
    assert all(s.nosing.x_m - (first + tread * k) > 0.012 for k, s in enumerate(seen_all))
