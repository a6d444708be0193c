"""Where the prosthetic foot lands on the terrain, and what each stride walks over.

The surface along the walking line (y = 0) is cut into planar segments (a height jump above
:data:`graph_slam.sim.surface.EDGE_JUMP_M` or a change of slope ends a segment). A foothold is
a heel position whose whole flat foot (heel to toe, :class:`LegParams` foot length) lies on
one segment with a margin, so a stance foot never straddles a riser, a box edge or a ramp's
kink. The planner walks forward at the speed's stride length and adapts:

* a flight of stairs (treads shorter than 0.5 m) is taken step over step: the foot lands on
  every second tread, the first one being the 1st or 2nd tread so that the approach stride is
  plausible (≤ 1 m); going down, the heel lands 6 cm onto the tread and the toe overhangs
  the nosing (the one exception to the whole foot on one segment);
* an obstacle too small to stand on is stepped over by the prosthetic foot: the stride before
  it ends with the toe 0.30 m before the obstacle, the next one lands 0.25 m after it;
* a box marked ``step_on`` is stepped onto when it is in reach;
* otherwise the foot lands at the valid position nearest the nominal stride.

Each stride (a strike to the next) gets a terrain label: ``level``, ``stairs_up``,
``stairs_down``, ``ramp_up``, ``ramp_down``, ``curb_up``, ``curb_down`` (also stepping off a
box), ``step_over`` or ``step_onto``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import SimulationError
from graph_slam.sim.surface import EDGE_JUMP_M, Surfaces

TERRAIN_LABELS = (
    "level", "stairs_up", "stairs_down", "ramp_up", "ramp_down",
    "curb_up", "curb_down", "step_over", "step_onto",
)  # fmt: skip

_TREAD_MAX_M = 0.5
_MARGIN_M = 0.02
_RISER_GAP_M = 0.10  # the toe stays this far back from a riser or a drop ahead
_DROP_GAP_M = 0.25
_EDGE_MID_M = 0.35
_DESCENT_HEEL_M = 0.06  # going down a flight the heel lands this far onto the tread  # a curb's edge this far from the toe before it and the heel after it  # the heel lands this far beyond a drop (a curb's or a box's edge)
_SLOPE_EPS = 1e-3  # tan of ~0.06°


@dataclass(frozen=True)
class Segment:
    """A planar piece of the walking line: x in [x0, x1], z = z0 + (x - x0)·tan(slope)."""

    x0_m: float
    x1_m: float
    z0_m: float
    slope_tan: float
    feature: tuple[str, str, str]  # (name, kind, role) of Surfaces.feature_at

    @property
    def length_m(self) -> float:
        return self.x1_m - self.x0_m

    def z_at(self, x_m):
        return self.z0_m + (np.asarray(x_m) - self.x0_m) * self.slope_tan

    @property
    def is_tread(self) -> bool:
        return self.feature[1] == "stairs" and self.length_m < _TREAD_MAX_M


@dataclass(frozen=True)
class Foothold:
    """A planned stance: the flat foot's heel point (world x, z), surface slope, segment."""

    heel_x_m: float
    heel_z_m: float
    slope_rad: float
    segment: int


def segments(surfaces: Surfaces, x0_m: float, x1_m: float, y_m: float = 0.0) -> list[Segment]:
    """The walking line's planar segments between ``x0_m`` and ``x1_m``."""
    step = 0.001
    x, z = surfaces.profile(x0_m, x1_m, y_m, step)
    dz = np.diff(z)
    jump = np.abs(dz) > EDGE_JUMP_M
    slope = np.where(jump, np.nan, dz / step)
    cuts = [0]
    for i in range(1, dz.size):
        if jump[i] or jump[i - 1]:
            if jump[i]:
                cuts.append(i + 1)
            continue
        if abs(slope[i] - slope[i - 1]) > _SLOPE_EPS * 10 and cuts[-1] != i:
            cuts.append(i)
    cuts.append(x.size)
    out = []
    for a, b in itertools.pairwise(cuts):
        if b - a < 3:
            continue
        xs, zs = x[a:b], z[a:b]
        tan = float((zs[-1] - zs[0]) / (xs[-1] - xs[0]))
        mid = 0.5 * (xs[0] + xs[-1])
        out.append(Segment(float(xs[0]), float(xs[-1]), float(zs[0]), tan,
                           surfaces.feature_at(mid, y_m)))  # fmt: skip
    return out


