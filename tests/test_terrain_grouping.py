"""metrics.json and report.md group strides by the terrain under the stance foot."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.evaluation.counts import FrameCounts
from graph_slam.evaluation.report import StrideEvaluation, VariantEvaluation
from graph_slam.evaluation.trajectory import StrideTrajectoryMetrics
from graph_slam.report.markdown import terrain_section
from graph_slam.report.scoring import terrain_labels
from graph_slam.sim.terrain_truth import read_stride_terrain


def stride(k: int, rmse_m: float, terrain: str | None) -> StrideEvaluation:
    traj = StrideTrajectoryMetrics(10, 10, rmse_m, rmse_m / 2, {}, None, np.zeros(10), np.zeros(10))
    return StrideEvaluation(k, "normal", k + 1, FrameCounts(10, 8, 2, 0, 0), traj, terrain)


def test_summary_groups_by_terrain():
    v = VariantEvaluation(
        [stride(0, 0.002, "level"), stride(1, 0.006, "ramp_up"), stride(2, 0.004, "ramp_up")]
    )
    by = v.summary()["by_terrain"]
    assert by["level"]["strides"] == 1
    assert by["ramp_up"]["strides"] == 2
    assert by["ramp_up"]["rmse_unaligned_m"]["median"] == pytest.approx(0.005)
    assert v.to_dict()["strides"][1]["terrain"] == "ramp_up"
    table = "\n".join(terrain_section({"icp+imu+kin": v}))
    assert "| icp+imu+kin | ramp_up | 2 | 5.0 | 2.5 |" in table
    plain = VariantEvaluation([stride(0, 0.002, None)])
    assert "by_terrain" not in plain.summary() and "terrain" not in plain.to_dict()["strides"][0]
    assert terrain_section({"x": plain}) == []


def test_labels_come_from_the_sessions_truth(tmp_path):
    (tmp_path / "strides_truth.csv").write_text(
        "stride,label,strike_t_s,heel_x_m,heel_y_m,heel_z_m,slope_deg,feature,edge_clearance_m\n"
        "0,level,0.25,0,0,0,0,floor,\n"
        "1,stairs_up,1.40,0.9,0,0.17,0,Stairs,0.041\n"
    )
    refs = [SimpleNamespace(t_strike_s=t) for t in (0.26, 1.38, 3.0)]
    run = SimpleNamespace(session=SimpleNamespace(path=tmp_path), references=refs)
    assert terrain_labels(run) == ["level", "stairs_up", None]
    rows = read_stride_terrain(tmp_path)
    assert rows[1].edge_clearance_m == pytest.approx(0.041) and rows[0].edge_clearance_m is None
    (tmp_path / "strides_truth.csv").write_text(
        "stride,label,strike_t_s,heel_x_m,heel_y_m,heel_z_m,slope_deg,feature,edge_clearance_m\n"
        "0,escalator,0.25,0,0,0,0,floor,\n"
    )
    with pytest.raises(Exception, match="escalator"):
        read_stride_terrain(tmp_path)


def test_anchor_case_and_slope_from_the_flags():
    from graph_slam.report.summary import anchor_of

    flags = ("floor:ok", "anchor:slope", "slope_deg:7.71", "icp:ok")
    assert anchor_of(flags) == {"anchor": "slope", "slope_deg": 7.71}
    assert anchor_of(("icp:ok",)) == {}
    s = StrideEvaluation(0, "normal", 1, FrameCounts(1, 1, 0, 0, 0), None, "ramp_up",
                         anchor_of(flags))  # fmt: skip
    assert s.to_dict()["anchor"] == "slope" and s.to_dict()["slope_deg"] == 7.71


def test_the_up_source_and_the_grid_frames_reach_the_metrics():
    from types import SimpleNamespace

    from graph_slam.report.scoring import anchor_of

    flags = ("floor:small_extent", "anchor:imu", "up:kinematics")
    stride = SimpleNamespace(grid_frames=(100, 12))
    got = anchor_of(flags, stride)
    assert got == {"anchor": "imu", "up_source": "kinematics", "grid_frames_fused": 100,
                   "grid_frames_held": 12}  # fmt: skip
    assert anchor_of(flags, SimpleNamespace(grid_frames=(0, 0))) == {
        "anchor": "imu", "up_source": "kinematics"}  # fmt: skip
    s = StrideEvaluation(0, "normal", 1, FrameCounts(1, 1, 0, 0, 0), None, "stairs_up", got)
    assert s.to_dict()["grid_frames_held"] == 12
