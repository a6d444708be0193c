"""The toe's clearance: an analytic toe path over an analytic step, the stance-time
prediction's warning just above and just below the threshold, the toe from the leg model."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.terrain.features.clearance import (
    ClearanceConfig,
    clearance_along,
    toe_path,
)
from graph_slam.terrain.features.extract import extract_features
from graph_slam.terrain.features.prediction import predict_clearance, reference_swing
from tests.test_terrain_features import CELL, X0, Y0, grid


def view_of(h, var):
    """What the clearance reads of a TerrainView, from the arrays."""
    return SimpleNamespace(
        height_m=h, sigma_m=np.sqrt(var), origin_xy_m=np.array([X0, Y0]), cell_m=CELL, toe_x_m=0.2
    )


def test_clearance_of_an_analytic_toe_path_over_an_analytic_step():
    edge, rise = 0.713, 0.15

    def surface(x, y):
        return np.where(x >= edge, rise, 0.0)

    h, var = grid(surface, 0.001, seed=1)
    feats = extract_features(h, var, (X0, Y0), CELL)
    assert len(feats.curbs) == 1
    # a parabola whose lowest point over the step is at the nosing: z = rise + c + k (x - edge)²
    x = np.linspace(0.3, 1.2, 400)
    for c in (0.005, 0.02, 0.05):
        z = rise + c + 2.0 * (x - edge) ** 2
        path = np.column_stack([x, np.full_like(x, 0.05), z])
        true = float(np.min(z - surface(x, 0.0)))
        got = clearance_along(view_of(h, var), feats, path)
        assert abs(got.min_m - true) <= 0.003, (c, got)
        assert got.edge == "curbs[0]" and abs(got.x_m - edge) <= 0.01
        assert 0 < got.sigma_m < 0.006  # the rise's: mostly the stride tilt over the terraces' 1 m


def _box_case(height, x0=0.8, depth=0.2):
    def surface(x, y):
        return np.where((x >= x0) & (x < x0 + depth) & (np.abs(y) < 0.15), height, 0.0)

    h, var = grid(surface, 0.0005, seed=2)
    return view_of(h, var), extract_features(h, var, (X0, Y0), CELL)


def _true_box(height, x0=0.8, depth=0.2):
    from graph_slam.terrain.features.model import BoxFeature, EdgeLine, TerrainFeatures

    lead = EdgeLine(x0, 0.0, 0.0, 0.0, 0.0, (-0.15, 0.15), 0, False)
    return TerrainFeatures(source="truth", boxes=(BoxFeature(height, 0.0, lead, depth, 0.0),))


def test_the_step_over_reference_rides_its_lift_over_the_box_top():
    """A 12 cm box 60 cm ahead of the toe: the reference steps over it (its base line at the
    top over the box, lift_m·√sin(πs) above), and lands on the floor past it."""
    cfg = ClearanceConfig()
    view, feats = _box_case(0.12)
    path, kind = reference_swing(view, feats, (0.2, 0.0), cfg)
    assert kind == "step_over"
    s = np.linspace(0.0, 1.0, cfg.samples)
    over = (path[:, 0] >= 0.8) & (path[:, 0] < 1.0)
    want = 0.12 + cfg.lift_m * np.sqrt(np.sin(np.pi * s[over]))
    assert np.allclose(path[over, 2], want, atol=0.001)
    assert abs(path[-1, 2]) <= 0.002 and abs(path[0, 2]) <= 0.002
    c = predict_clearance(view, feats, (0.2, 0.0), cfg)
    assert c.terrain == "step_over" and not c.warning and c.edge_m > 0.03


def test_a_box_the_swing_runs_onto_is_landed_on():
    """A box 40 cm ahead running past the landing: the path lands on its top."""
    view, feats = _box_case(0.1, x0=0.6, depth=1.0)
    path, kind = reference_swing(view, feats, (0.2, 0.0))
    assert kind == "step_over"
    assert path[-1, 2] == pytest.approx(0.1, abs=0.002)


@pytest.mark.parametrize(("lift", "warn"), [(0.022, True), (0.03, False)])
def test_step_over_warns_below_the_margin_as_the_analytic_box_gives(lift, warn):
    """The step-over reference's edge clearance over a 12 cm box found on a grid equals the
    one over the true box (within 1 mm); with a lift of 2.2 cm it clears the box's corners by
    under 2 cm (warning), with 3 cm by over 2 cm (none)."""
    from graph_slam.terrain.features.clearance import edge_clearance

    cfg = ClearanceConfig(lift_m=lift)
    view, feats = _box_case(0.12)
    assert len(feats.boxes) == 1
    got = predict_clearance(view, feats, (0.2, 0.0), cfg)
    path, _ = reference_swing(view, _true_box(0.12), (0.2, 0.0), cfg)
    want = edge_clearance(_true_box(0.12), path[cfg.mid_swing_mask(len(path))], cfg).min_m
    assert abs(got.edge_m - want) <= 0.001, (got, want)
    assert (want < cfg.warn_below_m) is warn and got.warning is warn
    assert abs(want - cfg.warn_below_m) >= 0.002  # each case clearly on its side


def test_level_ground_gives_the_reference_lift_and_no_warning():
    h, var = grid(lambda x, y: np.zeros_like(x), 0.001, seed=3)
    view = view_of(h, var)
    feats = extract_features(h, var, (X0, Y0), CELL)
    c = predict_clearance(view, feats)
    assert not c.warning and c.edge == "ground" and c.min_m > 0


def test_toe_path_follows_the_leg_model():
    from kinematics.leg_model import LegModel

    model = LegModel()
    q = np.array([[0.1, 0.05], [0.6, -0.1]])
    pose = np.eye(4)
    pose[:3, 3] = [0.3, 0.0, 0.8]
    got = toe_path(np.stack([pose, pose]), q, model)
    for k in range(2):
        want = pose @ model.frame_T_frame("camera_optical", "toe", q[k])
        assert np.allclose(got[k], want[:3, 3])
    assert not np.allclose(got[0], got[1])
    assert math.isfinite(got.sum())


@pytest.mark.parametrize("n", [0])
def test_unknown_terrain_gives_no_clearance(n):
    h = np.full((100, 60), np.nan)
    c = clearance_along(view_of(h, h), extract_features(h, h, (X0, Y0), CELL), np.zeros((3, 3)))
    assert c.edge == "unknown" and math.isnan(c.min_m)


def test_a_flight_beside_the_path_leaves_the_reference_level():
    from graph_slam.terrain.features.prediction import terrain_type
    from tests.test_terrain_features import stairs_surface

    def beside(x, y):  # the flight only at y < -0.2 m
        return np.where(y < -0.2, stairs_surface()(x, y), 0.0)

    h, var = grid(beside, 0.001, seed=4)
    feats = extract_features(h, var, (X0, Y0), CELL)
    assert feats.stairs
    assert terrain_type(feats, 0.2, 1.5, 0.0)[0] == "level"
    assert terrain_type(feats, 0.2, 1.5, -0.4)[0] == "stairs_up"


def _curb(x_m=0.7, rise=0.15):
    from graph_slam.terrain.features.model import Curb, EdgeLine, TerrainFeatures

    edge = EdgeLine(x_m, 0.0, 0.0, 0.001, 0.001, (-0.6, 0.6), 20, False)
    return TerrainFeatures(source="test", curbs=(Curb(rise, 0.001, edge, 0.0),))


def test_edge_clearance_is_the_distance_to_the_step_profile():
    """A toe skimming 12 mm over a 15 cm curb's top, one rising 17 mm in front of its face,
    one passing through it; sampled every 5 cm or every millimetre: the same (the path is
    resampled)."""
    from graph_slam.terrain.features.clearance import edge_clearance

    feats = _curb()
    x = np.linspace(0.3, 1.1, 17)  # 5 cm apart
    skim = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.162)])
    fine = np.column_stack([np.linspace(0.3, 1.1, 801), np.zeros(801), np.full(801, 0.162)])
    for path in (skim, fine):
        c = edge_clearance(feats, path)
        assert c is not None and c.edge == "curbs[0]"
        assert c.min_m == pytest.approx(0.012, abs=1e-6)
    # up the face 17 mm before it, then forward 5 cm above the top
    rise = np.column_stack([np.full(10, 0.683), np.zeros(10), np.linspace(0.01, 0.2, 10)])
    over = np.column_stack([np.linspace(0.683, 0.9, 10), np.zeros(10), np.full(10, 0.2)])
    c = edge_clearance(feats, np.vstack([rise, over]))
    assert c.min_m == pytest.approx(0.017, abs=1e-6)
    # through the curb 3 cm below its top: negative
    low = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.12)])
    assert edge_clearance(feats, low).min_m < -0.02


def test_level_floor_has_no_edge_clearance_and_no_warning():
    """On level floor the toe passes 1 cm over the ground: under the 2 cm margin, but no edge
    is crossed, so no edge clearance and no warning."""
    from graph_slam.terrain.features.clearance import edge_clearance

    h, var = grid(lambda x, y: np.zeros_like(x), 0.001, seed=5)
    feats = extract_features(h, var, (X0, Y0), CELL)
    x = np.linspace(0.2, 1.5, 60)
    path = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.01)])
    assert edge_clearance(feats, path) is None
    c = predict_clearance(view_of(h, var), feats, (0.2, 0.0), ClearanceConfig(lift_m=0.01))
    assert c.min_m < 0.02 and not c.warning and math.isnan(c.edge_m)


def test_cells_with_a_large_sigma_are_not_the_terrain():
    """A level floor with a patch of cells 4 cm high but σ 6 cm (garbage points): the toe's
    clearance is read over the trusted cells only; with the gate opened the patch wins."""
    h, var = grid(lambda x, y: np.zeros_like(x), 0.001, seed=6)
    i, j = int((1.1 - X0) / CELL), int((0.0 - Y0) / CELL)
    h, var = h.copy(), var.copy()
    h[i - 1 : i + 2, j - 1 : j + 2], var[i - 1 : i + 2, j - 1 : j + 2] = 0.04, 0.06**2
    x = np.linspace(0.4, 1.4, 50)
    path = np.column_stack([x, np.full_like(x, 0.005), np.full_like(x, 0.05)])
    feats = extract_features(h, var, (X0, Y0), CELL)
    got = clearance_along(view_of(h, var), feats, path)
    assert got.min_m == pytest.approx(0.05, abs=0.005)
    loose = clearance_along(view_of(h, var), feats, path, ClearanceConfig(max_cell_sigma_m=1.0))
    assert loose.min_m == pytest.approx(0.01, abs=0.003)


def test_the_true_clearance_is_over_the_surface_under_the_toe():
    from graph_slam.evaluation.clearance import true_swing_clearance

    class Step:
        def height_at(self, x, y):
            return np.where(np.asarray(x) >= 1.0, 0.1, 0.0)

    scene = SimpleNamespace(surfaces=Step())
    toe = np.array([[0.995, 0.0, 0.05], [1.005, 0.0, 0.13], [0.5, 0.0, 0.06]])
    assert true_swing_clearance(scene, np.eye(4), toe) == pytest.approx(0.03)
    lifted = np.eye(4)
    lifted[2, 3] = 0.01  # the stride frame 1 cm above the world: the surface 1 cm lower in it
    assert true_swing_clearance(scene, lifted, toe) == pytest.approx(0.04)


def test_poses_between_frames_follow_the_arc():
    from graph_slam.terrain.features.clearance import interpolate_poses

    def rot_y(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    a, b = np.eye(4), np.eye(4)
    b[:3, :3], b[:3, 3] = rot_y(0.8), [0.2, 0.0, 0.1]
    got = interpolate_poses(np.array([0.0, 0.04]), np.stack([a, b]), np.array([0.0, 0.01, 0.04]))
    assert np.allclose(got[0], a) and np.allclose(got[2], b)
    assert np.allclose(got[1][:3, :3], rot_y(0.2)) and np.allclose(got[1][:3, 3], [0.05, 0, 0.025])


def test_the_reference_descent_clears_the_nosing_it_leaves():
    """Stairs down 34 cm ahead of the toe: the reference toe stays at the lift over the tread
    it leaves until past that nosing (no warning), and lands a step lower."""
    h, var = grid(lambda x, y: np.where(x >= 0.55, -0.17 * (1 + np.floor((x - 0.55) / 0.28)), 0.0),
                  0.001, seed=7)  # fmt: skip
    feats = extract_features(h, var, (X0, Y0), CELL)
    path, kind = reference_swing(view_of(h, var), feats, (0.21, 0.0))
    assert kind == "stairs_down"
    assert path[-1, 2] == pytest.approx(-0.17, abs=0.01)
    c = predict_clearance(view_of(h, var), feats, (0.21, 0.0))
    assert c.edge_m > 0.02 and not c.warning


def test_edge_clearance_sigma_follows_the_part_of_the_profile_nearest():
    """Over the curb's top its σ is the top's height σ; beside its face the edge's position
    σ and the toe's along the ground; past its corner at 45° both, each times cos 45°; the
    toe's own σ adds in quadrature."""
    from graph_slam.terrain.features.clearance import ClearanceConfig, edge_clearance
    from graph_slam.terrain.features.model import Curb, EdgeLine, TerrainFeatures

    s_x, s_h, s_t = 0.004, 0.002, 0.003
    edge = EdgeLine(0.7, 0.0, 0.0, s_x, 0.001, (-0.6, 0.6), 20, False)
    feats = TerrainFeatures(source="test", curbs=(Curb(0.15, s_h, edge, 0.0),))
    cfg = ClearanceConfig(toe_along_sigma_m=s_t)
    x = np.linspace(0.72, 0.74, 5)
    over = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.17)])
    assert edge_clearance(feats, over, cfg).sigma_m == pytest.approx(s_h, rel=1e-6)
    beside = np.column_stack([np.full(5, 0.68), np.zeros(5), np.linspace(0.05, 0.1, 5)])
    assert edge_clearance(feats, beside, cfg).sigma_m == pytest.approx(math.hypot(s_x, s_t))
    no_toe = ClearanceConfig(toe_along_sigma_m=0.0)
    assert edge_clearance(feats, beside, no_toe).sigma_m == pytest.approx(s_x, rel=1e-6)
    corner = np.array([[0.68, 0.0, 0.17], [0.6, 0.0, 0.25]])  # 2 cm before and above it
    c = edge_clearance(feats, corner, no_toe)
    assert c.min_m == pytest.approx(math.hypot(0.02, 0.02), rel=1e-6)
    assert c.sigma_m == pytest.approx(math.hypot(s_x, s_h) / math.sqrt(2), rel=1e-6)
    c = edge_clearance(feats, corner, ClearanceConfig(toe_sigma_m=0.003, toe_along_sigma_m=0))
    assert c.sigma_m == pytest.approx(math.sqrt((s_x**2 + s_h**2) / 2 + 0.003**2), rel=1e-6)


