"""``run_planar``: the whole 2D study, as a list of steps, written into one output folder.

For every walking speed: walk two strides, scan the terrain, run the thesis pipeline and the
per-stride factor graph on the same scans, score both, and draw the figures. Then write the
per-stride error table. The resolved config is written first, next to the results.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.config import write_config
from graph_slam.errors import PlanarError
from graph_slam.planar import evaluation, figures
from graph_slam.planar.config import PlanarConfig
from graph_slam.planar.graph import run_graph
from graph_slam.planar.measurements import simulate_measurements
from graph_slam.planar.scanner import Scan, simulate_scan
from graph_slam.planar.terrain import OccupancyGrid, build_terrain
from graph_slam.planar.thesis import PlanarEstimate, run_thesis
from graph_slam.planar.trajectory import GaitTrajectory, simulate_gait

log = logging.getLogger(__name__)

Progress = Callable[[str], None]  # called once per finished step with its description


@dataclass(frozen=True)
class SpeedRun:
    """Everything computed at one walking speed."""

    trajectory: GaitTrajectory
    scans: list[Scan]
    thesis: PlanarEstimate
    graph: PlanarEstimate
    errors: list[evaluation.StrideError]


@dataclass(frozen=True)
class PlanarResult:
    """What ``run_planar`` produced: the runs, the table rows, and the files written."""

    out_dir: Path | None
    runs: list[SpeedRun]
    table: list[evaluation.StrideError]
    files: list[Path] = field(default_factory=list)


def n_steps(config: PlanarConfig, write: bool = True) -> int:
    """How many times ``run_planar`` calls its progress callback."""
    per_speed = 4 if write else 3
    return len(config.speeds_m_s) * per_speed + (2 if write else 0)


def run_speed(
    config: PlanarConfig,
    grid: OccupancyGrid,
    speed_m_s: float,
    progress: Progress | None = None,
) -> SpeedRun:
    """Simulate one speed and run both methods on it.

    The random streams (scan noise; IMU, encoder and motion-prior noise) are seeded from the
    config's seed and the speed, so a speed gives the same run whatever else is configured.
    """
    progress = progress or (lambda description: None)
    seed = np.random.SeedSequence([config.seed, round(speed_m_s * 1000)])
    trajectory = simulate_gait(speed_m_s, config.n_strides, config.scanner.rate_hz, config.leg)
    scan_rng, measurement_rng = (np.random.default_rng(s) for s in seed.spawn(2))
    scans = [
        simulate_scan(grid, world_T_sensor, t_s, config.scanner, scan_rng)
        for world_T_sensor, t_s in zip(trajectory.world_T_sensor, trajectory.t_s, strict=True)
    ]
    measurements = simulate_measurements(trajectory, config.leg, config.graph, measurement_rng)
    progress(f"{speed_m_s:.2f} m/s: simulated {len(scans)} scans")
    thesis = run_thesis(scans, trajectory.world_T_sensor[0], config)
    progress(f"{speed_m_s:.2f} m/s: thesis pipeline")
    graph = run_graph(
        scans, trajectory.stride_index, measurements, trajectory.world_T_stride, config
    )
    progress(f"{speed_m_s:.2f} m/s: factor graph")
    errors = [row for est in (thesis, graph) for row in evaluation.stride_errors(est, trajectory)]
    return SpeedRun(trajectory, scans, thesis, graph, errors)


def _write_speed(
    run: SpeedRun, grid: OccupancyGrid, config: PlanarConfig, out_dir: Path
) -> list[Path]:
    tag = f"v{run.trajectory.speed_m_s:.2f}"
    k = figures.failure_scan(run.thesis, run.trajectory)
    r_max = config.scanner.max_range_m
    number = _fig(run)
    return [
        figures.plot_scene(
            grid,
            run.trajectory,
            scan=run.scans[k],
            k=k,
            max_range_m=r_max,
            path=out_dir / f"fig3_3_scene_{tag}.png",
        ),
        figures.plot_failure(
            grid,
            run.trajectory,
            scans=run.scans,
            thesis=run.thesis,
            graph=run.graph,
            k=k,
            max_range_m=r_max,
            path=out_dir / f"fig3_{number}a_failure_{tag}.png",
        ),
        figures.plot_trajectory(
            grid,
            run.trajectory,
            estimates=[run.thesis, run.graph],
            path=out_dir / f"fig3_{number}bc_trajectory_{tag}.png",
        ),
        evaluation.write_scan_log(
            run.trajectory, [run.thesis, run.graph], out_dir / f"scans_{tag}.csv"
        ),
    ]


def _fig(run: SpeedRun) -> str:
    """Thesis figure number: 3.4 for the slow walk, 3.5 for the fast one."""
    return "4" if run.trajectory.speed_m_s < 1.0 else "5"


def run_planar(
    config: PlanarConfig, out_dir: Path | None = None, progress: Progress | None = None
) -> PlanarResult:
    """Run the 2D study at every configured speed; write everything under ``out_dir``."""
    progress = progress or (lambda description: None)
    files: list[Path] = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        if out_dir.exists() and not out_dir.is_dir():
            raise PlanarError(f"{out_dir}: the output path exists and is not a folder")
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise PlanarError(
                f"{out_dir}: cannot create the output folder ({err.strerror})"
            ) from None
        files.append(write_config(config, out_dir / "config.yaml"))
    grid = build_terrain(config.terrain)
    runs = []
    for speed in config.speeds_m_s:
        run = run_speed(config, grid, speed, progress)
        runs.append(run)
        if out_dir is not None:
            files += _write_speed(run, grid, config, out_dir)
            progress(f"{speed:.2f} m/s: figures")
    table = [row for run in runs for row in run.errors]
    if out_dir is not None:
        files += evaluation.write_table(table, out_dir)
        progress("error table")
        progress("done")
    log.info("planar study: %d speeds, %d table rows", len(runs), len(table))
    return PlanarResult(out_dir, runs, table, files)
