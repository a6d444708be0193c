"""Boxes on the online elevation grid, each dimension with a σ (stride frame, metres).

On demand from a :class:`graph_slam.terrain.grid.view.TerrainView`:

1. **Floor**: :func:`graph_slam.terrain.maps.obstacles.fit_floor` (the stride maps' RANSAC) on the
   known cells' centres at their heights; heights above it are cell heights minus the plane.
2. **Boxes**: 8-connected components of known cells at least ``min_height_m`` above the floor,
   with at least ``min_cells`` cells. The box's *height* is the median height of its top cells
   (those above ``top_fraction`` of its 90th-percentile height).
3. **Edges at sub-cell resolution**: a cell on a box's border holds top points over part of its
   area and floor points over the rest, so its height is about that fraction of the box's
   height. Per grid row (y) the leading edge is the nearest box cell's far bound minus that
   fraction of a cell (``f = clip(h / H, 0, 1)``); the box's leading edge is the median over its
   rows, its trailing edge likewise, and the width from the columns. ``leading_edge_x_m`` is
   along stride x from the heel; ``distance_m`` from the toe (``TerrainView.toe_x_m``).
4. **σ**: height, the top cells' median σ (pose errors do not average over cells); an edge, the
   border cells' height σ scaled to a position (``σ_h / H · cell``), with the quantisation
   (``cell / √12``) averaged over the rows; depth and width √2 times their edges'.
5. **Whole**: a box is *complete* when its footprint grown by ``margin_cells`` touches no
   unobserved cell connected to the grid's border (the area beyond the map: the box's shadow
   behind it is a hole, not beyond) and no other box, and its top fills at least
   ``min_fill_fraction`` of its bounding cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.terrain.maps.floor import FloorPlane, ObstacleConfig, fit_floor


class GridObstacleConfig(ConfigModel):
    min_height_m: float = Field(0.02, gt=0)
    min_cells: int = Field(6, ge=1)
    top_fraction: float = Field(0.7, gt=0, le=1)
    margin_cells: int = Field(2, ge=0)
    min_fill_fraction: float = Field(0.6, ge=0, le=1)
    ransac_iterations: int = Field(100, ge=1)


@dataclass(frozen=True, eq=False)
class GridObstacle:
    """A box on the grid (stride frame, metres; σ are 1-sigma)."""

    leading_edge_x_m: float
    leading_edge_sigma_m: float
    distance_m: float
    """Leading edge ahead of the toe."""
    height_m: float
    height_sigma_m: float
    depth_m: float
    depth_sigma_m: float
    width_m: float
    width_sigma_m: float
    center_xy_m: np.ndarray
    n_cells: int
    complete: bool
    skip_reason: str | None = None


@dataclass(frozen=True, eq=False)
class GridObstacleMap:
    floor: FloorPlane
    obstacles: tuple[GridObstacle, ...]
    """Nearest leading edge first."""

    @property
    def complete(self) -> tuple[GridObstacle, ...]:
        return tuple(o for o in self.obstacles if o.complete)


def _edges(h: np.ndarray, mask: np.ndarray, height: float, axis: int) -> tuple:
    """Per line along ``axis`` of the component: the near and far edge in cell units (the
    near edge of cell 0 is 0)."""
    m = mask if axis == 0 else mask.T
    hh = h if axis == 0 else h.T
    lines = np.flatnonzero(m.any(axis=0))
    first = np.argmax(m[:, lines], axis=0)
    last = m.shape[0] - 1 - np.argmax(m[::-1, lines], axis=0)
    f0 = np.clip(hh[first, lines] / height, 0, 1)
    f1 = np.clip(hh[last, lines] / height, 0, 1)
    return first + 1 - f0, last + f1


def grid_obstacles(
    view, config: GridObstacleConfig | None = None, *, complete_only: bool = False
) -> GridObstacleMap:
    """The floor and the boxes of a :class:`~graph_slam.terrain.grid.view.TerrainView` (see the
    module docstring). Raises :class:`~graph_slam.errors.MappingError` without a floor.
    ``complete_only``: leave out the boxes not seen whole before measuring them (the same
    whole boxes, in less time: most components of a grid touch its unobserved border)."""
    from scipy import ndimage

    cfg = config or GridObstacleConfig()
    known = view.known
    xc, yc = view.cell_centers_m()
    xx, yy = np.meshgrid(xc, yc, indexing="ij")
    pts = np.column_stack([xx[known], yy[known], view.height_m[known]])
    floor = fit_floor(pts, ObstacleConfig(ransac_iterations=cfg.ransac_iterations))
    above = np.full(view.shape, np.nan)
    n = floor.normal
    above[known] = (pts @ n + floor.offset_m) / n[2]  # vertical height over the plane
    occupied = known & (above >= cfg.min_height_m)
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3), bool))
    closed = ndimage.binary_closing(known, structure=np.ones((3, 3), bool))
    free, _ = ndimage.label(~closed)
    border = np.unique(np.concatenate([free[0], free[-1], free[:, 0], free[:, -1]]))
    beyond = np.isin(free, border[border > 0]) | ~np.pad(
        np.ones((view.shape[0] - 2, view.shape[1] - 2), bool), 1
    )
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    big = [k for k in range(1, count + 1) if sizes[k] >= cfg.min_cells]
    boxes = ndimage.find_objects(labels)
    pad = cfg.margin_cells
    found = []
    for k in big:
        # the component's bounding box grown by the margin (clipped at the grid): everything
        # below happens in that window (the dilation cannot leave it)
        sx, sy = boxes[k - 1]
        i0, j0 = max(sx.start - pad, 0), max(sy.start - pad, 0)
        win = (slice(i0, sx.stop + pad), slice(j0, sy.stop + pad))
        mask = labels[win] == k
        grown = ndimage.binary_dilation(mask, np.ones((3, 3), bool), iterations=pad)
        fill = int(sizes[k]) / ((sx.stop - sx.start) * (sy.stop - sy.start))
        reason = None
        if (grown & beyond[win]).any():
            reason = "edge_of_map"
        elif np.intersect1d(np.unique(labels[win][grown]), [b for b in big if b != k]).size:
            reason = "adjacent"
        elif fill < cfg.min_fill_fraction:
            reason = "top_incomplete"
        if reason is not None and complete_only:
            continue
        found.append(_measure(view, cfg, above[win], mask, (i0, j0), int(sizes[k]), reason))
    found.sort(key=lambda o: o.leading_edge_x_m)
    return GridObstacleMap(floor, tuple(found))


def _measure(view, cfg, above, mask, corner, n_cells: int, reason) -> GridObstacle:
    """One component's box (steps 2-4 of the module docstring); ``above``: heights over the
    floor in the component's window, ``mask`` the component there, ``corner`` the window's
    first cell (i, j)."""
    cell = view.cell_m
    i0, j0 = corner
    win = (slice(i0, i0 + mask.shape[0]), slice(j0, j0 + mask.shape[1]))
    hk = above[mask]
    top = hk >= cfg.top_fraction * np.quantile(hk, 0.9)
    height = float(np.median(hk[top]))
    h_sigma = float(np.median(view.sigma_m[win][mask][top]))
    h = np.where(mask, above, 0.0)
    near_x, far_x = _edges(h, mask, height, 0)
    near_y, far_y = _edges(h, mask, height, 1)
    x0, y0 = view.origin_xy_m
    lead = x0 + (i0 + float(np.median(near_x))) * cell
    trail = x0 + (i0 + float(np.median(far_x))) * cell
    right = y0 + (j0 + float(np.median(near_y))) * cell
    left = y0 + (j0 + float(np.median(far_y))) * cell
    edge_sigma = float(
        np.sqrt((h_sigma / max(height, 1e-6) * cell) ** 2 + cell**2 / 12 / max(len(near_x), 1))
    )
    return GridObstacle(
        leading_edge_x_m=lead,
        leading_edge_sigma_m=edge_sigma,
        distance_m=lead - view.toe_x_m,
        height_m=height,
        height_sigma_m=h_sigma,
        depth_m=trail - lead,
        depth_sigma_m=float(np.sqrt(2) * edge_sigma),
        width_m=left - right,
        width_sigma_m=float(np.sqrt(2) * edge_sigma),
        center_xy_m=np.array([(lead + trail) / 2, (left + right) / 2]),
        n_cells=n_cells,
        complete=reason is None,
        skip_reason=reason,
    )
