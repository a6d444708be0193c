"""Evaluation against ground truth: trajectory metrics (via evo), frame counts, obstacle
accuracy, timing, thesis-style tables and ``metrics.json`` (scoring only; plots: ``viz.plots``).

evo is GPL-3 and an optional extra (``pip install 'graph_slam[eval]'``): only this package
imports it, lazily, when trajectory metrics are computed. Nothing in the estimator imports
this package.
"""

from graph_slam.evaluation.boxes import (
    DIMENSIONS,
    BoxOutcome,
    DimensionStats,
    StrideObstacles,
    TrueBox,
    assess_stride,
    assign_obstacles,
    base_name,
    collect_measurements,
    count_outcomes,
    obstacle_accuracy,
    truth_boxes_in_stride,
)
from graph_slam.evaluation.counts import FrameCounts, frame_counts
from graph_slam.evaluation.report import (
    SCHEMA_VERSION,
    MapEvaluation,
    StrideEvaluation,
    VariantEvaluation,
    metrics_document,
    read_metrics_json,
    table_rows,
    write_metrics_json,
)
from graph_slam.evaluation.tables import (
    StrideRow,
    VariantStride,
    table_4_1,
    table_4_2,
    table_box_counts,
)
from graph_slam.evaluation.timing import TimingStats, timing_stats
from graph_slam.evaluation.trajectory import (
    StrideTrajectoryMetrics,
    gait_cycle_percent,
    stance_mask,
    stride_trajectory_metrics,
)

__all__ = [
    "DIMENSIONS",
    "SCHEMA_VERSION",
    "BoxOutcome",
    "DimensionStats",
    "FrameCounts",
    "MapEvaluation",
    "StrideEvaluation",
    "StrideObstacles",
    "StrideRow",
    "StrideTrajectoryMetrics",
    "TimingStats",
    "TrueBox",
    "VariantEvaluation",
    "VariantStride",
    "assess_stride",
    "assign_obstacles",
    "base_name",
    "collect_measurements",
    "count_outcomes",
    "frame_counts",
    "gait_cycle_percent",
    "metrics_document",
    "obstacle_accuracy",
    "read_metrics_json",
    "stance_mask",
    "stride_trajectory_metrics",
    "table_4_1",
    "table_4_2",
    "table_box_counts",
    "table_rows",
    "timing_stats",
    "truth_boxes_in_stride",
    "write_metrics_json",
]
