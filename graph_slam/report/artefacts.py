"""One variant's artefacts from ``run``: trajectories, stride maps, grids, per-frame flags, timing.

Everything lands in ``<out>/<session>/<variant tag>/`` (docs/run.md has the layout and every
column). Each writer has its reader where a file is meant to be read back
(:func:`read_kitti`, :func:`read_elevation_csv`, :func:`read_terrain_json`); the TUM files are
:func:`graph_slam.session.io.read_tum`'s and the PLY files
:func:`graph_slam.session.adapters.ply.read_ply`'s.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from graph_slam.errors import EvaluationError

STAGES = (
    "cloud",
    "preprocess",
    "registration",
    "floor",
    "graph",
    "terrain",
    "terrain_online",
    "stride_close",
)
"""The per-stage columns of ``timing.csv`` in this order (``FrameOutput.stages_s``; a stage
absent from a frame is 0 there); a stage not listed here follows them, by name."""
ELEVATION_COLUMNS = ("i", "j", "x_m", "y_m", "height_m", "variance_m2", "count")


def _num(x) -> float | None:
    """A JSON number (None for NaN/inf: JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


def write_variant(folder: Path, results, cfg, session=None, leg_model=None) -> list[Path]:
    """Every artefact of one variant's :class:`~graph_slam.pipelines.PipelineResults`
    (``session`` and ``leg_model``: for the measured swing clearance of the features files)."""
    folder.mkdir(parents=True, exist_ok=True)
    files = write_trajectories(folder, results, kitti=cfg.kitti)
    files.append(write_frames_csv(folder / "frames.csv", results))
    files.append(write_timing_csv(folder / "timing.csv", results))
    files += write_stride_maps(folder / "maps", results, cfg)
    files += write_stride_features(folder / "maps", results, session, leg_model)
    return files


def write_stride_features(folder: Path, results, session=None, leg_model=None) -> list[Path]:
    """Per stride with a grid: ``sNN_features.json`` (terrain features, predicted and measured
    toe clearance; :mod:`graph_slam.terrain.features.io`)."""
    from graph_slam.terrain.features.io import stride_features_document, write_features_json

    files = []
    for stride in results.strides:
        if stride.online_grid is None and stride.smoothed_grid is None:
            continue
        folder.mkdir(parents=True, exist_ok=True)
        doc = stride_features_document(stride, results, session, leg_model)
        files.append(write_features_json(folder / f"s{stride.index:02d}_features.json", doc))
    return files


def _finite(poses: np.ndarray) -> np.ndarray:
    return np.isfinite(poses).all(axis=(1, 2))


def write_trajectories(folder: Path, results, *, kitti: bool = False) -> list[Path]:
    """``{online,smoothed}.tum`` (``stride_T_camera``: each stride restarts at its foot
    strike, as compare writes them), ``{online,smoothed}_world.tum`` (``world_T_camera``, the
    strides chained) and, with ``kitti``, ``{online,smoothed}.kitti`` with their
    ``.times.txt``. Frames without a pose are left out; times are the frames' ``t_s``."""
    from graph_slam.session.io import write_tum

    files = []
    t_s = results.t_s
    for kind in ("online", "smoothed"):
        stride = results.poses(kind)
        world = (
            results.online_world_T_camera if kind == "online" else results.smoothed_world_T_camera
        )
        for name, poses in ((kind, stride), (f"{kind}_world", world)):
            keep = _finite(poses)
            write_tum(folder / f"{name}.tum", t_s[keep], poses[keep])
            files.append(folder / f"{name}.tum")
        if kitti:
            keep = _finite(stride)
            files += write_kitti(folder / f"{kind}.kitti", t_s[keep], stride[keep])
    return files


def write_kitti(path: Path, t_s: np.ndarray, parent_T_child: np.ndarray) -> list[Path]:
    """KITTI odometry format: the top 3×4 of each pose, row-major, 12 numbers a line; the
    times (s) one a line in ``<path>.times.txt`` (KITTI's ``times.txt``)."""
    rows = np.asarray(parent_T_child)[:, :3, :].reshape(-1, 12)
    np.savetxt(path, rows, fmt="%.9f")
    times = path.with_name(path.name + ".times.txt")
    np.savetxt(times, np.asarray(t_s, dtype=np.float64), fmt="%.9f")
    return [path, times]


def read_kitti(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``(t_s, parent_T_child)`` from :func:`write_kitti`'s two files."""
    rows = np.loadtxt(path, ndmin=2)
    if rows.size and rows.shape[1] != 12:
        raise EvaluationError(f"{path}: KITTI lines must hold 12 numbers, found {rows.shape[1]}")
    t_s = np.loadtxt(path.with_name(path.name + ".times.txt"), ndmin=1)
    if t_s.size != len(rows):
        raise EvaluationError(f"{path}: {len(rows)} poses but {t_s.size} times")
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :] = rows.reshape(-1, 3, 4)
    return t_s, poses


def write_frames_csv(path: Path, results) -> Path:
    """One row per frame: what the pipeline decided (docs/run.md, ``frames.csv``)."""
    from graph_slam.report.scoring import frame_categories

    categories = frame_categories(results)
    with path.open("w", encoding="utf-8", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(
            ["frame_index", "t_s", "stride", "status", "category", "foot_loaded", "fitness",
             "registered_to", "gate", "floor", "flags"]
        )  # fmt: skip
        for f, category in zip(results.frames, categories, strict=True):
            gate = "" if f.estimate is None or f.estimate.gate is None else f.estimate.gate.reason
            floor = ";".join(x.split(":", 1)[1] for x in f.flags if x.startswith("floor:"))
            w.writerow(
                [f.frame_index, f"{f.t_s:.9f}", f.stride_index, f.status, category,
                 int(f.foot_loaded), f"{f.fitness:.6g}",
                 "" if f.registered_to is None else f.registered_to, gate, floor,
                 ";".join(f.flags)]
            )  # fmt: skip
    return path


def stage_names(results) -> list[str]:
    """The stages the variant timed: :data:`STAGES` first, then any other by name."""
    seen = {k for f in results.frames for k in f.stages_s}
    return [s for s in STAGES if s in seen] + sorted(seen - set(STAGES))


def write_timing_csv(path: Path, results) -> Path:
    """One row per frame: wall time per stage (s) and the total (docs/run.md, ``timing.csv``)."""
    names = stage_names(results)
    with path.open("w", encoding="utf-8", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["frame_index", "t_s", *(f"{s}_s" for s in names), "total_s"])
        for f in results.frames:
            total = f.frontend_s + f.backend_s + f.terrain_s
            stages = [f"{f.stages_s.get(s, 0.0):.6g}" for s in names]
            w.writerow([f.frame_index, f"{f.t_s:.9f}", *stages, f"{total:.6g}"])
    return path


def map_kinds(results, terrain) -> list[str]:
    """The stride maps a variant has: the configured pose sets (the baseline's smoothed map is
    its online one, written once)."""
    kinds = [k for k in ("online", "smoothed") if terrain.by_kind(k) is not None]
    if results.variant.is_baseline and terrain.online is not None and "smoothed" in kinds:
        return ["online"] if terrain.smoothed is terrain.online else kinds
    return kinds


def write_stride_maps(folder: Path, results, cfg) -> list[Path]:
    """Per stride and pose set: ``sNN_<kind>.ply`` (the fused map), ``sNN_<kind>_elevation.csv``
    and ``sNN_<kind>_terrain.json`` (grid, floor, obstacles)."""
    files: list[Path] = []
    for stride in results.strides:
        terrain = stride.terrain
        if terrain is None:
            continue
        for kind in map_kinds(results, terrain):
            smap = terrain.by_kind(kind)
            base = folder / f"s{stride.index:02d}_{kind}"
            folder.mkdir(parents=True, exist_ok=True)
            if len(smap.fused):
                files.append(_write_map_ply(base.with_suffix(".ply"), smap.fused, cfg.map_dtype))
            files.append(write_elevation_csv(Path(f"{base}_elevation.csv"), smap.elevation))
            files.append(write_terrain_json(Path(f"{base}_terrain.json"), stride, kind, smap))
    return files


def _write_map_ply(path: Path, fused, dtype: str) -> Path:
    """The fused map as binary PLY, coordinates ``float32`` (PLY float) or ``float64``."""
    from graph_slam.session.adapters.ply import write_ply

    write_ply(fused.to_point_cloud(), path, dtype=dtype)
    return path


def write_elevation_csv(path: Path, grid) -> Path:
    """The grid's non-empty cells, one a row: index ``(i, j)``, cell centre, height, variance,
    points (:data:`ELEVATION_COLUMNS`; stride frame, metres)."""
    x_c, y_c = grid.cell_centers_m()
    i, j = np.nonzero(np.isfinite(grid.height_m))
    with path.open("w", encoding="utf-8", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(ELEVATION_COLUMNS)
        for a, b in zip(i, j, strict=True):
            w.writerow(
                [a, b, f"{x_c[a]:.6f}", f"{y_c[b]:.6f}", f"{grid.height_m[a, b]:.6f}",
                 f"{grid.variance_m2[a, b]:.9g}", int(grid.count[a, b])]
            )  # fmt: skip
    return path


def read_elevation_csv(path: Path, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """``(height_m, variance_m2)`` arrays of ``shape`` (NaN where no row) from
    :func:`write_elevation_csv`; ``shape`` is the ``grid.shape`` of the terrain JSON."""
    height = np.full(shape, np.nan)
    variance = np.full(shape, np.nan)
    with Path(path).open(encoding="utf-8", newline="") as handle:
        reader = csv.DictReader(handle)
        if tuple(reader.fieldnames or ()) != ELEVATION_COLUMNS:
            raise EvaluationError(f"{path}: the header must be {','.join(ELEVATION_COLUMNS)}")
        for n, row in enumerate(reader, start=2):
            i, j = int(row["i"]), int(row["j"])
            if not (0 <= i < shape[0] and 0 <= j < shape[1]):
                raise EvaluationError(f"{path}: line {n}: cell ({i}, {j}) outside {shape}")
            height[i, j] = float(row["height_m"])
            variance[i, j] = float(row["variance_m2"])
    return height, variance


def _obstacle(o) -> dict:
    return {
        "depth_m": _num(o.depth_m),
        "width_m": _num(o.width_m),
        "height_m": _num(o.height_m),
        "leading_edge_x_m": _num(o.leading_edge_x_m),
        "center_xy_m": [_num(v) for v in o.center_xy_m],
        "yaw_rad": _num(o.yaw_rad),
        "point_count": int(o.point_count),
        "complete": bool(o.complete),
        "skip_reason": o.skip_reason,
    }


def terrain_document(stride, kind: str, smap) -> dict:
    """``sNN_<kind>_terrain.json``: the stride, the grid's geometry, floor and obstacles."""
    grid = smap.elevation
    obstacles = smap.obstacles
    floor = None if obstacles is None else obstacles.floor
    return {
        "stride": int(stride.index),
        "poses": kind,
        "frame_indices": [int(stride.frame_indices[0]), int(stride.frame_indices[-1])],
        "frame": "stride (origin at the heel at foot strike, x forward, y left, z up)",
        "grid": {
            "origin_xy_m": [float(v) for v in grid.origin_xy_m],
            "cell_m": float(grid.cell_m),
            "shape": [int(n) for n in grid.shape],
            "cells_known": int(np.isfinite(grid.height_m).sum()),
            "points_outside": int(grid.points_outside),
        },
        "map_points": len(smap.fused),
        "floor": None
        if floor is None
        else {
            "normal": [float(v) for v in floor.normal],
            "offset_m": float(floor.offset_m),
            "inliers": int(floor.inliers),
            "rms_m": _num(floor.rms_m),
        },
        "obstacle_error": smap.obstacle_error,
        "obstacles": [] if obstacles is None else [_obstacle(o) for o in obstacles.obstacles],
    }


def write_terrain_json(path: Path, stride, kind: str, smap) -> Path:
    path.write_text(
        json.dumps(terrain_document(stride, kind, smap), indent=1, allow_nan=False),
        encoding="utf-8",
    )
    return path


def read_terrain_json(path: Path) -> dict:
    """:func:`write_terrain_json`'s document, its required fields checked."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise EvaluationError(f"{path}: not JSON ({err})") from None
    for key in ("stride", "poses", "grid", "floor", "obstacles"):
        if key not in doc:
            raise EvaluationError(f"{path}: field {key!r} is missing")
    return doc
