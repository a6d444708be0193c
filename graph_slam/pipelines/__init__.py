"""The thesis baseline and the factor-graph pipelines behind one interface (docs/pipelines.md).

from graph_slam.pipelines import PipelineConfig, run_session
results = run_session("runs/sim", PipelineConfig(variant="icp+imu+kin"))
"""

from graph_slam.pipelines.config import (
    BaselineConfig,
    GraphFrontendConfig,
    PipelineConfig,
    PipelineVariant,
)
from graph_slam.pipelines.protocol import Pipeline
from graph_slam.pipelines.results import FrameOutput, PipelineResults, StrideOutput
from graph_slam.pipelines.runner import make_pipeline, run_session

VARIANTS: tuple[str, ...] = ("icp", "icp+imu", "imu+kin", "icp+imu+kin")

__all__ = [
    "VARIANTS",
    "BaselineConfig",
    "FrameOutput",
    "GraphFrontendConfig",
    "Pipeline",
    "PipelineConfig",
    "PipelineResults",
    "PipelineVariant",
    "StrideOutput",
    "make_pipeline",
    "run_session",
]
