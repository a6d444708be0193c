"""The live session written by a process of its own, beside the estimator.

Writing a frame means quantising its depth and compressing two PNG images (a few milliseconds
of CPU a frame at 424×240). In the estimator's process that work took the cores and, in its
Python parts, the interpreter lock from the estimator. Here a child process
(``python -m graph_slam.live.session_worker``) at the lowest CPU priority (nice +19 by
default: it yields the cores to the estimator and the threads that feed it, and catches up
when they wait) writes the session with :class:`~graph_slam.session.SessionWriter`, exactly as
the estimator's process would; the live process only hands each frame's arrays to a thread that
writes them into the pipe (:func:`graph_slam.live.messages.send`, no copy, the system call
without the interpreter lock). Frames the child has not read yet wait in that thread's queue:
the estimator never waits for the disk.

On :meth:`SessionProcess.close` the child writes the frames still waiting, then the IMU, joints
and events, and the manifest last; a child that fails (a full disk) or is cut off
(:meth:`SessionProcess.abort`) writes no manifest: never a session that looks whole and is not.

Messages (:mod:`graph_slam.live.messages`), each a header ``{"kind": ...}``: ``open`` (the
session's folder, name, intrinsics, depth unit, camera profile, ``camera_T_imu`` and
provenance), ``frame`` (``t_s``, ``index``; arrays ``depth_m`` and, when it has colour,
``color_rgb``), ``imu``, ``joints``, ``events``, ``close``. The child answers ``ready`` once
the session's folder is made, and on ``close`` one line of JSON (``frames``, ``path``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import BinaryIO

import numpy as np

from graph_slam.errors import SessionError
from graph_slam.live.messages import read_line, read_message, read_within, send
from graph_slam.session.records import CameraIntrinsics, GaitEvents, ImuSeries, JointSeries

START_TIMEOUT_S = 60.0
CLOSE_TIMEOUT_S = 600.0
PIPE_BYTES = 1 << 20  # (Linux) fewer wake-ups of the feeding thread than the 64 kB default


class SessionProcess:
    """A session written by a child process (module docstring): :meth:`add_frame` during the
    run (never waits), :meth:`close` with the streams on stop. ``nice``: how far the child
    lowers its CPU priority (0: not at all)."""

    def __init__(self, path: str | Path, *, name: str, intrinsics: CameraIntrinsics,
                 depth_unit_m: float, camera_profile: str = "unknown",
                 camera_T_imu: np.ndarray | None = None, generator: str = "graph_slam",
                 source: str | None = None, nice: int = 19) -> None:  # fmt: skip
        self.path = Path(path)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        cmd = [sys.executable, "-m", "graph_slam.live.session_worker", "--nice", str(int(nice))]
        self._stderr_file = tempfile.TemporaryFile()  # noqa: SIM115 (not a pipe: never fills)
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      stderr=self._stderr_file, env=env)  # fmt: skip
        self._fd = self._proc.stdin.fileno()
        _widen_pipe(self._fd)
        self.n_frames = 0
        self.error: str | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._queue.put(({"kind": "open", "path": str(self.path), "name": name,
                          "intrinsics": [intrinsics.width_px, intrinsics.height_px,
                                         intrinsics.fx_px, intrinsics.fy_px,
                                         intrinsics.cx_px, intrinsics.cy_px],
                          "depth_unit_m": float(depth_unit_m), "camera_profile": camera_profile,
                          "camera_T_imu": None if camera_T_imu is None
                          else np.asarray(camera_T_imu, float).tolist(),
                          "generator": generator, "source": source}, {}))  # fmt: skip
        self._thread = threading.Thread(target=self._feed, name="live-writer", daemon=True)
        self._thread.start()

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S) -> None:
        """Wait until the child has made the session's folder (its imports take a second)."""
        line = read_line(self._proc.stdout, timeout_s)
        if line.strip() != b"ready":
            self.abort()
            raise SessionError(f"{self.path}: the session's writer did not start: "
                               f"{self._stderr() or line[:200]!r}")  # fmt: skip

    def add_frame(self, frame) -> None:
        """Hand one frame over (its arrays are read-only: nothing is copied here)."""
        arrays = {"depth_m": frame.depth_m}
        if frame.color_rgb is not None:
            arrays["color_rgb"] = frame.color_rgb
        self._queue.put(({"kind": "frame", "t_s": float(frame.t_s), "index": int(frame.index)},
                         arrays))  # fmt: skip
        self.n_frames += 1

    def _feed(self) -> None:
        while (message := self._queue.get()) is not None:
            if self.error is not None:
                continue  # the child is gone: what is left is not written
            try:
                send(self._fd, *message)
            except OSError as err:  # (BrokenPipeError: the child stopped)
                self.error = f"the session's writer stopped ({err})"

    def close(self, imu: ImuSeries | None = None, joints: JointSeries | None = None,
              events: GaitEvents | None = None) -> Path:  # fmt: skip
        """Write what waits, the streams and the manifest; the session's path. A child that
        failed raises :class:`~graph_slam.errors.SessionError` (no manifest was written)."""
        if imu is not None:
            self._queue.put(({"kind": "imu"}, {"t_s": imu.t_s, "gyro": imu.gyro_rad_s,
                                               "accel": imu.accel_m_s2}))  # fmt: skip
        if joints is not None:
            self._queue.put(({"kind": "joints"}, {"t_s": joints.t_s, "knee": joints.knee_rad,
                                                  "ankle": joints.ankle_rad}))  # fmt: skip
        if events is not None:
            self._queue.put(({"kind": "events", "kinds": list(events.kind),
                              "sources": list(events.source)}, {"t_s": events.t_s}))  # fmt: skip
        self._queue.put(({"kind": "close"}, {}))
        line = self._finish(CLOSE_TIMEOUT_S)
        try:
            done = json.loads(line) if self._proc.returncode == 0 else {}
        except ValueError:
            done = {}
        if self.error is not None or done.get("frames") != self.n_frames:
            raise SessionError(f"{self.path}: the session was not written whole "
                               f"({done.get('frames', 0)} of {self.n_frames} frames; "
                               f"{self.error or self._stderr()})")  # fmt: skip
        return self.path

    def abort(self) -> None:
        """Stop the child without a manifest (the frames it wrote stay; without the manifest
        the folder is no session)."""
        if self._proc.poll() is None:
            with contextlib.suppress(OSError):
                self._proc.send_signal(signal.SIGTERM)
        self._finish(10.0)

    def _finish(self, timeout_s: float) -> str:
        """Hand over what waits, end the child's input, wait for its last line and its exit."""
        self._queue.put(None)
        self._thread.join()
        with contextlib.suppress(OSError):
            self._proc.stdin.close()
        lines = read_within(self._proc.stdout.read, timeout_s).decode(errors="replace").splitlines()
        line = lines[-1].strip() if lines else ""  # (after "ready", when that was not read)
        try:
            self._proc.wait(timeout=10.0 if line else 1.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
            self.error = self.error or f"the session's writer did not finish in {timeout_s:g} s"
        return line

    def _stderr(self) -> str:
        f = self._stderr_file
        f.seek(0)
        return f.read().decode(errors="replace").strip()[-2000:] or (
            f"exit status {self._proc.returncode}"
        )


def _widen_pipe(fd: int) -> None:
    try:
        import fcntl
    except ImportError:  # (not on Windows)
        return
    if hasattr(fcntl, "F_SETPIPE_SZ"):
        with contextlib.suppress(OSError):
            fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)


