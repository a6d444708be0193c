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
YAML files.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.io import write_tum
from graph_slam.session.records import CameraIntrinsics
from graph_slam.sim.config import SimConfig
from graph_slam.sim.recording import _DEPTH, _ENCODERS, _IMU, _LOAD_CELL, Simulation, prepare
from graph_slam.sim.render import Renderer, intrinsics_for
from graph_slam.sim.sensors import simulate_encoders, simulate_imu

BAG_NAME = "recording.db3"
LOG_NAME = "prosthesis_log.csv"
TRUTH_NAME = "ground_truth.tum"
EXPORT_NAME = "export.yaml"
CONVERT_NAME = "convert.yaml"
EXPORT_COMMAND = "simulate --export realsense-sdk-bag"
"""The command its folder's marker names (a bag + log, not a session: never replaced by a
plain `simulate --overwrite`)."""
#: The load-cell thresholds written into convert.yaml (newtons, hysteresis).
STRIKE_ABOVE_N, TOE_OFF_BELOW_N = 50.0, 20.0
_ACCEL_STREAM = 6  # the accel's own random stream (the gyro uses the simulator's IMU stream)


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
        result.counts = _write_bag(tmp / BAG_NAME, sim, export, depth_k, color_k, progress)
        _write_log(tmp / LOG_NAME, sim, export)
        world_T_camera = sim.motion.world_T(sim.frame_times_s, sim.thigh_T_camera)
        write_tum(tmp / TRUTH_NAME, sim.frame_times_s + export.camera_epoch_s, world_T_camera)
        _write_yaml(tmp, result, sim, export)
    return result


def _color_times(t_frames: np.ndarray, export: RecordingExportConfig) -> np.ndarray:
    """The colour frames' times: at ``color_rate_hz`` from the first depth frame (+ delay),
    or with every depth frame."""
    if export.color_rate_hz is None:
        return t_frames + export.color_delay_s
    n = int(np.floor((t_frames[-1] - t_frames[0]) * export.color_rate_hz)) + 1
    return t_frames[0] + export.color_delay_s + np.arange(n) / export.color_rate_hz


def _write_bag(
    path: Path,
    sim: Simulation,
    export: RecordingExportConfig,
    depth_k: CameraIntrinsics,
    color_k: CameraIntrinsics,
    progress: Callable[[int, int], None] | None,
) -> dict[str, int]:
    """Depth and colour rendered at their own times, then given with accel and gyro in time
    order to librealsense's recorder (in memory first when recording in real time, so that
    rendering does not slow the recording's clock)."""
    from graph_slam.sim.realsense_sdk import SdkDevice, SdkRecorder

    cfg, camera = sim.cfg, sim.camera
    depth_only = camera.model_copy(update={"color": False})
    depth_r = Renderer(sim.scene, depth_k, depth_only, noise_scale=cfg.noise_scale)
    color_r = Renderer(
        sim.scene, color_k, camera, noise_scale=cfg.noise_scale, motion_blur=cfg.motion_blur
    )
    color_T_depth = pose(export.color_T_depth_rotvec_rad, export.color_T_depth_t_m)
    t_frames = sim.frame_times_s
    t_color = _color_times(t_frames, export)
    world_T_depth = sim.motion.world_T(t_frames, sim.thigh_T_camera)
    world_T_color = sim.motion.world_T(t_color, sim.thigh_T_camera) @ np.linalg.inv(color_T_depth)
    gyro_depth, _ = sim.motion.imu_ideal(t_color, sim.thigh_T_camera)
    gyro_color = gyro_depth @ color_T_depth[:3, :3].T
    accel, gyro = _imu_streams(sim, export)
    events = _schedule(t_frames, t_color, accel.t_s, gyro.t_s)
    rng_depth = np.random.default_rng([cfg.seed, _DEPTH])
    device = SdkDevice(
        depth=depth_k, depth_rate_hz=round(camera.rate_hz), depth_unit_m=export.depth_unit_m,
        color=color_k, color_rate_hz=round(export.color_rate_hz or camera.rate_hz),
        color_T_depth=color_T_depth, accel_rate_hz=round(export.accel_rate_hz),
        gyro_rate_hz=round(export.gyro_rate_hz), serial=export.serial,
    )  # fmt: skip

    def render(kind: int, i: int) -> np.ndarray:
        if kind == 0:
            depth_m, _ = depth_r.render(world_T_depth[i], rng_depth)
            if progress is not None:
                progress(i + 1, t_frames.size)
            raw = np.rint(depth_m / export.depth_unit_m)
            return np.clip(raw, 0, 65535).astype(np.uint16)
        return color_r.render_color(world_T_color[i], gyro_color[i])

    images: dict[tuple[int, int], np.ndarray] = {}
    if export.record_speed is not None:  # rendered first: the recorder's clock is real time
        images = {(k, i): render(k, i) for _, k, i in events if k in (0, 1)}
    epoch = export.camera_epoch_s
    with SdkRecorder(path, device, speed=export.record_speed) as rec:
        for t_s, kind, i in events:
            if kind in (0, 1):
                image = images.pop((kind, i)) if images else render(kind, i)
                (rec.depth if kind == 0 else rec.color)(t_s + epoch, image)
            elif kind == 2:
                rec.accel(t_s + epoch, accel.accel_m_s2[i])
            else:
                rec.gyro(t_s + epoch, gyro.gyro_rad_s[i])
        return {
            "depth": rec.counts["depth"],
            "color": rec.counts["color"],
            "accel": rec.counts["accel"],
            "gyro": rec.counts["gyro"],
        }


