"""Level evidence from several small level planes (stair treads): known answers on synthetic
flights (no rendering)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graph_slam.frontend.floor import FloorConfig, fit_floor
from graph_slam.frontend.treads import TreadsConfig, fit_level_planes


def flight_points(
    n_steps: int = 4, tilt_deg: float = 0.0, roll_deg: float = 0.0, seed: int = 0,
    n: int = 8000, noise_m: float = 0.001,
) -> np.ndarray:  # fmt: skip
    """Points (a level frame, z up) of a flight rising along +x: treads 0.28 m deep, 1.2 m
    wide, risers 0.17 m, starting 0.3 m ahead; the whole flight pitched by ``tilt_deg`` about
    y and rolled by ``roll_deg`` about x (a tilted "flight": not level)."""
    rng = np.random.default_rng(seed)
    per = n // (2 * n_steps)
    parts = []
    for k in range(n_steps):
        x0 = 0.3 + 0.28 * k
        tread = np.column_stack([rng.uniform(x0, x0 + 0.28, per), rng.uniform(-0.6, 0.6, per),
                                 np.full(per, 0.17 * k)])  # fmt: skip
        riser = np.column_stack([np.full(per, x0), rng.uniform(-0.6, 0.6, per),
                                 rng.uniform(0.17 * (k - 1), 0.17 * k, per)])  # fmt: skip
        parts += [tread, riser]
    p = np.vstack(parts)
    p += rng.normal(0.0, noise_m, p.shape)
    a, b = math.radians(tilt_deg), math.radians(roll_deg)
    ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    return p @ (rx @ ry).T


def test_a_flight_fails_the_floor_fit_but_its_treads_give_level():
    pts = flight_points()
    assert not fit_floor(pts, np.array([0.0, 0.0, 1.0])).ok  # a tread is too shallow a floor
    hint = np.array([0.0, math.sin(math.radians(1.0)), math.cos(math.radians(1.0))])  # 1° off
    lp = fit_level_planes(pts, hint)
    assert lp.ok and lp.n_planes >= 2
    assert math.degrees(math.acos(lp.normal[2])) < 0.05  # level within 0.05°
    assert math.degrees(lp.angle_to_hint_rad) == pytest.approx(1.0, abs=0.05)
    assert lp.sigma_rad == pytest.approx(TreadsConfig().sigma_min_rad)
    # the treads' heights: multiples of the rise below the origin (n·p + d = 0, d = -z)
    heights = sorted(-d for d in lp.offsets_m)
    assert np.allclose(np.diff(heights), 0.17, atol=0.002)


def test_the_risers_foot_does_not_tilt_a_tread():
    """Within the floor fit's 1 cm band a tread takes in its riser's foot and the next
    riser's top: on 0.28 m that tilted the pitch by up to 1.8° on the simulator; the 5 mm
    band and the trimmed edges keep it level."""
    pts = flight_points(noise_m=0.002, seed=1)
    lp = fit_level_planes(pts, np.array([0.0, 0.0, 1.0]))
    assert lp.ok
    assert abs(math.degrees(math.asin(lp.normal[0]))) < 0.1  # the pitch along the flight
    wide = TreadsConfig(distance_m=0.01, edge_trim=0.0)  # the floor fit's band, no trimming
    loose = fit_level_planes(pts, np.array([0.0, 0.0, 1.0]), config=wide)
    assert abs(math.degrees(math.asin(loose.normal[0]))) > 0.3


def test_a_tilted_flight_gives_its_own_tilt():
    """The planes are only as level as the ground: the caller gates them."""
    lp = fit_level_planes(flight_points(roll_deg=2.0), np.array([0.0, 0.0, 1.0]))
    assert lp.ok
    assert math.degrees(lp.angle_to_hint_rad) == pytest.approx(2.0, abs=0.05)


def test_nothing_level_in_view():
    rng = np.random.default_rng(2)
    wall = np.column_stack([np.full(4000, 1.0), rng.uniform(-1, 1, 4000), rng.uniform(0, 1, 4000)])
    lp = fit_level_planes(wall, np.array([0.0, 0.0, 1.0]))
    assert not lp.ok and lp.reason.startswith("no_level_plane")
    narrow = flight_points()
    narrow[:, 1] *= 0.2  # 0.24 m wide treads: too narrow to fix a roll
    assert not fit_level_planes(narrow, np.array([0.0, 0.0, 1.0]), FloorConfig()).ok
