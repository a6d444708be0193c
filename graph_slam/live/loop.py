"""Running the pipeline live: a camera source and the prosthesis's streams into the causal
real-time pipeline, until Ctrl-C, the end of a playback or a camera that stops sending.

Threads (docs/recording.md, "Live"):

- librealsense's callbacks put each depth frame (kept, not decoded) on the source's queue and
  the merged IMU samples straight on the estimator's inbox, stamped with their arrival
  (``time.perf_counter``);
- the **preparing** thread (:mod:`graph_slam.live.prep`) decodes each frame and registers its
  colour image to it (compiled, the GIL released) as it arrives, and does the frame-only part
  of the pipeline's preparation (its ``prepare_ahead``: organised points and normals);
- the **estimator** thread (the caller's) books what arrived in a :class:`~graph_slam.live.
  handoff.FrameQueue` and takes a frame by its rule: a frame is ready when the IMU has a sample
  at or after its time; the oldest ready frame is taken, unless newer ones became ready while
  the estimator was busy (then the newest, the older skipped as ``busy``); a frame whose IMU
  has not come ``imu_wait_s`` after its arrival is skipped as ``imu late``. Before a frame it
  gets the IMU samples up to and including the first one at or after the frame's time, the
  prosthesis samples known by then and the foot strikes stamped at or before the frame;
- the **session writer**, a process of its own at the lowest CPU priority
  (:mod:`graph_slam.live.session_worker`), writes the processed frames to the session as the
  run goes on; a thread here hands their arrays to its pipe.

Latency is measured from the frame's arrival in this process (librealsense's callback) to its
pose. A one-line status every ``status_interval_s`` (rate, skipped frames by reason, latency,
samples), and — when a viewer is given — poses and the live elevation grid to rerun. On stop:
the frames processed (with the IMU, joints and events) are written as a session, and the
outputs of ``graph-slam run`` for it from the live results (:func:`graph_slam.report.run`
with ``precomputed``), complete up to the last frame processed, each folder written whole,
and ``live.json`` (the counts, skips by reason, latency and where the time went).

The streams recorded and the outputs written on stop: :mod:`graph_slam.live.outputs` (its names
importable from here too).
"""

from __future__ import annotations

import contextlib
import math
import queue
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from graph_slam.live.camera import EndItem, ImuItem, RealsenseSource
from graph_slam.live.handoff import FrameQueue
from graph_slam.live.outputs import _Recorded, write_outputs  # noqa: F401 (re-exported)
from graph_slam.live.prep import PreparedFrame, Preparer, UnreadableFrame
from graph_slam.live.result import LiveResult, Timing
from graph_slam.live.warmup import leg_model, warm_up
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.session.records import GaitEvents, ImuSeries, JointSeries