# --------------------------------------------------------------------------- the child


def _writer(header: dict):
    from graph_slam.session import SessionWriter
    from graph_slam.session.manifest import Provenance
    from graph_slam.session.records import Calibration

    k = header["intrinsics"]
    intrinsics = CameraIntrinsics(int(k[0]), int(k[1]), *map(float, k[2:]))
    cal = Calibration() if header["camera_T_imu"] is None else Calibration(
        camera_T_imu=np.asarray(header["camera_T_imu"], float))  # fmt: skip
    return SessionWriter(header["path"], name=header["name"], intrinsics=intrinsics,
                         depth_unit_m=header["depth_unit_m"],
                         camera_profile=header["camera_profile"], calibration=cal,
                         provenance=Provenance(generator=header["generator"],
                                               source=header["source"]))  # fmt: skip


def serve(stream: BinaryIO, answer) -> int:
    """Write the session the messages of ``stream`` describe; ``answer(line)`` says ``ready``
    once it is open; the number of frames written. Input that ends before ``close`` raises
    :class:`~graph_slam.errors.SessionError`: the session is left without a manifest."""
    first = read_message(stream)
    if first is None or first[0].get("kind") != "open":
        raise SessionError("the session's writer: no 'open' message first")
    writer = _writer(first[0])
    answer("ready")
    with writer:  # the manifest on a clean exit only
        n = _write(writer, stream)
    return n


def _write(writer, stream: BinaryIO) -> int:
    from graph_slam.session.records import RgbdFrame

    n = 0
    while (message := read_message(stream)) is not None:
        head, arrays = message
        kind = head["kind"]
        if kind == "frame":
            writer.add_frame(RgbdFrame(head["t_s"], arrays["depth_m"],
                                       arrays.get("color_rgb"), head["index"]))  # fmt: skip
            n += 1
        elif kind == "imu":
            writer.write_imu(ImuSeries(arrays["t_s"], arrays["gyro"], arrays["accel"]))
        elif kind == "joints":
            writer.write_joints(JointSeries(arrays["t_s"], arrays["knee"], arrays["ankle"]))
        elif kind == "events":
            writer.write_events(GaitEvents(arrays["t_s"], tuple(head["kinds"]),
                                           tuple(head["sources"])))  # fmt: skip
        elif kind == "close":
            return n
    raise SessionError(f"{writer.path}: the session's writer: its input ended before 'close' "
                       f"({n} frames written, no manifest)")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m graph_slam.live.session_worker")
    parser.add_argument("--nice", type=int, default=0, help="lower this process's priority")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the run, which closes this
    if args.nice:
        os.nice(args.nice)

    def answer(line: str) -> None:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()

    try:
        n = serve(sys.stdin.buffer, answer)
    except SessionError as err:
        sys.stderr.write(f"{err}\n")
        return 1
    answer(json.dumps({"frames": n}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
