"""What a simulated walk's export is made with and what it gives: the settings
(:class:`RecordingExportConfig`), the folder's file names, the result (:class:`ExportResult`),
the colour camera's intrinsics and the poses given as rotation vector and translation.

The export itself is :func:`graph_slam.sim.export.export_realsense_recording`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.session.records import CameraIntrinsics

BAG_NAME = "recording.db3"
LOG_NAME = "prosthesis_log.csv"
TRUTH_NAME = "ground_truth.tum"
EXPORT_NAME = "export.yaml"
CONVERT_NAME = "convert.yaml"
EXPORT_COMMAND = "simulate --export realsense-sdk-bag"
"""The command its folder's marker names (a bag + log, not a session: never replaced by a
plain `simulate --overwrite`)."""


class RecordingExportConfig(ConfigModel):
    """How a simulated walk is exported as a RealSense SDK bag and a prosthesis log."""

    clock_offset_s: float = Field(
        3.217, description="the log's clock: camera time = log time + this (seconds)"
    )
    camera_epoch_s: float = Field(
        1_700_000_000.0, ge=0, description="bag stamps = simulator time + this (seconds)"
    )
    depth_unit_m: float = Field(0.001, gt=0, le=0.01, description="16-bit depth: m per value")
    color_scale: float = Field(
        1.5, gt=0.2, le=4, description="colour image size = depth image size × this"
    )
    color_size_px: tuple[int, int] | None = Field(
        None, description="colour image size (width, height); None: depth size × color_scale"
    )
    color_rate_hz: float | None = Field(
        30.0, gt=0, le=300, description="colour frames per second; None: with every depth frame"
    )
    record_speed: float | None = Field(
        1.0,
        gt=0,
        le=100,
        description="frames are given to the recorder at this multiple of real time (its "
        "playback follows the recording's own time); None: as fast as they come",
    )
    serial: str = Field("000000000001", description="the device's serial number in the file")
    color_fov_deg: tuple[float, float] = Field(
        (90.0, 65.0), description="colour camera field of view (x, y); D455 RGB ≈ 90° × 65°"
    )
    color_principal_offset_px: tuple[float, float] = Field(
        (1.3, -0.9), description="colour principal point − image centre, at the colour size"
    )
    color_T_depth_t_m: tuple[float, float, float] = Field(
        (-0.059, 0.0003, 0.0005), description="depth → colour translation (D455: ~59 mm)"
    )
    color_T_depth_rotvec_rad: tuple[float, float, float] = Field(
        (0.003, -0.004, 0.002), description="depth → colour rotation (rotation vector)"
    )
    color_delay_s: float = Field(
        0.0003, ge=0, le=0.01, description="colour stamp − depth stamp of one frame"
    )
    gyro_rate_hz: float = Field(400.0, gt=0, le=1000, description="D455: 200 or 400 Hz")
    accel_rate_hz: float = Field(250.0, gt=0, le=1000, description="D455: 63 or 250 Hz")
    body_weight_n: float = Field(750.0, gt=0, description="load-cell reading in stance")
    load_ramp_s: float = Field(0.03, gt=0, le=0.2, description="load rise/fall time")
    load_noise_n: float = Field(2.0, ge=0, description="σ of the load cell's noise")


@dataclass
class ExportResult:
    """What was exported, with the truth a conversion can be checked against."""

    path: Path
    frames: int
    duration_s: float
    clock_offset_s: float
    color_T_depth: np.ndarray
    camera_T_imu: np.ndarray
    depth_intrinsics: CameraIntrinsics
    color_intrinsics: CameraIntrinsics
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def bag(self) -> Path:
        return self.path / BAG_NAME

    @property
    def log(self) -> Path:
        return self.path / LOG_NAME

    @property
    def ground_truth(self) -> Path:
        return self.path / TRUTH_NAME

    @property
    def convert_config(self) -> Path:
        return self.path / CONVERT_NAME

    def lines(self) -> list[str]:
        d, c = self.depth_intrinsics, self.color_intrinsics
        return [
            f"wrote {self.bag} (RealSense SDK recording): {self.frames} depth frames "
            f"{d.width_px}x{d.height_px}, {self.counts.get('color', 0)} colour "
            f"{c.width_px}x{c.height_px} (not aligned), accel + gyro, over {self.duration_s:.2f} s",
            f"wrote {self.log} (clock offset {self.clock_offset_s:+.3f} s: camera = log + offset)",
            f"wrote {self.ground_truth} (for checking only), {self.path / EXPORT_NAME}, "
            f"{self.convert_config}",
        ]


def pose(rotvec: tuple[float, ...], t: tuple[float, ...]) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    out[:3, 3] = t
    return out


def color_intrinsics(depth: CameraIntrinsics, export: RecordingExportConfig) -> CameraIntrinsics:
    """The colour camera: the depth size × ``color_scale``, its own field of view, the
    principal point off centre by ``color_principal_offset_px``."""
    w = max(round(depth.width_px * export.color_scale), 8)
    h = max(round(depth.height_px * export.color_scale), 8)
    if export.color_size_px is not None:
        w, h = export.color_size_px
    fov_x, fov_y = export.color_fov_deg
    du, dv = export.color_principal_offset_px
    return CameraIntrinsics(
        w,
        h,
        0.5 * w / math.tan(math.radians(fov_x) / 2),
        0.5 * h / math.tan(math.radians(fov_y) / 2),
        (w - 1) / 2.0 + du,
        (h - 1) / 2.0 + dv,
    )
