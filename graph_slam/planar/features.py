"""Line features of a 2D scan by the roughness factor (thesis 3.1.1, eq. 3.1).

For each point i with its ``k`` neighbours on either side (the set S, |S| = 2k),

    c_i = || sum_{j in S} (X_i - X_j) || / (|S| · ||X_i||)                      (3.1)

Points with c below the threshold (0.5 in the thesis) are smooth; consecutive runs of smooth
points are grouped into lines, and each line gets the normal of its total-least-squares fit.
A run also ends where consecutive points are farther apart than ``max_gap_m`` (a depth jump).

Eq. 3.1 as printed scales with the ray spacing: with 150 rays over 75° a 90° corner scores only
about 0.01–0.05, so the threshold of 0.5 removes depth jumps (occlusion edges, the edge of the
max-range returns) but never a corner, and a run of smooth points can turn a corner. Each run
is therefore split into straight pieces (Douglas–Peucker, ``line_tolerance_m``) before its
normal is fitted; pieces shorter than ``min_line_points`` are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.planar.config import FeatureConfig


def roughness(points_xy_m: np.ndarray, neighbours: int = 3) -> np.ndarray:
    """Eq. 3.1 for every point of an ordered scan; NaN where a side has fewer than ``k`` points."""
    n, k = len(points_xy_m), neighbours
    c = np.full(n, np.nan)
    if n < 2 * k + 1:
        return c
    csum = np.vstack([np.zeros(2), np.cumsum(points_xy_m, axis=0)])
    i = np.arange(k, n - k)
    neighbour_sum = csum[i + k + 1] - csum[i - k] - points_xy_m[i]
    diff_sum = 2 * k * points_xy_m[i] - neighbour_sum
    c[i] = np.linalg.norm(diff_sum, axis=1) / (2 * k * np.linalg.norm(points_xy_m[i], axis=1))
    return c


@dataclass(frozen=True)
class LineFeatures:
    """The points of a scan that lie on lines, with their normals (unit, facing the sensor)."""

    points_xy_m: np.ndarray  # (m, 2)
    normals: np.ndarray  # (m, 2)
    line_id: np.ndarray  # (m,) which line each point belongs to
    roughness: np.ndarray  # (n,) eq. 3.1 for every input point

    @property
    def n_lines(self) -> int:
        return int(self.line_id.max()) + 1 if len(self.line_id) else 0


def _groups(smooth: np.ndarray, points: np.ndarray, max_gap_m: float) -> list[np.ndarray]:
    """Runs of consecutive smooth points without a gap wider than ``max_gap_m``."""
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1) > max_gap_m
    groups, current = [], []
    for i, ok in enumerate(smooth):
        if ok and current and gaps[i - 1]:
            groups.append(np.array(current))
            current = []
        if ok:
            current.append(i)
        elif current:
            groups.append(np.array(current))
            current = []
    if current:
        groups.append(np.array(current))
    return groups


def _split(points: np.ndarray, tolerance_m: float) -> list[np.ndarray]:
    """Split an ordered run of points into straight pieces (Douglas–Peucker); index arrays."""
    pieces, todo = [], [np.arange(len(points))]
    while todo:
        idx = todo.pop()
        a, b = points[idx[0]], points[idx[-1]]
        chord = b - a
        length = np.linalg.norm(chord)
        if len(idx) < 3 or length == 0.0:
            pieces.append(idx)
            continue
        offset = points[idx] - a
        dist = np.abs(offset[:, 0] * chord[1] - offset[:, 1] * chord[0]) / length
        worst = int(np.argmax(dist))
        if dist[worst] <= tolerance_m or worst in (0, len(idx) - 1):
            pieces.append(idx)
        else:
            todo += [idx[: worst + 1], idx[worst:]]
    return sorted(pieces, key=lambda piece: piece[0])


def _line_normal(points: np.ndarray) -> np.ndarray:
    """Unit normal of the total-least-squares line through ``points``, facing the sensor."""
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    return -normal if normal @ points.mean(axis=0) > 0 else normal


def extract_lines(points_xy_m: np.ndarray, config: FeatureConfig) -> LineFeatures:
    """Roughness (eq. 3.1), smooth points grouped into lines, and a normal for every point."""
    c = roughness(points_xy_m, config.neighbours)
    smooth = np.nan_to_num(c, nan=np.inf) < config.roughness_threshold
    pts, nrm, ids = [], [], []
    for group in _groups(smooth, points_xy_m, config.max_gap_m):
        for piece in _split(points_xy_m[group], config.line_tolerance_m):
            if len(piece) < config.min_line_points:
                continue
            line_points = points_xy_m[group[piece]]
            pts.append(line_points)
            nrm.append(np.tile(_line_normal(line_points), (len(piece), 1)))
            ids.append(np.full(len(piece), len(ids)))
    if not pts:
        empty = np.empty((0, 2))
        return LineFeatures(empty, empty, np.empty(0, dtype=int), c)
    return LineFeatures(np.vstack(pts), np.vstack(nrm), np.concatenate(ids), c)
