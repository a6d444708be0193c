"""``graph-slam bench pipelines`` bookkeeping on hand-made scores (no pipeline run)."""

from __future__ import annotations

import numpy as np

from graph_slam.bench.accuracy import (
    BRIDGE,
    SessionScore,
    StrideScore,
    VariantScore,
    summary_lines,
    swing_lines,
    variant_config,
)


def _stride(i, sm, end, swing_err, swing_frames):
    return StrideScore(
        index=i, n_frames=10, n_swing=len(swing_frames), online_rmse_m=sm, smoothed_rmse_m=sm,
        end_online_m=end, end_smoothed_m=end, n_with_pose=10, n_registered_stance=5, n_stance=5,
        swing_err_m=np.asarray(swing_err, float), swing_frames=np.asarray(swing_frames),
    )  # fmt: skip


def test_bridge_row_is_the_full_graph_without_swing_icp():
    cfg = variant_config(BRIDGE)
    assert cfg.variant == "icp+imu+kin" and cfg.graph.icp_in_swing is False
    assert variant_config("icp+imu+kin").graph.icp_in_swing is True


def test_summary_and_swing_lines_carry_the_known_figures():
    timing = {"median": 1.0, "p95": 2.0}
    graph = [
        _stride(1, 0.002, 0.004, [0.001, 0.001], [5, 6]),
        _stride(2, 0.006, 0.03, [0.002], [9]),
    ]
    base = [_stride(1, 0.1, 0.1, [0.01, np.nan], [5, 6]), _stride(2, 0.1, 0.1, [np.nan], [9])]
    sc = SessionScore("s", "normal")
    sc.variants["icp"] = VariantScore("icp", base, 2, 2, timing, 1.0)
    sc.variants["icp+imu+kin"] = VariantScore("icp+imu+kin", graph, 0, 0, timing, 1.0)
    summary = "\n".join(summary_lines([sc]))
    assert "icp+imu+kin  2 strides: smoothed RMSE median 4.0 / worst 6.0 mm" in summary
    assert "next strike median 17.0 / max 30.0 mm" in summary
    assert "  icp " not in summary  # the baseline has its own counts, not an RMSE summary
    swing = swing_lines(sc)[0]
    assert "3 frames; baseline without pose on 2" in swing
    assert "10.0/1.0 (10.0x)" in swing  # only the frame the baseline posed


def test_markdown_table_has_a_row_per_graph_variant_and_its_caption():
    from graph_slam.bench.accuracy import markdown_table

    timing = {"median": 1.0, "p95": 2.0}
    graph = [_stride(1, 0.002, 0.004, [], []), _stride(2, 0.006, 0.03, [], [])]
    sc = SessionScore("s", "normal")
    sc.variants["icp"] = VariantScore("icp", graph, 0, 0, timing, 1.0)
    sc.variants["icp+imu+kin"] = VariantScore("icp+imu+kin", graph, 0, 0, timing, 1.0)
    caption, _, header, rule, *body = markdown_table(
        [sc], "graph-slam bench pipelines s"
    ).splitlines()
    assert caption.endswith("cores: `graph-slam bench pipelines s`)")
    assert header.count("|") == rule.count("|") == 7
    assert body == ["| s | icp+imu+kin | 2 | 4.0 / 6.0 | 4.0 / 6.0 | 17.0 / 30.0 |"]
