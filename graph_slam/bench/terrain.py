"""``graph-slam bench terrain``: the per-frame elevation grid against the scene's truth.

Each row (``VARIANT``, ``VARIANT:PRESET``; a ``/nocarry`` suffix turns the carry off) runs a
session through ``run_session`` (causal), reads ``FrameOutput.terrain`` at every
frame and measures, over the session's complete strides (true stride frames from
:func:`graph_slam.strides.reference.stride_references`; boxes from the scene):

- **at toe-off** (the grid after the last frame at or before the stride's toe-off): every
  scene box matched by a whole grid obstacle (centre within the box's footprint grown by 5 cm)
  is a *sighting*: its height error and leading-edge error (obstacle's vs the box's nearest
  corner along stride x); the fraction within 5 mm and 10 mm;
- **carried** (the new stride's first frame): the cells known only from the previous stride
  (``count`` 0), height RMSE against the truth;
- **σ-consistency**: at toe-off, over all known cells, the standard deviation of
  ``(height - truth) / σ`` (target 0.7–1.5);
- cells within 3 cm of a box's outline are left out of the last two (a cell there mixes
  floor and top: its truth is not one height);
- **update time**: ``stages_s['terrain_online']``, median and p95 over frames (ms);
- **deadline**: per whole obstacle of the stride's re-fused grid, when the online grid first
  knew it (:mod:`graph_slam.evaluation.terrain_deadline`), relative to toe-off; and the time
  after the stride's first frame at which a whole obstacle ahead of the toe was first known.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.evaluation.boxes import truth_boxes_in_stride
from graph_slam.evaluation.terrain_deadline import obstacle_deadlines, summarise_deadlines
from graph_slam.pipelines import PipelineConfig
from graph_slam.pipelines.runner import run_session
from graph_slam.session import open_session
from graph_slam.strides.kinematics import session_leg_model
from graph_slam.strides.reference import stride_references
from graph_slam.strides.streams import session_streams

EDGE_MARGIN_M = 0.03
MATCH_MARGIN_M = 0.05


def row_config(row: str, base: PipelineConfig | None, covariances: bool) -> PipelineConfig:
    """``VARIANT[:PRESET][/nocarry]`` over ``base``; graph rows get per-frame covariances."""
    from graph_slam.bench.realtime import row_config as preset_row

    name, _, flag = row.partition("/")
    cfg = preset_row(name, base)
    data = cfg.model_dump(mode="json")
    if flag == "nocarry":
        data["terrain"]["online"]["carry"] = False
    elif flag:
        from graph_slam.errors import ConfigError

        raise ConfigError(f"row {row!r}: unknown suffix /{flag} (known: /nocarry)")
    if covariances and not cfg.variant.is_baseline:
        data["backend"]["covariances"] = True
    return PipelineConfig.model_validate(data)


@dataclass
class _Frame:
    t_s: float
    stride_index: int
    update_ms: float
    obstacles: tuple = ()


@dataclass
class TerrainRow:
    """One row's figures on one session (see the module docstring)."""

    session: str
    row: str
    sightings: list[tuple[float, float]] = field(default_factory=list)
    """(height error, leading-edge error) per box sighting at toe-off (m)."""
    carried_errors_m: list[float] = field(default_factory=list)
    normalised: list[float] = field(default_factory=list)
    update_ms: list[float] = field(default_factory=list)
    deadlines: list = field(default_factory=list)
    first_known_s: list[float] = field(default_factory=list)
    """Per stride: time from its first frame to the first whole obstacle ahead (NaN: none)."""

    def figures(self) -> dict[str, Any]:
        s = np.array(self.sightings).reshape(-1, 2)
        ok = (np.abs(s[:, 0]) <= 0.005) & (np.abs(s[:, 1]) <= 0.010)
        carried = np.array(self.carried_errors_m)
        ms = np.array(self.update_ms)
        ms = ms[np.isfinite(ms)]  # frames without a grid (before the first stride) left out
        first = np.array(self.first_known_s)
        return {
            "session": self.session,
            "row": self.row,
            "sightings": len(s),
            "sightings_within_5mm_10mm": float(ok.mean()) if len(s) else float("nan"),
            "height_error_mm_median": _med(np.abs(s[:, 0]) * 1e3),
            "edge_error_mm_median": _med(np.abs(s[:, 1]) * 1e3),
            "carried_cells": int(carried.size),
            "carried_rmse_mm": float(np.sqrt(np.mean(carried**2)) * 1e3)
            if carried.size
            else float("nan"),
            "normalised_error_std": float(np.std(self.normalised))
            if self.normalised
            else float("nan"),
            "normalised_error_robust_std": float(1.4826 * np.median(np.abs(self.normalised)))
            if self.normalised
            else float("nan"),
            "update_ms_median": _med(ms),
            "update_ms_p95": float(np.percentile(ms, 95)) if ms.size else float("nan"),
            "deadline": summarise_deadlines(self.deadlines),
            "first_obstacle_known_s_median": _med(first[np.isfinite(first)]),
        }


