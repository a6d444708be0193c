"""The plain floor, without texture: three directions are free (along the floor, yaw about
its normal), so no registration may be counted as one that held six. One stride at quarter
resolution through the full graph with the real-time front end: every frame posed, the
smoothed per-stride RMSE within the issue's 15 mm, no frame counted registered, the partial
frames (3 DoF: height, roll, pitch) and the bridged ones counted apart in the report."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graph_slam.bench.accuracy import score, variant_config
from graph_slam.bench.scenarios import SCENARIOS, simulate_scenario
from graph_slam.pipelines import run_session
from graph_slam.report.scoring import _counts, frame_categories
from graph_slam.session import open_session
from graph_slam.strides.kinematics import leg_model_for


@pytest.fixture(scope="module")
def flat_run(tmp_path_factory: pytest.TempPathFactory):
    scenario = next(s for s in SCENARIOS if s.name == "flat-textureless")
    path: Path = simulate_scenario(scenario, tmp_path_factory.mktemp("flat"), strides=1, seed=3)
    session = open_session(path)
    results = run_session(session, variant_config("icp+imu+kin:realtime"))
    return session, results


def test_flat_textureless_stride_ends_within_the_bound(flat_run) -> None:
    session, results = flat_run
    strides = score(session, results, leg_model_for(session.calibration.thigh_T_camera))
    assert strides, "no complete stride scored"
    for s in strides:
        assert s.n_with_pose == s.n_frames  # every frame posed
        assert s.smoothed_rmse_m <= 0.015
        assert s.end_smoothed_m <= 0.03


def test_report_counts_registered_partial_and_bridged_apart(flat_run) -> None:
    _, results = flat_run
    cats = frame_categories(results)
    counts = _counts(cats)
    assert counts.registered == 0  # a floor never holds six directions
    assert counts.partial > 0.5 * counts.recorded
    assert counts.registered + counts.partial + counts.bridged + counts.other == counts.recorded
    flags = [fl for f in results.frames for fl in f.flags if fl.startswith("icp:partial")]
    assert set(flags) == {"icp:partial (3 DoF)"}
    assert np.isfinite(results.smoothed_stride_T_camera[:, 0, 0]).all()


def test_scenarios_at_speeds_are_expanded_and_checked() -> None:
    from graph_slam.bench.scenarios import at_speeds
    from graph_slam.errors import ConfigError

    pico = [s for s in SCENARIOS if s.name == "boxes-pico-flexx"]
    out = at_speeds(pico, ("slow", "fast"))
    assert [(s.name, s.speed, s.camera) for s in out] == [
        ("boxes-pico-flexx@slow", "slow", "pico_flexx"),
        ("boxes-pico-flexx@fast", "fast", "pico_flexx"),
    ]
    assert at_speeds(pico, None) == pico
    # a scenario that is a speed itself is the textured box course at that speed: left out
    expanded = [s.name for s in at_speeds(SCENARIOS, ("slow", "normal", "fast"))]
    assert len(expanded) == 3 * (len(SCENARIOS) - 1) and not any(
        "boxes-fast" in n for n in expanded
    )
    assert "boxes-textured@fast" in expanded
    with pytest.raises(ConfigError, match="walk"):
        at_speeds(pico, ("walk",))


def test_scenario_config_keeps_the_base_and_turns_the_maps_off() -> None:
    from graph_slam.bench.scenarios import scenario_config
    from graph_slam.pipelines import PipelineConfig

    base = PipelineConfig.model_validate({"graph": {"keyframe": {"interval_s": 0.0}}})
    for variant in ("icp", "icp+imu+kin"):
        cfg = scenario_config(variant, base)
        assert cfg.variant == variant and cfg.graph.keyframe.interval_s == 0.0
        assert not cfg.terrain.enabled
    assert scenario_config("icp+imu+kin").graph.keyframe.interval_s == 0.05


def test_rows_at_several_speeds_are_pooled() -> None:
    from graph_slam.bench.scenarios import ScenarioScore, pooled

    def row(name, smoothed):
        arr = np.array(smoothed)
        return ScenarioScore(name, 10, 10, 0, 9, 0, 0, arr, arr + 1, 0, arr * 100)

    rows = [row("pico@slow", [8.0, 9.3]), row("pico@fast", [5.4]), row("flat", [1.0])]
    (all_speeds,) = pooled(rows)
    assert all_speeds.name == "pico@all" and all_speeds.frames == 20 and all_speeds.partial == 18
    np.testing.assert_array_equal(all_speeds.smoothed_mm, [8.0, 9.3, 5.4])
    assert "8.0/9.3" in all_speeds.line() and pooled(rows[2:]) == []


def test_scenario_markdown_table_has_its_caption_and_one_row_per_score() -> None:
    from graph_slam.bench.scenarios import ScenarioScore, markdown_table

    arr = np.array([1.25, 3.0])
    rows = [
        ScenarioScore("flat", 10, 9, 8, 1, 0, 0, arr, arr + 1, 7, arr * 10),
        ScenarioScore("pico", 5, 5, 0, 5, 0, 1, np.array([]), arr, 0, np.array([])),
    ]
    caption, _, header, rule, *body = markdown_table(
        rows, "graph-slam bench scenarios"
    ).splitlines()
    assert caption.endswith("cores: `graph-slam bench scenarios`)") and "commit" in caption
    assert header.count("|") == rule.count("|") == 11
    assert body == [
        "| flat | 9/10 | 8 | 1 | 0 | 0 | 2.1 / 3.0 | 3.1 / 4.0 | 7 | 21.2 / 30.0 |",
        "| pico | 5/5 | 0 | 5 | 0 | 1 | – | 2.1 / 3.0 | 0 | – |",
    ]
