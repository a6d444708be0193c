"""Terrain features ahead of the foot from an elevation grid: stairs, ramps, curbs and boxes.

What a controller plans a swing with is a handful of numbers, each with its σ, in the stride
frame (x forward from the heel, y left, z up; metres, radians). :func:`extract_features` reads
them off any elevation grid (the online grid of a frame, :meth:`TerrainView.features_ahead
<graph_slam.terrain.grid.view.TerrainView.features_ahead>`, or a stride's re-fused grid):

1. **Local planes**: every known cell gets a least-squares plane over its
   ``window_cells``² neighbourhood (one compiled loop: the cell offsets' moments from
   summed-area tables, the heights' sums over the window): slope and RMS residual.
2. **Terraces**: 4-connected components of *level* cells (slope under ``level_max_deg``,
   residual under ``fit_rms_max_m``); the cells by a height jump are not level (a step inside
   the window leaves a residual of about a third of its rise), so every tread, the floor and a
   box top fall apart. A terrace's height is the inverse-variance mean of its cells; it then
   grows by up to ``grow_cells`` into the known cells within ``grow_tol_m`` of that height, so
   that it reaches its edges. A cell whose depth-noise σ exceeds ``max_noise_sigma_m`` (held
   only by a depth edge's flying pixels) belongs to no terrace.
3. **Edges across x**: along each grid row, two terraces met within ``max_gap_cells`` whose
   heights differ by at least ``min_rise_m``; the edge lies where the area between them says
   (a cell holding the far surface over a fraction f of its length is about f of the way
   between the two heights: ``x = x_end - cell · Σ f``). Cells not seen between them (the
   shadow behind a nosing seen from above, and beyond a drop the cells of flying pixels and
   optionally the far surface's cells seen only from a few late viewpoints,
   ``shadow_sparse_fraction``) are
   taken as the far surface and the edge put ``shadow_cell_seen`` of the way through the last
   near cell (±``shadow_cell_sigma`` cell, common to all rows). Per terrace pair, a line ``x = x̄ + b (y - ȳ)`` is
   fitted to the rows (3σ outliers rejected): position, yaw and their σ.
4. **Kinds**: a terrace entered by a rise and left by a drop to the same level (within
   ``box_same_level_m``) is a **box**; chains of edges through shared terraces with the same
   sign of rise are **stairs** (two or more edges), a single edge whose far terrace runs at
   least ``curb_min_depth_m`` on is a **curb** (followed across up to ``max_gap_cells`` + 1
   cells not seen into terraces at its height: beyond a drop the edge's own shadow); a single edge whose short far terrace is a
   tread (a further rise the same way within ``max_gap_cells`` past its end, in at least
   ``min_edge_rows`` rows) is a stair of one step seen; a single rise whose short top runs
   into cells not seen (its far side in the shadow or out of view) is a box seen in part
   (``BoxFeature.far_seen`` False: leading edge and height, the part of the top seen, no
   trailing edge); any other single edge is left out. The other edges between a box's top
   and its floor level are that box's.
   Components of cells sloped between ``ramp_min_deg`` and ``ramp_max_deg`` are **ramps**:
   one plane fitted to them (slope, uphill direction, σ from the fit and a pose tilt's: the
   change of the cells' pose part of σ per metre up the slope) and their start line, the
   plane's intersection with the terrace they are entered from (the one nearest the heel
   among those before them along x; none in view: no start line).

σ: a terrace height carries its cells' depth noise averaged and their pose part (correlated:
it does not average); a rise or a box height the two independent parts, the difference of
the pose parts (a common height offset cancels in a rise) and ``stride_tilt_sigma_rad`` over
the distance between where the two heights lie along x. An edge's σ is the spread of its rows' positions
or, when larger, their height noise scaled to a position (``σ_h / rise · cell`` per cell),
over √rows; seen face-on, ``face_cell_sigma`` × the face's share of its cell's points of a
cell (where the edge lies in its cell; common to the rows). Beyond a drop whose far cells next to it are sparsely seen (few points
against the near cells: seen only from late viewpoints) the edge also carries
``sparse_span_sigma`` of the span between the readings that take those cells as seen and
as not seen (``sparse_span_fraction``). A tread between two nosings whose shadow parts
both come from the counts takes their errors as correlated (``shadow_count_common``), and
drops what both share: the carry's shift of two carried nosings, and, both seen face-on,
where in their cells they lie (correlated by the tread's fraction of a cell). The horizontal error of the stride frame itself (the heel position, the pose's
yaw) is not in the grid and not in these σ (docs/terrain.md, *Limits*).
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, fields

import numpy as np


@dataclass(frozen=True)
class EdgeLine:
    """A straight edge on the ground: ``x = x_m - tan(yaw_rad) (y - y_m)``; ``yaw_rad`` is
    the direction of its normal (the way across it, from stride x towards y)."""

    x_m: float
    y_m: float
    """The point reported: at y = 0 (the foot's line) when the edge is seen there, else at the
    nearest end of the part seen."""
    yaw_rad: float
    sigma_m: float
    """1σ of the position along the normal at (x_m, y_m)."""
    yaw_sigma_rad: float
    y_range_m: tuple[float, float]
    rows: int
    occluded: bool = False
    """The surface just beyond the edge was not seen (a nosing from above)."""

    def x_at(self, y_m: float) -> float:
        return float(self.x_m - math.tan(self.yaw_rad) * (y_m - self.y_m))


@dataclass(frozen=True)
class Step:
    """One step of a flight: its nosing edge and rise (signed: + up along the walk)."""

    rise_m: float
    rise_sigma_m: float
    nosing: EdgeLine
    tread_m: float = float("nan")
    """Depth of the tread beyond this nosing, to the next one (NaN: the next is not seen)."""
    tread_sigma_m: float = float("nan")
    lower_height_m: float = float("nan")
    upper_height_m: float = float("nan")


@dataclass(frozen=True)
class Stairs:
    steps: tuple[Step, ...]

    @property
    def n_steps(self) -> int:
        return len(self.steps)

    @property
    def ascending(self) -> bool:
        return self.steps[0].rise_m > 0

    @property
    def near_x_m(self) -> float:
        return self.steps[0].nosing.x_m

    @property
    def far_x_m(self) -> float:
        return self.steps[-1].nosing.x_m


@dataclass(frozen=True)
class Curb:
    height_m: float
    """Signed: + up along the walk."""
    height_sigma_m: float
    edge: EdgeLine
    near_height_m: float = 0.0
    """The surface before the edge (stride z)."""

    @property
    def near_x_m(self) -> float:
        return self.edge.x_m

    far_x_m = near_x_m


@dataclass(frozen=True)
class Ramp:
    slope_rad: float
    slope_sigma_rad: float
    uphill_yaw_rad: float
    """Direction of steepest ascent, from stride x towards y."""
    uphill_yaw_sigma_rad: float
    start: EdgeLine | None
    """Where the slope begins from the surface the walk comes from (None: not seen)."""
    n_cells: int
    rms_m: float
    x_range_m: tuple[float, float]

    @property
    def near_x_m(self) -> float:
        return self.start.x_m if self.start is not None else self.x_range_m[0]

    @property
    def far_x_m(self) -> float:
        return self.x_range_m[1]


@dataclass(frozen=True)
class BoxFeature:
    """A box found by the features pass (leading and trailing edges across x)."""

    height_m: float
    height_sigma_m: float
    leading: EdgeLine
    depth_m: float
    depth_sigma_m: float
    floor_height_m: float = 0.0
    """The surface it stands on (stride z)."""
    far_seen: bool = True
    """False: a box seen in part, its top running into cells not seen yet (its far side in
    the shadow or out of view): ``depth_m`` is the part of the top seen (to the end of its
    last cell; ``depth_sigma_m`` NaN) and it has no trailing edge."""

    @property
    def near_x_m(self) -> float:
        return self.leading.x_m

    @property
    def far_x_m(self) -> float:
        return self.leading.x_m + self.depth_m


KINDS = ("stairs", "ramps", "curbs", "boxes")


@dataclass(frozen=True)
class TerrainFeatures:
    """Every feature of one grid (stride frame). ``source``: ``online`` or ``smoothed``."""

    stride_index: int = -1
    t_s: float = float("nan")
    source: str = "online"
    stairs: tuple[Stairs, ...] = ()
    ramps: tuple[Ramp, ...] = ()
    curbs: tuple[Curb, ...] = ()
    boxes: tuple[BoxFeature, ...] = ()
    error: str | None = None

    def ahead(self, min_x_m: float) -> TerrainFeatures:
        """The features that reach beyond ``min_x_m`` (e.g. the toe)."""
        keep = {k: tuple(f for f in getattr(self, k) if f.far_x_m >= min_x_m) for k in KINDS}
        return TerrainFeatures(self.stride_index, self.t_s, self.source, error=self.error, **keep)

    def summary(self, toe_x_m: float = 0.0) -> str:
        """The nearest feature in words, distances from ``toe_x_m`` (cm), e.g.
        ``stairs 3 steps: next +16.8±0.2 cm, 41.0±0.4 cm ahead``; ``""`` when none."""
        near = []
        for st in self.stairs:
            ahead = [s for s in st.steps if s.nosing.x_m >= toe_x_m]
            s = ahead[0] if ahead else st.steps[-1]
            near.append((s.nosing.x_m, f"stairs {st.n_steps} step(s): next {s.rise_m * 100:+.1f}"
                         f"±{s.rise_sigma_m * 100:.1f} cm, {(s.nosing.x_m - toe_x_m) * 100:.1f}"
                         f"±{s.nosing.sigma_m * 100:.1f} cm ahead"))  # fmt: skip
        for c in self.curbs:
            near.append((c.edge.x_m, f"curb {c.height_m * 100:+.1f}±{c.height_sigma_m * 100:.1f}"
                         f" cm, {(c.edge.x_m - toe_x_m) * 100:.1f} cm ahead"))  # fmt: skip
        for r in self.ramps:
            near.append((r.near_x_m, f"ramp {math.degrees(r.slope_rad):.1f}"
                         f"±{math.degrees(r.slope_sigma_rad):.1f}°, from "
                         f"{(r.near_x_m - toe_x_m) * 100:.1f} cm ahead"))  # fmt: skip
        if not near:
            return ""
        return min(near)[1]

    def count(self) -> int:
        return sum(len(getattr(self, k)) for k in KINDS)

    def to_dict(self) -> dict:
        return _plain(self)

    @staticmethod
    def from_dict(d: dict) -> TerrainFeatures:
        return TerrainFeatures(
            stride_index=int(d["stride_index"]),
            t_s=_num(d["t_s"]),
            source=str(d["source"]),
            stairs=tuple(
                Stairs(tuple(_build(Step, s, nosing=EdgeLine) for s in x["steps"]))
                for x in d["stairs"]
            ),
            ramps=tuple(_build(Ramp, x, start=EdgeLine) for x in d["ramps"]),
            curbs=tuple(_build(Curb, x, edge=EdgeLine) for x in d["curbs"]),
            boxes=tuple(_build(BoxFeature, x, leading=EdgeLine) for x in d["boxes"]),
            error=d.get("error"),
        )


def _num(v):
    return float("nan") if v is None else float(v)


def _plain(obj):
    """Dataclasses, tuples and floats as JSON values (NaN as None)."""
    if hasattr(obj, "__dataclass_fields__"):
        return {f.name: _plain(getattr(obj, f.name)) for f in fields(obj)}
    if isinstance(obj, (tuple, list)):
        return [_plain(x) for x in obj]
    if isinstance(obj, (float, np.floating)):
        return None if not math.isfinite(obj) else float(obj)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    return obj


def _build(cls, d: dict, **nested):
    kwargs = {}
    for f in fields(cls):
        if f.name not in d and f.default is not MISSING:
            continue  # a field added since the document was written: its default
        v = d[f.name]
        if f.name in nested:
            v = None if v is None else _build(nested[f.name], v)
        elif f.name in {"y_range_m", "x_range_m"}:
            v = (_num(v[0]), _num(v[1]))
        elif f.type in ("float", float):
            v = _num(v)
        kwargs[f.name] = v
    return cls(**kwargs)


@dataclass
class _Grid:
    """The arrays the extraction works on (axis 0 x, axis 1 y)."""

    h: np.ndarray
    var: np.ndarray
    corr: np.ndarray
    x0: float
    y0: float
    cell: float
    noisy: np.ndarray | None = None
    """Cells held only by a depth edge's flying pixels (None: none): on no surface, and not
    seen beyond a drop."""
    count: np.ndarray | None = None
    """Points per cell (None: unknown); where a shadow begins inside the last cell seen."""
    known: np.ndarray | None = None
    """Cells with a finite height and variance that are not noisy (None: from those)."""

    def __post_init__(self) -> None:
        if self.noisy is None:
            self.noisy = np.zeros(self.h.shape, dtype=bool)
        if self.known is None:
            self.known = np.isfinite(self.h) & np.isfinite(self.var) & ~self.noisy

    def x_of(self, i):
        return self.x0 + (np.asarray(i) + 0.5) * self.cell

    def y_of(self, j):
        return self.y0 + (np.asarray(j) + 0.5) * self.cell
