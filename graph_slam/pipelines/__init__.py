"""The thesis baseline and the factor-graph pipelines behind one interface (docs/pipelines.md).

from graph_slam.pipelines import PipelineConfig, run_session
results = run_session("runs/sim", PipelineConfig(variant="icp+imu+kin"))
online = replay_session("runs/sim", PipelineConfig(), pace="virtual")  # causal, timed
"""

from graph_slam.pipelines.config import (
    BaselineConfig,
    GraphFrontendConfig,
    PipelineConfig,
    PipelineVariant,
)
from graph_slam.pipelines.protocol import Pipeline
from graph_slam.pipelines.replay import ReplayResult, replay_session
from graph_slam.pipelines.results import FrameOutput, PipelineResults, StrideOutput
from graph_slam.pipelines.runner import make_pipeline, run_session
from graph_slam.variants import VARIANTS, Variant

__all__ = [
    "VARIANTS",
    "BaselineConfig",
    "FrameOutput",
    "GraphFrontendConfig",
    "Pipeline",
    "PipelineConfig",
    "PipelineResults",
    "PipelineVariant",
    "ReplayResult",
    "StrideOutput",
    "Variant",
    "make_pipeline",
    "replay_session",
    "run_session",
]