def _imu_streams(sim: Simulation, export: RecordingExportConfig):
    """(accel, gyro) ImuSeries at their own rates (each from its own random stream)."""
    cfg = sim.cfg
    kw = dict(noise_scale=cfg.noise_scale, accel_range_g=cfg.accel_range_g,
              time_offset_s=cfg.imu_time_offset_s)  # fmt: skip
    gyro, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu,
                           np.random.default_rng([cfg.seed, _IMU]), rate_hz=export.gyro_rate_hz,
                           **kw)  # fmt: skip
    accel, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu,
                            np.random.default_rng([cfg.seed, _ACCEL_STREAM]),
                            rate_hz=export.accel_rate_hz, **kw)  # fmt: skip
    return accel, gyro


def _schedule(
    t_frames: np.ndarray, t_color: np.ndarray, t_accel: np.ndarray, t_gyro: np.ndarray
) -> list[tuple[float, int, int]]:
    """Every frame and sample as (simulator time s, kind, index), in time order: kind 0
    depth, 1 colour, 2 accel, 3 gyro."""
    return sorted(
        [(float(t), 0, i) for i, t in enumerate(t_frames)]
        + [(float(t), 1, i) for i, t in enumerate(t_color)]
        + [(float(t), 2, i) for i, t in enumerate(t_accel)]
        + [(float(t), 3, i) for i, t in enumerate(t_gyro)]
    )


def load_signal(
    t_s: np.ndarray,
    strikes_s: np.ndarray,
    toe_offs_s: np.ndarray,
    export: RecordingExportConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    """The load cell (N): body weight over each stance (strike → next toe-off), linear ramps
    of ``load_ramp_s`` starting at strike and ending at toe-off, plus white noise. A threshold
    of F N is crossed F / weight × ramp after the strike (50 N: 2 ms with the defaults)."""
    load = np.zeros_like(t_s)
    for strike in strikes_s:
        later = toe_offs_s[toe_offs_s > strike]
        toe_off = later[0] if later.size else t_s[-1] + 1.0
        up = np.clip((t_s - strike) / export.load_ramp_s, 0.0, 1.0)
        down = np.clip((toe_off - t_s) / export.load_ramp_s, 0.0, 1.0)
        load = np.maximum(load, export.body_weight_n * up * down)
    return load + export.load_noise_n * rng.standard_normal(t_s.size)


def _write_log(path: Path, sim: Simulation, export: RecordingExportConfig) -> None:
    """The controller's CSV: log time = camera time − clock offset, in ms."""
    cfg, motion = sim.cfg, sim.motion
    joints, _ = simulate_encoders(motion, sim.prosthesis,
                                  np.random.default_rng([cfg.seed, _ENCODERS]),
                                  noise_scale=cfg.noise_scale)  # fmt: skip
    load = load_signal(joints.t_s, motion.foot_strikes_s, motion.toe_offs_s, export,
                       np.random.default_rng([cfg.seed, _LOAD_CELL]))  # fmt: skip
    t_log_ms = (joints.t_s + export.camera_epoch_s - export.clock_offset_s) * 1e3
    table = np.column_stack(
        [t_log_ms, np.rad2deg(joints.knee_rad), np.rad2deg(joints.ankle_rad), load]
    )
    np.savetxt(path, table, delimiter=",", fmt=["%.3f", "%.4f", "%.4f", "%.2f"],
               header="time_ms,knee_deg,ankle_deg,load_n", comments="")  # fmt: skip


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