def test_the_reference_is_up_a_near_curb_by_its_edge():
    """A 10 cm curb 21 cm ahead of the toe (before mid-swing): the base line is up by the
    edge, so the toe passes it the lift there high (5 cm·√sin(π·0.16), 3.5 cm) and raises no
    warning; one 80 cm ahead is reached by mid-swing as before."""
    for edge_x, reach_x in ((0.41, 0.41), (1.0, 0.85)):
        h, var = grid(lambda x, y, e=edge_x: np.where(x >= e, 0.10, 0.0), 0.0005, seed=8)
        feats = extract_features(h, var, (X0, Y0), CELL)
        assert len(feats.curbs) == 1
        cfg = ClearanceConfig()
        path, kind = reference_swing(view_of(h, var), feats, (0.2, 0.0), cfg)
        assert kind == "curb"
        s = (path[:, 0] - 0.2) / cfg.stride_length_m
        lift = cfg.lift_m * np.sqrt(np.sin(np.pi * s))
        up = path[:, 0] >= reach_x
        assert np.allclose(path[up, 2] - lift[up], 0.10, atol=0.002)
        c = predict_clearance(view_of(h, var), feats, (0.2, 0.0), cfg)
        assert not c.warning and c.edge_m > 0.03, (edge_x, c)


def test_the_measured_toe_is_placed_by_the_poses_that_placed_the_grid():
    """A stride whose final grid is its online grid (no clouds kept): its online poses carry a
    common 6 mm error forward, which moves the grid's curb edge by the same 6 mm; the toe
    path from those poses (``grid_stride_T_camera``) rising 17 mm in front of the true face
    gives 17 mm (the error cancels), the smoothed poses' (error-free) 23 mm. A grid re-fused
    from the smoothed poses takes the smoothed ones."""
    from graph_slam.pipelines.results import StrideOutput
    from graph_slam.terrain.features.clearance import edge_clearance

    rng = np.random.default_rng(7)
    n = 40
    true = np.tile(np.eye(4), (n, 1, 1))  # the toe's true path: up the face 17 mm before it
    true[:, 0, 3] = np.concatenate([np.full(20, 0.683), np.linspace(0.683, 0.9, 20)])
    true[:, 2, 3] = np.concatenate([np.linspace(0.01, 0.2, 20), np.full(20, 0.2)])
    true[:, 1, 3] = rng.normal(0.0, 0.01, n)  # off the walking line a little, seeded
    online = true.copy()
    online[:, 0, 3] += 0.006
    leg = SimpleNamespace(frame_T_frame=lambda *a, **k: np.eye(4))  # the toe at the camera
    summary = SimpleNamespace(online_stride_T_camera=online, smoothed_stride_T_camera=true)
    grid = object()
    live = StrideOutput(summary, online_grid=grid, smoothed_grid=grid)
    q = np.zeros((n, 2))
    feats = _curb(0.7 + 0.006)  # the edge where the online poses put it
    got = edge_clearance(feats, toe_path(live.grid_stride_T_camera, q, leg))
    assert got.min_m == pytest.approx(0.017, abs=1e-6)
    wrong = edge_clearance(feats, toe_path(live.smoothed_stride_T_camera, q, leg))
    assert wrong.min_m == pytest.approx(0.023, abs=1e-6)
    refused = StrideOutput(summary, online_grid=grid, smoothed_grid=object())
    assert refused.grid_stride_T_camera is true
    baseline = StrideOutput(SimpleNamespace(smoothed_stride_T_camera=true), grid, grid)
    assert baseline.grid_stride_T_camera is true


