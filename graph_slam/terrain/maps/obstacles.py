"""Obstacles from a stride map: the floor plane, then the boxes standing on it.

Steps:

1.-2. **Floor** and **floor frame**: :func:`~graph_slam.terrain.maps.floor.fit_floor`
   (:mod:`graph_slam.terrain.maps.floor`); heights are distances above the floor.
3. **Boxes**: points higher than ``min_height_m`` are binned on an x–y grid; 8-connected
   components of occupied cells with at least ``min_cells`` cells are obstacles. Components
   joined across gaps of ``join_gap_cells`` empty cells form a *group*: the small pieces of an
   obstacle's group (a top seen thinly from afar) are not measured but count in its
   completeness check (5).
4. **Dimensions** (thesis Table 3.1 order): *depth* along the box's own axis nearest the
   walking direction x, *width* across it, *height* the top surface above the floor. The *top
   layer* is the component's points within ``top_band_m`` of its top (a high quantile), narrowed
   to 3 robust sigmas (MAD), at least ``top_layer_min_m``, of their height about its median; the
   height is their median height, the footprint is theirs (side faces seen edge-on smear an edge
   by the depth noise, the top face does not). The footprint's yaw is the one whose rectangle
   (between the ``extent_trim_fraction`` and ``1 - extent_trim_fraction`` quantiles along the
   rotated axes) has the least area, searched over [-45°, 45°); a box yawed against the walking
   direction is measured along its own sides, not by its bounding extents.
   ``leading_edge_x_m`` is the x of the rectangle's corner nearest the foot (its near edge when
   the box is square to the walk), the distance of the leading edge ahead of the foot.
5. **Completeness**: a stride map often holds only part of a box (entering the view, cut by the
   field of view or the depth range, or seen in pieces). On a coverage grid (``coverage_cell_m``)
   the observed cells are those holding any map point; the unobserved cells connected to the
   grid's border after a closing are the area *beyond the map* (holes inside it, such as a box's
   shadow seen past, are not). A box is *complete* when its footprint grown by
   ``edge_margin_m`` stays clear of that area and of other obstacles, its top face fills at
   least ``min_top_fill_fraction`` of its rectangle and no more than
   ``max_beyond_top_fraction`` of its points lie beyond it (side faces reaching past a top seen
   in part), and floor was seen in at least
   ``min_floor_seen_fraction`` of the margin ring. Otherwise ``Obstacle.skip_reason`` names the
   first failed check (:data:`SKIP_REASONS`): the box is still returned, but its dimensions are
   those of the part seen and must not be taken as the box's.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from graph_slam.terrain.maps.floor import FloorPlane, ObstacleConfig, fit_floor

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A box above the floor, in the floor frame (metres)."""

    depth_m: float
    """Extent along x, the walking direction."""
    width_m: float
    """Extent along y."""
    height_m: float
    """Top surface above the floor."""
    leading_edge_x_m: float
    """Distance of the edge nearest the foot, along x, from the foot (stride origin)."""
    center_xy_m: np.ndarray
    point_count: int
    yaw_rad: float = 0.0
    """Angle of the box's depth axis from floor x, in [-π/4, π/4); depth and width are
    measured along the box's own axes."""
    skip_reason: str | None = None
    """None when the box was seen whole; else one of :data:`SKIP_REASONS`."""
    skip_detail: str = ""
    floor_seen_fraction: float = float("nan")
    top_fill_fraction: float = float("nan")

    @property
    def complete(self) -> bool:
        """Seen whole: its dimensions are measurements of the box, not of a part of it."""
        return self.skip_reason is None

    @property
    def size_m(self) -> np.ndarray:
        """(depth, width, height), the order of ``SceneObject.size_m`` and Table 3.1."""
        return np.array([self.depth_m, self.width_m, self.height_m])

    def corners_xy_m(self) -> np.ndarray:
        """The measured footprint's four corners (4×2, floor frame), counter-clockwise."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [self.depth_m / 2, self.width_m / 2]
        return half @ np.array([[c, s], [-s, c]]) + self.center_xy_m


SKIP_REASONS = {
    "edge_of_map": "outline within edge_margin_m of the unobserved area around the map "
    "(cut by the field of view or the depth range)",
    "adjacent": "another obstacle within edge_margin_m (touching boxes, or one box in pieces)",
    "top_incomplete": "top face seen in part: more than max_beyond_top_fraction of its points "
    "beyond the top's rectangle, or the top fills less than min_top_fill_fraction of it",
    "floor_not_seen": "floor seen in less than min_floor_seen_fraction of the ring around it",
}
"""Why a box is not measured, in the order the checks run (the first that fails is given)."""


@dataclass(frozen=True, eq=False)
class Coverage:
    """Which cells of the floor plane (floor frame x–y) the map observed.

    ``observed``: cells holding any map point. ``outside``: unobserved cells connected to the
    grid's border after a morphological closing of ``observed``, i.e. the area beyond the map
    (outside the field of view or the depth range); holes inside the map, such as the shadow
    behind a box seen again beyond it, are not outside.
    """

    observed: np.ndarray
    outside: np.ndarray
    origin_xy_m: np.ndarray
    """(x, y) of the corner of cell (0, 0)."""
    cell_m: float

    def cells_of(self, xy_m: np.ndarray) -> np.ndarray:
        """Cell indices (N×2) of points on the grid (callers pass points of the map)."""
        ij = np.floor((np.asarray(xy_m, dtype=np.float64) - self.origin_xy_m) / self.cell_m)
        return np.clip(ij.astype(np.int64), 0, np.array(self.observed.shape) - 1)

    def is_outside(self, xy_m: np.ndarray) -> np.ndarray:
        """True for points beyond the mapped area (off the grid counts as beyond)."""
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        ij = np.floor((xy - self.origin_xy_m) / self.cell_m).astype(np.int64)
        on = (ij >= 0).all(axis=1) & (ij < np.array(self.observed.shape)).all(axis=1)
        out = np.ones(len(xy), dtype=bool)
        out[on] = self.outside[ij[on, 0], ij[on, 1]]
        return out


@dataclass(frozen=True, eq=False)
class ObstacleMap:
    floor: FloorPlane
    obstacles: tuple[Obstacle, ...]
    """Every box found, complete or not, sorted by ``leading_edge_x_m`` (nearest first)."""
    coverage: Coverage | None = None

    @property
    def complete(self) -> tuple[Obstacle, ...]:
        """The boxes seen whole (the ones to measure)."""
        return tuple(o for o in self.obstacles if o.complete)


def _coverage(xy_m: np.ndarray, cfg: ObstacleConfig) -> Coverage:
    """Observed cells of the map (any point) and the unobserved area beyond it."""
    from scipy import ndimage

    cell = cfg.coverage_cell_m
    pad = 2 + cfg.coverage_closing_cells
    origin = xy_m.min(axis=0) - pad * cell
    ij = np.floor((xy_m - origin) / cell).astype(np.int64)
    observed = np.zeros(ij.max(axis=0) + 1 + pad, dtype=bool)
    observed[ij[:, 0], ij[:, 1]] = True
    closed = observed
    if cfg.coverage_closing_cells:
        closed = ndimage.binary_closing(
            observed, structure=np.ones((3, 3), bool), iterations=cfg.coverage_closing_cells
        )
    labels, _ = ndimage.label(~closed)  # 4-connected unobserved regions
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    outside = np.isin(labels, border[border > 0])
    return Coverage(observed=observed, outside=outside, origin_xy_m=origin, cell_m=cell)


def _oriented_extents(
    xy_m: np.ndarray, trim: float
) -> tuple[float, tuple[float, float], tuple[float, float]]:
    """Yaw in [-45°, 45°) of the rectangle of least (trimmed) area around ``xy_m``, and its
    extents along the rotated x (u) and y (v) axes."""
    step = max(1, len(xy_m) // 4000)
    sample = xy_m[::step]

    def extents(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, s = np.cos(angles), np.sin(angles)
        u = sample[:, :1] * c + sample[:, 1:] * s
        v = -sample[:, :1] * s + sample[:, 1:] * c
        qu = np.quantile(u, [trim, 1 - trim], axis=0)
        qv = np.quantile(v, [trim, 1 - trim], axis=0)
        return qu[1] - qu[0], qv[1] - qv[0]

    coarse = np.deg2rad(np.arange(-45.0, 45.0, 1.0))
    du, dv = extents(coarse)
    best = coarse[np.argmin(du * dv)]
    fine = best + np.deg2rad(np.arange(-1.0, 1.0 + 1e-9, 0.05))
    du, dv = extents(fine)
    yaw = float((fine[np.argmin(du * dv)] + np.pi / 4) % (np.pi / 2) - np.pi / 4)
    c, s = np.cos(yaw), np.sin(yaw)
    u = xy_m[:, 0] * c + xy_m[:, 1] * s
    v = -xy_m[:, 0] * s + xy_m[:, 1] * c
    u0, u1 = np.quantile(u, [trim, 1 - trim])
    v0, v1 = np.quantile(v, [trim, 1 - trim])
    return yaw, (float(u0), float(u1)), (float(v0), float(v1))


def _top_layer(q: np.ndarray, cfg: ObstacleConfig) -> np.ndarray:
    """The component's points on its top face (see the module docstring)."""
    top = q[q[:, 2] >= np.quantile(q[:, 2], 1 - cfg.extent_trim_fraction) - cfg.top_band_m]
    top_m = np.median(top[:, 2])
    sigma = 1.4826 * float(np.median(np.abs(top[:, 2] - top_m)))
    return top[np.abs(top[:, 2] - top_m) <= max(3 * sigma, cfg.top_layer_min_m)]