def pooled(rows: Sequence[TerrainRow]) -> list[TerrainRow]:
    """Per row name, every session's figures together (session ``all``)."""
    out: dict[str, TerrainRow] = {}
    for r in rows:
        p = out.setdefault(r.row, TerrainRow("all", r.row))
        for name in ("sightings", "carried_errors_m", "normalised", "update_ms", "deadlines",
                     "first_known_s"):  # fmt: skip
            getattr(p, name).extend(getattr(r, name))
    return list(out.values())


def _med(a: np.ndarray) -> float:
    return float(np.median(a)) if a.size else float("nan")


def truth_heights(xy_m: np.ndarray, world_T_stride: np.ndarray, boxes) -> np.ndarray:
    """Stride-frame height of the scene's surface (floor z = 0 in the world, boxes on it) at
    stride-frame (x, y); NaN within ``EDGE_MARGIN_M`` of a box's outline."""
    world = np.column_stack([xy_m, np.zeros(len(xy_m)), np.ones(len(xy_m))]) @ world_T_stride.T
    h_world = np.zeros(len(xy_m))
    for b in boxes:
        h_world = np.where(b.contains(xy_m), b.size_m[2], h_world)
        edge = b.contains(xy_m, EDGE_MARGIN_M) & ~b.contains(xy_m, -EDGE_MARGIN_M)
        h_world[edge] = np.nan
    up = np.column_stack([world[:, 0], world[:, 1], h_world, np.ones(len(xy_m))])
    return (up @ np.linalg.inv(world_T_stride).T)[:, 2]


def _cells(view):
    xc, yc = view.cell_centers_m()
    xx, yy = np.meshgrid(xc, yc, indexing="ij")
    return np.column_stack([xx.ravel(), yy.ravel()])


def _recorder(keep: Callable[[int, float], bool]):
    """An ``on_frame`` for :func:`~graph_slam.pipelines.runner.run_session` and what it
    records: per frame its obstacles and update time; the views of the frames ``keep(index,
    t)`` asks for and of each stride's first frame. Returns ``(frames, views, on_frame)``."""
    frames: list[_Frame] = []
    views: dict[int, Any] = {}

    def on_frame(out) -> None:
        prev_stride = frames[-1].stride_index if frames else None
        view = out.terrain
        rec = _Frame(out.t_s, out.stride_index, out.stages_s.get("terrain_online", np.nan) * 1e3)
        if view is not None:
            m = view.obstacle_map
            rec.obstacles = () if m is None else m.complete
            if keep(out.frame_index, out.t_s) or out.stride_index != prev_stride:
                views[out.frame_index] = view
        frames.append(rec)

    return frames, views, on_frame