def _true_stairs(first, n=3, rise=0.17, tread=0.28):
    """A flight up with its first nosing at ``first`` (exact features, the last tread unseen)."""
    from graph_slam.terrain.features.model import EdgeLine, Stairs, Step, TerrainFeatures

    steps = tuple(
        Step(rise, 0.0, EdgeLine(first + k * tread, 0.0, 0.0, 0.0, 0.0, (-0.6, 0.6), 0, False),
             tread if k < n - 1 else math.nan, 0.0, k * rise, (k + 1) * rise)
        for k in range(n)
    )  # fmt: skip
    return TerrainFeatures(source="truth", stairs=(Stairs(steps),))


def test_the_stairs_up_landing_is_a_tread_step_over_step():
    """Nosings 7, 35 and 63 cm ahead of the toe: the swing climbs two (landing on the tread
    34 cm up, its toe 3 cm short of the next riser: 60 cm long); step to step, one (32 cm);
    a stride length ending before the second nosing's tread ends there; one nosing seen with
    its tread unknown: the stride length."""
    from graph_slam.terrain.features.prediction import stairs_up_landing

    feats = _true_stairs(0.27)
    got = stairs_up_landing(feats, 0.2, 0.0, ClearanceConfig())
    assert got == pytest.approx((0.60, 0.34, 0.34), abs=1e-9)
    got = stairs_up_landing(feats, 0.2, 0.0, ClearanceConfig(stairs_steps_per_swing=1))
    assert got == pytest.approx((0.32, 0.17, 0.17), abs=1e-9)
    got = stairs_up_landing(feats, 0.2, 0.0, ClearanceConfig(stride_length_m=0.5))
    assert got == pytest.approx((0.5, 0.34, 0.34), abs=1e-9)
    got = stairs_up_landing(feats, 0.2, 0.0, ClearanceConfig(stride_length_m=0.3))
    assert got == pytest.approx((0.3, 0.17, 0.17), abs=1e-9)
    one = _true_stairs(0.27, n=1)
    assert stairs_up_landing(one, 0.2, 0.0, ClearanceConfig())[0] == pytest.approx(1.3)