def _top_fill(top_xy_m: np.ndarray, yaw: float, u: tuple, v: tuple, cell_m: float) -> float:
    """Fraction of the measured rectangle's cells that hold a top-face point."""
    c, s = np.cos(yaw), np.sin(yaw)
    pu = top_xy_m[:, 0] * c + top_xy_m[:, 1] * s - u[0]
    pv = -top_xy_m[:, 0] * s + top_xy_m[:, 1] * c - v[0]
    nu = max(1, int((u[1] - u[0]) / cell_m))
    nv = max(1, int((v[1] - v[0]) / cell_m))
    iu, iv = np.floor(pu / cell_m).astype(np.int64), np.floor(pv / cell_m).astype(np.int64)
    keep = (iu >= 0) & (iu < nu) & (iv >= 0) & (iv < nv)
    filled = np.zeros((nu, nv), dtype=bool)
    filled[iu[keep], iv[keep]] = True
    return float(filled.mean())


def extract_obstacles(
    points_stride_m: np.ndarray, config: ObstacleConfig | None = None
) -> ObstacleMap:
    """Fit the floor, measure every box above it and judge whether it was seen whole.

    See the module docstring for the steps. Every box is returned; those seen only in part
    carry a ``skip_reason`` (``Obstacle.complete`` is False).
    """
    from scipy import ndimage

    cfg = config or ObstacleConfig()
    floor = fit_floor(points_stride_m, cfg)
    points = np.asarray(points_stride_m, dtype=np.float64)
    floor_T_stride = floor.floor_T_stride()
    p = points @ floor_T_stride[:3, :3].T + floor_T_stride[:3, 3]
    coverage = _coverage(p[:, :2], cfg)
    above = p[p[:, 2] >= cfg.min_height_m]
    if len(above) == 0:
        return ObstacleMap(floor, (), coverage)
    lo = above[:, :2].min(axis=0)
    ij = np.floor((above[:, :2] - lo) / cfg.cell_m).astype(np.int64)
    occupied = np.zeros(ij.max(axis=0) + 1 + cfg.join_gap_cells, dtype=bool)
    occupied[ij[:, 0], ij[:, 1]] = True
    labels, n = ndimage.label(occupied, structure=np.ones((3, 3), dtype=bool))
    point_label = labels[ij[:, 0], ij[:, 1]]
    cells = np.bincount(labels.ravel(), minlength=n + 1)
    components = [k for k in range(1, n + 1) if cells[k] >= cfg.min_cells]
    small = n - len(components)
    # Groups: components joined across gaps of join_gap_cells. A box's dense part is measured,
    # but the sparse pieces of its group (a top seen thinly from afar) count against it.
    group_point = point_label
    if cfg.join_gap_cells:
        joined = ndimage.binary_dilation(
            occupied, structure=np.ones((3, 3), bool), iterations=cfg.join_gap_cells
        )
        groups, _ = ndimage.label(joined, structure=np.ones((3, 3), dtype=bool))
        group_point = groups[ij[:, 0], ij[:, 1]]
    big = np.isin(point_label, components)
    # Each component's footprint on the coverage grid (for the completeness checks).
    cov_label = np.zeros(coverage.observed.shape, dtype=np.int64)
    footprints = {}
    for k in components:
        cij = coverage.cells_of(above[point_label == k, :2])
        footprint = np.zeros(coverage.observed.shape, dtype=bool)
        footprint[cij[:, 0], cij[:, 1]] = True
        footprints[k] = footprint
        cov_label[footprint] = k
    margin_cells = max(1, int(np.ceil(cfg.edge_margin_m / coverage.cell_m)))
    obstacles = []
    for k in components:
        q = above[point_label == k]
        top = _top_layer(q, cfg)
        trim = cfg.extent_trim_fraction
        yaw, (u0, u1), (v0, v1) = _oriented_extents(top[:, :2], trim)
        c, s = np.cos(yaw), np.sin(yaw)
        centre_uv = np.array([(u0 + u1) / 2, (v0 + v1) / 2])
        centre = np.array([[c, -s], [s, c]]) @ centre_uv
        footprint = footprints[k]
        grown = ndimage.binary_dilation(
            footprint, structure=np.ones((3, 3), bool), iterations=margin_cells
        )
        ring = grown & ~footprint
        neighbours = np.setdiff1d(np.unique(cov_label[ring]), [0, k])
        floor_ring = ring & (cov_label == 0)
        floor_seen = float((floor_ring & coverage.observed).sum() / max(1, floor_ring.sum()))
        fill = _top_fill(top[:, :2], yaw, (u0, u1), (v0, v1), coverage.cell_m)
        # this component and the small pieces of its group (not other obstacles)
        mine = (point_label == k) | (~big & (group_point == group_point[point_label == k][0]))
        g = above[mine]
        qu = g[:, 0] * c + g[:, 1] * s - centre_uv[0]
        qv = -g[:, 0] * s + g[:, 1] * c - centre_uv[1]
        margin = cfg.beyond_top_margin_m
        beyond = float(
            np.mean((np.abs(qu) > (u1 - u0) / 2 + margin) | (np.abs(qv) > (v1 - v0) / 2 + margin))
        )
        reason, detail = None, ""
        if (grown & coverage.outside).any():
            reason = "edge_of_map"
            detail = (
                f"its outline comes within {cfg.edge_margin_m * 100:.0f} cm of the unobserved "
                "area around the map"
            )
        elif neighbours.size:
            reason = "adjacent"
            detail = (
                f"{neighbours.size} other obstacle(s) within {cfg.edge_margin_m * 100:.0f} cm "
                "(touching boxes, or one box seen in pieces)"
            )
        elif beyond > cfg.max_beyond_top_fraction:
            reason = "top_incomplete"
            detail = (
                f"{beyond:.0%} of its points lie more than {margin * 100:.0f} cm outside its top "
                f"face (> {cfg.max_beyond_top_fraction:.0%}): the top was seen in part"
            )
        elif fill < cfg.min_top_fill_fraction:
            reason = "top_incomplete"
            detail = (
                f"top face covers {fill:.0%} of its rectangle (< {cfg.min_top_fill_fraction:.0%})"
            )
        elif floor_seen < cfg.min_floor_seen_fraction:
            reason = "floor_not_seen"
            detail = (
                f"floor seen in {floor_seen:.0%} of the ring around it "
                f"(< {cfg.min_floor_seen_fraction:.0%})"
            )
        obstacles.append(
            Obstacle(
                depth_m=u1 - u0,
                width_m=v1 - v0,
                height_m=float(np.median(top[:, 2])),
                # the rectangle's corner nearest the foot along x (its near edge when yaw = 0)
                leading_edge_x_m=float(centre[0] - abs(c) * (u1 - u0) / 2 - abs(s) * (v1 - v0) / 2),
                center_xy_m=centre,
                point_count=len(q),
                yaw_rad=yaw,
                skip_reason=reason,
                skip_detail=detail,
                floor_seen_fraction=floor_seen,
                top_fill_fraction=fill,
            )
        )
    if small:
        log.debug(
            "extract_obstacles: %d components below min_cells=%d ignored", small, cfg.min_cells
        )
    obstacles.sort(key=lambda o: o.leading_edge_x_m)
    return ObstacleMap(floor, tuple(obstacles), coverage)
