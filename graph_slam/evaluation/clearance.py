"""The toe's clearance against the scene's truth: the swing's toe paths, the least clearance
over the terrain and over each edge the swing passes, the features a swing must clear.

:func:`swing_clearance_pair` and :func:`edge_clearance_pairs` score a stride's measured swing
(the poses that placed the final grid, the encoders, the final grid) against the true one (the true poses, the
same encoders, the scene's surface and features, :mod:`graph_slam.evaluation.features`), both
sampled at 200 Hz between the stride's mid-swing frames (docs/terrain.md, "Toe clearance");
:func:`swing_toe_extent` and :func:`in_swing` say which features a swing must clear (the
per-feature deadline's ``swing`` counts).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from graph_slam.evaluation.features import (
    _nearest_edge,
    feature_truth_from_scene,
    scene_height_at,
)


def _swing_paths(run_session, ref, stride, leg_model, cfg, rate_hz: float = 200.0):
    """The measured and the true toe paths (N×3 each, stride frame) over a scored stride's
    mid-swing, sampled at ``rate_hz`` between its first and last frames there: the camera
    poses interpolated between frames (those that placed the stride's final grid,
    ``StrideOutput.grid_stride_T_camera``: the smoothed ones, or the online ones when the
    final grid is the online grid; the true ones), the encoders at the same times; None when
    they cannot be had."""
    from graph_slam.strides.joints import interp_q
    from graph_slam.terrain.features.clearance import interpolate_poses, toe_path

    session = run_session.session
    if ref.toe_off_s is None or session.joints is None or leg_model is None:
        return None
    t = np.asarray(ref.t_s)
    s = (t - ref.toe_off_s) / max(ref.t_next_strike_s - ref.toe_off_s, 1e-9)
    est = np.asarray(getattr(stride, "grid_stride_T_camera", stride.smoothed_stride_T_camera))
    rows = np.flatnonzero((s >= cfg.mid_swing[0]) & (s <= cfg.mid_swing[1]))
    rows = [k for k in rows if np.isfinite(est[k]).all()]
    if len(rows) < 2:
        return None
    t_joint = np.asarray(session.joints.t_s) + session.calibration.joints_time_offset_s
    tq = np.arange(t[rows[0]], t[rows[-1]], 1.0 / rate_hz)
    q = [interp_q(float(tk), t_joint, session.joints.q_rad) for tk in tq]
    keep = np.array([qk is not None for qk in q])
    if keep.sum() < 2:
        return None
    qs, tq = np.array([qk for qk in q if qk is not None]), tq[keep]
    measured = toe_path(interpolate_poses(t[rows], est[rows], tq), qs, leg_model)
    true_poses = interpolate_poses(t[rows], np.asarray(ref.stride_T_camera)[rows], tq)
    return measured, toe_path(true_poses, qs, leg_model)


def swing_clearance_pair(run_session, ref, stride, leg_model, config=None):
    """The measured least toe clearance of a scored stride's swing (the variant's smoothed
    poses and final grid) and the true one (the true poses over the scene's surface), both
    from the encoders over the same mid-swing frames and the truth over the points whose
    terrain the measurement knows; None when either cannot be had."""
    from graph_slam.terrain.features.clearance import ClearanceConfig, clearance_along
    from graph_slam.terrain.features.extract import features_of_view

    cfg = config or ClearanceConfig()
    grid = getattr(stride, "smoothed_grid", None)
    paths = None if grid is None else _swing_paths(run_session, ref, stride, leg_model, cfg)
    if paths is None:
        return None
    est_toe, true_toe = paths
    feats = features_of_view(grid, source="smoothed")
    measured = clearance_along(grid, feats, est_toe, cfg)
    if not math.isfinite(measured.min_m):
        return None
    known = _known_samples(grid, feats, est_toe, cfg)
    true = true_swing_clearance(run_session.session.scene, ref.world_T_stride, true_toe[known])
    return measured.min_m, true, measured.sigma_m


def _known_samples(grid, features, toe_xyz_m, cfg) -> np.ndarray:
    """The toe path's points whose terrain the measurement knows (the grid or a feature's
    edge): the truth is taken over the same points."""
    from graph_slam.terrain.features.clearance import clearance_profile

    clear, _, _ = clearance_profile(grid, features, toe_xyz_m, cfg)
    return np.isfinite(clear)


def true_swing_clearance(scene, world_T_stride, toe_xyz_m: np.ndarray) -> float:
    """The true least clearance of a toe path: its height over the scene's surface under each
    point (a footprint's highest point would sink the toe into a riser it rises 8 mm before)."""
    toe = np.asarray(toe_xyz_m, dtype=np.float64).reshape(-1, 3)
    ground = scene_height_at(scene, world_T_stride, toe[:, :2])
    return float(np.min(toe[:, 2] - ground))


def edge_clearance_pairs(run_session, ref, stride, leg_model, config=None, match_m=0.05):
    """The swing's clearance over each edge it must clear
    (:func:`graph_slam.terrain.features.clearance.edge_clearances`): per edge the true toe
    path passes (the scene's features), (measured, true, σ) — measured over the final grid's
    edge nearest it (within ``match_m`` along x at its y) from the measured toe path,
    NaN when no such measured edge lies on that path — and the swing's true edge clearance
    (the least; None: the true path passes no edge, or the paths cannot be had)."""
    from graph_slam.terrain.features.clearance import ClearanceConfig, edge_clearances
    from graph_slam.terrain.features.extract import features_of_view

    cfg = config or ClearanceConfig()
    grid = getattr(stride, "smoothed_grid", None)
    paths = None if grid is None else _swing_paths(run_session, ref, stride, leg_model, cfg)
    if paths is None:
        return [], None
    est_toe, true_toe = paths
    truth = feature_truth_from_scene(run_session.session.scene, ref.world_T_stride)
    true_edges = edge_clearances(truth, true_toe, cfg)
    if not true_edges:
        return [], None
    measured = edge_clearances(features_of_view(grid, source="smoothed"), est_toe, cfg)
    pairs = []
    for line, true in true_edges:
        hit = _nearest_edge(line, measured, match_m)
        got = (float("nan"), float("nan")) if hit is None else (hit[1].min_m, hit[1].sigma_m)
        pairs.append((got[0], true.min_m, got[1]))
    return pairs, min(t.min_m for _, t in true_edges)


def summarise_clearances(pairs: Sequence[tuple[float, float, float]]) -> dict:
    """n, RMSE, bias (measured − true), the fraction within ±5 mm, the std of error/σ; pairs
    whose measured value is NaN (an edge the measured features missed) are counted as
    ``missed`` and left out of the rest."""
    a = np.asarray(pairs, dtype=np.float64).reshape(-1, 3)
    missed = int((~np.isfinite(a[:, 0])).sum())
    a = a[np.isfinite(a[:, 0])]
    if not len(a):
        return {"n": 0, "missed": missed, "rmse": None, "bias": None,
                "within_5mm_fraction": None, "std_error_over_sigma": None}  # fmt: skip
    e = a[:, 0] - a[:, 1]
    z = e / np.where(a[:, 2] > 0, a[:, 2], np.nan)
    z = z[np.isfinite(z)]
    return {
        "n": int(e.size),
        "missed": missed,
        "rmse": float(np.sqrt(np.mean(e**2))),
        "bias": float(np.mean(e)),
        "within_5mm_fraction": float(np.mean(np.abs(e) <= 0.005)),
        "std_error_over_sigma": float(np.std(z, ddof=1)) if z.size > 1 else None,
    }


def swing_toe_extent(run_session, ref, stride, leg_model, config=None):
    """(least x, greatest x, mean y) of the measured toe over a scored stride's mid-swing: the
    features whose edge lies in that x range at that y are those the swing must clear; None
    when the path cannot be had."""
    from graph_slam.terrain.features.clearance import ClearanceConfig

    cfg = config or ClearanceConfig()
    paths = _swing_paths(run_session, ref, stride, leg_model, cfg)
    if paths is None:
        return None
    x = paths[0][:, 0]
    return float(np.min(x)), float(np.max(x)), float(np.mean(paths[0][:, 1]))


def in_swing(row: dict, extent) -> bool:
    """Whether a deadline row's feature is one the swing of ``extent``
    (:func:`swing_toe_extent`) must clear: its edge within the toe's x range and, for an edge
    line, the toe's y within the line's y range (5 cm margin)."""
    if extent is None or not extent[0] <= row["edge_x_m"] <= extent[1]:
        return False
    lo, hi = row.get("edge_y_range_m") or (-math.inf, math.inf)
    return lo - 0.05 <= extent[2] <= hi + 0.05