def _flight_case(first):
    from tests.test_terrain_features import stairs_surface

    surface = stairs_surface(first=first, n=3)
    h, var = grid(surface, 0.0005, seed=5)
    return view_of(h, var), extract_features(h, var, (X0, Y0), CELL), surface


def test_the_stairs_up_reference_lands_on_a_tread_and_never_under_the_flight():
    """From the floor, a flight 70 cm ahead (nosings at 0.90, 1.18, 1.46 m): the reference
    lands on the second tread (34 cm up, its toe 3 cm short of the riser at 1.46 m) and every
    mid-swing point lies over the flight's surface — run on over the stride length (1.3 m)
    with one rise, it went through the riser at 1.18 m 4 cm under its nosing and warned
    falsely; it clears the nosing at 1.18 m by the lift there (3.6 cm), no warning."""
    cfg = ClearanceConfig()
    view, feats, surface = _flight_case(0.90)
    path, kind = reference_swing(view, feats, (0.2, 0.0), cfg)
    assert kind == "stairs_up"
    assert path[-1] == pytest.approx([1.43, 0.0, 0.34], abs=0.002)
    mid = path[cfg.mid_swing_mask(len(path))]
    assert np.all(mid[:, 2] > surface(mid[:, 0], mid[:, 1]) + 0.02)
    c = predict_clearance(view, feats, (0.2, 0.0), cfg)
    assert not c.warning and c.edge_m == pytest.approx(0.036, abs=0.002)


