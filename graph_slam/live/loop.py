"""Running the pipeline live: a camera source and the prosthesis's streams into the causal
real-time pipeline, until Ctrl-C, the end of a playback or a camera that stops sending.

The rules are the causal replay's (graph_slam.pipelines.replay): the estimator is one
worker; when it is free it takes **the newest frame that has arrived and skips the older
waiting ones** (counted); before a frame it gets the IMU samples up to and including the
first one at or after the frame's time (it waits for that one at most ``imu_wait_s``), the
prosthesis samples known by then and the foot strikes stamped at or before the frame.
Latency is measured from the frame's arrival in this process (librealsense's callback) to
its pose.

While it runs: a one-line status every ``status_interval_s`` (rate, skipped frames, latency,
samples), and — when a viewer is given — poses and the live elevation grid to rerun. On stop:
the frames processed (with the IMU, joints and events) are written as a session, and the
outputs of ``graph-slam run`` for it from the live results (:func:`graph_slam.report.run`
with ``precomputed``): complete up to the last frame processed, each folder written whole.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.live.camera import EndItem, FrameItem, ImuItem, RealsenseSource
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.session.records import GaitEvents, ImuSeries, JointSeries, RgbdFrame


@dataclass
class LiveResult:
    """What a live run did: the pipeline's results, timing, counts, why it stopped."""

    results: object
    latency_s: np.ndarray
    n_arrived: int
    skipped: int
    stop_reason: str
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    session: Path | None = None
    outputs: Path | None = None

    @property
    def n_processed(self) -> int:
        return int(self.latency_s.size)


@dataclass
class _Recorded:
    """The streams as given to the pipeline (written as the live session on stop)."""

    frames: list[RgbdFrame] = field(default_factory=list)
    imu: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    joints: list[tuple[float, float, float]] = field(default_factory=list)
    events: list[tuple[float, str]] = field(default_factory=list)


def leg_model(mount_pitch_deg: float):
    from kinematics.leg_model import LegModel, LegParams

    return LegModel(LegParams(mount_pitch_down_rad=math.radians(mount_pitch_deg)))


def warm_up(pipe, setup, n: int = 4) -> None:
    """A throw-away pipeline over a few made-up frames (a textured floor 1 m ahead, moving
    1 cm per frame) and IMU samples, so that the first real frame is not the one that loads
    and compiles everything."""
    k = setup.intrinsics
    v = np.mgrid[0 : k.height_px, 0 : k.width_px][0]
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 255, (k.height_px, k.width_px, 3), dtype=np.uint8)
    for i in range(n):
        t = 0.011 * i
        t_imu = t - 0.01 + np.arange(5) * 0.0025
        pipe.add_imu(t_imu, np.zeros((5, 3)), np.tile([0.0, -9.81, 0.0], (5, 1)))
        if i == 1:
            pipe.foot_strike(t - 0.005)
        depth = (1.0 + 0.2 * v / k.height_px + 0.01 * i).astype(np.float32)
        color = np.roll(texture, i, axis=1) if setup.color_model is not None else None
        pipe.add_frame(RgbdFrame(t, depth, color, i), True)
    pipe.finish()


