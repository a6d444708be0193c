"""RealSense SDK recordings written by librealsense itself: a ``software_device`` with a depth,
a colour and a motion sensor, recorded by ``rs.recorder`` into the ``.db3`` file the current SDK
(2.5x) writes and plays (``rs.config.enable_device_from_file``). One writer for the simulator's
export and for the tests' recordings: what the SDK writes is what the reader is tested against.

The frames are given in time order on the camera clock (``t_s``, seconds); each becomes an SDK
frame with that timestamp (milliseconds, hardware-clock domain: the frame metadata's
``timestamp``). The recording's own time (the bag's receive time and ``header.stamp``) is the
wall clock while recording, so frames are fed in real time (``speed`` = 1) for a recording
that plays back at its rate, or as fast as they come (``speed`` None) when only its content
matters. The SDK's recorder writes no extrinsics for motion streams (observed with 2.59):
``camera_T_imu`` is not in the file (docs/adapters.md).

pyrealsense2 is the optional extra ``realsense``, imported when a recorder is made.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import RealsenseError
from graph_slam.live.sdk import rs_module
from graph_slam.session.records import CameraIntrinsics


@dataclass(frozen=True)
class SdkDevice:
    """What the recording says about the device and its streams."""

    depth: CameraIntrinsics
    depth_rate_hz: int
    depth_unit_m: float
    color: CameraIntrinsics | None = None
    color_rate_hz: int = 30
    #: depth → colour extrinsics (maps depth-frame points to the colour frame)
    color_T_depth: np.ndarray | None = None
    accel_rate_hz: int | None = None
    gyro_rate_hz: int | None = None
    product: str = "Intel RealSense D435I"
    serial: str = "000000000000"
    firmware: str = "5.16.0.1"
    #: Brown-Conrady coefficients of the depth / colour camera (k1 k2 p1 p2 k3)
    depth_coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    color_coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass
class _Streams:
    depth: Any
    color: Any = None
    accel: Any = None
    gyro: Any = None
    sensors: list = field(default_factory=list)


def _intrinsics(rs, k: CameraIntrinsics, coeffs: tuple[float, ...]):
    out = rs.intrinsics()
    out.width, out.height = int(k.width_px), int(k.height_px)
    out.fx, out.fy, out.ppx, out.ppy = k.fx_px, k.fy_px, k.cx_px, k.cy_px
    out.model = rs.distortion.brown_conrady
    out.coeffs = [float(c) for c in coeffs]
    return out


def _video(rs, sensor, kind, uid, k, rate, fmt, bpp, coeffs):
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid = kind, 0, uid
    vs.width, vs.height, vs.fps, vs.bpp, vs.fmt = k.width_px, k.height_px, int(rate), bpp, fmt
    vs.intrinsics = _intrinsics(rs, k, coeffs)
    return sensor.add_video_stream(vs)


def _motion(rs, sensor, kind, uid, rate):
    ms = rs.motion_stream()
    ms.type, ms.index, ms.uid, ms.fps, ms.fmt = kind, 0, uid, int(rate), rs.format.motion_xyz32f
    intr = rs.motion_device_intrinsic()
    intr.data = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
    intr.noise_variances = [0.0, 0.0, 0.0]
    intr.bias_variances = [0.0, 0.0, 0.0]
    ms.intrinsics = intr
    return sensor.add_motion_stream(ms)


def _extrinsics(rs, b_T_a: np.ndarray):
    """librealsense extrinsics from a to b: ``p_b = R p_a + t``, R stored column-major."""
    ext = rs.extrinsics()
    ext.rotation = [float(v) for v in np.asarray(b_T_a)[:3, :3].T.ravel()]
    ext.translation = [float(v) for v in np.asarray(b_T_a)[:3, 3]]
    return ext


class SdkRecorder:
    """Write an SDK recording through librealsense; use as a context manager and give the
    frames in time order (:meth:`depth`, :meth:`color`, :meth:`accel`, :meth:`gyro`)."""

    def __init__(self, path: str | Path, device: SdkDevice, *, speed: float | None = None):
        self.rs = rs = rs_module()
        self.path = Path(path)
        if self.path.suffix != ".db3":
            raise RealsenseError(f"{self.path}: the RealSense SDK records .db3 files")
        self.device = device
        self.speed = speed
        self.counts: dict[str, int] = {"depth": 0, "color": 0, "accel": 0, "gyro": 0}
        self._dev = rs.software_device()
        for key, value in (
            (rs.camera_info.name, device.product),
            (rs.camera_info.serial_number, device.serial),
            (rs.camera_info.firmware_version, device.firmware),
        ):
            self._dev.register_info(key, value)
        self._s = self._add_streams(device)
        self._recorder = None
        self._t0: tuple[float, float] | None = None
        self._last_t = -np.inf

    def _add_streams(self, d: SdkDevice) -> _Streams:
        rs, dev = self.rs, self._dev
        stereo = dev.add_sensor("Stereo Module")
        depth = _video(rs, stereo, rs.stream.depth, 0, d.depth, d.depth_rate_hz, rs.format.z16,
                       2, d.depth_coeffs)  # fmt: skip
        stereo.add_read_only_option(rs.option.depth_units, float(d.depth_unit_m))
        s = _Streams(depth, sensors=[(stereo, [depth])])
        if d.color is not None:
            rgb = dev.add_sensor("RGB Camera")
            s.color = _video(rs, rgb, rs.stream.color, 1, d.color, d.color_rate_hz,
                             rs.format.rgb8, 3, d.color_coeffs)  # fmt: skip
            c_T_d = np.eye(4) if d.color_T_depth is None else d.color_T_depth
            depth.register_extrinsics_to(s.color, _extrinsics(rs, c_T_d))
            s.sensors.append((rgb, [s.color]))
        if d.accel_rate_hz and d.gyro_rate_hz:
            motion = dev.add_sensor("Motion Module")
            s.accel = _motion(rs, motion, rs.stream.accel, 2, d.accel_rate_hz)
            s.gyro = _motion(rs, motion, rs.stream.gyro, 3, d.gyro_rate_hz)
            s.sensors.append((motion, [s.accel, s.gyro]))
        return s

    def __enter__(self) -> SdkRecorder:
        self._recorder = self.rs.recorder(str(self.path), self._dev)
        for sensor, profiles in self._s.sensors:
            sensor.open(profiles if len(profiles) > 1 else profiles[0])
        for sensor, _ in self._s.sensors:
            sensor.start(lambda frame: None)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the sensors and let the recorder finish the file."""
        if self._recorder is None:
            return
        for sensor, _ in self._s.sensors:
            sensor.stop()
        for sensor, _ in self._s.sensors:
            sensor.close()
        self._recorder = None  # the file is complete when the recorder is released

    # ------------------------------------------------------------------ frames
    def _at(self, t_s: float, what: str) -> float:
        """Wait until ``t_s`` is due (with ``speed``) and return its timestamp in ms."""
        if t_s < self._last_t:
            raise RealsenseError(f"{self.path}: {what} at {t_s:.6f} s is out of time order")
        self._last_t = t_s
        if self.speed is not None:
            now = time.perf_counter()
            if self._t0 is None:
                self._t0 = (now, t_s)
            wait = self._t0[0] + (t_s - self._t0[1]) / self.speed - now
            if wait > 0:
                time.sleep(wait)
        return t_s * 1e3

    def _video_frame(self, profile, t_s: float, pixels: np.ndarray, bpp: int, kind: str):
        rs = self.rs
        frame = rs.software_video_frame()
        frame.pixels = np.ascontiguousarray(pixels)
        frame.stride = int(pixels.shape[1]) * bpp
        frame.bpp = bpp
        frame.timestamp = self._at(t_s, kind)
        frame.domain = rs.timestamp_domain.hardware_clock
        frame.frame_number = self.counts[kind]
        frame.profile = profile.as_video_stream_profile()
        return frame

    def depth(self, t_s: float, raw: np.ndarray) -> None:
        """A 16-bit depth image (value × depth unit = metres; 0: no reading)."""
        frame = self._video_frame(self._s.depth, t_s, raw.astype(np.uint16), 2, "depth")
        frame.depth_units = float(self.device.depth_unit_m)
        self._s.sensors[0][0].on_video_frame(frame)
        self.counts["depth"] += 1

    def color(self, t_s: float, rgb: np.ndarray) -> None:
        """An RGB8 colour image of the colour camera's size."""
        if self._s.color is None:
            raise RealsenseError(f"{self.path}: the device was made without a colour stream")
        frame = self._video_frame(self._s.color, t_s, rgb.astype(np.uint8), 3, "color")
        self._s.sensors[1][0].on_video_frame(frame)
        self.counts["color"] += 1

    def _motion_frame(self, profile, t_s: float, xyz: np.ndarray, kind: str) -> None:
        rs = self.rs
        if profile is None:
            raise RealsenseError(f"{self.path}: the device was made without motion streams")
        frame = rs.software_motion_frame()
        vec = rs.vector()
        vec.x, vec.y, vec.z = (float(v) for v in xyz)
        frame.data = vec
        frame.timestamp = self._at(t_s, kind)
        frame.domain = rs.timestamp_domain.hardware_clock
        frame.frame_number = self.counts[kind]
        frame.profile = profile.as_motion_stream_profile()
        self._s.sensors[-1][0].on_motion_frame(frame)
        self.counts[kind] += 1

    def accel(self, t_s: float, accel_m_s2: np.ndarray) -> None:
        self._motion_frame(self._s.accel, t_s, accel_m_s2, "accel")

    def gyro(self, t_s: float, gyro_rad_s: np.ndarray) -> None:
        self._motion_frame(self._s.gyro, t_s, gyro_rad_s, "gyro")
