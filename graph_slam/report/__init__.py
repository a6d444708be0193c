"""The applications on top of the pipelines: ``compare`` (run the variants over sessions →
score → tables → plots, PLY/TUM files and the rerun recording). See docs/evaluation.md.

    from graph_slam.report import CompareConfig, compare
    report = compare(["runs/slow", "runs/fast"], "runs/report", CompareConfig())
"""

from graph_slam.report.compare import (
    CompareConfig,
    CompareReport,
    SessionSpec,
    compare,
    speed_label,
)
from graph_slam.report.keys import Kind, MapSource, RunKey
from graph_slam.report.markdown import summary_table

__all__ = [
    "CompareConfig",
    "CompareReport",
    "Kind",
    "MapSource",
    "RunKey",
    "SessionSpec",
    "compare",
    "speed_label",
    "summary_table",
]