def _first_known(frames: Sequence[_Frame], idx: np.ndarray, toe_x_m: float) -> float:
    t0 = frames[idx[0]].t_s
    for k in idx:
        if any(o.leading_edge_x_m > toe_x_m for o in frames[k].obstacles):
            return frames[k].t_s - t0
    return float("nan")


def run_terrain_row(
    session_path: Path, row: str, base: PipelineConfig | None = None, covariances: bool = True
) -> TerrainRow:
    """One row on one session (see the module docstring)."""
    cfg = row_config(row, base, covariances)
    session = open_session(session_path)
    streams = session_streams(session, cfg.event_source)
    scene = session.scene
    toe_offs = np.asarray(streams.events.toe_offs_s)

    def keep(_i: int, t: float) -> bool:  # the last frame before each toe-off
        return bool(np.any((toe_offs >= t) & (toe_offs < t + 0.03)))

    frames, views, on_frame = _recorder(keep)
    res = run_session(session, cfg, on_frame=on_frame)
    t_frames = np.array([f.t_s for f in frames])
    leg, _ = session_leg_model(session, cfg.mount_pitch_deg, cfg.mount_estimate, streams=streams)
    refs = stride_references(session, t_frames, res.strides, streams.events, leg)
    out = TerrainRow(str(session_path), row, update_ms=[f.update_ms for f in frames])
    toe_x = cfg.terrain.online.toe_x_m
    for ref in refs:
        idx = np.asarray(ref.frame_indices)
        boxes = truth_boxes_in_stride(scene, ref.world_T_stride) if scene is not None else []
        first = views.get(int(idx[0]))
        if first is not None:
            carried = first.known.ravel() & (first.count.ravel() == 0)
            err = first.height_m.ravel() - truth_heights(_cells(first), ref.world_T_stride, boxes)
            out.carried_errors_m += [float(e) for e in err[carried & np.isfinite(err)]]
        out.first_known_s.append(_first_known(frames, idx, toe_x))
        if ref.toe_off_s is None:
            continue
        before = [int(i) for i in idx if frames[i].t_s <= ref.toe_off_s and int(i) in views]
        if before:
            _at_toe_off(out, views[before[-1]], ref, boxes)
        stride = res.strides[ref.stride_index]
        grid = stride.smoothed_grid
        final = () if grid is None or grid.obstacle_map is None else grid.obstacle_map.complete
        out.deadlines += obstacle_deadlines(
            t_frames[idx],
            [frames[i].obstacles for i in idx],
            final,
            ref.toe_off_s,
            stride_index=ref.stride_index,
        )
    return out


def _at_toe_off(out: TerrainRow, view, ref, boxes) -> None:
    """The toe-off grid's box sightings and normalised cell errors."""
    truth = truth_heights(_cells(view), ref.world_T_stride, boxes)
    err = view.height_m.ravel() - truth
    sigma = view.sigma_m.ravel()
    ok = np.isfinite(err) & (sigma > 0)
    out.normalised += list(err[ok] / sigma[ok])
    m = view.obstacle_map
    for b in boxes:
        if m is None:
            break
        hits = [o for o in m.complete if b.contains(o.center_xy_m, MATCH_MARGIN_M)[0]]
        if len(hits) != 1:
            continue
        lead_true = float(b.outline_xy_m()[:, 0].min())
        floor_z = truth_heights(np.array([[lead_true - 0.1, b.center_xy_m[1]]]),
                                ref.world_T_stride, [])[0]  # fmt: skip
        o = hits[0]
        out.sightings.append(
            (o.height_m - float(b.size_m[2]), o.leading_edge_x_m - lead_true)
            if np.isfinite(floor_z)
            else (np.nan, np.nan)
        )


HEADER = (
    f"{'row':<26} {'sight':>5} {'≤5/10mm':>8} {'|dh|mm':>7} {'|dx|mm':>7} {'carried':>7} "
    f"{'RMSEmm':>7} {'err/σ':>6} {'robust':>6} {'upd p50':>7} {'upd p95':>7} {'known<toe':>9} {'lead s':>6} "
    f"{'1st s':>6}"
)


