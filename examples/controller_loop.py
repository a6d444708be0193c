"""A controller's loop: replay a session causally and print, per frame, what a prosthesis
controller would read: gait phase, the obstacle ahead (distance from the toe and height, with
σ), the nearest stair, curb or ramp ahead (``TerrainView.features_ahead()``), during stance the
coming swing's predicted toe clearance with its low-clearance warning, and the time left to
toe-off (predicted from the stances seen so far).

graph-slam simulate --scene thesis-boxes --strides 3 --resolution 424x240 --drops none --out runs/sim
python examples/controller_loop.py runs/sim [VARIANT[:PRESET]] [--measured]

The session is replayed by :func:`graph_slam.pipelines.replay.replay_session` (every stream in
time-stamp order, nothing read ahead; the newest frame taken when the estimator is free) on
its deterministic virtual clock (every frame processed, one line each; ``--measured``: the
clock advances by the measured compute time, so frames arriving while the estimator is busy
are skipped, and which depends on the machine's load) into
the pipeline wrapped by :class:`graph_slam.pipelines.controller.ControllerTap`. Each frame's
``FrameOutput`` carries the pose (``stride_T_camera``), its covariance (``covariance``; graph
variants with ``backend.covariances``) and the terrain (``terrain``: height_at(x, y), the grid
arrays, ``obstacles_ahead()``, ``features_ahead()``), all in the stride frame (docs/terrain.md).
"""

from __future__ import annotations

import sys

from graph_slam.pipelines.controller import ControllerTap
from graph_slam.pipelines.replay import MEASURED, replay_session
from graph_slam.pipelines.runner import make_pipeline


def row_config(row: str):
    """The pipeline of a bench row (``VARIANT[:PRESET]``), graph variants with per-frame
    covariances (the terrain's variance then carries the pose's)."""
    from graph_slam.bench.realtime import row_config as preset_row

    config = preset_row(row)
    if config.variant.is_baseline:
        return config
    return config.model_copy(
        update={"backend": config.backend.model_copy(update={"covariances": True})}
    )


def controller_readouts(session, config, compute_cost=None):
    """The readout of every processed frame of a causal replay of ``session``."""
    taps: list[ControllerTap] = []

    def factory(*args, **kwargs):
        taps.append(ControllerTap(make_pipeline(*args, **kwargs)))
        return taps[-1]

    replay_session(session, config, compute_cost=compute_cost, pipeline_factory=factory)
    return taps[-1].readouts  # the first tap warmed up the host


def main() -> None:
    args = [a for a in sys.argv[1:] if a != "--measured"]
    row = args[1] if len(args) > 1 else "icp+imu+kin"  # the default preset: realtime
    cost = MEASURED if "--measured" in sys.argv[1:] else None
    for readout in controller_readouts(args[0], row_config(row), compute_cost=cost):
        print(readout.line())


if __name__ == "__main__":
    main()