@pytest.mark.parametrize(("lift", "warn"), [(0.025, True), (0.035, False)])
def test_stairs_up_warns_below_the_margin_as_the_analytic_flight_gives(lift, warn):
    """The stairs-up reference's edge clearance over a flight found on a grid equals the one
    over the exact flight (within 1.5 mm); a lift of 2.5 cm passes the nosing of the tread it
    lands on under 2 cm above (warning), one of 3.5 cm over 2 cm (none)."""
    from graph_slam.terrain.features.clearance import edge_clearance

    cfg = ClearanceConfig(lift_m=lift)
    view, feats, _ = _flight_case(0.90)
    got = predict_clearance(view, feats, (0.2, 0.0), cfg)
    true = _true_stairs(0.90)
    path, _ = reference_swing(view, true, (0.2, 0.0), cfg)
    want = edge_clearance(true, path[cfg.mid_swing_mask(len(path))], cfg).min_m
    assert abs(got.edge_m - want) <= 0.0015, (got, want)
    assert (want < cfg.warn_below_m) is warn and got.warning is warn
    assert abs(want - cfg.warn_below_m) >= 0.002  # each case clearly on its side


def test_a_toe_close_behind_a_riser_warns():
    """The toe 7 cm behind a 17 cm riser (the tread it stands on ends there): a toe moving
    forward as it rises cannot clear that nosing by 2 cm — the warning, the reference through
    the riser (edge clearance under 0); it still lands two treads up (0.80 m, 34 cm)."""
    view, feats, _ = _flight_case(0.27)
    path, kind = reference_swing(view, feats, (0.2, 0.0))
    assert kind == "stairs_up" and path[-1] == pytest.approx([0.80, 0.0, 0.34], abs=0.002)
    c = predict_clearance(view, feats, (0.2, 0.0))
    assert c.warning and c.edge_m < 0.0
