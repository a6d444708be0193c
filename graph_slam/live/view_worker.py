"""The live viewer's own process: poses and the elevation grid to rerun, beside the estimator.

Drawing the grid means searching its boxes (a floor fit: several milliseconds of Python each
time) and building rerun's arrays; in the estimator's process that work takes Python's
interpreter lock in bursts and delays the frame being estimated. Here it runs in a child
process (``python -m graph_slam.live.view_worker RRD [--spawn | --connect ADDR]``) that reads
the frames from its standard input and draws them; the estimator's process only copies each
frame's pose and, with the frames due a grid, the grid's cell sums into the pipe
(:class:`graph_slam.live.viewer.ViewerConfig`: 30 poses and 5 grids a second by default).

Messages: :mod:`graph_slam.live.messages` (no pickle). When its input ends the worker closes
the recording and writes one line of JSON with its counts (``drawn``, ``failed``) to its
standard output.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import fields
from types import SimpleNamespace
from typing import BinaryIO

import numpy as np

from graph_slam.live.messages import pack, read_message, unpack  # noqa: F401 (re-exported)

log = logging.getLogger(__name__)


def _sum_names() -> tuple[str, ...]:
    """The fields of :class:`~graph_slam.terrain.grid.online.CellSums`, sent with a grid."""
    from graph_slam.terrain.grid.online import CellSums

    return tuple(f.name for f in fields(CellSums))


def frame_message(out, with_grid: bool) -> bytes:
    """What the worker needs of one ``FrameOutput``: its time, stride, pose and (``with_grid``)
    the terrain view's cell sums."""
    header = {"frame": int(out.frame_index), "stride": int(out.stride_index), "t_s": float(out.t_s)}
    arrays = {}
    pose = out.stride_T_camera
    if pose is not None:
        arrays["stride_T_camera"] = np.asarray(pose, np.float64)
    view = out.terrain
    if with_grid and view is not None:
        header["view"] = {"stride": int(view.stride_index), "t_s": float(view.t_s),
                          "origin": [float(v) for v in view.origin_xy_m],
                          "cell_m": float(view.cell_m), "shape": list(view.shape),
                          "toe_x_m": float(view.toe_x_m)}  # fmt: skip
        arrays.update({f"sums.{k}": np.asarray(getattr(view.sums, k)) for k in _sum_names()})
    return pack(header, arrays)


def frame_of(header: dict, arrays: dict[str, np.ndarray]) -> SimpleNamespace:
    """The message back as what :meth:`Drawer.draw` reads of a ``FrameOutput``."""
    view = None
    if "view" in header:
        from graph_slam.terrain.grid.online import CellSums
        from graph_slam.terrain.grid.view import TerrainView

        v = header["view"]
        sums = CellSums(**{k: arrays[f"sums.{k}"] for k in _sum_names()})
        view = TerrainView(v["stride"], v["t_s"], np.asarray(v["origin"], float), v["cell_m"],
                           sums, tuple(v["shape"]), v["toe_x_m"])  # fmt: skip
    return SimpleNamespace(frame_index=header["frame"], stride_index=header["stride"],
                           t_s=header["t_s"], stride_T_camera=arrays.get("stride_T_camera"),
                           terrain=view)  # fmt: skip


class Drawer:
    """Draws frames into a rerun recording: every frame's camera pose; the grid (heights, σ,
    boxes) of the frames that carry one."""

    def __init__(self, path, *, spawn: bool = False, connect: str | None = None) -> None:
        import rerun as rr
        from matplotlib import colormaps  # noqa: F401 (the grid's colours: before "ready")

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
        self.trace = TerrainTrace(grid_step=1, every_frame=False)

    def draw(self, out) -> None:
        logger = self.logger
        logger.set_time(out.stride_index, out.t_s)
        if out.stride_T_camera is not None and np.isfinite(out.stride_T_camera).all():
            logger.log_camera(out.stride_T_camera)
        if out.terrain is None:
            return
        self.trace(out)
        snap = self.trace.snapshots.pop(int(out.frame_index), None)
        if snap is not None:
            logger.log_grid(snap)
        self.trace.obstacles.clear()
        self.trace.t_s.clear()
        self.trace.stride_index.clear()
        self.trace.features.clear()
        self.trace.predictions.clear()

    def close(self) -> None:
        self.logger.close()


def serve(drawer: Drawer, stream: BinaryIO) -> dict[str, int]:
    """Draw every message of ``stream`` until it ends; the counts."""
    counts = {"drawn": 0, "failed": 0}
    while (message := read_message(stream)) is not None:
        out = frame_of(*message)
        try:
            drawer.draw(out)
            counts["drawn"] += 1
        except Exception as err:  # the view only: never the run
            counts["failed"] += 1
            log.warning("rerun: frame %s not drawn (%s)", out.frame_index, err)
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m graph_slam.live.view_worker")
    parser.add_argument("rrd")
    parser.add_argument("--spawn", action="store_true")
    parser.add_argument("--connect", default=None)
    parser.add_argument("--nice", type=int, default=0, help="lower this process's priority")
    args = parser.parse_args(argv)
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the run, which closes this
    if args.nice:
        import os

        os.nice(args.nice)
    drawer = Drawer(args.rrd, spawn=args.spawn, connect=args.connect)
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    counts = serve(drawer, sys.stdin.buffer)
    drawer.close()
    sys.stdout.write(json.dumps(counts) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
