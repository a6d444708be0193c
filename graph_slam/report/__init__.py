"""The applications on top of the pipelines: ``run`` (every variant over sessions, with or
without ground truth → trajectories, maps, grids, flags, timing, agreement; docs/run.md) and
``compare`` (``run``'s variants scored against ground truth → tables, plots; docs/evaluation.md).

    from graph_slam.report import CompareConfig, RunConfig, compare, run
    out = run(["runs/walk"], "runs/walk_out", RunConfig())
    report = compare(["runs/slow", "runs/fast"], "runs/report", CompareConfig())
"""

from graph_slam.report.compare import (
    CompareConfig,
    CompareReport,
    compare,
    speed_label,
)
from graph_slam.report.keys import Kind, MapSource, RunKey
from graph_slam.report.markdown import summary_table
from graph_slam.report.run import RunConfig, RunReport, SessionSpec, run

__all__ = [
    "CompareConfig",
    "CompareReport",
    "Kind",
    "MapSource",
    "RunConfig",
    "RunKey",
    "RunReport",
    "SessionSpec",
    "compare",
    "run",
    "speed_label",
    "summary_table",
]
