"""Poses and the live elevation grid to rerun while a live run goes on: saved to a ``.rrd``
file, and streamed to a viewer that is spawned (``spawn``) or running at an address
(``connect``: ``rerun+http://HOST:9876/proxy``).

The drawing runs in a process of its own (:mod:`graph_slam.live.view_worker`): the grid's
boxes are searched and rerun's arrays built there, not under the estimator's interpreter lock.
The estimator hands each frame's output over (a frame's terrain view is a snapshot: later
frames do not change it) and goes on; a thread here copies the frame's pose and, with it, the
grid's cell sums into the worker's pipe. How often (:class:`ViewerConfig`, on the frames'
own clock, so the same recording gives the same drawing): a pose ``pose_hz`` times a second
(default 30, a screen's rate; 0: every frame), the grid ``grid_hz`` times (default 5; a grid
is a box search of several milliseconds in the worker, which shares the cores with the
estimator). The frames between are not sent (counted: ``not sent``). When the viewer falls
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

from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.live.messages import read_line

log = logging.getLogger(__name__)
START_TIMEOUT_S = 60.0
CLOSE_TIMEOUT_S = 120.0
SLACK_S = 0.002  # a frame this much before a message is due counts as at it (stamp jitter)


class ViewerConfig(ConfigModel):
    """What the live viewer is sent, and its process's priority (module docstring)."""

    pose_hz: float = Field(30.0, ge=0, description="poses drawn per second (0: every frame)")
    grid_hz: float = Field(5.0, ge=0, description="grids drawn per second (0: every frame)")
    max_waiting: int = Field(8, ge=1, description="frames waiting for the pipe before the "
                             "oldest is not drawn")  # fmt: skip
    nice: int = Field(10, ge=0, le=19, description="how far the viewer's process lowers its "
                      "CPU priority")  # fmt: skip


class LiveViewer:
    """Call with every frame's ``FrameOutput``; it sends the poses and grids due
    (:class:`ViewerConfig`)."""

    def __init__(self, path: str | Path, config: ViewerConfig | None = None, *,
                 spawn: bool = False, connect: str | None = None) -> None:  # fmt: skip
        self.path, self.config = Path(path), config or ViewerConfig()
        self.counts = {"drawn": 0, "not sent": 0, "dropped": 0, "failed": 0, "lost": 0}
        self._sent = 0
        self._next_pose_s = self._next_grid_s = -float("inf")
        cmd = [sys.executable, "-m", "graph_slam.live.view_worker", str(self.path),
               "--nice", str(int(self.config.nice))]  # fmt: skip
        if spawn:
            cmd.append("--spawn")
        elif connect:
            cmd += ["--connect", connect]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        self._waiting: queue.Queue = queue.Queue(maxsize=self.config.max_waiting)
        self._thread = threading.Thread(target=self._drain, name="live-viewer", daemon=True)
        self._thread.start()

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S) -> bool:
        """Wait until the worker has rerun open (its imports take a second or two)."""
        line = read_line(self._proc.stdout, timeout_s)
        if line.strip() != b"ready":
            log.warning("rerun: the viewer's process did not start (%r)", line[:200])
            return False
        return True

    def due(self, t_s: float) -> tuple[bool, bool]:
        """Whether a frame at ``t_s`` brings a pose, and a grid, to the viewer (and books it)."""
        grid = t_s >= self._next_grid_s - SLACK_S
        pose = grid or t_s >= self._next_pose_s - SLACK_S
        if grid:
            self._next_grid_s = _next(self._next_grid_s, t_s, self.config.grid_hz)
        if pose:
            self._next_pose_s = _next(self._next_pose_s, t_s, self.config.pose_hz)
        return pose, grid

    def frame(self, out) -> None:
        """Hand one frame's output over when it is due (never waits)."""
        pose, grid = self.due(float(out.t_s))
        if not pose:
            self.counts["not sent"] += 1
            return
        while True:
            try:
                self._waiting.put_nowait((out, grid))
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
        while (item := self._waiting.get()) is not None:
            if pipe is None:
                self.counts["lost"] += 1
                continue
            try:
                pipe.write(frame_message(*item))
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


def _next(due_s: float, t_s: float, hz: float) -> float:
    """The next time a message at ``hz`` is due after one sent at ``t_s`` (on the grid of
    periods from the first, so the rate holds when frames come between; 0 Hz: every frame)."""
    if hz <= 0:
        return -float("inf")
    period = 1.0 / hz
    if not due_s > -float("inf") or t_s - due_s >= period:
        return t_s + period  # the first, or after a gap: from this frame
    return due_s + period
