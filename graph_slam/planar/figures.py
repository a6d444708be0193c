"""PNG equivalents of the thesis's Figures 3.3, 3.4 and 3.5 (matplotlib, Agg, no pyplot).

* ``scene``: the occupancy grid, the true sensor trajectory and one scan's rays (Fig. 3.3);
* ``failure`` (Fig. 3.4a / 3.5a): two consecutive scans in the sensor frame, the current scan
  aligned onto the previous one, and the map with estimated and true trajectories, at the
  scan where the thesis pipeline's registration went most wrong during swing;
* ``trajectory`` (Fig. 3.4b–c / 3.5b–c): whole trajectories, and the absolute trajectory
  error over time, with swing shaded — for the thesis pipeline and the factor graph.

Plotting never happens inside estimation code: these functions take finished results.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.evaluation import position_errors_m, step_errors_m
from graph_slam.planar.scanner import Scan
from graph_slam.planar.terrain import OccupancyGrid
from graph_slam.planar.thesis import PlanarEstimate
from graph_slam.planar.trajectory import GaitTrajectory

COLOURS = {"truth": "tab:red", "thesis": "tab:blue", "graph": "tab:orange", "map": "tab:green"}


def _figure(width_in: float, height_in: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), dpi=110, layout="constrained")


def _terrain(ax, grid: OccupancyGrid, x_range: tuple[float, float]) -> None:
    ax.imshow(
        grid.occupied,
        origin="lower",
        extent=grid.extent_m,
        cmap="Greys",
        vmin=0,
        vmax=2.5,
        interpolation="nearest",
    )
    ax.set_xlim(*x_range)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def _x_range(trajectory: GaitTrajectory, margin_m: float) -> tuple[float, float]:
    x = trajectory.world_T_sensor[:, 0, 2]
    return float(x.min() - 0.3), float(x.max() + margin_m)


def failure_scan(thesis: PlanarEstimate, trajectory: GaitTrajectory) -> int:
    """The scan where the thesis's step error is largest during swing (else anywhere)."""
    step = np.nan_to_num(step_errors_m(thesis, trajectory), nan=-1.0)
    swing = np.where(~trajectory.in_stance, step, -1.0)
    return int(np.argmax(swing) if swing.max() > 0 else np.argmax(step))


def plot_scene(
    grid: OccupancyGrid,
    trajectory: GaitTrajectory,
    *,
    scan: Scan,
    k: int,
    max_range_m: float,
    path: Path,
) -> Path:
    """Figure 3.3: occupancy grid, sensor trajectory, and the rays of scan ``k``."""
    fig = _figure(10, 4)
    ax = fig.add_subplot()
    _terrain(ax, grid, _x_range(trajectory, max_range_m))
    ax.set_ylim(-0.2, 1.8)
    xy = trajectory.world_T_sensor[:, :2, 2]
    ax.plot(xy[:, 0], xy[:, 1], color="tab:green", lw=1.5, label="sensor trajectory")
    world_T_sensor = trajectory.world_T_sensor[k]
    ends = se2.apply(world_T_sensor, scan.points_xy_m())
    for (ex, ey), hit in zip(ends, scan.hit, strict=True):
        ax.plot(
            [xy[k, 0], ex],
            [xy[k, 1], ey],
            color="tab:red" if hit else "salmon",
            lw=0.4,
            alpha=0.8 if hit else 0.4,
        )
    heading = se2.xyt(world_T_sensor)[2]
    ax.plot(
        *xy[k], marker=(3, 0, np.degrees(heading) - 90), color="tab:blue", ms=12, label="sensor"
    )
    ax.set_title(
        f"{trajectory.speed_m_s:.2f} m/s: terrain, sensor trajectory and the rays "
        f"of scan {k} (pale: max-range returns)"
    )
    ax.legend(loc="upper left", fontsize=8)
    fig.savefig(path)
    return path


