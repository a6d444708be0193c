"""Poses and the live elevation grid to rerun while a live run goes on: saved to a ``.rrd``
file, and streamed to a viewer that is spawned (``spawn``) or running at an address
(``connect``: ``rerun+http://HOST:9876/proxy``).

The drawing runs in a process of its own (:mod:`graph_slam.live.view_worker`): the grid's
boxes are searched and rerun's arrays built there, not under the estimator's interpreter lock.
The estimator hands each frame's output over (a frame's terrain view is a snapshot: later
frames do not change it) and goes on; a thread here copies the frame's pose and, every
``grid_step``-th frame, the grid's cell sums into the worker's pipe. When the viewer falls
``max_waiting`` frames behind, the oldest waiting frame is not drawn (counted: ``dropped``).
A worker that stops (it crashed, or could not start rerun) stops the drawing, never the run
(counted: ``lost``)."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import subprocess
import sys
import threading
from pathlib import Path

from graph_slam.errors import ConfigError

log = logging.getLogger(__name__)
START_TIMEOUT_S = 60.0
CLOSE_TIMEOUT_S = 120.0


class LiveViewer:
    """Call with every frame's ``FrameOutput``; every ``grid_step``-th frame logs the grid."""

    def __init__(self, path: str | Path, *, spawn: bool = False, connect: str | None = None,
                 grid_step: int = 9, max_waiting: int = 8, nice: int = 5) -> None:  # fmt: skip
        if grid_step < 1:
            raise ConfigError(f"live viewer: grid_step must be ≥ 1, got {grid_step}")
        self.path, self.grid_step = Path(path), int(grid_step)
        self.counts = {"drawn": 0, "dropped": 0, "failed": 0, "lost": 0}
        self._sent = 0
        cmd = [sys.executable, "-m", "graph_slam.live.view_worker", str(self.path),
               "--nice", str(int(nice))]  # fmt: skip
        if spawn:
            cmd.append("--spawn")
        elif connect:
            cmd += ["--connect", connect]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        self._waiting: queue.Queue = queue.Queue(maxsize=max_waiting)
        self._thread = threading.Thread(target=self._drain, name="live-viewer", daemon=True)
        self._thread.start()

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S) -> bool:
        """Wait until the worker has rerun open (its imports take a second or two)."""
        line = _readline(self._proc.stdout, timeout_s)
        if line.strip() != b"ready":
            log.warning("rerun: the viewer's process did not start (%r)", line[:200])
            return False
        return True

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
        from graph_slam.live.view_worker import frame_message

        pipe = self._proc.stdin
        while (out := self._waiting.get()) is not None:
            if pipe is None:
                self.counts["lost"] += 1
                continue
            try:
                pipe.write(frame_message(out, int(out.frame_index) % self.grid_step == 0))
                pipe.flush()
                self._sent += 1
            except (BrokenPipeError, OSError, ValueError) as err:
                log.warning("rerun: the viewer's process stopped (%s); not drawing", err)
                self.counts["lost"] += 1
                pipe = None

    def close(self) -> None:
        """Draw what waits, then close the recording (the worker writes its counts)."""
        if self._thread.is_alive():
            self._waiting.put(None)
            self._thread.join()
        proc = self._proc
        with contextlib.suppress(OSError):
            proc.stdin.close()
        try:
            proc.wait(timeout=CLOSE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            log.warning("rerun: the viewer's process did not finish in %.0f s", CLOSE_TIMEOUT_S)
            proc.kill()
            proc.wait()
        lines = proc.stdout.read().splitlines()
        try:
            worker = json.loads(lines[-1]) if lines else {}
        except ValueError:
            worker = {}
        for key in ("drawn", "failed"):
            self.counts[key] = int(worker.get(key, 0))
        # frames the pipe took but the worker never drew (it stopped with them unread)
        self.counts["lost"] += max(self._sent - self.counts["drawn"] - self.counts["failed"], 0)
        if proc.returncode != 0:
            log.warning("rerun: the viewer's process ended with status %s", proc.returncode)


def _readline(stream, timeout_s: float) -> bytes:
    """One line of ``stream`` within ``timeout_s`` (b"" when none came)."""
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(stream.readline()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    return got[0] if got else b""