def row_line(f: dict[str, Any]) -> str:
    d = f["deadline"]
    return (
        f"{f['row']:<26} {f['sightings']:>5d} {f['sightings_within_5mm_10mm']:>8.0%} "
        f"{f['height_error_mm_median']:>7.1f} {f['edge_error_mm_median']:>7.1f} "
        f"{f['carried_cells']:>7d} {f['carried_rmse_mm']:>7.1f} "
        f"{f['normalised_error_std']:>6.2f} {f['normalised_error_robust_std']:>6.2f} "
        f"{f['update_ms_median']:>7.2f} "
        f"{f['update_ms_p95']:>7.2f} {d['n_before_toe_off']:>4d}/{d['n']:<4d} "
        f"{d['lead_s_median']:>6.2f} {f['first_obstacle_known_s_median']:>6.2f}"
    )


def markdown_table(figures: list[dict[str, Any]], command: str) -> str:
    """The rows' figures as a markdown table with its caption (date, commit, cores, command):
    what docs/benchmarks.md pastes ("Terrain for the controller")."""
    from graph_slam.bench.caption import caption

    lines = [
        f"({caption(command)})",
        "",
        "| row | sightings | within 5 / 10 mm | median height error mm | median edge error mm "
        "| carried cells | carried RMSE mm | error/σ std | robust | update ms median / p95 "
        "| known before toe-off | median lead s | first box known s |",
        "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for f in figures:
        d = f["deadline"]
        lines.append(
            f"| {f['session']}: {f['row']} | {f['sightings']} "
            f"| {f['sightings_within_5mm_10mm']:.0%} | {f['height_error_mm_median']:.1f} "
            f"| {f['edge_error_mm_median']:.1f} | {f['carried_cells']} "
            f"| {f['carried_rmse_mm']:.1f} | {f['normalised_error_std']:.2f} "
            f"| {f['normalised_error_robust_std']:.2f} "
            f"| {f['update_ms_median']:.2f} / {f['update_ms_p95']:.2f} "
            f"| {d['n_before_toe_off']}/{d['n']} | {d['lead_s_median']:.2f} "
            f"| {f['first_obstacle_known_s_median']:.2f} |"
        )
    return "\n".join(lines)


def update_cost_ms(session_path: Path, config: PipelineConfig | None = None, repeats: int = 5):
    """The grid update alone, per frame of a session (its true camera orientations and heights
    over the grid's origin, a fixed pose covariance), the least of ``repeats`` timings per frame (a loaded machine's preemptions
    left out): (median, p95) in ms. Each repeat is a fresh copy of the frame's map."""
    import time

    from graph_slam.session import open_session
    from graph_slam.terrain.grid.live import LiveTerrain

    cfg = config or PipelineConfig()
    session = open_session(session_path)
    gt = session.ground_truth
    live = LiveTerrain(cfg.terrain.online, session.intrinsics, cfg.cloud.min_depth_m,
                       cfg.cloud.max_depth_m)  # fmt: skip
    cov = np.diag([1e-5] * 3 + [1e-5] * 3)
    best = []
    for i, frame in enumerate(session.iter_frames(0, session.n_frames)):
        pose = np.array(gt.parent_T_child[i])
        pose[:2, 3] = 0.0  # over the grid's origin: the view ahead stays on the grid
        times = []
        for _ in range(repeats):
            saved = live.map.sums if live.map is not None else None
            t0 = time.perf_counter()
            live.frame(i, frame, 0, pose, pose, cov)
            times.append(time.perf_counter() - t0)
            if saved is not None:
                live.map.sums = saved
        live.frame(i, frame, 0, pose, pose, cov)
        best.append(min(times) * 1e3)
    ms = np.array(best)
    return float(np.median(ms)), float(np.percentile(ms, 95))
