"""A RealSense camera as a live source: a device by serial number, or an SDK recording played
back in real time through the same ``rs.pipeline`` a camera uses.

librealsense calls back on its own threads; each callback turns what arrived into items on
a queue, in arrival order, each stamped with its arrival time (``time.perf_counter``):

- a depth frame becomes an :class:`~graph_slam.session.records.RgbdFrame` (metres), with the
  colour image of its frameset registered to it (as ``graph-slam convert`` does) when that
  image is within ``max_color_dt_s`` and not given to an earlier frame; else depth-only;
- accel and gyro samples are merged online (:class:`ImuMerger`): each gyro sample gets the
  accel interpolated at its time once the accel sample after it has arrived (causal; samples
  outside the accel's span or across an accel gap are dropped, counted). The IMU items go on
  the same queue as the frames, or (:meth:`RealsenseSource.route_imu`) straight to the
  estimator's inbox, past the thread that decodes the frames.

Stamps are the frames' own times (the device clock, ms → s), as in a converted recording.
The source ends when the playback ends, when ``stop`` is called, or when nothing arrived for
``timeout_s`` (a camera unplugged).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import RealsenseError
from graph_slam.live.sdk import rs_module
from graph_slam.session.adapters.align import CameraModel
from graph_slam.session.records import CameraIntrinsics, RgbdFrame


@dataclass(frozen=True)
class CameraSetup:
    """What the source found: the depth camera, colour, units, extrinsics, the device."""

    intrinsics: CameraIntrinsics
    depth_model: CameraModel
    depth_unit_m: float
    color_model: CameraModel | None
    color_T_depth: np.ndarray | None
    camera_T_imu: np.ndarray | None
    has_imu: bool
    device: dict[str, str]
    color_bgr: bool = False


@dataclass(frozen=True)
class FrameItem:
    """A depth frame as librealsense gave it (kept, not decoded); :meth:`rgbd` decodes it
    and registers its colour image (when paired) to it, off librealsense's callback (the live
    loop does it on its preparing thread, as each frame arrives)."""

    t_s: float
    index: int
    arrival_s: float
    depth: Any  # rs.depth_frame (kept)
    color: Any = None  # rs.video_frame (kept) or None: depth-only
    setup: CameraSetup | None = None
    registration: Any = None  # align_compiled.Registration for the camera pair

    def rgbd(self) -> RgbdFrame:
        s = self.setup
        depth_m = np.asanyarray(self.depth.get_data()).astype(np.float32)
        depth_m *= np.float32(s.depth_unit_m)
        color = None
        if self.color is not None:
            rgb = np.asanyarray(self.color.get_data())
            if s.color_bgr:
                rgb = rgb[:, :, ::-1]
            color = self.registration(depth_m, rgb).color_rgb  # compiled, the GIL released
        return RgbdFrame(t_s=self.t_s, depth_m=depth_m, color_rgb=color, index=self.index)


@dataclass(frozen=True)
class ImuItem:
    t_s: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    arrival_s: float


@dataclass(frozen=True)
class EndItem:
    reason: str
    arrival_s: float


@dataclass
class ImuMerger:
    """Online accel + gyro → IMU samples on the gyro's stamps (accel interpolated linearly).
    A gyro sample waits for the first accel sample at or after it; counts every sample, and
    the samples that never arrived (``gyro missing`` / ``accel missing``: a gap between two
    samples of a stream longer than 1.5 of its shortest interval so far counts the periods
    it skipped; librealsense drops motion frames when its callback is held up)."""

    max_gap_s: float = 0.05
    _accel: list[tuple[float, np.ndarray]] = field(default_factory=list)
    _gyro: list[tuple[float, np.ndarray]] = field(default_factory=list)
    _last_gyro_s: float = -np.inf
    _period_s: dict[str, float] = field(default_factory=lambda: {"gyro": np.inf, "accel": np.inf})
    counts: dict[str, int] = field(
        default_factory=lambda: {
            "gyro": 0, "accel": 0, "used": 0, "before accel": 0, "accel gap": 0,
            "out of order": 0, "gyro missing": 0, "accel missing": 0,
        }
    )  # fmt: skip

    def _missing(self, stream: str, dt_s: float) -> None:
        period = self._period_s[stream] = min(self._period_s[stream], dt_s)
        if dt_s > 1.5 * period:
            self.counts[f"{stream} missing"] += round(dt_s / period) - 1

    def accel(self, t_s: float, value: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
        self.counts["accel"] += 1
        if self._accel and t_s <= self._accel[-1][0]:
            self.counts["out of order"] += 1
            return []
        if self._accel:
            self._missing("accel", t_s - self._accel[-1][0])
        self._accel = [*self._accel[-1:], (t_s, value)]
        return self._release()

    def gyro(self, t_s: float, value: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
        self.counts["gyro"] += 1
        if t_s <= self._last_gyro_s:
            self.counts["out of order"] += 1
            return []
        if np.isfinite(self._last_gyro_s):
            self._missing("gyro", t_s - self._last_gyro_s)
        self._last_gyro_s = t_s
        self._gyro.append((t_s, value))
        return self._release()

    def _release(self) -> list[tuple[float, np.ndarray, np.ndarray]]:
        out = []
        while self._gyro and self._accel:
            t, g = self._gyro[0]
            if t > self._accel[-1][0]:
                break  # wait for the accel sample after it
            self._gyro.pop(0)
            if len(self._accel) < 2 or t < self._accel[0][0]:
                self.counts["before accel"] += 1
                continue
            (t0, a0), (t1, a1) = self._accel
            if t1 - t0 > self.max_gap_s:
                self.counts["accel gap"] += 1
                continue
            w = 0.0 if t1 == t0 else (t - t0) / (t1 - t0)
            out.append((t, g, (1 - w) * a0 + w * a1))
            self.counts["used"] += 1
        return out


def _model(rs, profile) -> CameraModel:
    i = profile.as_video_stream_profile().get_intrinsics()
    name = str(i.model).split(".")[-1]
    return CameraModel(i.width, i.height, i.fx, i.fy, i.ppx, i.ppy, name, tuple(i.coeffs))


def _pose(ext) -> np.ndarray:
    """librealsense extrinsics a → b (R column-major) → ``b_T_a``."""
    out = np.eye(4)
    out[:3, :3] = np.reshape(ext.rotation, (3, 3)).T
    out[:3, 3] = ext.translation
    return out


class RealsenseSource:
    """A camera (``serial``; None: the first one) or a recording played back (``playback``)
    in real time; :meth:`start`, then :meth:`get` items until an :class:`EndItem`."""

    def __init__(
        self,
        *,
        serial: str | None = None,
        playback: str | Path | None = None,
        real_time: bool = True,
        max_color_dt_s: float = 0.02,
        timeout_s: float = 2.0,
        camera_T_imu: np.ndarray | None = None,
    ) -> None:
        self.rs = rs_module()  # the extra first: before anything else is checked or done
        if serial is not None and playback is not None:
            raise RealsenseError("give a camera serial or a recording to play back, not both")
        if playback is not None and not Path(playback).is_file():
            raise RealsenseError(f"{playback}: no such recording")
        self.serial, self.playback = serial, None if playback is None else Path(playback)
        self.real_time = real_time
        self.max_color_dt_s = max_color_dt_s
        self.timeout_s = timeout_s
        self._camera_T_imu = camera_T_imu
        self.items: queue.Queue = queue.Queue()
        self._imu_items: queue.Queue = self.items  # where IMU items go (:meth:`route_imu`)
        self.merger = ImuMerger()
        self.counts: dict[str, int] = {"depth": 0, "color used": 0, "depth-only": 0}
        self._pipe = None
        self._lock = threading.Lock()
        self._last_arrival = time.perf_counter()
        self._used_color = -1
        self._last_depth_s = -np.inf
        self._ended = threading.Event()
        self._setup: CameraSetup | None = None

    # ------------------------------------------------------------------ start / stop
    def start(self) -> CameraSetup:
        """Start the camera or the playback (a playback paused at once: :meth:`resume`
        plays it) and read what it gives."""
        from graph_slam.session.adapters.align_compiled import Registration  # numba: first

        rs = self.rs
        cfg = rs.config()
        if self.playback is not None:
            cfg.enable_device_from_file(str(self.playback), repeat_playback=False)
        elif self.serial is not None:
            cfg.enable_device(self.serial)
        cfg.enable_all_streams()
        self._pipe = rs.pipeline()
        try:
            profile = self._pipe.start(cfg, self._on_frame)
        except RuntimeError as err:
            where = self.playback or f"camera {self.serial or '(first found)'}"
            raise RealsenseError(f"{where}: librealsense cannot start it ({err})") from None
        device = profile.get_device()
        if self.playback is not None:
            playback = device.as_playback()
            playback.pause()  # nothing of the recording is played before the run starts
            playback.set_real_time(self.real_time)
            playback.set_status_changed_callback(self._on_status)
        setup = self._read_setup(rs, profile, device)
        self._registration = None
        if setup.color_model is not None:
            self._registration = Registration(setup.depth_model, setup.color_model,
                                              setup.color_T_depth)  # fmt: skip
        self._setup = setup
        return setup

    def _read_setup(self, rs, profile, device) -> CameraSetup:
        streams = {s.stream_type(): s for s in profile.get_streams()}
        if rs.stream.depth not in streams:
            raise RealsenseError(f"{self.playback or 'camera'}: no depth stream")
        depth_p = streams[rs.stream.depth]
        depth_model = _model(rs, depth_p)
        color_p = streams.get(rs.stream.color)
        color_model = color_T_depth = None
        if color_p is not None and color_p.format() in (rs.format.rgb8, rs.format.bgr8):
            color_model = _model(rs, color_p)
            color_T_depth = _pose(depth_p.get_extrinsics_to(color_p))
        camera_T_imu = self._camera_T_imu
        has_imu = rs.stream.accel in streams and rs.stream.gyro in streams
        if camera_T_imu is None and has_imu:
            try:  # depth → gyro extrinsics: imu_T_depth; a recording made by 2.5x has none
                camera_T_imu = np.linalg.inv(
                    _pose(depth_p.get_extrinsics_to(streams[rs.stream.gyro]))
                )
            except RuntimeError:
                camera_T_imu = None
        info = {}
        for key, name in ((rs.camera_info.name, "product"), (rs.camera_info.serial_number,
                          "serial"), (rs.camera_info.firmware_version, "firmware")):  # fmt: skip
            if device.supports(key):
                info[name] = device.get_info(key)
        unit = device.first_depth_sensor().get_depth_scale()
        return CameraSetup(
            intrinsics=CameraIntrinsics(
                depth_model.width_px,
                depth_model.height_px,
                depth_model.fx_px,
                depth_model.fy_px,
                depth_model.cx_px,
                depth_model.cy_px,
            ),
            depth_model=depth_model,
            depth_unit_m=float(f"{unit:.7g}"),
            color_model=color_model,
            color_T_depth=color_T_depth,
            camera_T_imu=camera_T_imu,
            has_imu=has_imu,
            device=info,
            color_bgr=color_p is not None and color_p.format() == rs.format.bgr8,
        )

    def pause(self) -> None:
        """A playback waits (while the estimator warms up); a camera goes on (its frames
        are dropped by :meth:`discard`)."""
        if self.playback is not None and self._pipe is not None:
            self._pipe.get_active_profile().get_device().as_playback().pause()

    def resume(self) -> None:
        self._last_arrival = time.perf_counter()  # the pause is not a camera gone quiet
        if self.playback is not None and self._pipe is not None:
            self._pipe.get_active_profile().get_device().as_playback().resume()

    def route_imu(self, to: queue.Queue) -> None:
        """Put the IMU items on ``to`` from now on (the estimator's own inbox), not behind
        the depth frames on :attr:`items`: a frame's IMU sample is not held up while the
        frame before it is decoded."""
        self._imu_items = to

    def discard(self) -> int:
        """Drop what arrived so far (before the run started); how many items."""
        n = 0
        while not self.items.empty():
            item = self.items.get_nowait()
            if isinstance(item, EndItem):
                self.items.put(item)
                break
            n += 1
        return n

    def stop(self) -> None:
        if self._pipe is not None:
            pipe, self._pipe = self._pipe, None
            with contextlib.suppress(RuntimeError):
                pipe.stop()
        self._end("stopped")

    def _end(self, reason: str) -> None:
        if not self._ended.is_set():
            self._ended.set()
            self.items.put(EndItem(reason, time.perf_counter()))

    # ------------------------------------------------------------------ items
    def get(self, timeout_s: float) -> Any | None:
        """The next item, or None after ``timeout_s``; an :class:`EndItem` when the playback
        ended or nothing arrived for ``self.timeout_s`` (a camera unplugged)."""
        try:
            return self.items.get(timeout=timeout_s)
        except queue.Empty:
            pass
        idle = time.perf_counter() - self._last_arrival
        if self._pipe is not None and idle > self.timeout_s:
            self._end(
                "end of playback" if self.playback is not None else f"no frame for {idle:.1f} s"
            )
        return None

    def _on_status(self, status) -> None:
        if status == self.rs.playback_status.stopped:
            self._end("end of playback")

    def _on_frame(self, frame) -> None:
        """librealsense's callback (its threads): items onto the queue."""
        arrival = time.perf_counter()
        self._last_arrival = arrival
        rs = self.rs
        try:
            if frame.is_frameset():
                self._frameset(frame.as_frameset(), arrival)
            elif frame.is_motion_frame():
                self._motion(rs, frame, arrival)
        except Exception as err:
            self.items.put(EndItem(f"error in the camera callback: {err}", arrival))

    def _motion(self, rs, frame, arrival: float) -> None:
        d = frame.as_motion_frame().get_motion_data()
        value = np.array([d.x, d.y, d.z], dtype=np.float64)
        t_s = frame.get_timestamp() * 1e-3
        with self._lock:  # (put under the lock: the samples stay in time order)
            if frame.profile.stream_type() == rs.stream.accel:
                out = self.merger.accel(t_s, value)
            else:
                out = self.merger.gyro(t_s, value)
            if out:
                t = np.array([o[0] for o in out])
                self._imu_items.put(ImuItem(t, np.array([o[1] for o in out]),
                                            np.array([o[2] for o in out]), arrival))  # fmt: skip

    def _frameset(self, fs, arrival: float) -> None:
        depth = fs.get_depth_frame()
        if not depth:
            return
        if self._setup is None:  # before start() has read the camera: not yet running
            self.counts["before start"] = self.counts.get("before start", 0) + 1
            return
        t_s = depth.get_timestamp() * 1e-3
        if t_s <= self._last_depth_s:  # the frame syncer gives a depth frame again
            return
        self._last_depth_s = t_s
        setup = self._setup
        color = None
        c = fs.get_color_frame() if setup.color_model is not None else None
        if c and abs(c.get_timestamp() * 1e-3 - t_s) <= self.max_color_dt_s:
            number = c.get_frame_number()
            if number != self._used_color:
                self._used_color = number
                c.keep()  # held past the callback (released when the item is dropped)
                color = c
        depth.keep()
        self.counts["depth"] += 1
        self.counts["color used" if color is not None else "depth-only"] += 1
        index = depth.get_frame_number()
        self.items.put(FrameItem(t_s, index, arrival, depth, color, setup, self._registration))
