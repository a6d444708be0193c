"""The exported walk's RealSense SDK recording: depth and colour rendered from their own
cameras at their own times, accel and gyro at their own rates, all given in time order to
librealsense's recorder (:mod:`graph_slam.sim.realsense_sdk`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from graph_slam.session.records import CameraIntrinsics
from graph_slam.sim.export_config import RecordingExportConfig, pose
from graph_slam.sim.recording import _DEPTH, _IMU, Simulation
from graph_slam.sim.render import Renderer
from graph_slam.sim.sensors import simulate_imu

_ACCEL_STREAM = 6  # the accel's own random stream (the gyro uses the simulator's IMU stream)


def _color_times(t_frames: np.ndarray, export: RecordingExportConfig) -> np.ndarray:
    """The colour frames' times: at ``color_rate_hz`` from the first depth frame (+ delay),
    or with every depth frame."""
    if export.color_rate_hz is None:
        return t_frames + export.color_delay_s
    n = int(np.floor((t_frames[-1] - t_frames[0]) * export.color_rate_hz)) + 1
    return t_frames[0] + export.color_delay_s + np.arange(n) / export.color_rate_hz


def write_bag(
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
    from graph_slam.sim.realsense_sdk import SdkRecorder

    t_frames = sim.frame_times_s
    t_color = _color_times(t_frames, export)
    render = _frame_renderer(sim, export, depth_k, color_k, t_color, progress)
    accel, gyro = _imu_streams(sim, export)
    events = _schedule(t_frames, t_color, accel.t_s, gyro.t_s)
    images: dict[tuple[int, int], np.ndarray] = {}
    if export.record_speed is not None:  # rendered first: the recorder's clock is real time
        images = {(k, i): render(k, i) for _, k, i in events if k in (0, 1)}
    epoch = export.camera_epoch_s
    device = _sdk_device(sim, export, depth_k, color_k)
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


def _frame_renderer(
    sim: Simulation,
    export: RecordingExportConfig,
    depth_k: CameraIntrinsics,
    color_k: CameraIntrinsics,
    t_color: np.ndarray,
    progress: Callable[[int, int], None] | None,
) -> Callable[[int, int], np.ndarray]:
    """``render(kind, i)``: depth frame ``i`` (kind 0: 16-bit, ``depth_unit_m`` per value,
    reported to ``progress``) from the depth camera, or colour frame ``i`` (kind 1) from the
    colour camera at ``t_color[i]`` (with its motion blur)."""
    cfg, camera = sim.cfg, sim.camera
    depth_only = camera.model_copy(update={"color": False})
    depth_r = Renderer(sim.scene, depth_k, depth_only, noise_scale=cfg.noise_scale)
    color_r = Renderer(
        sim.scene, color_k, camera, noise_scale=cfg.noise_scale, motion_blur=cfg.motion_blur
    )
    color_T_depth = pose(export.color_T_depth_rotvec_rad, export.color_T_depth_t_m)
    t_frames = sim.frame_times_s
    world_T_depth = sim.motion.world_T(t_frames, sim.thigh_T_camera)
    world_T_color = sim.motion.world_T(t_color, sim.thigh_T_camera) @ np.linalg.inv(color_T_depth)
    gyro_depth, _ = sim.motion.imu_ideal(t_color, sim.thigh_T_camera)
    gyro_color = gyro_depth @ color_T_depth[:3, :3].T
    rng_depth = np.random.default_rng([cfg.seed, _DEPTH])

    def render(kind: int, i: int) -> np.ndarray:
        if kind == 0:
            depth_m, _ = depth_r.render(world_T_depth[i], rng_depth)
            if progress is not None:
                progress(i + 1, t_frames.size)
            raw = np.rint(depth_m / export.depth_unit_m)
            return np.clip(raw, 0, 65535).astype(np.uint16)
        return color_r.render_color(world_T_color[i], gyro_color[i])

    return render


def _sdk_device(
    sim: Simulation,
    export: RecordingExportConfig,
    depth_k: CameraIntrinsics,
    color_k: CameraIntrinsics,
):
    """The recorded device: both cameras, the depth→colour extrinsics, the motion streams."""
    from graph_slam.sim.realsense_sdk import SdkDevice

    camera = sim.camera
    color_T_depth = pose(export.color_T_depth_rotvec_rad, export.color_T_depth_t_m)
    return SdkDevice(
        depth=depth_k, depth_rate_hz=round(camera.rate_hz), depth_unit_m=export.depth_unit_m,
        color=color_k, color_rate_hz=round(export.color_rate_hz or camera.rate_hz),
        color_T_depth=color_T_depth, accel_rate_hz=round(export.accel_rate_hz),
        gyro_rate_hz=round(export.gyro_rate_hz), serial=export.serial,
    )  # fmt: skip


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