@contextlib.contextmanager
def _gil_switch(interval_s: float | None):
    """Python's thread switch interval for the run (None: left as it is). The estimator's
    thread holds the GIL in Python code; librealsense's callbacks (the IMU samples a waiting
    frame needs) get it after at most this long (Python's default, 5 ms, delayed them
    by that much)."""
    if interval_s is None:
        yield
        return
    before = sys.getswitchinterval()
    sys.setswitchinterval(interval_s)
    try:
        yield
    finally:
        sys.setswitchinterval(before)


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
        gil_switch_s: float | None = 0.0005,
        writer_nice: int = 19,
    ) -> None:
        self.source, self.prosthesis, self.config = source, prosthesis, config
        self.mount_pitch_deg = mount_pitch_deg
        self.status, self.status_interval_s = status, status_interval_s
        self.viewer, self.imu_wait_s, self.keep_frames = viewer, imu_wait_s, keep_frames
        self.pipeline_factory = pipeline_factory
        self.gil_switch_s, self.writer_nice = gil_switch_s, writer_nice
        self.session_path = None if session_path is None else Path(session_path)
        self._writer = None  # SessionProcess, with session_path
        self.rec = _Recorded()
        self._imu_pending: list[ImuItem] = []
        self._latency: list[float] = []
        self.compute_s: list[float] = []
        self.timing = Timing()
        self.frames: FrameQueue | None = None
        self._loaded = False
        self._events_pending: list[tuple[float, str]] = []  # known, stamped after the frame
        self.n_strikes = 0  # the foot strikes given to the pipeline
        self._t0 = self.warm_up_s = 0.0

    def run(self, max_s: float | None = None) -> LiveResult:
        try:
            return self._run(max_s)
        except BaseException:  # the session's writer stops too, without a manifest
            if self._writer is not None:
                self._writer.abort()
                self._writer = None
            raise

    def _run(self, max_s: float | None) -> LiveResult:
        from graph_slam.pipelines.replay import frozen_heap
        from graph_slam.pipelines.runner import make_pipeline

        setup = self.source.start()
        self.source.pause()
        self.setup = setup
        camera_T_imu = setup.camera_T_imu if setup.camera_T_imu is not None else np.eye(4)

        factory = self.pipeline_factory or make_pipeline
        if self.session_path is not None:  # (its imports run beside the warm-up)
            self._writer = self._session_process(self.session_path)

        def make():
            return factory(self.config, setup.intrinsics, camera_T_imu,
                           leg_model(self.mount_pitch_deg),
                           setup.color_model is not None)  # fmt: skip

        w0 = time.perf_counter()
        warm_up(make(), setup)  # imports, compiled kernels, thread pools: not per-frame work
        self.pipe = make()
        self.warm_up_s = time.perf_counter() - w0
        self.frames = FrameQueue(self.imu_wait_s, needs_imu=setup.has_imu)
        if self._writer is not None:
            self._writer.wait_ready()
        prep = Preparer(self.source, ahead=getattr(self.pipe, "prepare_ahead", None))
        self.source.route_imu(prep.items)  # the IMU straight to the estimator, not behind frames
        self.source.discard()
        prep.discard()
        prep.start()
        self.source.resume()
        reason = "stopped"
        t_start = self._t0 = time.perf_counter()
        with frozen_heap(), _gil_switch(self.gil_switch_s):
            try:
                reason = self._loop(prep.items, t_start, max_s)
            except KeyboardInterrupt:
                reason = "interrupted (Ctrl-C)"
            finally:
                self.source.stop()
                prep.stop()
                self.timing.ahead_cpu_s.extend(prep.ahead_cpu_s)
                self.prosthesis.close()
        results = self.pipe.finish()
        results.counts["foot_strikes"] = self.n_strikes  # as graph-slam run counts them
        results.config["mount_pitch"] = {"source": "config", "pitch_deg": self.mount_pitch_deg}
        counts = {"camera": dict(self.source.counts), "imu": dict(self.source.merger.counts),
                  "prosthesis": dict(self.prosthesis.counts),
                  "skipped": dict(self.frames.skips)}  # fmt: skip
        return LiveResult(results, np.asarray(self._latency), self.frames.n_arrived,
                          self.frames.n_skipped, reason, counts, timing=self.timing,
                          warm_up_s=self.warm_up_s)  # fmt: skip

    # ------------------------------------------------------------------ the loop
    def _loop(self, inbox: queue.Queue, t_start: float, max_s: float | None) -> str:
        """Book what arrived, take a ready frame (the rule: graph_slam.live.handoff), process
        it; wait on the inbox in between (never longer than the next IMU deadline)."""
        frames, timing = self.frames, self.timing
        next_status = t_start + self.status_interval_s
        ended: str | None = None
        busy = False  # a frame was processed since the last update
        while True:
            now = time.perf_counter()
            if not busy and ended is None:
                deadline = frames.deadline_s()
                wait = min(next_status, deadline if deadline is not None else math.inf) - now
                item = self._get(inbox, min(max(wait, 0.0), 0.05))
            else:
                item = self._get(inbox, 0.0)
            c0 = time.thread_time()
            while item is not None:
                ended = self._book(item) or ended
                item = self._get(inbox, 0.0)
            now = time.perf_counter()
            frames.update(now, busy=busy)
            if ended is not None:
                frames.end()
            taken = frames.take()
            timing.book_cpu_s += time.thread_time() - c0
            busy = taken is not None
            if busy:
                self._process(taken.item, taken.ready_s)
                now = time.perf_counter()
            if self.status is not None and now >= next_status:
                self.status(self.status_line(now - t_start))
                next_status += self.status_interval_s * max(1, math.ceil((now - next_status)
                                                                          / self.status_interval_s))  # fmt: skip
            if ended is not None and not busy and not frames.waiting:
                return ended
            if max_s is not None and now - t_start > max_s:
                return f"time limit {max_s:g} s"

    @staticmethod
    def _get(inbox: queue.Queue, timeout_s: float):
        try:
            return inbox.get(timeout=timeout_s) if timeout_s > 0 else inbox.get_nowait()
        except queue.Empty:
            return None

    def _book(self, item) -> str | None:
        """One item from the preparing thread into the queues; the reason when it ends."""
        if isinstance(item, PreparedFrame):
            self.frames.frame(item, item.t_s, item.arrival_s)
            self.timing.prepare_cpu_s.append(item.cpu_s)
            self.timing.prepare_color.append(item.with_color)
        elif isinstance(item, UnreadableFrame):
            self.frames.unreadable(item.t_s)
        elif isinstance(item, ImuItem):
            self._imu_pending.append(item)
            self.frames.imu(float(item.t_s[-1]))
        elif isinstance(item, EndItem):
            return item.reason
        return None

    def _feed_imu(self, t_s: float) -> None:
        """The IMU samples up to and including the first one at or after ``t_s``, given in
        one call (the samples arrive one or two at a time: one call a frame, not one a chunk;
        the estimator appends them alike)."""
        taken: list[ImuItem] = []
        while self._imu_pending:
            chunk = self._imu_pending[0]
            k = int(np.searchsorted(chunk.t_s, t_s, side="left")) + 1
            if k < chunk.t_s.size:
                taken.append(ImuItem(chunk.t_s[:k], chunk.gyro_rad_s[:k], chunk.accel_m_s2[:k],
                                     chunk.arrival_s))  # fmt: skip
                self._imu_pending[0] = ImuItem(chunk.t_s[k:], chunk.gyro_rad_s[k:],
                                               chunk.accel_m_s2[k:], chunk.arrival_s)  # fmt: skip
                break
            taken.append(self._imu_pending.pop(0))
            if chunk.t_s[-1] >= t_s:
                break
        if not taken:
            return
        if len(taken) == 1:
            t, gyro, accel = taken[0].t_s, taken[0].gyro_rad_s, taken[0].accel_m_s2
        else:
            t = np.concatenate([c.t_s for c in taken])
            gyro = np.concatenate([c.gyro_rad_s for c in taken])
            accel = np.concatenate([c.accel_m_s2 for c in taken])
        self.pipe.add_imu(t, gyro, accel)
        self.rec.imu.append((t, gyro, accel))

    def _process(self, item: PreparedFrame, ready_s: float) -> None:
        c0 = time.thread_time()
        w0 = time.perf_counter()
        frame = item.frame
        self._feed_imu(frame.t_s)
        known = self.prosthesis.until(frame.t_s)
        if known.joints_t_s:
            self.pipe.add_joints(np.asarray(known.joints_t_s), np.asarray(known.knee_rad),
                                 np.asarray(known.ankle_rad))  # fmt: skip
            self.rec.joints += list(zip(known.joints_t_s, known.knee_rad, known.ankle_rad,
                                        strict=True))  # fmt: skip
        self.rec.events += known.events
        self._events_pending = sorted(self._events_pending + known.events)
        while self._events_pending and self._events_pending[0][0] <= frame.t_s:
            t_event, kind = self._events_pending.pop(0)  # stamped at or before the frame
            if kind == "foot_strike":
                self.pipe.foot_strike(t_event)
                self.n_strikes += 1
            self._loaded = kind == "foot_strike"
        index = len(self._latency)
        frame = frame.renumbered(index)  # (checked once, when it was decoded)
        c1 = time.thread_time()
        out = self.pipe.add_frame(frame, self._loaded)
        c2 = time.thread_time()
        now = time.perf_counter()
        self._latency.append(now - item.arrival_s)
        self.compute_s.append(now - w0)
        if self._writer is not None:
            self._writer.add_frame(frame)  # written by the writer's process as the run goes on
        elif self.keep_frames:
            self.rec.frames.append(frame)
        if self.viewer is not None:
            self.viewer.frame(out)
        c3 = time.thread_time()
        self.timing.frame(wait_s=w0 - item.arrival_s, ready_s=ready_s - item.arrival_s,
                          feed_cpu_s=c1 - c0, pipeline_cpu_s=c2 - c1, after_cpu_s=c3 - c2,
                          since_start_s=now - self._t0)  # fmt: skip

    def status_line(self, elapsed_s: float) -> str:
        lat = np.asarray(self._latency[-200:]) * 1e3
        p95 = f"{np.percentile(lat, 95):5.1f}" if lat.size else "    –"
        n = len(self._latency)
        rate = n / elapsed_s if elapsed_s > 0 else 0.0
        p = self.prosthesis.counts
        extra = ", ".join(f"{k} {v}" for k, v in p.items() if v and k != "received")
        skips = self.frames.skips if self.frames is not None else {}
        why = ", ".join(f"{k} {v}" for k, v in skips.items() if v)
        m = self.source.merger.counts
        lost = m.get("gyro missing", 0) + m.get("accel missing", 0)
        missing = f" ({lost} samples never arrived)" if lost else ""
        return (
            f"{elapsed_s:6.1f} s  {rate:5.1f} frames/s  processed {n}  skipped "
            f"{sum(skips.values())}{f' ({why})' if why else ''}  "
            f"latency p95 {p95} ms  imu {m['used']}{missing}  {extra}"
        )

    # ------------------------------------------------------------------ outputs
    def _session_args(self) -> dict:
        setup = self.setup
        return dict(name="live", intrinsics=setup.intrinsics, depth_unit_m=setup.depth_unit_m,
                    camera_profile="realsense-live", generator="graph_slam.live",
                    source=str(self.source.playback or setup.device.get("serial", "camera")))  # fmt: skip

    def _session_process(self, path: Path):
        """The session's frames are written by a process of its own while the run goes on
        (memory stays bounded, the estimator keeps its core); the manifest last, on stop."""
        from graph_slam.live.session_worker import SessionProcess

        return SessionProcess(path, **self._session_args(), camera_T_imu=self._camera_T_imu(),
                              nice=self.writer_nice)  # fmt: skip

    def _camera_T_imu(self) -> np.ndarray:
        t = self.setup.camera_T_imu
        return t if t is not None else np.eye(4)

    def _streams(self) -> tuple[ImuSeries | None, JointSeries | None, GaitEvents | None]:
        """The IMU, joints and events given to the pipeline."""
        imu = joints = events = None
        if self.rec.imu:
            imu = ImuSeries(*(np.concatenate([c[k] for c in self.rec.imu]) for k in range(3)))
        if self.rec.joints:
            j = np.asarray(self.rec.joints)
            joints = JointSeries(j[:, 0], j[:, 1], j[:, 2])
        if self.rec.events:
            ev = sorted(self.rec.events)
            events = GaitEvents(np.array([e[0] for e in ev]), tuple(e[1] for e in ev),
                                ("live",) * len(ev))  # fmt: skip
        return imu, joints, events

    def write_session(self, path: Path | None = None) -> Path:
        """The frames processed, with the streams given to the pipeline, as a session (at
        ``session_path`` when it was written during the run)."""
        imu, joints, events = self._streams()
        if self._writer is not None:
            return self._writer.close(imu, joints, events)
        from graph_slam.session import SessionWriter
        from graph_slam.session.manifest import Provenance
        from graph_slam.session.records import Calibration

        args = self._session_args()
        provenance = Provenance(generator=args.pop("generator"), source=args.pop("source"))
        with SessionWriter(path, **args, calibration=Calibration(camera_T_imu=self._camera_T_imu()),
                           provenance=provenance) as writer:  # fmt: skip
            for frame in self.rec.frames:
                writer.add_frame(frame)
            if imu is not None:
                writer.write_imu(imu)
            if joints is not None:
                writer.write_joints(joints)
            if events is not None:
                writer.write_events(events)
        return writer.path
