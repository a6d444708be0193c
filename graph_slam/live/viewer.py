"""Poses and the live elevation grid to rerun while a live run goes on: saved to a ``.rrd``
file, and streamed to a viewer that is spawned (``spawn``) or running at an address
(``connect``: ``rerun+http://HOST:9876/proxy``).

The logging runs on its own thread (``live-viewer``): the estimator hands each frame's output
over (a frame's terrain view is a snapshot: later frames do not change it) and goes on; the
grid's boxes are searched there, not on the estimator's thread. When the viewer falls
``max_waiting`` frames behind, the oldest waiting frame is not drawn (counted: ``dropped``)."""

from __future__ import annotations

import logging
import queue
import threading
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


class LiveViewer:
    """Call with every frame's ``FrameOutput``; every ``grid_step``-th frame logs the grid."""

    def __init__(self, path: str | Path, *, spawn: bool = False, connect: str | None = None,
                 grid_step: int = 9, max_waiting: int = 8) -> None:  # fmt: skip
        import rerun as rr

        from graph_slam.report.terrain_trace import TerrainTrace
        from graph_slam.viz.rerun_logger import RerunLogger

        self.logger = RerunLogger(path, application_id="graph_slam_live")
        sinks = [rr.FileSink(str(path))]
        if spawn:
            rr.spawn(connect=False)
            sinks.append(rr.GrpcSink())
        elif connect:
            sinks.append(rr.GrpcSink(connect))
        if len(sinks) > 1:
            self.logger._rec.set_sinks(*sinks)  # the file and the viewer
        self.trace = TerrainTrace(grid_step=grid_step, every_frame=False)
        self._stride = -1
        self.counts = {"drawn": 0, "dropped": 0}
        self._waiting: queue.Queue = queue.Queue(maxsize=max_waiting)
        self._thread = threading.Thread(target=self._drain, name="live-viewer", daemon=True)
        self._thread.start()

    def frame(self, out) -> None:
        """Hand one frame's output over (never waits)."""
        while True:
            try:
                self._waiting.put_nowait(out)
                return
            except queue.Full:
                try:
                    self._waiting.get_nowait()
                    self.counts["dropped"] += 1
                except queue.Empty:
                    pass

    def _drain(self) -> None:
        while (out := self._waiting.get()) is not None:
            try:
                self._draw(out)
                self.counts["drawn"] += 1
            except Exception as err:  # the view only: never the run
                self.counts["failed"] = self.counts.get("failed", 0) + 1
                log.warning("rerun: frame %s not drawn (%s)", getattr(out, "frame_index", "?"), err)

    def _draw(self, out) -> None:
        log = self.logger
        log.set_time(out.stride_index, out.t_s)
        if out.stride_T_camera is not None and np.isfinite(out.stride_T_camera).all():
            log.log_camera(out.stride_T_camera)
        self.trace(out)
        snap = self.trace.snapshots.pop(int(out.frame_index), None)
        if snap is not None:
            log.log_grid(snap)
        self.trace.obstacles.clear()
        self.trace.t_s.clear()
        self.trace.stride_index.clear()

    def close(self) -> None:
        """Draw what waits, then close the recording."""
        if self._thread.is_alive():
            self._waiting.put(None)
            self._thread.join()
        self.logger.close()
