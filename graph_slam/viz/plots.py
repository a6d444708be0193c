"""PNG figures of an evaluation (matplotlib, object API with the Agg canvas: no display, no
global backend change, imported lazily).

Every function draws one figure, writes it to ``path`` and returns the path:

- :func:`plot_stride_trajectories`: camera positions in the stride frame (top x–y and side x–z
  views), each variant against the ground truth.
- :func:`plot_error_over_gait_cycle`: per-frame translation error against gait-cycle percentage
  (0 = foot strike), one line per stride and variant, toe-off marked if given.
- :func:`plot_map_top_view`: the fused map from above, coloured, with obstacle outlines.
- :func:`plot_elevation`: the elevation grid's height (and its standard deviation).
- :func:`plot_obstacle_boxes`: measured against true (depth, width, height) per box.
- :func:`plot_obstacle_known_vs_phase`: per walking speed, the fraction of the obstacles
  (whole in the strides' final maps) the online map knew by each % of the gait cycle, one line
  per variant, toe-off marked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from graph_slam.evaluation.boxes import DIMENSIONS
from graph_slam.terrain.maps.elevation import ElevationGrid
from graph_slam.terrain.maps.obstacles import Obstacle


def _figure(ncols: int = 1, width_in: float = 6.0, height_in: float = 4.5):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in * ncols, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    return fig, axes


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def plot_stride_trajectories(
    path: str | Path,
    truth_positions_m: np.ndarray,
    estimates_positions_m: Mapping[str, np.ndarray],
    title: str = "",
) -> Path:
    """Top (x–y) and side (x–z) views of camera positions, stride frame; NaN rows are gaps."""
    fig, (top, side) = _figure(2)
    for ax, (i, j, label) in zip((top, side), ((0, 1, "y (m)"), (0, 2, "z (m)")), strict=True):
        ax.plot(truth_positions_m[:, i], truth_positions_m[:, j], "k-", lw=2, label="ground truth")
        for name, p in estimates_positions_m.items():
            ax.plot(p[:, i], p[:, j], ".-", ms=3, label=name)
        ax.set_xlabel("x (m, walking direction)")
        ax.set_ylabel(label)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    top.legend(fontsize="small")
    fig.suptitle(title or "camera trajectory, stride frame")
    return _save(fig, path)


def plot_error_over_gait_cycle(
    path: str | Path,
    curves: Mapping[str, Sequence[tuple[np.ndarray, np.ndarray]]],
    toe_off_percent: float | None = None,
    ylabel: str = "translation error (mm)",
) -> Path:
    """``curves``: variant -> list of (gait cycle %, error m) per stride; one colour per variant."""
    fig, (ax,) = _figure()
    for c, (name, strides) in enumerate(curves.items()):
        for k, (phase_pct, error_m) in enumerate(strides):
            ax.plot(
                phase_pct,
                np.asarray(error_m) * 1000,
                color=f"C{c}",
                alpha=0.5,
                lw=1,
                label=name if k == 0 else None,
            )
    if toe_off_percent is not None:
        ax.axvline(toe_off_percent, color="k", ls="--", lw=1, label="toe-off")
    ax.set_xlabel("gait cycle (%), 0 = foot strike")
    ax.set_ylabel(ylabel)
    ax.set_xlim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return _save(fig, path)


def plot_map_top_view(
    path: str | Path,
    points_m: np.ndarray,
    colors_rgb: np.ndarray | None = None,
    obstacles: Sequence[Obstacle] = (),
    title: str = "stride map, top view",
    truth_boxes: Sequence = (),
) -> Path:
    """Map points seen from above (stride frame), obstacle footprints outlined.

    Boxes seen whole: solid red (measured); seen in part: dashed magenta with the skip reason;
    ``truth_boxes`` (:class:`~graph_slam.evaluation.boxes.TrueBox`): dotted black.
    """
    from matplotlib.patches import Polygon

    fig, (ax,) = _figure()
    colors = None if colors_rgb is None else np.asarray(colors_rgb) / 255.0
    ax.scatter(
        points_m[:, 0],
        points_m[:, 1],
        s=1,
        c=colors if colors is not None else points_m[:, 2],
        linewidths=0,
    )
    labelled = set()

    def outline(corners, label, **style):
        first = label not in labelled
        labelled.add(label)
        ax.add_patch(
            Polygon(corners, closed=True, fill=False, label=label if first else None, **style)
        )

    lo, hi = points_m[:, :2].min(axis=0), points_m[:, :2].max(axis=0)
    for box in truth_boxes:
        if not ((box.center_xy_m >= lo - 0.3) & (box.center_xy_m <= hi + 0.3)).all():
            continue  # far along the course: off this map
        hd, hw = np.asarray(box.size_m[:2]) / 2
        c, s = np.cos(box.yaw_rad), np.sin(box.yaw_rad)
        local = np.array([[-hd, -hw], [hd, -hw], [hd, hw], [-hd, hw]])
        outline(
            local @ np.array([[c, s], [-s, c]]) + box.center_xy_m,
            "true box",
            ec="k",
            lw=1.0,
            ls=":",
        )
    for o in obstacles:
        if o.complete:
            outline(o.corners_xy_m(), "measured (seen whole)", ec="r", lw=1.5)
        else:
            outline(o.corners_xy_m(), "seen in part (skipped)", ec="m", lw=1.2, ls="--")
            x, y = o.corners_xy_m().max(axis=0)
            ax.annotate(o.skip_reason, (x, y), fontsize="x-small", color="m")
    ax.plot([0], [0], "k^", ms=8, label="foot (stride origin)")
    ax.set_xlabel("x (m, walking direction)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize="small")
    ax.set_title(title)
    return _save(fig, path)


def plot_elevation(path: str | Path, grid: ElevationGrid, title: str = "elevation grid") -> Path:
    """Height (mm) and its standard deviation (mm) per cell; empty cells blank."""
    fig, (ax_h, ax_s) = _figure(2)
    x, y = grid.cell_centers_m()
    extent = (
        x[0] - grid.cell_m / 2,
        x[-1] + grid.cell_m / 2,
        y[0] - grid.cell_m / 2,
        y[-1] + grid.cell_m / 2,
    )
    for ax, data, label in (
        (ax_h, grid.height_m * 1000, "height (mm)"),
        (ax_s, np.sqrt(grid.variance_m2) * 1000, "std (mm)"),
    ):
        image = ax.imshow(data.T, origin="lower", extent=extent, cmap="viridis", aspect="equal")
        fig.colorbar(image, ax=ax, label=label, shrink=0.8)
        ax.set_xlabel("x (m, walking direction)")
        ax.set_ylabel("y (m)")
    fig.suptitle(title)
    return _save(fig, path)


def plot_obstacle_boxes(
    path: str | Path,
    measured_size_m: Mapping[str, Sequence[np.ndarray]],
    truth_size_m: Mapping[str, np.ndarray],
) -> Path:
    """Per box, every measurement of depth, width, height (mm) against the true value (line)."""
    names = sorted(measured_size_m)
    fig, axes = _figure(len(DIMENSIONS), width_in=4.0)
    for d, (ax, dim) in enumerate(zip(axes, DIMENSIONS, strict=True)):
        for b, name in enumerate(names):
            m = np.asarray(measured_size_m[name]).reshape(-1, 3)[:, d] * 1000
            ax.plot(np.full(m.size, b) + np.linspace(-0.15, 0.15, m.size), m, "o", ms=4, alpha=0.6)
            truth = float(np.asarray(truth_size_m[name])[d]) * 1000
            ax.hlines(truth, b - 0.3, b + 0.3, color="k", lw=2)
        ax.set_xticks(range(len(names)), names)
        ax.set_title(dim)
        ax.set_ylabel("mm")
        ax.grid(alpha=0.3)
    fig.suptitle("obstacle dimensions: measured (dots) vs ground truth (lines)")
    return _save(fig, path)


def plot_obstacle_known_vs_phase(
    path: str | Path,
    known_pct: Mapping[str, Mapping[str, Sequence[float]]],
    toe_off_pct: Mapping[str, float] | None = None,
    title: str = "obstacle known vs gait phase",
) -> Path:
    """``known_pct[speed][variant]``: per obstacle, the gait-cycle % at which the online map
    first knew it (NaN: never; it still counts in the fraction's denominator);
    ``toe_off_pct[speed]``: the mean toe-off, drawn as a dashed line. One panel per speed."""
    speeds = list(known_pct)
    fig, axes = _figure(max(1, len(speeds)), width_in=4.5, height_in=3.8)
    phase = np.linspace(0.0, 100.0, 201)
    for ax, speed in zip(axes, speeds, strict=False):
        if not any(len(p) for p in known_pct[speed].values()):
            ax.text(50, 0.5, "no obstacle measured whole", ha="center", va="center")
        for variant, pcts in known_pct[speed].items():
            p = np.asarray(pcts, dtype=float)
            if p.size == 0:
                ax.plot([], [], label=f"{variant} (n=0: no box whole in its final maps)")
                continue
            known = np.where(np.isfinite(p), p, np.inf)
            frac = (known[None, :] <= phase[:, None]).mean(axis=1)
            ax.step(phase, frac, where="post", label=f"{variant} (n={p.size})")
        toe = None if toe_off_pct is None else toe_off_pct.get(speed)
        if toe is not None and np.isfinite(toe):
            ax.axvline(toe, color="k", ls="--", lw=1, label=f"toe-off ({toe:.0f} %)")
        ax.set_xlim(0, 100)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("gait cycle (%; 0 = foot strike)")
        ax.set_ylabel("fraction of obstacles known")
        ax.set_title(f"{speed}")
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize="small", loc="lower right")
    fig.suptitle(title)
    return _save(fig, path)
