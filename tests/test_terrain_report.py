"""The terrain in the reports: the per-stride deadline from a recorded trace, its metrics.json
section, the live grid's rerun layers and the "obstacle known vs gait phase" plot."""

from __future__ import annotations

import json
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.errors import EvaluationError
from graph_slam.evaluation.report import (
    SCHEMA_VERSION,
    metrics_document,
    read_metrics_json,
    write_metrics_json,
)
from graph_slam.report.terrain_trace import GridSnapshot, TerrainTrace, log_grids, stride_deadlines


@dataclass
class Box:
    leading_edge_x_m: float
    height_m: float
    center_xy_m: tuple[float, float]
    complete: bool = True


FINAL = Box(1.00, 0.190, (1.10, -0.28))


class _Grid:
    """A stand-in for a TerrainView: only ``obstacle_map`` and the snapshot fields."""

    def __init__(self, boxes, stride_index=0):
        self.obstacle_map = SimpleNamespace(
            complete=tuple(b for b in boxes if b.complete),
            obstacles=tuple(boxes),
            floor=SimpleNamespace(floor_T_stride=lambda: np.eye(4)),
        )
        self.stride_index = stride_index
        self.origin_xy_m = np.array([-0.2, -0.6])
        self.cell_m = 0.02
        self.height_m = np.zeros((3, 2))
        self.sigma_m = np.full((3, 2), 0.001)


def _trace(grid_step=0, interval_s=0.0) -> TerrainTrace:
    """Frames at 0.0 .. 0.5 s; box known (within 1 cm / 2 cm) from frame 3 (0.3 s) on."""
    trace = TerrainTrace(
        grid_step, interval_s=interval_s, whole_boxes=lambda view: view.obstacle_map.complete
    )
    online = [[], [Box(1.05, 0.19, (1.1, -0.28))], [Box(1.0, 0.175, (1.1, -0.28))],
              [Box(1.019, 0.181, (1.1, -0.28))], [FINAL], [FINAL]]  # fmt: skip
    for k, boxes in enumerate(online):
        trace(SimpleNamespace(t_s=0.1 * k, stride_index=0, frame_index=k, terrain=_Grid(boxes)))
    return trace


def test_stride_deadline_from_the_trace_known_answer():
    trace = _trace()
    stride = SimpleNamespace(smoothed_grid=_Grid([FINAL, Box(2.0, 0.1, (2.1, 0.0), False)]))
    # gait cycle from 0.0 to 1.0 s, toe-off at 0.6 s (60 %)
    ref = SimpleNamespace(frame_indices=np.arange(6), toe_off_s=0.6, t_strike_s=0.0,
                          t_next_strike_s=1.0, toe_off_pct=60.0)  # fmt: skip
    sd = stride_deadlines(trace, stride, ref, index=7, speed="Slow", number=2)
    assert len(sd.deadlines) == 1  # the part-seen box is not scored
    (d,) = sd.deadlines
    assert d.known_t_s == pytest.approx(0.3) and d.lead_s == pytest.approx(0.3)
    assert sd.known_pct == [pytest.approx(30.0)]
    row = sd.to_dict()
    assert row["index"] == 7 and row["obstacles"][0]["known_pct"] == pytest.approx(30.0)
    # searched at most every 0.15 s: frames 0, 2, 4; the box is known at the first of them
    # that knows it (0.4 s), the others are not searched
    sparse = _trace(interval_s=0.15)
    assert [o is None for o in sparse.obstacles] == [False, True, False, True, False, True]
    (late,) = stride_deadlines(sparse, stride, ref, 7, "Slow", 2).deadlines
    assert late.known_t_s == pytest.approx(0.4)
    # a stride without a final grid has nothing to score
    assert stride_deadlines(trace, None, ref, 7, "Slow", 2).deadlines == []


def test_metrics_json_carries_the_deadline_section(tmp_path):
    ref = SimpleNamespace(frame_indices=np.arange(6), toe_off_s=0.25, t_strike_s=0.0,
                          t_next_strike_s=1.0, toe_off_pct=25.0)  # fmt: skip
    stride = SimpleNamespace(smoothed_grid=_Grid([FINAL]))
    sd = stride_deadlines(_trace(), stride, ref, 0, "Normal", 1)
    doc = metrics_document("s", {}, {}, {"icp+imu+kin": [sd]})
    path = write_metrics_json(doc, tmp_path / "metrics.json")
    back = read_metrics_json(path)
    assert back["schema_version"] == SCHEMA_VERSION == 4
    section = back["terrain_deadlines"]["icp+imu+kin"]
    assert section["all"]["n"] == 1 and section["all"]["n_before_toe_off"] == 0  # known late
    assert section["by_speed"]["Normal"]["lead_s_min"] == pytest.approx(-0.05)
    assert section["strides"][0]["obstacles"][0]["known_t_s"] == pytest.approx(0.3)
    # version 3 without the section is refused, naming the field
    doc = json.loads(path.read_text())
    del doc["terrain_deadlines"]
    path.write_text(json.dumps(doc))
    with pytest.raises(EvaluationError, match="terrain_deadlines"):
        read_metrics_json(path)


