"""graph_slam.evaluation: metrics on hand-made trajectories, tables, obstacle stats, metrics.json."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.errors import EvaluationError
from graph_slam.evaluation import (
    FrameCounts,
    MapEvaluation,
    StrideEvaluation,
    TrueBox,
    VariantEvaluation,
    assess_stride,
    collect_measurements,
    count_outcomes,
    frame_counts,
    gait_cycle_percent,
    metrics_document,
    obstacle_accuracy,
    read_metrics_json,
    stance_mask,
    stride_trajectory_metrics,
    table_4_1,
    table_4_2,
    table_box_counts,
    table_rows,
    timing_stats,
    write_metrics_json,
)
from graph_slam.evaluation.report import MapStride
from graph_slam.evaluation.tables import StrideRow, VariantStride
from graph_slam.session.records import SceneObject, SceneTruth
from graph_slam.terrain import Obstacle, extract_obstacles

needs_evo = pytest.mark.skipif(
    importlib.util.find_spec("evo") is None, reason="evo (the 'eval' extra) is not installed"
)


def _reference(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """A curved camera path with turning orientation, stride frame."""
    t = np.linspace(0.0, 1.0, n)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler(
        "xyz", np.column_stack([0.3 * t, 0.5 * np.sin(3 * t), t])
    ).as_matrix()
    poses[:, :3, 3] = np.column_stack([0.8 * t, 0.1 * np.sin(6 * t), 0.5 + 0.05 * np.cos(5 * t)])
    return t, poses


@needs_evo
def test_constant_offset_gives_10mm_unaligned_and_zero_aligned():
    t, ref = _reference()
    est = ref.copy()
    est[:, :3, 3] += [0.006, 0.0, -0.008]  # 10 mm in the stride frame
    m = stride_trajectory_metrics(t, est, ref, stance_mask(t, 0.6))
    assert m.rmse_unaligned_m == pytest.approx(0.010, abs=1e-12)
    assert m.rmse_aligned_m == pytest.approx(0.0, abs=1e-9)
    assert m.rmse_by_phase_m["stance"]["unaligned"] == pytest.approx(0.010, abs=1e-12)
    assert m.rmse_by_phase_m["stance"]["n"] + m.rmse_by_phase_m["swing"]["n"] == 40
    assert m.rpe_rmse_m == pytest.approx(0.0, abs=1e-12)


@needs_evo
def test_rigid_transform_of_whole_trajectory_is_removed_by_alignment():
    t, ref = _reference()
    world = np.eye(4)
    world[:3, :3] = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    world[:3, 3] = [0.2, -0.1, 0.05]
    est = world @ ref
    m = stride_trajectory_metrics(t, est, ref)
    assert m.rmse_unaligned_m > 0.05
    assert m.rmse_aligned_m == pytest.approx(0.0, abs=1e-9)
    assert m.rmse_by_phase_m == {}


@needs_evo
def test_error_only_in_swing_and_missing_frames_are_not_counted():
    t, ref = _reference()
    est = ref.copy()
    swing = t >= 0.5
    est[swing, 2, 3] += 0.02  # +20 mm in z during swing only
    est[-3:] = np.nan  # registration failed, nothing bridged: not evaluated
    m = stride_trajectory_metrics(t, est, ref, ~swing)
    assert m.n_evaluated == 37
    n_swing = int(swing.sum()) - 3
    assert m.rmse_by_phase_m["stance"]["unaligned"] == pytest.approx(0.0, abs=1e-12)
    assert m.rmse_by_phase_m["swing"]["unaligned"] == pytest.approx(0.02, abs=1e-12)
    assert m.rmse_by_phase_m["swing"]["n"] == n_swing
    assert m.rmse_unaligned_m == pytest.approx(0.02 * np.sqrt(n_swing / 37), abs=1e-12)
    assert np.isnan(m.errors_unaligned_m[-3:]).all()


@needs_evo
def test_bad_trajectory_input_is_an_error():
    t, ref = _reference(5)
    with pytest.raises(EvaluationError, match="shape"):
        stride_trajectory_metrics(t, ref[:4], ref)
    bad = ref.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(EvaluationError, match="reference"):
        stride_trajectory_metrics(t, ref, bad)


def test_missing_evo_names_the_extra(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_evo(name, *args, **kwargs):
        if name.startswith("evo"):
            raise ImportError("No module named 'evo'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_evo)
    t, ref = _reference(5)
    with pytest.raises(EvaluationError, match=r"graph_slam\[eval\]"):
        stride_trajectory_metrics(t, ref, ref)


def test_frame_counts_and_timing():
    counts = frame_counts(["registered"] * 5 + ["bridged"] * 2 + ["failed", "first"])
    assert counts == FrameCounts(recorded=9, registered=5, bridged=2, other=2)
    stats = timing_stats(np.arange(1, 101) / 1000.0)
    assert stats.median_s == pytest.approx(0.0505)
    assert stats.p95_s == pytest.approx(0.09505)
    with pytest.raises(EvaluationError):
        timing_stats(np.array([0.1, np.nan]))


def test_obstacle_accuracy_of_known_measurements():
    truth = {"Box1": np.array([0.2, 0.3, 0.1])}
    measured = {"Box1": [np.array([0.21, 0.30, 0.10]), np.array([0.19, 0.32, 0.13])]}
    stats = obstacle_accuracy(measured, truth)["Box1"]
    assert stats["depth"].mean_m == pytest.approx(0.2)
    assert stats["depth"].std_m == pytest.approx(np.sqrt(2) * 0.01)  # sample std, ddof=1
    assert stats["depth"].rmse_m == pytest.approx(0.01)
    assert stats["width"].rmse_m == pytest.approx(np.sqrt(0.02**2 / 2))
    assert stats["height"].rmse_m == pytest.approx(np.sqrt(0.03**2 / 2))
    assert stats["height"].n == 2
    with pytest.raises(EvaluationError, match="Box9"):
        obstacle_accuracy({"Box9": [np.ones(3)]}, truth)


def _box(x, y, reason=None, size=(0.2, 0.2, 0.1)):
    return Obstacle(*size[:3], x - size[0] / 2, np.array([x, y]), 100, skip_reason=reason)


def test_truth_boxes_in_a_yawed_stride_frame():
    """A box at world (2, 1) yawed 30°, seen from a stride frame at (1, 1) yawed 90°."""
    from graph_slam.evaluation import truth_boxes_in_stride

    world_T_box = np.eye(4)
    world_T_box[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    world_T_box[:3, 3] = [2.0, 1.0, 0.05]
    scene = SceneTruth("s", (SceneObject("Box1#2", world_T_box, np.array([0.2, 0.3, 0.1])),))
    world_T_stride = np.eye(4)
    world_T_stride[:3, :3] = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    world_T_stride[:3, 3] = [1.0, 1.0, 0.0]
    (box,) = truth_boxes_in_stride(scene, world_T_stride)
    np.testing.assert_allclose(box.center_xy_m, [0.0, -1.0], atol=1e-12)
    assert box.yaw_rad == pytest.approx(np.radians(30 - 90))
    assert box.contains(np.array([[0.0, -1.0], [0.5, -1.0]])).tolist() == [True, False]


def test_assess_stride_gives_each_box_in_view_one_outcome():
    """Measured, skipped (mapping reason), split, missed; off-map boxes are not counted."""
    from graph_slam.terrain import Coverage, FloorPlane, ObstacleMap

    truth = [
        TrueBox("Box1", np.array([0.6, -0.3]), np.array([0.2, 0.27, 0.19])),
        TrueBox("Box2", np.array([1.2, -0.3]), np.array([0.27, 0.36, 0.08])),
        TrueBox("Box3", np.array([1.9, -0.4]), np.array([0.34, 0.44, 0.06])),
        TrueBox("Box1#2", np.array([2.6, -0.3]), np.array([0.2, 0.27, 0.19])),
        TrueBox("Box2#2", np.array([3.9, -0.3]), np.array([0.27, 0.36, 0.08])),
    ]
    found = [
        _box(0.62, -0.29),  # Box1, whole
        _box(1.15, -0.35, "edge_of_map"),  # Box2, cut by the map's edge
        _box(1.85, -0.5),  # Box3 in two pieces
        _box(1.95, -0.3),
        _box(3.0, 0.6),  # in no box's footprint
    ]
    # Coverage: the map covers x < 3 m; Box1#2 stands inside it, Box2#2 beyond it.
    outside = np.zeros((30, 20), bool)
    outside[15:] = True
    coverage = Coverage(np.ones((30, 20), bool), outside, np.array([0.0, -1.0]), 0.2)
    floor = FloorPlane(np.array([0.0, 0.0, 1.0]), 0.0, 1000, 0.001)
    stride = assess_stride(ObstacleMap(floor, tuple(found), coverage), truth)
    outcomes = {o.box: (o.status, o.reason) for o in stride.outcomes}
    assert outcomes == {
        "Box1": ("measured", None),
        "Box2": ("skipped", "edge_of_map"),
        "Box3": ("skipped", "split"),
        "Box1#2": ("missed", None),
    }
    assert stride.unmatched == 1 and stride.measured() == {"Box1": found[0]}
    counts = count_outcomes([stride, assess_stride(None, truth, error="no floor")])
    assert counts["measured"] == 1 and counts["missed"] == 1 and counts["no_map"] == 1
    assert counts["skipped"] == {"edge_of_map": 1, "split": 1} and counts["unmatched"] == 1
    assert counts["by_box"]["Box1"] == {"measured": 1, "skipped": {}, "missed": 1}
    assert collect_measurements([stride]) == {"Box1": [pytest.approx(found[0].size_m)]}
    lines = table_box_counts(counts).splitlines()
    assert lines[0] == (
        "| Object | measured | skipped: edge of map | skipped: adjacent | skipped: top in part "
        "| skipped: floor not seen | skipped: split | missed |"
    )
    assert lines[2] == "| Box1 | 1 | 0 | 0 | 0 | 0 | 0 | 1 |"
    assert lines[-1] == "| all (unmatched obstacles: 1) | 1 | 1 | 0 | 0 | 0 | 1 | 1 |"


def test_a_box_cut_by_the_map_edge_is_skipped_end_to_end():
    """Extraction and assessment together, on a cloud whose map ends inside Box2."""
    rng = np.random.default_rng(4)
    floor = np.column_stack(
        [rng.uniform(-0.2, 1.25, 60_000), rng.uniform(-0.8, 0.4, 60_000), np.zeros(60_000)]
    )
    tops = []
    for (cx, cy), (d, w, h) in [
        ((0.6, -0.3), (0.2, 0.27, 0.19)),
        ((1.2, -0.3), (0.27, 0.36, 0.08)),
    ]:
        top = np.column_stack(
            [
                rng.uniform(cx - d / 2, cx + d / 2, 20_000),
                rng.uniform(cy - w / 2, cy + w / 2, 20_000),
            ]
        )
        floor = floor[~((np.abs(floor[:, 0] - cx) < d / 2) & (np.abs(floor[:, 1] - cy) < w / 2))]
        tops.append(np.column_stack([top, np.full(len(top), h)]))
    cloud = np.concatenate([floor, *tops])
    cloud = cloud[cloud[:, 0] < 1.25] + rng.normal(0, 0.0005, (len(cloud[cloud[:, 0] < 1.25]), 3))
    truth = [
        TrueBox("Box1", np.array([0.6, -0.3]), np.array([0.2, 0.27, 0.19])),
        TrueBox("Box2", np.array([1.2, -0.3]), np.array([0.27, 0.36, 0.08])),
    ]
    stride = assess_stride(extract_obstacles(cloud), truth)
    by_box = {o.box: o for o in stride.outcomes}
    assert by_box["Box1"].status == "measured"
    np.testing.assert_allclose(by_box["Box1"].obstacle.size_m, [0.2, 0.27, 0.19], atol=0.003)
    assert (by_box["Box2"].status, by_box["Box2"].reason) == ("skipped", "edge_of_map")
    assert by_box["Box2"].obstacle.depth_m < 0.2  # what was seen of it: not measured


def test_table_4_2_layout_of_known_numbers():
    rows = [
        StrideRow(
            "Slow",
            1,
            70,
            {"baseline": VariantStride(70, 0, 0.021), "graph": VariantStride(68, 2, 0.0104)},
        ),
        StrideRow("Slow", 2, 62, {"baseline": VariantStride(37, 0, float("nan"))}),
        StrideRow(
            "Normal",
            1,
            35,
            {"baseline": VariantStride(35, 0, 0.034), "graph": VariantStride(35, 0, 0.0)},
        ),
    ]
    text = table_4_2(rows, ["baseline", "graph"])
    lines = text.splitlines()
    assert lines[0] == (
        "| Walking speed | Stride # | Frames recorded | baseline registered | baseline bridged | "
        "baseline RMSE (m) | graph registered | graph bridged | graph RMSE (m) |"
    )
    assert lines[2] == "| Slow | 1 | 70 | 70 | 0 | 0.021 | 68 | 2 | 0.010 |"
    assert lines[3] == "|  | 2 | 62 | 37 | 0 | – | – | – | – |"
    assert lines[4] == "| Normal | 1 | 35 | 35 | 0 | 0.034 | 35 | 0 | 0.000 |"


def test_table_4_1_layout_of_known_numbers():
    truth = {"Box1": np.array([0.2032, 0.2667, 0.1905])}
    # The thesis's Box1 means (depth 216, width 267, height 180 mm) from two symmetric samples.
    measured = {"Box1": [np.array([0.206, 0.258, 0.172]), np.array([0.226, 0.276, 0.188])]}
    text = table_4_1(obstacle_accuracy(measured, truth))
    lines = text.splitlines()
    assert lines[0].startswith("| Object | Width mean | Width stdev | Width RMSE | Depth mean")
    assert lines[2] == "| Box1 | 267 | 13 | 9.0 | 216 | 14 | 16.2 | 180 | 11 | 13.2 |"


@needs_evo
def test_metrics_json_round_trip_and_schema_checks(tmp_path):
    t, ref = _reference(10)
    est = ref.copy()
    est[:, 0, 3] += 0.01
    traj = stride_trajectory_metrics(t, est, ref, stance_mask(t, 0.5))
    variant = VariantEvaluation(
        strides=[StrideEvaluation(0, "Slow", 1, frame_counts(["registered"] * 10), traj)],
        timing=timing_stats(np.full(10, 0.02)),
        obstacles=obstacle_accuracy(
            {"Box1": [np.array([0.2, 0.3, 0.1])]}, {"Box1": np.array([0.2, 0.3, 0.1])}
        ),
    )
    truth = [TrueBox("Box1", np.array([0.6, -0.3]), np.array([0.2, 0.3, 0.1]))]
    from graph_slam.terrain import Coverage, FloorPlane, ObstacleMap

    coverage = Coverage(np.ones((4, 4), bool), np.zeros((4, 4), bool), np.array([0, -1.0]), 0.5)
    floor = FloorPlane(np.array([0.0, 0.0, 1.0]), 0.0, 1000, 0.001)
    box = ObstacleMap(floor, (_box(0.6, -0.3, size=(0.2, 0.3, 0.1)),), coverage)
    maps = {
        "ground truth": MapEvaluation(
            "ground truth", [MapStride(0, "Slow", 1, assess_stride(box, truth))], variant.obstacles
        )
    }
    path = write_metrics_json(
        metrics_document("tiny", {"graph": variant}, maps), tmp_path / "metrics.json"
    )
    doc = read_metrics_json(path)
    truth_map = doc["maps"]["ground truth"]
    assert truth_map["counts"]["measured"] == 1 and truth_map["counts"]["skipped"] == {}
    (stride,) = truth_map["strides"]
    assert (stride["index"], stride["speed"], stride["measured"]) == (0, "Slow", 1)
    assert stride["boxes"][0]["status"] == "measured"
    assert stride["boxes"][0]["size_m"] == pytest.approx([0.2, 0.3, 0.1])
    assert truth_map["obstacles"]["Box1"]["width"]["rmse_m"] == pytest.approx(0.0)
    v = doc["variants"]["graph"]
    assert v["strides"][0]["trajectory"]["rmse_unaligned_m"] == pytest.approx(0.01)
    assert v["summary"]["frames_registered"] == 10
    assert v["obstacles"]["Box1"]["depth"]["std_m"] is None  # NaN (one measurement) -> null
    assert table_rows({"graph": variant})[0].variants["graph"].rmse_m == pytest.approx(
        traj.rmse_aligned_m
    )
    (tmp_path / "bad.json").write_text(json.dumps({**doc, "schema_version": 99}))
    with pytest.raises(EvaluationError, match="schema_version"):
        read_metrics_json(tmp_path / "bad.json")
    (tmp_path / "bad.json").write_text(json.dumps({**doc, "maps": []}))
    with pytest.raises(EvaluationError, match="'maps'"):
        read_metrics_json(tmp_path / "bad.json")
    # Version 1 files (before the completeness filter; no "maps") are still read.
    old = {k: v for k, v in doc.items() if k != "maps"}
    (tmp_path / "v1.json").write_text(json.dumps({**old, "schema_version": 1}))
    assert read_metrics_json(tmp_path / "v1.json")["schema_version"] == 1


def test_gait_cycle_percent_and_stance_mask():
    t = np.array([10.0, 10.5, 11.0, 11.2])
    np.testing.assert_allclose(gait_cycle_percent(t, 10.0, 11.0), [0, 50, 100, 120])
    np.testing.assert_array_equal(stance_mask(t, 10.6), [True, True, False, False])
    assert stance_mask(t, None).all()
    with pytest.raises(EvaluationError, match="must follow"):
        gait_cycle_percent(t, 11.0, 10.0)