class FootholdPlanner:
    """Plans the prosthetic foot's footholds along the walking line (see the module text)."""

    def __init__(self, surfaces: Surfaces, foot_length_m: float, stride_m: float) -> None:
        self.surfaces = surfaces
        self.foot_m = float(foot_length_m)
        self.stride_m = float(stride_m)
        self.segs: list[Segment] = []

    def plan(self, n: int, x_first_m: float = 0.0) -> list[Foothold]:
        """``n`` footholds; the first at ``-stride`` before ``x_first_m``, the second at it."""
        span = (n + 2) * 1.6 * self.stride_m + 5.0
        self.segs = segments(self.surfaces, x_first_m - self.stride_m - 2.0, x_first_m + span)
        first = [self._snap(x_first_m - self.stride_m), self._snap(x_first_m)]
        for x in first:
            if x is None:
                raise SimulationError(
                    f"the walk's start (x {x_first_m - self.stride_m:.2f}..{x_first_m:.2f} m) "
                    "has no flat place for the foot"
                )
        out = [self._foothold(x) for x in first]
        while len(out) < n:
            out.append(self._foothold(self._next(out[-1])))
        return out[:n]

    # ------------------------------------------------------------ helpers
    def _seg_index(self, x: float) -> int:
        for i, s in enumerate(self.segs):
            if s.x0_m <= x <= s.x1_m:
                return i
        raise SimulationError(f"x = {x:.3f} m is outside the planned walking line")

    def _range(self, seg: Segment) -> tuple[float, float] | None:
        """Valid heel x range on a segment (the flat foot on it with a margin; on a long
        segment the toe stays ``_RISER_GAP_M`` back from a riser or edge ahead)."""
        foot_dx = self.foot_m * math.cos(math.atan(seg.slope_tan))
        margin = min(_MARGIN_M, (seg.length_m - foot_dx) / 2)
        if margin < 0.004:
            return None
        start = end = margin
        i = self.segs.index(seg) if seg in self.segs else -1
        if i >= 0 and not seg.is_tread:
            room = seg.length_m - foot_dx - margin
            if i < len(self.segs) - 1:
                nxt = self.segs[i + 1]
                if abs(nxt.z0_m - float(seg.z_at(seg.x1_m))) > EDGE_JUMP_M:
                    end = max(margin, min(_RISER_GAP_M, room))
            if i > 0:
                prev = self.segs[i - 1]
                if float(prev.z_at(prev.x1_m)) > seg.z0_m + EDGE_JUMP_M:  # below a drop
                    start = max(margin, min(_DROP_GAP_M, room - end + margin))
        if seg.x0_m + start > seg.x1_m - end - foot_dx + 1e-9:
            return None
        return seg.x0_m + start, seg.x1_m - end - foot_dx

    def _snap(self, x: float) -> float | None:
        """The valid heel position nearest ``x``."""
        best = None
        for seg in self.segs:
            r = self._range(seg)
            if r is None:
                continue
            c = min(max(x, r[0]), r[1])
            if best is None or abs(c - x) < abs(best - x):
                best = c
        return best

    def _foothold(self, x: float) -> Foothold:
        i = self._seg_index(x)
        s = self.segs[i]
        return Foothold(x, float(s.z_at(x)), math.atan(s.slope_tan), i)

    def _next(self, f: Foothold) -> float:
        L = self.stride_m
        segs = self.segs
        cur = segs[f.segment]
        if cur.slope_tan != 0.0 or any(
            s.slope_tan != 0.0 for s in segs[f.segment + 1 : f.segment + 3]
        ):
            L *= 0.92  # shorter strides on ramps
        x = f.heel_x_m
        ahead = [i for i in range(f.segment + 1, len(segs)) if segs[i].x0_m < x + 1.4 * L]
        # Stairs: every second tread.
        if cur.is_tread or any(segs[i].is_tread for i in ahead):
            return self._stairs_next(f, L)
        # An obstacle to step over (a raised segment too short for the foot, not a tread).
        for i in ahead:
            s, before = segs[i], segs[i - 1]
            jump = abs(s.z0_m - float(before.z_at(before.x1_m))) > EDGE_JUMP_M
            if jump and self._range(s) is not None and s.feature[2] != "step_on":
                # a curb (up or down): the edge in the middle of the prosthetic foot's swing
                land = self._snap(s.x0_m + _EDGE_MID_M)
                if land is not None and 0.5 * L <= land - x <= 1.25 * L and land > s.x0_m:
                    return land
                pre = s.x0_m - _EDGE_MID_M - self.foot_m
                if pre - x >= 0.45 * L:
                    return self._checked(f, min(pre, x + L))
            if self._range(s) is None and s.z0_m > cur.z_at(s.x0_m) + EDGE_JUMP_M:
                land = self._snap(s.x1_m + _EDGE_MID_M)
                if land is not None and land - x <= 1.25 * L:
                    return land
                pre = s.x0_m - _EDGE_MID_M - self.foot_m
                return self._checked(f, max(pre, x + 0.45 * L) if pre > x + 0.3 else x + L)
            if s.feature[2] == "step_on" and self._range(s) is not None:
                land = self._range(s)[0] + 0.03
                if 0.45 * L <= land - x <= 1.2 * L:
                    return land
                if land - x > 1.2 * L:
                    return self._checked(f, max(x + 0.45 * L, land - 0.85 * L))
        return self._checked(f, x + L)

    def _stairs_next(self, f: Foothold, L: float) -> float:
        segs = self.segs
        cur = segs[f.segment]
        x = f.heel_x_m
        if cur.is_tread:
            nxt = segs[f.segment + 2] if f.segment + 2 < len(segs) else None
            if nxt is not None and nxt.is_tread:
                if nxt.z0_m < cur.z0_m:  # going down: the toe overhangs the nosing
                    return nxt.x0_m + _DESCENT_HEEL_M
                return self._range(nxt)[0]
            one = segs[f.segment + 1]
            run = cur.length_m
            down = one.z0_m < cur.z0_m  # off the flight's foot: beyond the drop gap
            if one.is_tread:  # two treads ahead is the landing (or the floor)
                return self._checked(f, one.x1_m + _MARGIN_M, exact=not down)
            return self._checked(f, one.x0_m + run + _MARGIN_M, exact=not down)
        first = next(i for i in range(f.segment + 1, len(segs)) if segs[i].is_tread)
        t1 = self._range(segs[first])[0]
        t2 = self._range(segs[first + 1])[0] if segs[first + 1].is_tread else None
        if segs[first].z0_m < cur.z0_m:  # a flight down: land on its 2nd tread
            t2 = segs[first + 1].x0_m + _DESCENT_HEEL_M if segs[first + 1].is_tread else None
            t1 = segs[first].x0_m + _DESCENT_HEEL_M
        if t2 is not None and 0.45 <= t2 - x <= 1.0:
            return t2
        if 0.45 <= t1 - x <= 1.0:
            return t1
        if t2 is not None and t2 - x > 1.0:  # approach: land 0.7 m before the 2nd tread
            target = max(t2 - 0.7, x + 0.45 * L)
            target = min(target, segs[first].x0_m - self.foot_m - 0.05)
            return self._checked(f, target)
        raise SimulationError(f"no foothold on the stairs from x = {x:.2f} m")

    def _checked(self, f: Foothold, x: float, exact: bool = False) -> float:
        snapped = self._snap(x)
        if snapped is None or (exact and abs(snapped - x) > 0.05) or snapped <= f.heel_x_m + 0.2:
            raise SimulationError(
                f"no place for the foot near x = {x:.2f} m (after the foothold at "
                f"{f.heel_x_m:.2f} m): the scene's layout leaves no flat spot"
            )
        return snapped


