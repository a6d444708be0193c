"""The thesis's 2D study (graph_slam.planar): known answers on synthetic truth.

Every random generator is seeded; tolerances are stated where they are used.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from graph_slam.config import config_from_dict
from graph_slam.errors import ConfigError, PlanarError
from graph_slam.planar import se2
from graph_slam.planar.config import FeatureConfig, IcpConfig, PlanarConfig
from graph_slam.planar.evaluation import position_errors_m, step_errors_m
from graph_slam.planar.features import extract_lines, roughness
from graph_slam.planar.icp import register
from graph_slam.planar.scanner import Scan, simulate_scan
from graph_slam.planar.study import run_speed
from graph_slam.planar.terrain import build_terrain, cast_rays
from graph_slam.planar.trajectory import heel_T_sensor, simulate_gait
from graph_slam.planar.trilateration import trilaterate

CONFIG = PlanarConfig()


@pytest.fixture(scope="module")
def grid():
    return build_terrain(CONFIG.terrain)


@pytest.fixture(scope="module")
def fast_run(grid):
    """The default config at 1.33 m/s (the default seed), run once for several tests."""
    return run_speed(CONFIG, grid, 1.33)


def _clean_scan(grid, world_T_sensor):
    scanner = CONFIG.scanner.model_copy(update={"range_sigma_m": 0.0})
    return simulate_scan(grid, world_T_sensor, 0.0, scanner, np.random.default_rng(0))


# --- terrain and sensor -------------------------------------------------------------------


def test_ray_casting_hits_flat_ground_at_the_known_range(grid):
    # A ray 30° below the horizontal from (−0.9, 0.6) meets the floor y = 0 after 1.2 m,
    # before any obstacle; the grid quantises to 5 mm cells, so within 3 mm.
    r = cast_rays(grid, np.array([-0.9, 0.6]), np.array([-math.pi / 6]), 4.0)
    assert r[0] == pytest.approx(1.2, abs=0.003)
    # Straight up: nothing within range.
    assert np.isnan(cast_rays(grid, np.array([0.0, 0.6]), np.array([math.pi / 2]), 4.0)[0])


def test_scan_has_150_rays_over_75_degrees_and_max_range_returns(grid):
    scan = _clean_scan(grid, se2.se2(0.0, 0.6, math.radians(-10)))
    assert len(scan.ranges_m) == 150
    assert np.ptp(scan.angles_rad) == pytest.approx(math.radians(75))
    assert (~scan.hit).sum() > 10  # looking near the horizon: some rays see nothing
    assert np.all(scan.ranges_m[~scan.hit] == CONFIG.scanner.max_range_m)


# --- eq. 3.1: roughness ---------------------------------------------------------------------


def test_roughness_known_values():
    # Equally spaced collinear points: the sums cancel, c = 0.
    line = np.column_stack([np.linspace(-1, 1, 21), np.full(21, 2.0)])
    assert np.allclose(roughness(line)[3:-3], 0.0, atol=1e-12)
    # A right-angle corner with spacing s at range r: c = 6 s sqrt(2) / (6 r) = sqrt(2) s / r.
    s, corner = 0.05, np.array([0.0, 1.0])
    arm1 = corner + np.outer(np.arange(3, 0, -1) * s, [-1.0, 0.0])
    arm2 = corner + np.outer(np.arange(1, 4) * s, [0.0, 1.0])
    points = np.vstack([arm1, corner, arm2])
    assert roughness(points)[3] == pytest.approx(math.sqrt(2) * s / 1.0, rel=1e-12)
    assert np.isnan(roughness(points)[0])  # fewer than 3 neighbours on a side


def test_roughness_separates_lines_from_corners(grid):
    # A clean scan of a box on the floor. Label every point by the surface it lies on (floor,
    # box front, box top): a point whose neighbours all lie on its own surface is on a line;
    # a point where the surface turns a corner (floor -> front -> top) is a corner. Eq. 3.1
    # scores every corner point higher than any line point, and the extracted lines carry
    # the true surface normals.
    world_T_sensor = se2.se2(0.2, 0.6, math.radians(-45))
    points = _clean_scan(grid, world_T_sensor).points_xy_m(drop_max_range=True)
    c = roughness(points)
    world = se2.apply(world_T_sensor, points)
    box = CONFIG.terrain.boxes[0]
    label = np.full(len(world), -1)
    label[np.abs(world[:, 1]) < 0.003] = 0  # floor
    label[(np.abs(world[:, 0] - box.x_m) < 0.003) & (world[:, 1] > 0.003)] = 1  # front face
    on_top = np.abs(world[:, 1] - box.height_m) < 0.003
    label[on_top & (world[:, 0] > box.x_m + 0.003)] = 2  # top face
    k = CONFIG.features.neighbours
    windows = np.lib.stride_tricks.sliding_window_view(label, 2 * k + 1)
    on_line = np.zeros(len(label), dtype=bool)
    on_line[k:-k] = np.all(windows == windows[:, [k]], axis=1) & (windows[:, k] >= 0)
    turns = np.flatnonzero((label[1:] != label[:-1]) & (label[1:] >= 0) & (label[:-1] >= 0))
    corner = np.unique(np.r_[turns, turns + 1])
    assert on_line.sum() > 50 and len(corner) >= 4  # floor->front and front->top
    assert np.min(c[corner]) > 3 * np.max(c[on_line])

    lines = extract_lines(points, CONFIG.features)
    normals_world = lines.normals @ world_T_sensor[:2, :2].T
    ramp = CONFIG.terrain.ramps[0]
    slope = math.atan2(ramp.rise_m, ramp.length_m)
    # Floors and box tops face up, box fronts face -x, and the ramp farther on is tilted.
    expected = np.array([[0.0, 1.0], [-1.0, 0.0], [-math.sin(slope), math.cos(slope)]])
    angle = np.arccos(np.clip(np.max(normals_world @ expected.T, axis=1), -1, 1))
    assert np.all(angle < math.radians(1.0))


def test_roughness_threshold_cuts_depth_jumps():
    # Eq. 3.1 with the thesis's 0.5: a jump from 1 m to 3 m away is rough (c ≈ 3·2/6 = 1).
    angles = np.linspace(-0.3, 0.3, 31)
    ranges = np.where(angles < 0, 1.0, 3.0)
    points = np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles)])
    c = roughness(points)
    jump = np.flatnonzero(np.diff(ranges))[0]
    assert max(c[jump], c[jump + 1]) > 0.5
    lines = extract_lines(points, FeatureConfig(line_tolerance_m=0.5))
    assert lines.n_lines == 2  # one on each side of the jump


# --- eq. 3.2–3.7: ICP ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("dx", "dy", "dtheta_deg"),
    [(0.03, 0.0, 0.0), (0.02, -0.01, 3.0), (-0.03, 0.02, -4.0), (0.0, 0.0, 5.0)],
)
def test_icp_recovers_known_transforms_on_clean_scans(grid, dx, dy, dtheta_deg):
    # Scan twice from poses a known transform apart (no noise, max-range returns dropped):
    # ICP from zero motion returns that transform within 2 mm and 0.1° (grid: 5 mm cells).
    world_T_a = se2.se2(0.3, 0.6, math.radians(-45))
    a_T_b = se2.se2(dx, dy, math.radians(dtheta_deg))
    lines_a = extract_lines(_clean_scan(grid, world_T_a).points_xy_m(True), CONFIG.features)
    scan_b = _clean_scan(grid, world_T_a @ a_T_b)
    lines_b = extract_lines(scan_b.points_xy_m(True), CONFIG.features)
    result = register(lines_b.points_xy_m, lines_a, CONFIG.icp)
    assert result.ok, result.failure
    error = se2.xyt(se2.inverse(a_T_b) @ result.target_T_source)
    assert np.linalg.norm(error[:2]) < 0.002
    assert abs(error[2]) < math.radians(0.1)


def test_icp_reports_a_flat_floor_as_degenerate_not_as_zero_motion():
    # Floor only, shifted along itself by 5 cm: the motion along the floor is unobservable.
    x = np.linspace(0.5, 2.0, 80)
    floor = np.column_stack([x, np.zeros_like(x)])
    sensor_T_floor = se2.inverse(se2.se2(0.0, 0.6, 0.0))
    target = extract_lines(se2.apply(sensor_T_floor, floor), CONFIG.features)
    source = se2.apply(sensor_T_floor, floor + np.array([0.05, 0.0]))
    result = register(source, target, CONFIG.icp)
    assert not result.ok
    assert "degenerate" in result.failure


def test_icp_without_enough_points_gives_no_estimate():
    target = extract_lines(np.column_stack([np.linspace(0, 1, 30), np.ones(30)]), FeatureConfig())
    result = register(np.zeros((2, 2)), target, IcpConfig())
    assert result.target_T_source is None
    assert "no estimate" in result.failure


# --- eq. 3.9–3.10: trilateration -----------------------------------------------------------


def test_trilateration_recovers_a_known_sensor_position(grid):
    sensor_xy = np.array([1.0, 0.6])
    world_T_sensor = se2.se2(*sensor_xy, math.radians(-45))
    scan = _clean_scan(grid, world_T_sensor)
    world = se2.apply(world_T_sensor, scan.points_xy_m(True))
    ranges = scan.ranges_m[scan.hit]
    assert trilaterate(world, ranges) == pytest.approx(sensor_xy, abs=1e-9)
    # With 1 mm range noise the solution is unbiased: the mean of 200 solutions is within
    # 3 mm (their spread, about 4 mm in x and 8 mm in y, shows how eq. 3.10's differences of
    # neighbouring points amplify noise).
    rng = np.random.default_rng(1)
    solutions = [trilaterate(world, ranges + rng.normal(0, 0.001, len(ranges))) for _ in range(200)]
    assert np.mean(solutions, axis=0) == pytest.approx(sensor_xy, abs=0.003)


def test_trilateration_rejects_bad_input():
    with pytest.raises(PlanarError, match="3 points"):
        trilaterate(np.zeros((2, 2)), np.ones(2))
    with pytest.raises(PlanarError, match="ranges"):
        trilaterate(np.zeros((4, 2)), np.ones(3))


# --- gait-driven trajectory ----------------------------------------------------------------


def test_trajectory_is_periodic_and_the_leg_prior_matches_the_simulation():
    trajectory = simulate_gait(1.33, 2, 45.0, CONFIG.leg)
    # The leg model is consistent: forward kinematics from the heel at each foot strike gives
    # the simulated sensor pose in the stride frame (the heel is the pinned contact).
    for stride, world_T_stride in enumerate(trajectory.world_T_stride):
        k = np.flatnonzero(trajectory.stride_index == stride)[0]
        stride_T_sensor = se2.inverse(world_T_stride) @ trajectory.world_T_sensor[k]
        fk = heel_T_sensor(trajectory.leg_angles_rad[k][None], CONFIG.leg)[0]
        assert np.allclose(fk, stride_T_sensor, atol=2e-3)  # 2 mm: the heel rocks after strike
    # The second stride repeats the first one, one stride length further on (compared at
    # the same time since foot strike; 3 mm covers the linear interpolation between scans).
    first, second = trajectory.stride_index == 0, trajectory.stride_index == 1
    t2 = trajectory.t_s[second] - trajectory.foot_strike_t_s[1]
    shift = trajectory.world_T_stride[1][0, 2] - trajectory.world_T_stride[0][0, 2]
    for axis, offset in ((0, shift), (1, 0.0)):
        repeated = np.interp(t2, trajectory.t_s[first], trajectory.world_T_sensor[first, axis, 2])
        assert np.allclose(
            trajectory.world_T_sensor[second, axis, 2] - offset, repeated, atol=0.003
        )
    # The sensor's pitch follows the thigh: from about 15° to 60° below the horizontal.
    pitch = np.degrees(
        np.arctan2(trajectory.world_T_sensor[:, 1, 0], trajectory.world_T_sensor[:, 0, 0])
    )
    assert -65 < pitch.min() < -50 and -20 < pitch.max() < -10


# --- the comparison the study exists for ---------------------------------------------------


def test_at_fast_walking_the_thesis_fails_in_swing_and_the_graph_does_not(fast_run):
    trajectory, thesis, graph = fast_run.trajectory, fast_run.thesis, fast_run.graph
    swing = ~trajectory.in_stance
    thesis_steps = step_errors_m(thesis, trajectory)
    graph_steps = step_errors_m(graph, trajectory)
    # The thesis pipeline: a scan-to-scan error in swing above the sensor's whole motion
    # between two scans (~3 cm), and an absolute error of decimetres.
    assert np.nanmax(thesis_steps[swing]) > 0.03
    assert np.nanmax(position_errors_m(thesis, trajectory)) > 0.1
    # The graph: every step within 15 mm and every pose within 3 cm, in every stride.
    assert np.nanmax(graph_steps) < 0.015
    assert np.all(np.isfinite(graph.world_T_sensor))
    assert np.max(position_errors_m(graph, trajectory)) < 0.03
    # Where registration failed the graph says why, and bridged (it still has a pose).
    reasons = [f for f in graph.failure if f is not None]
    assert reasons and all(isinstance(f, str) and f for f in reasons)


def test_a_scan_without_terrain_is_a_failure_not_zero_motion(grid):
    # Replace one scan by one that saw nothing: the thesis pipeline (without max-range
    # returns) has no pose there and says why; the graph bridges it with the motion prior.
    from graph_slam.planar.graph import run_graph
    from graph_slam.planar.measurements import simulate_measurements
    from graph_slam.planar.thesis import run_thesis

    config = CONFIG.model_copy(
        update={"thesis": CONFIG.thesis.model_copy(update={"keep_max_range": False})}
    )
    trajectory = simulate_gait(0.83, 1, 45.0, config.leg)
    rng = np.random.default_rng(5)
    scans = [
        simulate_scan(grid, T, t, config.scanner, rng)
        for T, t in zip(trajectory.world_T_sensor[:12], trajectory.t_s[:12], strict=True)
    ]
    blind = scans[6]
    scans[6] = Scan(
        blind.t_s,
        blind.angles_rad,
        np.full(150, config.scanner.max_range_m),
        np.zeros(150, dtype=bool),
    )
    thesis = run_thesis(scans, trajectory.world_T_sensor[0], config)
    assert np.isnan(thesis.world_T_sensor[6]).all()
    assert "no estimate" in thesis.failure[6]
    measurements = simulate_measurements(trajectory, config.leg, config.graph, rng)
    stride = trajectory.stride_index[:12]
    graph = run_graph(scans, stride, measurements, trajectory.world_T_stride, config)
    assert "no estimate" in graph.failure[6]
    error = np.linalg.norm(graph.world_T_sensor[6][:2, 2] - trajectory.world_T_sensor[6][:2, 2])
    assert error < 0.03


# --- config and CLI -------------------------------------------------------------------------


def test_config_rejects_a_sensor_below_the_knee():
    with pytest.raises(ConfigError, match="leg"):
        config_from_dict(PlanarConfig, {"leg": {"sensor_from_hip_m": 0.5}})
    with pytest.raises(ConfigError, match="n_rays"):
        config_from_dict(PlanarConfig, {"scanner": {"n_rays": 2}})


def test_cli_writes_figures_table_and_config(tmp_path):
    from graph_slam.cli import main

    cfg = tmp_path / "planar.yaml"
    cfg.write_text("speeds_m_s: [1.33]\nn_strides: 1\n", encoding="utf-8")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        main(["planar", "--out", str(out), "--config", str(cfg)])
    assert exit_info.value.code == 0
    for name in (
        "config.yaml",
        "errors.md",
        "errors.csv",
        "errors.json",
        "fig3_3_scene_v1.33.png",
        "fig3_5a_failure_v1.33.png",
        "fig3_5bc_trajectory_v1.33.png",
        "scans_v1.33.csv",
    ):
        assert (out / name).stat().st_size > 0, name
    rows = json.loads((out / "errors.json").read_text(encoding="utf-8"))
    assert {r["method"] for r in rows} == {"thesis", "graph"}
    assert "n_strides: 1" in (out / "config.yaml").read_text(encoding="utf-8")
    assert (out / "fig3_5a_failure_v1.33.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_bad_config_is_exit_code_2(tmp_path, capsys):
    from graph_slam.cli import main

    cfg = tmp_path / "planar.yaml"
    cfg.write_text("scanner: {fov_rad: 4.0}\n", encoding="utf-8")
    with pytest.raises(SystemExit) as exit_info:
        main(["planar", "--out", str(tmp_path / "out"), "--config", str(cfg)])
    assert exit_info.value.code == 2
    assert "scanner.fov_rad" in capsys.readouterr().err
