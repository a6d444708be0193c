"""Pipelines benchmark: every variant on simulated thesis-box sessions.

For each session (one speed) and variant: poses per frame (online, smoothed), per-stride
camera-position RMSE in the stride frame (no alignment) against the simulator's truth, swing
errors of the full graph vs the thesis baseline on the same frames, the IMU+kinematics error at
the next foot strike, the baseline's registered-frame counts per stride (thesis Table 4.2) and
the per-frame processing time.

Truth stride frame: :func:`graph_slam.strides.reference.truth_world_T_stride` (the
ground-truth camera pose at the stride's first frame carried to the foot by the encoders; heel
origin, z up, x the horizontal projection of the sole's x axis), as the comparison report. Only strides that start at a load-cell foot
strike and end at the next are scored.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.pipelines import VARIANTS, PipelineConfig, PipelineResults, run_session
from graph_slam.pipelines.config import with_preset


@dataclass
class StrideScore:
    index: int
    n_frames: int
    n_swing: int
    online_rmse_m: float
    smoothed_rmse_m: float
    end_online_m: float
    end_smoothed_m: float
    n_with_pose: int
    n_registered_stance: int
    n_stance: int
    swing_err_m: np.ndarray  # per swing frame, smoothed (NaN without pose)
    swing_frames: np.ndarray


@dataclass
class VariantScore:
    variant: str
    strides: list[StrideScore]
    frames_without_pose_online: int
    frames_without_pose_smoothed: int
    timing_ms: dict[str, float]
    wall_s: float


@dataclass
class SessionScore:
    name: str
    speed: str
    variants: dict[str, VariantScore] = field(default_factory=dict)


def score(session, results: PipelineResults, leg_model) -> list[StrideScore]:
    """Per complete stride (:func:`graph_slam.strides.reference.stride_references`, strides
    cut at the load cell's events): errors of the online and smoothed ``stride_T_camera``."""
    from graph_slam.strides.reference import stride_references
    from graph_slam.strides.streams import session_streams

    events = session_streams(session, "load_cell").events
    refs = stride_references(session, results.t_s, results.strides, events, leg_model)
    online = results.online_stride_T_camera
    smoothed = results.smoothed_stride_T_camera
    out = []
    for ref in refs:
        idx = ref.frame_indices
        truth = ref.stride_T_camera
        e_on = np.linalg.norm(online[idx, :3, 3] - truth[:, :3, 3], axis=1)
        e_sm = np.linalg.norm(smoothed[idx, :3, 3] - truth[:, :3, 3], axis=1)
        loaded = np.array([results.frames[i].foot_loaded for i in idx])
        swing = ~loaded
        has = np.isfinite(e_sm)
        out.append(
            StrideScore(
                index=ref.stride_index,
                n_frames=idx.size,
                n_swing=int(swing.sum()),
                online_rmse_m=float(np.sqrt(np.nanmean(e_on**2))) if has.any() else np.nan,
                smoothed_rmse_m=float(np.sqrt(np.nanmean(e_sm**2))) if has.any() else np.nan,
                end_online_m=float(e_on[-1]),
                end_smoothed_m=float(e_sm[-1]),
                n_with_pose=int(has.sum()),
                n_registered_stance=int((has & loaded).sum()),
                n_stance=int(loaded.sum()),
                swing_err_m=e_sm[swing],
                swing_frames=idx[swing],
            )
        )
    return out


BRIDGE = "bridge"
"""The bridging experiment: ``icp+imu+kin`` with no registration in swing (``graph.icp_in_swing``
False), as if every swing registration failed; scored at the next foot strike."""


def variant_config(name: str) -> PipelineConfig:
    """The pipeline configuration of a benchmark row (a variant or :data:`BRIDGE`, optionally
    ``:preset`` for a registration preset, e.g. ``icp+imu+kin:realtime``); no terrain maps
    (this benchmark scores poses only). ``:preset``: a pipeline preset
    (:data:`graph_slam.pipelines.config.PIPELINE_PRESETS`)."""
    name, _, preset = name.partition(":")
    data: dict = {"variant": "icp+imu+kin" if name == BRIDGE else name, "graph": {}}
    if preset:
        data = with_preset(data, preset)
    if name == BRIDGE:
        data["graph"] = {**data["graph"], "icp_in_swing": False}
    data["terrain"] = {"enabled": False}
    return PipelineConfig.model_validate(data)


def run_pipelines_bench(
    sessions: dict[str, Path],
    variants: tuple[str, ...] = (*VARIANTS, BRIDGE),
    progress=None,
    on_variant=None,
) -> list[SessionScore]:
    """Run every variant on every session (speed -> folder) and score it.

    ``on_variant(session_score, variant)`` is called as soon as a variant is scored (the CLI
    prints its lines then: a full run takes many minutes)."""
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import session_leg_model

    scores = []
    for speed, path in sessions.items():
        session = open_session(path)
        leg, _ = session_leg_model(session)
        sc = SessionScore(session.name, speed)
        for v in variants:
            t0 = time.perf_counter()
            res = run_session(session, variant_config(v), progress=progress)
            wall = time.perf_counter() - t0
            sm = res.smoothed_stride_T_camera
            sc.variants[v] = VariantScore(
                variant=v,
                strides=score(session, res, leg),
                frames_without_pose_online=int((~res.has_pose).sum()),
                frames_without_pose_smoothed=int((~np.isfinite(sm[:, 0, 0])).sum()),
                timing_ms=res.timings_ms(),
                wall_s=wall,
            )
            if on_variant is not None:
                on_variant(sc, v)
        scores.append(sc)
    return scores


def variant_lines(v: str, vs: VariantScore) -> list[str]:
    """One variant on one session: poses, timing, stride-frame RMSE (or the baseline's counts)."""
    on = np.array([s.online_rmse_m for s in vs.strides]) * 1e3
    sm = np.array([s.smoothed_rmse_m for s in vs.strides]) * 1e3
    endo = np.array([s.end_online_m for s in vs.strides]) * 1e3
    ends = np.array([s.end_smoothed_m for s in vs.strides]) * 1e3
    lines = [
        f"  {v:12s} {len(vs.strides)} full strides; frames without pose online "
        f"{vs.frames_without_pose_online}, smoothed {vs.frames_without_pose_smoothed}; "
        f"per-frame time median {vs.timing_ms['median']:.1f} ms, "
        f"p95 {vs.timing_ms['p95']:.1f} ms; wall {vs.wall_s:.1f} s"
    ]
    if v != "icp" and on.size:
        lines.append(
            f"    stride-frame RMSE online median {np.median(on):.1f} / worst "
            f"{on.max():.1f} mm; smoothed median {np.median(sm):.1f} / worst "
            f"{sm.max():.1f} mm; error at next foot strike online max "
            f"{endo.max():.1f} mm, smoothed max {ends.max():.1f} mm"
        )
        lines.append(
            "    per stride smoothed / online / next strike (mm): "
            + ", ".join(f"{a:.1f}/{b:.1f}/{c:.1f}" for a, b, c in zip(sm, on, ends, strict=True))
        )
    if v == "icp":
        for s in vs.strides:
            lines.append(
                f"    stride {s.index}: {s.n_with_pose}/{s.n_frames} frames with a pose "
                f"(stance {s.n_registered_stance}/{s.n_stance}, swing "
                f"{s.n_with_pose - s.n_registered_stance}/{s.n_swing}); RMSE on them "
                f"{s.smoothed_rmse_m * 1e3:.1f} mm"
            )
    return lines


def swing_lines(sc: SessionScore) -> list[str]:
    """The full graph vs the baseline on the same swing frames."""
    if "icp" not in sc.variants or "icp+imu+kin" not in sc.variants:
        return []
    base = {
        int(s.swing_frames[0]) if s.swing_frames.size else -s.index - 1: s
        for s in sc.variants["icp"].strides
    }
    n_sw = n_nopose = 0
    ratios = []
    for s in sc.variants["icp+imu+kin"].strides:
        b = base.get(int(s.swing_frames[0]) if s.swing_frames.size else -s.index - 1)
        if b is None or not np.array_equal(b.swing_frames, s.swing_frames):
            continue
        n_sw += s.swing_frames.size
        has = np.isfinite(b.swing_err_m)
        n_nopose += int((~has).sum())
        if has.any():
            g = np.sqrt(np.mean(s.swing_err_m[has] ** 2))
            bb = np.sqrt(np.mean(b.swing_err_m[has] ** 2))
            ratios.append((bb * 1e3, g * 1e3, bb / g))
    return [
        f"  swing: {n_sw} frames; baseline without pose on {n_nopose}; where it has "
        "one, baseline / full-graph RMSE (mm, ratio) per stride: "
        + (", ".join(f"{a:.1f}/{b:.1f} ({r:.1f}x)" for a, b, r in ratios) or "none")
    ]


def summary_lines(scores: list[SessionScore]) -> list[str]:
    """Per variant over every session: smoothed stride RMSE median / worst, next-strike max."""
    lines = ["== all sessions"]
    names = dict.fromkeys(v for sc in scores for v in sc.variants)
    for v in names:
        if v == "icp":
            continue
        st = [s for sc in scores if v in sc.variants for s in sc.variants[v].strides]
        if not st:
            continue
        sm = np.array([s.smoothed_rmse_m for s in st]) * 1e3
        ends = np.array([s.end_smoothed_m for s in st]) * 1e3
        lines.append(
            f"  {v:12s} {len(st)} strides: smoothed RMSE median {np.median(sm):.1f} / worst "
            f"{sm.max():.1f} mm; next strike median {np.median(ends):.1f} / max "
            f"{ends.max():.1f} mm"
        )
    return lines


def markdown_table(scores: list[SessionScore], command: str) -> str:
    """Per session and graph variant: strides, smoothed and online stride-frame RMSE (median /
    worst), the smoothed error at the next foot strike (median / max), as a markdown table
    with its caption (date, commit, cores, command)."""
    from graph_slam.bench.caption import caption

    lines = [
        f"({caption(command)})",
        "",
        "| session | variant | strides | smoothed RMSE mm median / worst "
        "| online RMSE mm median / worst | next strike mm median / max |",
        "| :-- | :-- | --: | --: | --: | --: |",
    ]
    for sc in scores:
        for v, vs in sc.variants.items():
            if v == "icp" or not vs.strides:
                continue
            sm = np.array([s.smoothed_rmse_m for s in vs.strides]) * 1e3
            on = np.array([s.online_rmse_m for s in vs.strides]) * 1e3
            ends = np.array([s.end_smoothed_m for s in vs.strides]) * 1e3
            lines.append(
                f"| {sc.name} | {v} | {len(sm)} | {np.median(sm):.1f} / {sm.max():.1f} "
                f"| {np.median(on):.1f} / {on.max():.1f} "
                f"| {np.median(ends):.1f} / {ends.max():.1f} |"
            )
    return "\n".join(lines)


def header_line() -> str:
    return f"pipelines benchmark ({len(os.sched_getaffinity(0))} CPUs visible)"