def stride_label(a: Foothold, b: Foothold, segs: list[Segment]) -> str:
    """The terrain label of the stride from foothold ``a`` to foothold ``b``."""
    sa, sb = segs[a.segment], segs[b.segment]
    dz = b.heel_z_m - a.heel_z_m
    if abs(a.slope_rad) > 1e-3 or abs(b.slope_rad) > 1e-3:
        return "ramp_up" if a.slope_rad + b.slope_rad > 0 else "ramp_down"
    if sa.is_tread or sb.is_tread:
        if dz > EDGE_JUMP_M:
            return "stairs_up"
        if dz < -EDGE_JUMP_M:
            return "stairs_down"
    if dz > EDGE_JUMP_M:
        return "step_onto" if sb.feature[2] == "step_on" else "curb_up"
    if dz < -EDGE_JUMP_M:
        return "curb_down"
    between = segs[a.segment + 1 : b.segment]
    if any(s.z0_m > a.heel_z_m + EDGE_JUMP_M for s in between):
        return "step_over"
    return "level"


def crossed_edges(a: Foothold, b: Foothold, segs: list[Segment]) -> list[tuple[float, float]]:
    """(x, z) of the convex edges the swing from ``a`` to ``b`` passes over: every segment end
    between the two footholds that is higher than the next segment's start, and every
    segment start that is higher than the previous segment's end (nosings, box edges)."""
    out = []
    for i in range(a.segment, b.segment):
        s, t = segs[i], segs[i + 1]
        z_end, z_start = float(s.z_at(s.x1_m)), t.z0_m
        if z_start > z_end + EDGE_JUMP_M / 2:
            out.append((t.x0_m, z_start))
        elif z_end > z_start + EDGE_JUMP_M / 2:
            out.append((s.x1_m, z_end))
        elif t.slope_tan < s.slope_tan - _SLOPE_EPS:  # convex kink (top of a ramp)
            out.append((t.x0_m, z_start))
    return out