def plot_failure(
    grid: OccupancyGrid,
    trajectory: GaitTrajectory,
    *,
    scans: list[Scan],
    thesis: PlanarEstimate,
    graph: PlanarEstimate,
    k: int,
    max_range_m: float,
    path: Path,
) -> Path:
    """Figure 3.4a / 3.5a at scan ``k``."""
    fig = _figure(11, 8)
    top_left, top_right = fig.add_subplot(2, 2, 1), fig.add_subplot(2, 2, 2)
    bottom = fig.add_subplot(2, 1, 2)
    prev, curr = scans[k - 1], scans[k]
    for ax in (top_left, top_right):
        ax.set_aspect("equal")
        ax.set_xlabel("sensor x (m)")
        ax.set_ylabel("sensor y (m)")
    for scan, colour, label in (
        (prev, "tab:blue", f"scan {k - 1}"),
        (curr, "tab:red", f"scan {k}"),
    ):
        pts = scan.points_xy_m()
        top_left.scatter(*pts[scan.hit].T, s=4, color=colour, label=label)
        top_left.scatter(*pts[~scan.hit].T, s=8, marker="x", color=colour, alpha=0.5)
    top_left.set_title("two consecutive scans (x: max-range returns)")
    top_left.legend(fontsize=8)

    pts_prev, pts_curr = prev.points_xy_m(), curr.points_xy_m()
    top_right.scatter(*pts_prev.T, s=4, color="tab:blue", label=f"scan {k - 1}")
    for est, colour in ((graph, COLOURS["graph"]), (thesis, COLOURS["thesis"])):
        if not (
            np.isfinite(est.world_T_sensor[k]).all()
            and np.isfinite(est.world_T_sensor[k - 1]).all()
        ):
            continue
        prev_T_curr = se2.inverse(est.world_T_sensor[k - 1]) @ est.world_T_sensor[k]
        moved = se2.apply(prev_T_curr, pts_curr)
        top_right.scatter(
            *moved.T,
            s=4,
            color="tab:red" if est is thesis else colour,
            alpha=0.8 if est is thesis else 0.5,
            label=f"scan {k} aligned by the {est.method}",
        )
    step = step_errors_m(thesis, trajectory)[k]
    top_right.set_title(f"scan {k} aligned to scan {k - 1} (thesis step error {step * 1e3:.0f} mm)")
    top_right.legend(fontsize=8)

    _terrain(bottom, grid, _x_range(trajectory, max_range_m))
    bottom.set_ylim(-0.2, 1.6)
    if np.isfinite(thesis.world_T_sensor[: k + 1]).all():
        cloud = np.vstack(
            [
                se2.apply(thesis.world_T_sensor[i], scans[i].points_xy_m(True))
                for i in range(0, k + 1)
            ]
        )
        bottom.scatter(*cloud.T, s=1, color=COLOURS["map"], alpha=0.4, label="thesis map")
    for est in (thesis, graph):
        xy = est.world_T_sensor[: k + 1, :2, 2]
        bottom.plot(*xy.T, color=COLOURS[est.method], lw=1.2, label=f"{est.method} estimate")
    bottom.plot(
        *trajectory.world_T_sensor[: k + 1, :2, 2].T, color=COLOURS["truth"], lw=1.2, label="truth"
    )
    phase = "swing" if not trajectory.in_stance[k] else "stance"
    bottom.set_title(
        f"map and trajectories up to scan {k} ({phase}, t = {trajectory.t_s[k]:.2f} s)"
    )
    bottom.legend(fontsize=8, loc="upper left", ncol=2)
    fig.suptitle(
        f"{trajectory.speed_m_s:.2f} m/s: the scan where the thesis pipeline's "
        f"registration went most wrong"
    )
    fig.savefig(path)
    return path


def _shade_swing(ax, trajectory: GaitTrajectory) -> None:
    swing = ~trajectory.in_stance
    t = trajectory.t_s
    edges = np.flatnonzero(np.diff(np.r_[0, swing.astype(int), 0]))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(t[start], t[stop - 1], color="0.9", lw=0)


def plot_trajectory(
    grid: OccupancyGrid, trajectory: GaitTrajectory, *, estimates: list[PlanarEstimate], path: Path
) -> Path:
    """Figure 3.4b–c / 3.5b–c: whole trajectories and absolute error over time."""
    fig = _figure(12, 4.5)
    left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    _terrain(left, grid, _x_range(trajectory, 0.6))
    left.set_ylim(-0.1, 1.3)
    left.plot(*trajectory.world_T_sensor[:, :2, 2].T, color=COLOURS["truth"], lw=1.5, label="truth")
    for est in estimates:
        left.plot(
            *est.world_T_sensor[:, :2, 2].T,
            color=COLOURS[est.method],
            lw=1.2,
            label=f"{est.method} estimate",
        )
    left.legend(fontsize=8, loc="upper left")
    left.set_title("(b) sensor trajectory, estimated and true")

    _shade_swing(right, trajectory)
    for est in estimates:
        err = position_errors_m(est, trajectory) * 1e3
        right.plot(trajectory.t_s, err, color=COLOURS[est.method], lw=1.2, label=est.method)
        failed = np.array([f is not None for f in est.failure])
        right.plot(
            trajectory.t_s[failed],
            err[failed],
            "x",
            color=COLOURS[est.method],
            ms=5,
            label=f"{est.method}: registration reported failed",
        )
    for t in trajectory.foot_strike_t_s:
        right.axvline(t, color="0.5", lw=0.8, ls="--")
    right.set_yscale("symlog", linthresh=10.0)
    right.set_ylim(bottom=0.0)
    right.set_xlabel("t (s)  [grey: swing; dashed: foot strike]")
    right.set_ylabel("absolute position error (mm)")
    right.legend(fontsize=8)
    right.set_title("(c) absolute trajectory error")
    fig.suptitle(
        f"{trajectory.speed_m_s:.2f} m/s (mean hip speed {trajectory.hip_speed_m_s:.2f} m/s)"
    )
    fig.savefig(path)
    return path
