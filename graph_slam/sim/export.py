"""A simulated walk exported as a real recording: a RealSense SDK recording and a prosthesis log.

What a researcher brings home from a session, made from the simulator so that the whole path
(``graph-slam convert`` then ``graph-slam run``, or ``graph-slam live --playback``,
docs/recording.md) can be tried and tested without a camera:

- ``recording.db3``: a RealSense SDK recording written by librealsense itself
  (:mod:`.realsense_sdk`: a software device recorded by ``rs.recorder``), which the SDK's
  playback opens: 16-bit depth at the camera's rate (with the profile's frame drops), colour
  **not aligned** to depth at its own rate and size — rendered from the colour camera's own
  pose (``color_T_depth``, a D455-like 59 mm baseline and a small rotation) —, the cameras'
  intrinsics, the depth→colour extrinsics, the depth units, accel and gyro at their own rates
  in the IMU's frame. Frames are fed at ``record_speed`` × real time, so the recording's own
  time (what the SDK's real-time playback follows) matches the frames' stamps;
- ``prosthesis_log.csv``: the controller's log on its own clock (camera time = log time +
  ``clock_offset_s``): ``time_ms``, ``knee_deg``, ``ankle_deg`` (the encoders) and
  ``load_n`` (a load cell: body weight over stance, linear ramps at strike and toe-off);
- ``ground_truth.tum``: world_T_camera (depth optical frame) at the frames' stamps, on the
  camera clock — for checking only, ``convert`` and ``run`` do not read it;
- ``export.yaml``: what was exported (the truth to check a conversion against) and the
  simulator's resolved config;
- ``convert.yaml``: the conversion config for this recording — the topic preset, the log's
  column mapping and ``calibration.camera_T_imu`` (librealsense records no extrinsics for its
  motion streams; a camera's own are read with pyrealsense2, docs/recording.md). No clock
  offset and no camera extrinsics: ``convert`` finds them.

Steps of :func:`export_realsense_recording`: prepare the simulation → render depth (the depth
camera) and colour (the colour camera) at their own times → feed them, merged in time order
with the IMU samples, to librealsense's recorder → write the log, the ground truth and the two
YAML files. The settings, file names and result are in :mod:`.export_config`, the recording in
:mod:`.export_bag`, the log in :mod:`.export_log`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.io import write_tum
from graph_slam.session.records import CameraIntrinsics
from graph_slam.sim.config import SimConfig
from graph_slam.sim.export_bag import write_bag
from graph_slam.sim.export_config import (
    BAG_NAME,
    CONVERT_NAME,
    EXPORT_COMMAND,
    EXPORT_NAME,
    LOG_NAME,
    TRUTH_NAME,
    ExportResult,
    RecordingExportConfig,
    color_intrinsics,
    pose,
)
from graph_slam.sim.export_log import load_signal, write_log
from graph_slam.sim.recording import Simulation, prepare
from graph_slam.sim.render import intrinsics_for

__all__ = [
    "BAG_NAME",
    "CONVERT_NAME",
    "EXPORT_COMMAND",
    "EXPORT_NAME",
    "LOG_NAME",
    "STRIKE_ABOVE_N",
    "TOE_OFF_BELOW_N",
    "TRUTH_NAME",
    "ExportResult",
    "RecordingExportConfig",
    "color_intrinsics",
    "convert_config",
    "export_realsense_recording",
    "load_signal",
    "pose",
]

#: The load-cell thresholds written into convert.yaml (newtons, hysteresis).
STRIKE_ABOVE_N, TOE_OFF_BELOW_N = 50.0, 20.0


def export_realsense_recording(
    cfg: SimConfig,
    out: str | Path,
    export: RecordingExportConfig | None = None,
    *,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> ExportResult:
    """Simulate ``cfg``'s walk and write it as a RealSense SDK bag + a prosthesis log into the
    folder ``out`` (module docstring). Deterministic: the same configs give the same files."""
    export = export or RecordingExportConfig()
    check_output(out, overwrite=overwrite, command=EXPORT_COMMAND)  # before any work
    sim = prepare(cfg)
    depth_k = intrinsics_for(sim.camera, cfg.fast, cfg.resolution)
    color_k = color_intrinsics(depth_k, export)
    color_T_depth = pose(export.color_T_depth_rotvec_rad, export.color_T_depth_t_m)
    camera_T_imu = sim.calibration.camera_T_imu
    result = ExportResult(
        Path(out),
        int(sim.frame_times_s.size),
        sim.motion.duration_s,
        export.clock_offset_s,
        color_T_depth,
        camera_T_imu,
        depth_k,
        color_k,
    )
    with atomic_folder(out, overwrite=overwrite, command=EXPORT_COMMAND) as tmp:
        result.counts = write_bag(tmp / BAG_NAME, sim, export, depth_k, color_k, progress)
        write_log(tmp / LOG_NAME, sim, export)
        world_T_camera = sim.motion.world_T(sim.frame_times_s, sim.thigh_T_camera)
        write_tum(tmp / TRUTH_NAME, sim.frame_times_s + export.camera_epoch_s, world_T_camera)
        _write_yaml(tmp, result, sim, export)
    return result


def convert_config(log_path: str | Path, camera_T_imu: np.ndarray) -> dict:
    """The conversion config of an exported recording: the SDK preset, the log's column
    mapping and the IMU's extrinsics (which librealsense does not record for its motion
    streams); ``convert`` estimates the clock offset and reads the cameras' extrinsics."""
    return {
        "bag": {"preset": "realsense-sdk"},
        "calibration": {"camera_T_imu": np.asarray(camera_T_imu, float).tolist()},
        "prosthesis_log": {
            "path": str(log_path),
            "time": {"column": "time_ms", "unit": "ms"},
            "knee": {"column": "knee_deg", "unit": "deg"},
            "ankle": {"column": "ankle_deg", "unit": "deg"},
            "load": {
                "column": "load_n",
                "foot_strike_above_n": STRIKE_ABOVE_N,
                "toe_off_below_n": TOE_OFF_BELOW_N,
            },
        },
    }


def _write_yaml(tmp: Path, result: ExportResult, sim: Simulation, export: RecordingExportConfig):
    def k(x: CameraIntrinsics) -> dict:
        return {n: getattr(x, n) for n in ("width_px", "height_px", "fx_px", "fy_px", "cx_px", "cy_px")}  # fmt: skip

    truth = {
        "note": "what the recording and the log were made with; graph-slam convert does not "
        "read it",
        "clock_offset_s": export.clock_offset_s,
        "color_T_depth": result.color_T_depth.tolist(),
        "camera_T_imu": result.camera_T_imu.tolist(),
        "thigh_T_camera": sim.thigh_T_camera.tolist(),
        "depth_intrinsics": k(result.depth_intrinsics),
        "color_intrinsics": k(result.color_intrinsics),
        "frames": result.frames,
        "foot_strikes_s": [float(t) + export.camera_epoch_s for t in sim.motion.foot_strikes_s],
        "messages": result.counts,
        "export": export.model_dump(mode="json"),
        "sim": sim.cfg.model_dump(mode="json"),
    }
    (tmp / EXPORT_NAME).write_text(yaml.safe_dump(truth, sort_keys=False), encoding="utf-8")
    log_path = result.path / LOG_NAME
    (tmp / CONVERT_NAME).write_text(
        yaml.safe_dump(convert_config(log_path, result.camera_T_imu), sort_keys=False),
        encoding="utf-8",
    )
