"""The scene's walkable surfaces: a height function and the terrain features' geometry.

:class:`Surfaces` keeps every object that stands on the floor as an analytic primitive (box,
ramp, flight of stairs), so :meth:`Surfaces.height_at` answers the top surface's height at any
world (x, y) (vectorised; the floor is z = 0) and :meth:`Surfaces.features` lists each
feature's geometry as ground truth: every step's rise, tread and nosing line, a ramp's slope
and its start and end lines, a curb's height and edge, a box's size and pose. The
terrain-following walker plans its footholds on :meth:`Surfaces.profile`, the surface along
the walking line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Height jumps above this along the walking line are edges (risers, box faces).
EDGE_JUMP_M = 0.01


@dataclass(frozen=True)
class StepTruth:
    """One step of a flight: its tread (x range, top height) and its nosing line (world)."""

    index: int
    rise_m: float
    tread_m: float
    top_z_m: float
    tread_x0_m: float
    tread_x1_m: float
    nosing_m: tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class FeatureTruth:
    """A terrain feature as ground truth (world frame, metres, degrees).

    ``kind``: ``stairs`` (``steps``, ``direction``), ``ramp`` (``slope_deg``, ``direction``;
    ``start_line_m`` where the slope begins along +x, ``end_line_m`` where it ends), ``box``
    (``role``: obstacle, step_on, platform, curb; ``size_m`` depth × width × height,
    ``center_m`` of the footprint on the floor, ``yaw_deg``; ``edge_m`` the top edge that
    faces the walker coming along +x).
    """

    name: str
    kind: str
    direction: str = ""
    role: str = ""
    height_m: float = 0.0
    slope_deg: float = 0.0
    size_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_deg: float = 0.0
    start_line_m: tuple = ()
    end_line_m: tuple = ()
    edge_m: tuple = ()
    steps: tuple[StepTruth, ...] = ()


@dataclass
class Surfaces:
    """Analytic top surfaces of a scene's objects (the floor z = 0 is implicit)."""

    boxes: list[tuple[str, np.ndarray, np.ndarray, float, str]] = field(default_factory=list)
    ramps: list[tuple[str, float, float, float, float, float, str]] = field(default_factory=list)
    stairs: list[tuple[str, float, float, tuple[float, float, float], int, str, float]] = field(
        default_factory=list
    )

    # ------------------------------------------------------------ building
    def add_box(self, name: str, center, size, yaw_rad: float, role: str) -> None:
        self.boxes.append((name, np.asarray(center, float), np.asarray(size, float), yaw_rad, role))

    def add_ramp(self, name: str, center, size, direction: str) -> None:
        length, width, rise = (float(v) for v in size)
        x0 = float(center[0]) - length / 2
        y0 = float(center[1]) - width / 2
        self.ramps.append((name, x0, x0 + length, y0, y0 + width, rise, direction))

    def add_stairs(
        self, name: str, start_xy, size, steps: int, direction: str, base_m: float = 0.0
    ) -> None:
        self.stairs.append(
            (name, float(start_xy[0]), float(start_xy[1]), tuple(map(float, size)), steps,
             direction, float(base_m))
        )  # fmt: skip

    # ------------------------------------------------------------ queries
    def height_at(self, x_m, y_m) -> np.ndarray:
        """Top-surface height (m) at world (x, y), arrays of any (broadcastable) shape."""
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        z = np.zeros(x.shape)
        for _, center, size, yaw, _ in self.boxes:
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = x - center[0], y - center[1]
            u, v = c * dx + s * dy, -s * dx + c * dy
            inside = (np.abs(u) <= size[0] / 2) & (np.abs(v) <= size[1] / 2)
            z = np.where(inside, np.maximum(z, size[2]), z)
        for _, x0, x1, y0, y1, rise, direction in self.ramps:
            inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
            frac = (x - x0) / (x1 - x0)
            h = rise * (frac if direction == "up" else 1.0 - frac)
            z = np.where(inside, np.maximum(z, h), z)
        for _, sx, sy, (run, width, rise), steps, direction, base in self.stairs:
            n_boxes = steps - 1 if direction == "down" else steps
            i = np.floor((x - sx) / run)
            inside = (i >= 0) & (i < n_boxes) & (np.abs(y - sy) <= width / 2)
            h = base + (steps - 1 - i if direction == "down" else i + 1) * rise
            z = np.where(inside, np.maximum(z, h), z)
        return z

    def feature_at(self, x_m: float, y_m: float = 0.0) -> tuple[str, str, str]:
        """(name, kind, role) of the top-most object at (x, y); ("floor", "floor", "") if none."""
        best, best_z = ("floor", "floor", ""), 1e-9
        for name, kind, role, z in self._each_height(float(x_m), float(y_m)):
            if z > best_z:
                best, best_z = (name, kind, role), z
        return best

    def _each_height(self, x: float, y: float):
        probe = Surfaces()
        for box in self.boxes:
            probe.boxes = [box]
            yield box[0], "box", box[4], float(probe.height_at(x, y))
        probe.boxes = []
        for ramp in self.ramps:
            probe.ramps = [ramp]
            yield ramp[0], "ramp", "", float(probe.height_at(x, y))
        probe.ramps = []
        for st in self.stairs:
            probe.stairs = [st]
            yield st[0], "stairs", "", float(probe.height_at(x, y))

    def profile(self, x0_m: float, x1_m: float, y_m: float = 0.0, step_m: float = 0.001):
        """The surface along the line y = ``y_m``: sample x and heights (m) every ``step_m``."""
        x = np.arange(x0_m, x1_m + step_m / 2, step_m)
        return x, self.height_at(x, np.full_like(x, y_m))

    # ------------------------------------------------------------ truth
    def features(self) -> list[FeatureTruth]:
        """Every object's geometry as ground truth, in the order they were added."""
        out: list[FeatureTruth] = []
        for name, sx, sy, (run, width, rise), steps, direction, base in self.stairs:
            y0, y1 = sy - width / 2, sy + width / 2
            rows = []
            for k in range(steps):
                if direction == "up":  # nosing k: top of riser k, the near edge of tread k
                    x_n, top = sx + k * run, base + (k + 1) * rise
                    tread = (x_n, x_n + run)
                else:  # nosing k: the far edge of the platform (k = 0) or of tread k
                    x_n, top = sx + k * run, base + (steps - k) * rise
                    tread = (x_n - run, x_n)
                rows.append(
                    StepTruth(k + 1, rise, run, top, *tread, ((x_n, y0, top), (x_n, y1, top)))
                )
            out.append(
                FeatureTruth(name, "stairs", direction=direction, height_m=steps * rise,
                             slope_deg=math.degrees(math.atan2(rise, run)),
                             size_m=(run, width, rise), center_m=(sx, sy, base), steps=tuple(rows))
            )  # fmt: skip
        for name, x0, x1, y0, y1, rise, direction in self.ramps:
            z_start, z_end = (0.0, rise) if direction == "up" else (rise, 0.0)
            out.append(
                FeatureTruth(name, "ramp", direction=direction, height_m=rise,
                             slope_deg=math.degrees(math.atan2(rise, x1 - x0)),
                             size_m=(x1 - x0, y1 - y0, rise),
                             center_m=((x0 + x1) / 2, (y0 + y1) / 2, 0.0),
                             start_line_m=((x0, y0, z_start), (x0, y1, z_start)),
                             end_line_m=((x1, y0, z_end), (x1, y1, z_end)))
            )  # fmt: skip
        for name, center, size, yaw, role in self.boxes:
            c, s = math.cos(yaw), math.sin(yaw)
            hx, hy, h = size[0] / 2, size[1] / 2, size[2]
            ends = [(-hx, -hy), (-hx, hy)]
            edge = tuple((center[0] + c * u - s * v, center[1] + s * u + c * v, h) for u, v in ends)
            out.append(
                FeatureTruth(name, "box", role=role, height_m=float(h),
                             size_m=tuple(float(v) for v in size),
                             center_m=(float(center[0]), float(center[1]), 0.0),
                             yaw_deg=math.degrees(yaw),
                             edge_m=tuple(tuple(float(v) for v in p) for p in edge))
            )  # fmt: skip
        return out
