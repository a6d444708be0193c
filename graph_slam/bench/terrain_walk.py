"""``graph-slam bench terrain``: the full graph on the terrain-following walker's scenes.

Per scene and speed: simulate a few strides (every frame, ``drops: none``, the given
resolution), run ``icp+imu+kin`` (a preset over the defaults, e.g. ``realtime``) twice on the
same session — with the stride anchor that fuses the ground plane only where it is level
(the default) and with the level-ground anchor (``graph.floor.assume_level: true``) — and
score every complete stride against the truth: smoothed and online RMSE in the stride frame
(unaligned), the anchor's tilt error (the angle between the estimated and the true up vector
in the camera frame at the stride's first frame), the anchor's case and measured slope, and
the terrain label under the stance foot (``strides_truth.csv``). A level reference (the
level-floor walker on ``flat-floor``, same speed, resolution and preset) gives the RMSE the
targets compare with. Figures: docs/benchmarks.md ("Terrain-following walker").
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class TerrainStrideScore:
    scene: str
    speed: str
    anchor: str  # "new" or "level"
    stride: int
    label: str
    smoothed_mm: float
    online_mm: float
    tilt_deg: float
    case: str
    slope_deg: float
    floor: str = ""
    registered: int = 0
    """Frames of the stride whose registration the graph took (``icp:ok`` / ``icp:partial``)."""
    registered_off: int = 0
    """Of those, frames whose online or smoothed position is more than ``OFF_M`` off the truth."""


@dataclass(frozen=True)
class TerrainRun:
    scene: str
    speed: str
    anchor: str
    frames: int
    posed_online: int
    posed_smoothed: int
    strides: list[TerrainStrideScore]


OFF_M = 0.02
"""A frame counted registered must not be farther than this from the truth (stride frame)."""


def _registered_off(res, ref) -> tuple[int, int]:
    """(registered frames, of them more than ``OFF_M`` off online or smoothed) of one stride."""
    idx = np.asarray(ref.frame_indices)
    truth = ref.stride_T_camera[:, :3, 3]
    err = np.maximum(
        np.linalg.norm(res.online_stride_T_camera[idx, :3, 3] - truth, axis=1),
        np.linalg.norm(res.smoothed_stride_T_camera[idx, :3, 3] - truth, axis=1),
    )
    reg = np.array([any(f in ("icp:ok",) or f.startswith("icp:partial")
                        for f in res.frames[i].flags) for i in idx])  # fmt: skip
    return int(reg.sum()), int((reg & ~(err <= OFF_M)).sum())


def _config(preset: str | None, assume_level: bool, overrides: dict | None = None):
    """The full graph's config: the preset, then ``overrides`` (a partial PipelineConfig
    dict, e.g. ``--config``'s YAML), then the bench's own settings."""
    from graph_slam.config import merge_dicts
    from graph_slam.pipelines import PipelineConfig
    from graph_slam.pipelines.config import with_preset

    data = PipelineConfig().model_dump(mode="json")
    if preset:
        data = with_preset(data, preset)
    if overrides:
        data = merge_dicts(data, overrides)
    data["variant"] = "icp+imu+kin"
    data["terrain"] = {**data["terrain"], "enabled": False}
    data["graph"]["floor"] = {**data["graph"]["floor"], "assume_level": assume_level}
    return PipelineConfig.model_validate(data)


def _flag(flags, prefix: str) -> str:
    return next((f.split(":", 1)[1] for f in flags if f.startswith(prefix)), "")


def score_terrain_run(
    scene: str,
    speed: str,
    path: Path,
    preset: str | None,
    assume_level: bool,
    overrides: dict | None = None,
):
    """One run of the full graph on a simulated session, scored per stride."""
    from graph_slam.bench.accuracy import score
    from graph_slam.pipelines import run_session
    from graph_slam.session import open_session
    from graph_slam.sim.terrain_truth import read_stride_terrain
    from graph_slam.strides.kinematics import session_leg_model
    from graph_slam.strides.reference import stride_references
    from graph_slam.strides.streams import session_streams

    session = open_session(path)
    leg, _ = session_leg_model(session)
    truth = read_stride_terrain(path) if (path / "strides_truth.csv").exists() else []
    res = run_session(session, _config(preset, assume_level, overrides))
    scores = score(session, res, leg)
    refs = stride_references(
        session, res.t_s, res.strides, session_streams(session, "load_cell").events, leg
    )
    rows = []
    for ref, sc in zip(refs, scores, strict=True):
        i0 = int(ref.frame_indices[0])
        up = np.array([0.0, 0.0, 1.0])
        est = res.smoothed_stride_T_camera[i0, :3, :3].T @ up
        tru = ref.stride_T_camera[0, :3, :3].T @ up
        tilt = math.degrees(math.acos(min(1.0, float(est @ tru))))
        label = "level"
        for row in truth:  # the true stride whose strike is nearest this one
            if abs(row.strike_t_s - ref.t_strike_s) < 0.1:
                label = row.label
        flags = res.frames[i0].flags
        slope = _flag(flags, "slope_deg:")
        registered, off = _registered_off(res, ref)
        rows.append(
            TerrainStrideScore(
                scene, speed, "level" if assume_level else "new", int(ref.stride_index), label,
                sc.smoothed_rmse_m * 1e3, sc.online_rmse_m * 1e3, tilt,
                _flag(flags, "anchor:") or "-", float(slope) if slope else float("nan"),
                _flag(flags, "floor:"), registered, off,
            )
        )  # fmt: skip
    online = np.isfinite(res.online_stride_T_camera[:, 0, 0]).sum()
    return TerrainRun(
        scene, speed, "level" if assume_level else "new", len(res.frames), int(online),
        int(res.has_pose.sum()), rows,
    )  # fmt: skip


def run_terrain_bench(
    scenes: list[str],
    speeds: list[str],
    strides: int = 2,
    resolution: str = "424x240",
    preset: str | None = "realtime",
    seed: int = 3,
    level_scene: str = "flat-floor",
    progress=None,
    overrides: dict | None = None,
    compare_level: bool = True,
) -> list[TerrainRun]:
    """Simulate and score every scene at every speed (module text); the level reference
    first. ``progress(line)`` gets each run's lines as they finish; ``overrides``: a partial
    PipelineConfig dict for every run (the level reference's too); ``compare_level`` False:
    the level-ground anchor is not run (half the time; no tilt of its own to compare)."""
    from graph_slam.sim import SPEEDS_M_S, SimConfig, simulate

    out: list[TerrainRun] = []
    with tempfile.TemporaryDirectory() as tmp:
        for speed in speeds:
            for scene in [level_scene, *scenes]:
                path = Path(tmp) / f"{scene}-{speed}"
                cfg = SimConfig(
                    scene=scene, speed_m_s=SPEEDS_M_S[speed], strides=strides, seed=seed,
                    drops="none", resolution=resolution, quicklook=False,
                )  # fmt: skip
                simulate(cfg, path, overwrite=True)
                compare = compare_level and scene != level_scene
                anchors = (False, True) if compare else (False,)
                for assume_level in anchors:
                    run = score_terrain_run(scene, speed, path, preset, assume_level, overrides)
                    out.append(run)
                    if progress is not None:
                        for line in run_lines(run):
                            progress(line)
    return out


def run_lines(run: TerrainRun) -> list[str]:
    head = (
        f"{run.scene:16s} {run.speed:6s} anchor={run.anchor:5s} posed online "
        f"{run.posed_online}/{run.frames} smoothed {run.posed_smoothed}/{run.frames}"
    )
    lines = [head]
    for s in run.strides:
        lines.append(
            f"  stride {s.stride} {s.label:11s} smoothed {s.smoothed_mm:6.1f} mm online "
            f"{s.online_mm:6.1f} mm  tilt {s.tilt_deg:5.2f} deg  {s.case:5s} "
            f"slope {s.slope_deg:6.2f} deg  registered {s.registered} (>2 cm: "
            f"{s.registered_off})  {s.floor}"
        )
    return lines


def summary_rows(runs: list[TerrainRun], skip_first: bool = True) -> list[dict]:
    """Per scene and speed (the new anchor): median smoothed/online RMSE (mm) and their ratio
    to the level reference's, the worst tilt error of each anchor on ramp strides (deg), the
    frames posed. ``skip_first``: leave out each session's first stride (its anchor has under
    a second of IMU history: 10-40° off, on every scene)."""
    if skip_first:
        runs = [replace(r, strides=[s for s in r.strides if s.stride > 1]) for r in runs]
    level = {r.speed: r for r in runs if r.anchor == "new" and r.scene == runs[0].scene}

    def median(run: TerrainRun | None, key: str) -> float:
        values = [getattr(s, key) for s in run.strides] if run else []
        return float(np.median(values)) if values else math.nan

    rows = []
    for r in runs:
        if r.anchor != "new":
            continue
        ref = level.get(r.speed)
        old = next((o for o in runs if o.anchor == "level" and o.scene == r.scene
                    and o.speed == r.speed), None)  # fmt: skip
        ramp = [s.tilt_deg for s in r.strides if s.label.startswith("ramp")]
        ramp_old = [s.tilt_deg for s in (old.strides if old else []) if s.label.startswith("ramp")]
        ramp_tilt = "-"
        if ramp:
            ramp_tilt = f"{max(ramp):.2f}/" + (f"{max(ramp_old):.2f}" if ramp_old else "-")
        sm, on = median(r, "smoothed_mm"), median(r, "online_mm")
        rows.append({
            "scene": r.scene, "speed": r.speed, "smoothed_mm": sm, "online_mm": on,
            "smoothed_x_level": sm / median(ref, "smoothed_mm"),
            "online_x_level": on / median(ref, "online_mm"),
            "ramp_tilt": ramp_tilt,
            "posed": f"{r.posed_online}/{r.frames}",
            "registered_off": f"{sum(s.registered_off for s in r.strides)}/"
            f"{sum(s.registered for s in r.strides)}",
        })  # fmt: skip
    return rows


def summary_lines(runs: list[TerrainRun], skip_first: bool = True) -> list[str]:
    """:func:`summary_rows` as aligned text."""
    lines = [
        f"{'scene':16s} {'speed':6s} {'smoothed mm':>11s} {'×level':>6s} {'online mm':>9s} "
        f"{'×level':>6s} {'ramp tilt new/level deg':>24s} {'posed':>9s} {'reg >2cm':>9s}"
    ]
    for r in summary_rows(runs, skip_first):
        lines.append(
            f"{r['scene']:16s} {r['speed']:6s} {r['smoothed_mm']:11.1f} "
            f"{r['smoothed_x_level']:6.2f} {r['online_mm']:9.1f} {r['online_x_level']:6.2f} "
            f"{r['ramp_tilt']:>24s} {r['posed']:>9s} {r['registered_off']:>9s}"
        )
    return lines


def markdown_table(runs: list[TerrainRun], command: str, skip_first: bool = True) -> str:
    """:func:`summary_rows` as a markdown table with its caption (date, commit, cores,
    command)."""
    from graph_slam.bench.caption import caption

    lines = [
        f"({caption(command)})",
        "",
        "| scene | speed | smoothed mm | × level | online mm | × level "
        "| ramp tilt °, new / level-ground anchor | posed online | registered > 2 cm off |",
        "| :-- | :-- | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for r in summary_rows(runs, skip_first):
        lines.append(
            f"| {r['scene']} | {r['speed']} | {r['smoothed_mm']:.1f} "
            f"| {r['smoothed_x_level']:.2f} | {r['online_mm']:.1f} | {r['online_x_level']:.2f} "
            f"| {r['ramp_tilt']} | {r['posed']} | {r['registered_off']} |"
        )
    return "\n".join(lines)


def joint_peaks(scene: str, speed: str, strides: int = 6, seed: int = 3) -> list[dict]:
    """Per recorded stride of the terrain walker (no rendering): its terrain label, the label
    of the stride before it (``arrived``) and the peaks of the prosthetic leg's angles (deg):
    knee flexion at the strike, in stance and in swing, thigh flexion (from the vertical),
    ankle dorsiflexion and plantarflexion."""
    from graph_slam.sim import SPEEDS_M_S
    from graph_slam.sim.scene import load_scene
    from graph_slam.sim.walker import TerrainMotion

    m = TerrainMotion(SPEEDS_M_S[speed], strides, seed, load_scene(scene).surfaces)
    out = []
    for k, label in enumerate(m.stride_labels):
        t = np.linspace(m.foot_strikes_s[k], m.foot_strikes_s[k + 1], 400)
        knee, ankle = (np.degrees(a) for a in m.joint_angles(t))
        thigh = np.degrees(m.thigh_angle(t))
        st = m.stance_mask(t)
        out.append({
            "label": label, "arrived": m.labels[k], "knee_strike": knee[0],
            "knee_stance": knee[st].max(), "knee_swing": knee[~st].max(), "thigh_max": thigh.max(), "thigh_min": thigh.min(),
            "ankle_max": ankle.max(), "ankle_min": ankle.min(),
        })  # fmt: skip
    return out


def angle_lines(scenes: list[str], speeds: list[str], strides: int, seed: int) -> list[str]:
    """Per terrain label: the range over strides (scenes × speeds) of each joint peak; a
    stride that arrived from another terrain is grouped as ``before>label``."""
    keys = ("knee_strike", "knee_stance", "knee_swing", "thigh_max", "ankle_max", "ankle_min")
    groups: dict[str, list[dict]] = {}
    for scene in scenes:
        for speed in speeds:
            for row in joint_peaks(scene, speed, strides, seed):
                label, before = row["label"], row["arrived"]
                groups.setdefault(label if before == label else f"{before}>{label}", []).append(row)
    lines = [f"{'terrain':23s} {'n':>3s} " + " ".join(f"{k:>13s}" for k in keys)]
    for label, rows in sorted(groups.items()):
        cells = [f"{min(r[k] for r in rows):6.0f}..{max(r[k] for r in rows):<5.0f}" for k in keys]
        lines.append(f"{label:23s} {len(rows):3d} " + " ".join(cells))
    return lines
