"""The live loop's preparing thread: between the camera's callbacks and the estimator.

It takes the source's items in arrival order and passes them on in the same order (the IMU
items skip it: the source puts them on :attr:`Preparer.items` itself); a depth
frame is decoded to metres and its colour image (when paired) registered to it here, as the
frame arrives (the compiled registration releases the GIL: it runs beside the estimator), so
the estimator's thread only books the frame; with ``ahead`` (the pipeline's
``prepare_ahead``), the part of the pipeline's own preparation that depends on the frame alone
is done here too, once the frame is handed over (compiled, the GIL released). librealsense's frames are released as soon as
they are decoded. The CPU time of each frame's preparation is kept (``cpu_s``).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from dataclasses import dataclass

from graph_slam.live.camera import EndItem, FrameItem
from graph_slam.session.records import RgbdFrame

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class UnreadableFrame:
    """A frame librealsense gave that could not be decoded (skipped, counted)."""

    t_s: float
    index: int
    error: str


@dataclass(frozen=True)
class PreparedFrame:
    """A frame decoded (and its colour registered): what the estimator takes."""

    frame: RgbdFrame
    t_s: float
    arrival_s: float
    prepared_s: float
    cpu_s: float
    with_color: bool


class Preparer:
    """Runs ``source.get`` on its own thread; items for the loop on :attr:`items`."""

    def __init__(self, source, poll_s: float = 0.05, ahead=None) -> None:
        self.source, self.poll_s, self.ahead = source, poll_s, ahead
        self.ahead_cpu_s: list[float] = []  # per frame prepared ahead
        self.items: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="live-prepare", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def discard(self) -> int:
        """Drop what is on :attr:`items` (before :meth:`start`: the IMU items the source
        routed here before the run started); how many items."""
        n = 0
        while True:
            try:
                self.items.get_nowait()
            except queue.Empty:
                return n
            n += 1

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while not self._stop.is_set():
            item = self.source.get(self.poll_s)
            if item is None:
                continue
            if isinstance(item, FrameItem):
                try:
                    item = self._prepare(item)
                except Exception as err:  # a frame librealsense gave that cannot be read
                    log.warning("frame %d (t %.6f s) skipped: %s", item.index, item.t_s, err)
                    item = UnreadableFrame(item.t_s, item.index, str(err))
            self.items.put(item)
            if isinstance(item, EndItem):
                return
            if isinstance(item, PreparedFrame) and self.ahead is not None:
                self._ahead(item)

    def _ahead(self, item: PreparedFrame) -> None:
        """The pipeline's frame-only preparation, after the frame is handed over (it never
        waits for it: an estimator that takes the frame first does that part itself, with
        the same result). Its CPU time: :attr:`ahead_cpu_s`."""
        c0 = time.thread_time()
        try:  # (the estimator does it itself when this fails, and says why)
            self.ahead(item.frame)
        except Exception as err:
            log.debug("frame at %.6f s: not prepared ahead: %s", item.t_s, err)
        self.ahead_cpu_s.append(time.thread_time() - c0)

    def _prepare(self, item: FrameItem) -> PreparedFrame:
        c0 = time.thread_time()
        frame = item.rgbd()
        cpu = time.thread_time() - c0
        return PreparedFrame(frame, item.t_s, item.arrival_s, time.perf_counter(), cpu,
                             item.color is not None)  # fmt: skip
