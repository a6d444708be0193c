"""The per-stride factor-graph back end (GTSAM): keys, noise models, IMU preintegration,
ICP gating, factors, the per-stride graph (iSAM2 + batch smoothing) and the streaming
estimator :class:`StrideSLAM`. See docs/backend.md.

GTSAM is imported by the modules that use it; this package never imports open3d.
"""

from __future__ import annotations

from graph_slam.backend.config import BackendConfig, GateConfig, ImuNoiseConfig
from graph_slam.backend.estimator import StrideSLAM
from graph_slam.backend.measurements import IcpMeasurement, KinematicMeasurement
from graph_slam.backend.results import FrameEstimate, Results, StrideSummary

__all__ = [
    "BackendConfig",
    "FrameEstimate",
    "GateConfig",
    "IcpMeasurement",
    "ImuNoiseConfig",
    "KinematicMeasurement",
    "Results",
    "StrideSLAM",
    "StrideSummary",
]
