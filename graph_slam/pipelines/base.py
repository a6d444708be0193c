"""The one interface every pipeline variant implements."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from graph_slam.pipelines.results import FrameOutput, PipelineResults
from graph_slam.session.records import RgbdFrame


@runtime_checkable
class Pipeline(Protocol):
    """A SLAM pipeline fed in time order: sensor streams first (any chunking), then per frame
    ``foot_strike`` (when one happened since the previous frame) and ``add_frame``."""

    variant: str

    def add_imu(self, t_s: np.ndarray, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray) -> None:
        """IMU samples on the camera clock (IMU frame)."""

    def add_joints(self, t_s: np.ndarray, knee_rad: np.ndarray, ankle_rad: np.ndarray) -> None:
        """Encoder samples on the camera clock."""

    def foot_strike(self, t_s: float) -> None:
        """A foot strike: the stride ends, the next frame starts a new one."""

    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        """Process one frame; returns its online output."""

    def finish(self) -> PipelineResults:
        """Close the open stride and return everything."""