def test_trace_keeps_every_nth_grid_and_logs_it():
    trace = _trace(grid_step=2)
    assert sorted(trace.snapshots) == [0, 2, 4]
    assert trace.snapshots[4].height_m.dtype == np.float32
    calls = []

    class Fake:
        def set_time(self, stride, t):
            calls.append(("time", stride, round(t, 6)))

        def log_stride(self, world_T_stride):
            calls.append(("stride",))

        def log_grid(self, snapshot):
            calls.append(("grid", len(snapshot.obstacles)))

    assert log_grids(Fake(), trace, range(1, 6), 3, 10.0, np.eye(4)) == 2
    assert calls == [("time", 3, 10.2), ("stride",), ("grid", 1), ("time", 3, 10.4),
                     ("stride",), ("grid", 1)]  # fmt: skip


def test_grid_layers_and_boxes_known_answer():
    from graph_slam.viz.rerun_logger import grid_boxes, grid_layers

    h = np.full((3, 2), np.nan)
    h[0, 0], h[2, 1] = 0.0, 0.1
    snap = GridSnapshot(0, 0.0, np.array([-0.2, -0.6]), 0.02, h, np.full((3, 2), 0.5), ())
    layers = grid_layers(snap)
    np.testing.assert_allclose(layers["points_m"], [[-0.19, -0.59, 0.0], [-0.15, -0.57, 0.1]],
                               atol=1e-6)  # fmt: skip
    assert layers["height_rgb"].shape == (2, 3) and layers["height_rgb"].dtype == np.uint8
    assert (layers["sigma_rgb"][0] == layers["sigma_rgb"][1]).all()  # both clipped at the top
    # a box standing on a floor 5 cm below the stride origin, tilted 0.1 rad about y
    c, s = np.cos(0.1), np.sin(0.1)
    stride_T_floor = np.eye(4)
    stride_T_floor[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    stride_T_floor[:3, 3] = [0.0, 0.0, -0.05]
    box = SimpleNamespace(center_xy_m=np.array([1.0, 0.2]), depth_m=0.2, width_m=0.3,
                          height_m=0.1)  # fmt: skip
    centers, sizes = grid_boxes([box], np.linalg.inv(stride_T_floor))
    floor_z = -0.05 - np.tan(0.1) * 1.0  # the floor under x = 1 m
    np.testing.assert_allclose(centers, [[1.0, 0.2, floor_z + 0.05]], atol=1e-9)
    np.testing.assert_allclose(sizes, [[0.2, 0.3, 0.1]])


def test_rerun_recording_holds_the_grid_layers(tmp_path):
    pytest.importorskip("rerun")
    from graph_slam.viz import TERRAIN_HEIGHT, TERRAIN_OBSTACLES, TERRAIN_SIGMA, make_logger

    h = np.zeros((4, 3))
    h[1:3, 1] = 0.1
    box = SimpleNamespace(center_xy_m=np.array([-0.17, -0.57]), depth_m=0.04, width_m=0.02,
                          height_m=0.1, height_sigma_m=0.001, distance_m=-0.4, complete=True)  # fmt: skip
    snap = GridSnapshot(0, 0.0, np.array([-0.2, -0.6]), 0.02, h, np.full((4, 3), 0.002), (box,),
                        np.eye(4))  # fmt: skip
    path = tmp_path / "r.rrd"
    logger = make_logger(path)
    logger.set_time(0, 0.0)
    logger.log_grid(snap)
    logger.set_time(0, 0.1)
    logger.log_grid(GridSnapshot(0, 0.1, snap.origin_xy_m, 0.02, h, snap.sigma_m, ()))
    logger.close()
    paths = _entity_paths(path)
    for entity in (TERRAIN_HEIGHT, TERRAIN_SIGMA, TERRAIN_OBSTACLES):
        assert "/" + entity in paths, entity


def _entity_paths(path) -> set[str]:
    try:
        from rerun.chunk import RrdReader
    except ImportError:  # an older rerun: the entity paths are in the file's bytes
        data = path.read_bytes()
        return {p for p in ("/world/stride/terrain/height", "/world/stride/terrain/sigma",
                            "/world/stride/terrain/obstacles") if p[1:].encode() in data}  # fmt: skip
    return set(RrdReader(path).store().schema().entity_paths())


def test_obstacle_known_vs_phase_plot(tmp_path):
    from graph_slam.viz.plots import plot_obstacle_known_vs_phase

    known = {"Slow": {"icp": [10.0, np.nan], "icp+imu+kin": [5.0, 20.0]}, "Fast": {"icp": []}}
    path = plot_obstacle_known_vs_phase(tmp_path / "plots" / "k.png", known, {"Slow": 62.0})
    assert path.is_file() and path.read_bytes()[:4] == b"\x89PNG"