class LiveRunner:
    """One live run (see the module docstring); :meth:`run` returns a :class:`LiveResult`."""

    def __init__(
        self,
        source: RealsenseSource,
        prosthesis,
        config: PipelineConfig,
        *,
        mount_pitch_deg: float,
        status: Callable[[str], None] | None = None,
        status_interval_s: float = 1.0,
        viewer=None,
        imu_wait_s: float = 0.02,
        keep_frames: bool = True,
        pipeline_factory: Callable | None = None,
        session_path: Path | None = None,
    ) -> None:
        self.source, self.prosthesis, self.config = source, prosthesis, config
        self.mount_pitch_deg = mount_pitch_deg
        self.status, self.status_interval_s = status, status_interval_s
        self.viewer, self.imu_wait_s, self.keep_frames = viewer, imu_wait_s, keep_frames
        self.pipeline_factory = pipeline_factory
        self.session_path = None if session_path is None else Path(session_path)
        self._writer = None
        self._writer_thread: threading.Thread | None = None
        self._to_write: queue.Queue = queue.Queue()
        self.rec = _Recorded()
        self._imu_t: list[float] = []
        self._imu_pending: list[ImuItem] = []
        self._latency: list[float] = []
        self.compute_s: list[float] = []
        self._arrived = self._skipped = 0
        self._loaded = False

    def run(self, max_s: float | None = None) -> LiveResult:
        from graph_slam.pipelines.replay import frozen_heap
        from graph_slam.pipelines.runner import make_pipeline

        setup = self.source.start()
        self.source.pause()
        self.setup = setup
        camera_T_imu = setup.camera_T_imu if setup.camera_T_imu is not None else np.eye(4)

        factory = self.pipeline_factory or make_pipeline

        def make():
            return factory(self.config, setup.intrinsics, camera_T_imu,
                           leg_model(self.mount_pitch_deg),
                           setup.color_model is not None)  # fmt: skip

        warm_up(make(), setup)  # imports, compiled kernels, thread pools: not per-frame work
        self.pipe = make()
        if self.session_path is not None:
            self._start_writer(self.session_path)
        self.source.discard()
        self.source.resume()
        reason = "stopped"
        t_start = time.perf_counter()
        with frozen_heap():
            try:
                reason = self._loop(t_start, max_s)
            except KeyboardInterrupt:
                reason = "interrupted (Ctrl-C)"
            finally:
                self.source.stop()
                self.prosthesis.close()
        results = self.pipe.finish()
        results.config["mount_pitch"] = {"source": "config", "pitch_deg": self.mount_pitch_deg}
        counts = {"camera": dict(self.source.counts), "imu": dict(self.source.merger.counts),
                  "prosthesis": dict(self.prosthesis.counts)}  # fmt: skip
        return LiveResult(results, np.asarray(self._latency), self._arrived, self._skipped,
                          reason, counts)  # fmt: skip

    # ------------------------------------------------------------------ the loop
    def _loop(self, t_start: float, max_s: float | None) -> str:
        newest: FrameItem | None = None
        next_status = t_start + self.status_interval_s
        ended: str | None = None
        while True:
            item = self.source.get(0.002 if newest is None else 0.0005)
            while item is not None:
                if isinstance(item, FrameItem):
                    self._arrived += 1
                    if newest is not None:
                        self._skipped += 1
                    newest = item
                elif isinstance(item, ImuItem):
                    self._imu_pending.append(item)
                    self._imu_t.append(float(item.t_s[-1]))
                elif isinstance(item, EndItem):
                    ended = item.reason
                item = self.source.items.get_nowait() if not self.source.items.empty() else None
            now = time.perf_counter()
            if newest is not None and (ended or self._covered(newest, now)):
                self._process(newest)
                newest = None
            if self.status is not None and now >= next_status:
                self.status(self.status_line(now - t_start))
                next_status += self.status_interval_s
            if ended and newest is None:
                return ended
            if max_s is not None and now - t_start > max_s:
                return f"time limit {max_s:g} s"

    def _covered(self, item: FrameItem, now: float) -> bool:
        """The IMU has a sample at or after the frame (or waited long enough for it)."""
        if not self.setup.has_imu:
            return True
        last = self._imu_t[-1] if self._imu_t else -math.inf
        return last >= item.t_s or now - item.arrival_s > self.imu_wait_s

    def _feed_imu(self, t_s: float) -> None:
        """IMU chunks up to and including the first sample at or after ``t_s``."""
        while self._imu_pending:
            chunk = self._imu_pending[0]
            k = int(np.searchsorted(chunk.t_s, t_s, side="left")) + 1
            take = slice(0, min(k, chunk.t_s.size))
            self.pipe.add_imu(chunk.t_s[take], chunk.gyro_rad_s[take], chunk.accel_m_s2[take])
            self.rec.imu.append((chunk.t_s[take], chunk.gyro_rad_s[take], chunk.accel_m_s2[take]))
            if k < chunk.t_s.size:
                self._imu_pending[0] = ImuItem(chunk.t_s[k:], chunk.gyro_rad_s[k:],
                                               chunk.accel_m_s2[k:], chunk.arrival_s)  # fmt: skip
                return
            self._imu_pending.pop(0)
            if chunk.t_s[-1] >= t_s:
                return

    def _process(self, item: FrameItem) -> None:
        frame = item.rgbd()  # colour registered to depth now: only for the frames taken
        self._feed_imu(frame.t_s)
        known = self.prosthesis.until(frame.t_s)
        if known.joints_t_s:
            self.pipe.add_joints(np.asarray(known.joints_t_s), np.asarray(known.knee_rad),
                                 np.asarray(known.ankle_rad))  # fmt: skip
            self.rec.joints += list(zip(known.joints_t_s, known.knee_rad, known.ankle_rad,
                                        strict=True))  # fmt: skip
        for t_event, kind in known.events:
            self.rec.events.append((t_event, kind))
            if kind == "foot_strike" and t_event <= frame.t_s:
                self.pipe.foot_strike(t_event)
            self._loaded = kind == "foot_strike"
        index = len(self._latency)
        frame = RgbdFrame(frame.t_s, frame.depth_m, frame.color_rgb, index)
        w0 = time.perf_counter()
        out = self.pipe.add_frame(frame, self._loaded)
        now = time.perf_counter()
        self._latency.append(now - item.arrival_s)
        self.compute_s.append(now - w0)
        if self._writer is not None:
            self._to_write.put(frame)  # written by the writer thread as the run goes on
        elif self.keep_frames:
            self.rec.frames.append(frame)
        if self.viewer is not None:
            self.viewer.frame(out)

    def status_line(self, elapsed_s: float) -> str:
        lat = np.asarray(self._latency[-200:]) * 1e3
        p95 = f"{np.percentile(lat, 95):5.1f}" if lat.size else "    –"
        n = len(self._latency)
        rate = n / elapsed_s if elapsed_s > 0 else 0.0
        p = self.prosthesis.counts
        extra = ", ".join(f"{k} {v}" for k, v in p.items() if v and k != "received")
        return (
            f"{elapsed_s:6.1f} s  {rate:5.1f} frames/s  processed {n}  skipped {self._skipped}  "
            f"latency p95 {p95} ms  imu {self.source.merger.counts['used']}  {extra}"
        )

    # ------------------------------------------------------------------ outputs
    def _session_writer(self, path: Path, name: str = "live"):
        from graph_slam.session import SessionWriter
        from graph_slam.session.manifest import Provenance
        from graph_slam.session.records import Calibration

        setup = self.setup
        calibration = Calibration(
            camera_T_imu=setup.camera_T_imu if setup.camera_T_imu is not None else np.eye(4)
        )
        provenance = Provenance(generator="graph_slam.live", source=str(
            self.source.playback or setup.device.get("serial", "camera")))  # fmt: skip
        return SessionWriter(path, name=name, intrinsics=setup.intrinsics,
                             depth_unit_m=setup.depth_unit_m, camera_profile="realsense-live",
                             calibration=calibration, provenance=provenance)  # fmt: skip

    def _start_writer(self, path: Path) -> None:
        """The session's frames are written by a thread while the run goes on (memory stays
        bounded); the manifest is written last, on stop."""
        self._writer = self._session_writer(path)

        def drain() -> None:
            while (frame := self._to_write.get()) is not None:
                self._writer.add_frame(frame)

        self._writer_thread = threading.Thread(target=drain, name="live-writer", daemon=True)
        self._writer_thread.start()

    def write_session(self, path: Path | None = None) -> Path:
        """The frames processed, with the streams given to the pipeline, as a session (at
        ``session_path`` when it was written during the run)."""
        if self._writer is not None:
            self._to_write.put(None)
            self._writer_thread.join()
            writer = self._writer
        else:
            writer = self._session_writer(path)
            for frame in self.rec.frames:
                writer.add_frame(frame)
        with writer:
            if self.rec.imu:
                t = np.concatenate([c[0] for c in self.rec.imu])
                writer.write_imu(ImuSeries(t, np.concatenate([c[1] for c in self.rec.imu]),
                                           np.concatenate([c[2] for c in self.rec.imu])))  # fmt: skip
            if self.rec.joints:
                j = np.asarray(self.rec.joints)
                writer.write_joints(JointSeries(j[:, 0], j[:, 1], j[:, 2]))
            if self.rec.events:
                ev = sorted(self.rec.events)
                writer.write_events(GaitEvents(np.array([e[0] for e in ev]),
                                               tuple(e[1] for e in ev), ("live",) * len(ev)))  # fmt: skip
        return writer.path


def write_outputs(runner: LiveRunner, result: LiveResult, out: Path, *, overwrite: bool = False):
    """``out/session`` (the frames processed) and ``out/run`` (``graph-slam run``'s outputs
    from the live results)."""
    from graph_slam.report import RunConfig, run

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    session = runner.write_session(out / "session")  # (written during the run if asked)
    variant = runner.config.variant
    cfg = RunConfig(variants=[variant], pipeline=runner.config.model_copy(
        update={"mount_pitch_deg": runner.mount_pitch_deg, "event_source": None}), rrd=False)  # fmt: skip
    from graph_slam.variants import Variant

    report = run([session], out / "run", cfg, overwrite=overwrite,
                 precomputed={"live": {Variant(variant): result.results}})  # fmt: skip
    result.session, result.outputs = session, report.out
    return report
