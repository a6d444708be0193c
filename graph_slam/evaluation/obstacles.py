"""Obstacle dimensions against the scene's ground truth (thesis Table 4.1).

Each stride's map gives a measurement of every box it saw; :func:`match_obstacles` pairs the
extracted obstacles with the scene's boxes (nearest centre in the stride's floor plane), and
:func:`obstacle_accuracy` reduces all measurements of a box to mean, standard deviation (sample,
ddof=1; NaN for one measurement) and RMSE against the true size, per dimension. Copies of a box
in a repeated course (``Box1#2``) count as ``Box1``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.mapping.obstacles import Obstacle
from graph_slam.session.records import SceneTruth

DIMENSIONS = ("depth", "width", "height")
"""Order of ``size_m`` (thesis Table 3.1): depth along x (walking direction), width y, height z."""


@dataclass(frozen=True)
class DimensionStats:
    n: int
    truth_m: float
    mean_m: float
    std_m: float
    rmse_m: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def base_name(name: str) -> str:
    """``Box1#2`` -> ``Box1`` (a repeated course's copies are the same box)."""
    return name.split("#", 1)[0]


def truth_boxes_in_stride(
    scene: SceneTruth, world_T_stride: np.ndarray
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, centre xy in the stride frame, size_m) of every box of the scene."""
    stride_T_world = np.linalg.inv(np.asarray(world_T_stride, dtype=np.float64))
    out = []
    for obj in scene.objects:
        if obj.kind != "box":
            continue
        centre = stride_T_world[:3, :3] @ obj.world_T_object[:3, 3] + stride_T_world[:3, 3]
        out.append((obj.name, centre[:2], obj.size_m))
    return out


def match_obstacles(
    obstacles: Sequence[Obstacle],
    truth: Sequence[tuple[str, np.ndarray, np.ndarray]],
    max_distance_m: float = 0.15,
) -> dict[str, Obstacle]:
    """Pair each true box with the extracted obstacle whose centre is nearest (within the limit).

    Greedy by distance, each obstacle used once; boxes with no obstacle near are left out.
    """
    pairs = []
    for name, centre, _ in truth:
        for k, obstacle in enumerate(obstacles):
            d = float(np.linalg.norm(obstacle.center_xy_m - np.asarray(centre)[:2]))
            if d <= max_distance_m:
                pairs.append((d, name, k))
    matched: dict[str, Obstacle] = {}
    used: set[int] = set()
    for _, name, k in sorted(pairs):
        if name not in matched and k not in used:
            matched[name] = obstacles[k]
            used.add(k)
    return matched


def obstacle_accuracy(
    measured_size_m: Mapping[str, Sequence[np.ndarray]],
    truth_size_m: Mapping[str, np.ndarray],
) -> dict[str, dict[str, DimensionStats]]:
    """Per box and dimension: mean, std and RMSE of the measurements against the truth.

    Args:
        measured_size_m: box name -> list of measured (depth, width, height), metres.
        truth_size_m: box name -> true (depth, width, height), metres.
    """
    result: dict[str, dict[str, DimensionStats]] = {}
    for name, sizes in measured_size_m.items():
        if name not in truth_size_m:
            raise EvaluationError(f"obstacle_accuracy: no ground truth for box {name!r}")
        m = np.asarray(sizes, dtype=np.float64).reshape(-1, 3)
        if m.shape[0] == 0:
            continue
        truth = np.asarray(truth_size_m[name], dtype=np.float64).reshape(3)
        std = m.std(axis=0, ddof=1) if m.shape[0] > 1 else np.full(3, np.nan)
        rmse = np.sqrt(np.mean((m - truth) ** 2, axis=0))
        result[name] = {
            dim: DimensionStats(
                n=int(m.shape[0]),
                truth_m=float(truth[d]),
                mean_m=float(m[:, d].mean()),
                std_m=float(std[d]),
                rmse_m=float(rmse[d]),
            )
            for d, dim in enumerate(DIMENSIONS)
        }
    return result


def collect_measurements(
    matches: Sequence[Mapping[str, Obstacle]],
) -> dict[str, list[np.ndarray]]:
    """Gather per-stride matches into ``{base box name: [size_m, ...]}``."""
    out: dict[str, list[np.ndarray]] = {}
    for matched in matches:
        for name, obstacle in matched.items():
            out.setdefault(base_name(name), []).append(obstacle.size_m)
    return out
