"""What ``run`` can say without ground truth: per-stride frame counts, the baseline's stop points,
timing, and how far the variants' trajectories and maps agree with a reference variant.

Agreement is not accuracy: two variants that drift alike agree. It says where the variants
differ, which is where a recording deserves a look (docs/run.md).
"""

from __future__ import annotations

import numpy as np

from graph_slam.report.artefacts import _num, stage_names
from graph_slam.variants import Variant


def _stats_ms(seconds) -> dict:
    """:func:`graph_slam.evaluation.timing.timing_stats` in milliseconds (None when empty)."""
    from graph_slam.evaluation.timing import timing_stats

    if np.asarray(seconds).size == 0:
        return {"n": 0, "median_ms": None, "p95_ms": None, "max_ms": None}
    t = timing_stats(np.asarray(seconds, dtype=float))
    return {
        "n": t.n,
        "median_ms": _num(t.median_s * 1e3),
        "p95_ms": _num(t.p95_s * 1e3),
        "max_ms": _num(t.max_s * 1e3),
    }


def timing(results) -> dict:
    """Per-frame wall time (front + back end + terrain) and per stage: median / p95 / max."""
    frames = results.frames
    out = {"total": _stats_ms([f.frontend_s + f.backend_s + f.terrain_s for f in frames])}
    for stage in stage_names(results):
        out[stage] = _stats_ms([f.stages_s[stage] for f in frames if stage in f.stages_s])
    return out


def stride_counts(results) -> list[dict]:
    """Per stride: its frames and how many were registered / partial / bridged / other."""
    from graph_slam.report.scoring import frame_categories

    cats = frame_categories(results)
    out = []
    for s in results.strides:
        idx = [int(i) for i in s.frame_indices]
        if not idx:
            continue
        mine = [cats[i] for i in idx]
        out.append(
            {
                "stride": int(s.index),
                "start": s.start,
                "first_frame": idx[0],
                "last_frame": idx[-1],
                "t_start_s": float(results.frames[idx[0]].t_s),
                "t_end_s": float(results.frames[idx[-1]].t_s),
                "frames": len(idx),
                **{c: mine.count(c) for c in ("registered", "partial", "bridged", "other")},
                "stop_reason": s.stop_reason,
                **anchor_of(results.frames[idx[0]].flags),
                **grid_frames_of(s),
            }
        )
    return out


def anchor_of(flags) -> dict:
    """The stride anchor's case and measured slope from a stride's first frame's flags
    (``anchor:<case>``, ``slope_deg:<x>``; graph variants), else nothing."""
    out: dict = {}
    for f in flags:
        if f.startswith("anchor:"):
            out["anchor"] = f.split(":", 1)[1]
        elif f.startswith("up:"):
            out["up_source"] = f.split(":", 1)[1]
        elif f.startswith("slope_deg:"):
            out["slope_deg"] = float(f.split(":", 1)[1])
    return out


def grid_frames_of(stride) -> dict:
    """The stride's online grid's frames fused and held back by the settling gate
    (``StrideOutput.grid_frames``; docs/terrain.md), when any frame reached the grid."""
    fused, held = getattr(stride, "grid_frames", (0, 0))
    return {"grid_frames_fused": int(fused), "grid_frames_held": int(held)} if fused + held else {}


def stop_points(results) -> list[dict]:
    """The baseline's stop points: per stride where registration stopped, the first frame
    without a pose, its time and the reason."""
    out = []
    for s in results.strides:
        if s.stop_reason is None:
            continue
        lost = [i for i in s.frame_indices if not results.frames[i].has_pose]
        first = int(lost[0]) if lost else int(s.frame_indices[-1])
        out.append(
            {
                "stride": int(s.index),
                "frame_index": first,
                "t_s": float(results.frames[first].t_s),
                "frames_without_pose": len(lost),
                "reason": s.stop_reason,
            }
        )
    return out


def _by_first_frame(results) -> dict[int, object]:
    """Strides keyed by their first frame (variants number strides differently: the graph
    counts the part before the first foot strike)."""
    return {int(s.frame_indices[0]): s for s in results.strides if s.frame_indices}


def rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R, t`` minimising ``Σ |R·src + t − dst|²`` (N×3 each; Kabsch, no scale)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rot, cd - rot @ cs


def _position_rms(a: np.ndarray, b: np.ndarray, aligned: bool) -> tuple[float | None, int]:
    """RMS of the positions' difference over the frames both posed; ``aligned``: after the
    rigid fit of ``a`` onto ``b`` (a pose set not in the stride frame: the baseline's)."""
    both = np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=(1, 2))
    if both.sum() < (3 if aligned else 1):
        return None, 0
    pa, pb = a[both, :3, 3], b[both, :3, 3]
    if aligned:
        rot, t = rigid_fit(pa, pb)
        pa = pa @ rot.T + t
    d = pa - pb
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1)))), int(both.sum())


def _grid_difference(a, b) -> dict | None:
    """|height difference| over the cells both grids saw (same grid geometry)."""
    if a is None or b is None or a.elevation.shape != b.elevation.shape:
        return None
    ha, hb = a.elevation.height_m, b.elevation.height_m
    both = np.isfinite(ha) & np.isfinite(hb)
    if not both.any():
        return {"cells": 0, "median_mm": None, "p95_mm": None}
    d = np.abs(ha[both] - hb[both]) * 1e3
    return {
        "cells": int(both.sum()),
        "median_mm": _num(np.median(d)),
        "p95_mm": _num(np.percentile(d, 95)),
    }


def agreement(results: dict, reference: Variant) -> dict[str, list[dict]]:
    """Per variant other than ``reference`` and per stride both cut at the same frames:
    the RMS of the camera positions' difference in the stride frame (online and smoothed poses;
    over frames both have; after a rigid fit when either is the thesis baseline, whose frame
    restarts at its own reset, not at the heel: ``aligned`` in the row) and the elevation
    grids' height difference (the smoothed maps; the baseline's is its online one) over the
    cells both saw."""
    ref = results[reference]
    ref_strides = _by_first_frame(ref)
    ref_poses = {k: ref.poses(k) for k in ("online", "smoothed")}
    out: dict[str, list[dict]] = {}
    for variant, res in results.items():
        if variant == reference:
            continue
        rows = []
        poses = {k: res.poses(k) for k in ("online", "smoothed")}
        for first, s in _by_first_frame(res).items():
            r = ref_strides.get(first)
            if r is None or len(r.frame_indices) != len(s.frame_indices):
                continue
            idx = np.asarray(s.frame_indices, dtype=int)
            aligned = variant.is_baseline or Variant(reference).is_baseline
            row: dict = {"stride": int(s.index), "first_frame": first, "aligned": aligned}
            for kind in ("online", "smoothed"):
                rms, n = _position_rms(poses[kind][idx], ref_poses[kind][idx], aligned)
                row[f"{kind}_position_rms_mm"] = None if rms is None else rms * 1e3
                row[f"{kind}_frames"] = n
            maps = [x.terrain.smoothed if x.terrain is not None else None for x in (s, r)]
            row["elevation"] = _grid_difference(*maps)
            rows.append(row)
        out[str(variant)] = rows
    return out


def summarise_session(session, results: dict, reference: Variant) -> dict:
    """``run.json``'s entry for one session."""
    variants = {}
    for variant, res in results.items():
        variants[str(variant)] = {
            "frames": len(res.frames),
            "frames_with_pose": int(res.has_pose.sum()) if res.frames else 0,
            "frames_outside_strides": len(res.frames)
            - sum(len(s.frame_indices) for s in res.strides),
            "strides": stride_counts(res),
            "stop_points": stop_points(res) if variant.is_baseline else [],
            "timing": timing(res),
            "counts": {k: int(v) for k, v in res.counts.items()},
        }
    mounts = [res.config["mount_pitch"] for res in results.values() if "mount_pitch" in res.config]
    return {
        "path": str(session.path),
        "frames": int(session.n_frames),
        "ground_truth": session.ground_truth is not None,
        "mount_pitch": mounts[0] if mounts else None,
        "variants": variants,
        "agreement": agreement(results, reference),
    }


def _short(reason: str | None, n: int = 100) -> str:
    """A stop reason for a table (run.json keeps it whole)."""
    if not reason:
        return ""
    return reason if len(reason) <= n else reason[: n - 1] + "…"


def _fmt(x, spec: str = ".1f") -> str:
    return "–" if x is None else format(x, spec)


def _med(values) -> float | None:
    a = np.asarray([v for v in values if v is not None], dtype=float)
    return float(np.median(a)) if a.size else None


def _counts_table(variants: dict) -> list[str]:
    lines = [
        "| variant | strides | frames | registered | partial | bridged | other | "
        "before the first stride | time median / p95 (ms) |",
        "| :-- | --: | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for name, v in variants.items():
        total = {c: sum(s[c] for s in v["strides"]) for c in ("registered", "partial", "bridged")}
        other = sum(s["other"] for s in v["strides"])
        t = v["timing"]["total"]
        lines.append(
            f"| {name} | {len(v['strides'])} | {v['frames']} | {total['registered']} | "
            f"{total['partial']} | {total['bridged']} | {other} | "
            f"{v['frames_outside_strides']} | {_fmt(t['median_ms'])} / {_fmt(t['p95_ms'])} |"
        )
    return [*lines, ""]


def _per_stride_table(variants: dict) -> list[str]:
    lines = [
        "| variant | stride | frames | registered | partial | bridged | other | stop |",
        "| :-- | --: | --: | --: | --: | --: | --: | :-- |",
    ]
    for name, v in variants.items():
        for s in v["strides"]:
            lines.append(
                f"| {name} | {s['stride']} ({s['first_frame']}–{s['last_frame']}) | "
                f"{s['frames']} | {s['registered']} | {s['partial']} | {s['bridged']} | "
                f"{s['other']} | {_short(s['stop_reason'], 40)} |"
            )
    return [*lines, ""]


def _agreement_table(agree: dict, reference: str) -> list[str]:
    if not agree:
        return [f"Only {reference} ran: nothing to compare it with.", ""]
    lines = [
        f"Against {reference}, medians over strides (online: max in brackets):",
        "",
        "| variant | strides | position RMS online (mm) | smoothed (mm) | "
        "elevation |Δh| median / p95 (mm) |",
        "| :-- | --: | --: | --: | --: |",
    ]
    for variant, rows in agree.items():
        name = f"{variant} (rigidly aligned)" if rows and rows[0]["aligned"] else variant
        on = [r["online_position_rms_mm"] for r in rows]
        sm = [r["smoothed_position_rms_mm"] for r in rows]
        el = [r["elevation"] for r in rows if r["elevation"] is not None]
        mx = [x for x in on if x is not None]
        lines.append(
            f"| {name} | {len(rows)} | {_fmt(_med(on))} ({_fmt(max(mx) if mx else None)}) | "
            f"{_fmt(_med(sm))} | {_fmt(_med([e['median_mm'] for e in el]))} / "
            f"{_fmt(_med([e['p95_mm'] for e in el]))} |"
        )
    return [*lines, ""]


_MOUNT_SOURCES = {
    "config": "set by pipeline.mount_pitch_deg",
    "calibration": "fitted to the session's thigh_T_camera",
    "estimated": "estimated from the session's foot-flat stance (docs/kinematics.md)",
}


def _mount_line(mount: dict | None) -> list[str]:
    """The leg model's camera mount pitch and where it came from."""
    if not mount:
        return []
    text = f"Camera mount pitch {mount['pitch_deg']:.2f}° below horizontal, "
    text += _MOUNT_SOURCES.get(mount["source"], mount["source"])
    if "n_samples" in mount:
        text += (
            f": {mount['n_samples']} IMU samples, spread {mount['spread_deg']:.2f}° (1.4826·MAD)"
        )
    return [text + ".", ""]


def run_markdown(summary: dict, cfg) -> str:
    """``report.md`` of a run: per session, the counts, stop points, timing and agreement."""
    lines = [
        "# graph_slam run",
        "",
        f"Preset: {cfg.pipeline.preset}. Variants: {', '.join(summary['variants'])}; agreement against "
        f"{summary['reference']}. Wall time {summary.get('wall_s', 0.0):.0f} s. Resolved "
        "config: `config.yaml`; every number: `run.json`; layout: docs/run.md.",
        "",
        "Registered: frames whose pose came from a registration that held all six directions; "
        "partial: one that held only some, the rest bridged; bridged: frames carried by "
        "IMU/kinematics factors over a missing, rejected or degenerate registration; other: "
        "the stride's first (reset) frame and frames without a pose.",
        "",
    ]
    if summary["warnings"]:
        lines += ["## Warnings", ""]
        lines += [f"- **{w['code']}** — `{w['file']}`: {w['message']}" for w in summary["warnings"]]
        lines += [""]
    for name, sess in summary["sessions"].items():
        gt = (
            "has ground truth (score it with `graph-slam compare`)"
            if sess["ground_truth"]
            else ("no ground truth")
        )
        lines += [f"## Session {name}", "", f"`{sess['path']}`: {sess['frames']} frames, {gt}.", ""]
        lines += [*_mount_line(sess.get("mount_pitch"))]
        lines += ["### Frames and timing", "", *_counts_table(sess["variants"])]
        lines += ["### Per stride", "", *_per_stride_table(sess["variants"])]
        stops = [(v, p) for v, x in sess["variants"].items() for p in x["stop_points"]]
        lines += ["### Where the baseline stopped", ""]
        if stops:
            lines += [
                f"- {v}, stride {p['stride']}: frame {p['frame_index']} (t = {p['t_s']:.3f} s), "
                f"{p['frames_without_pose']} frames without pose: {_short(p['reason'])}"
                for v, p in stops
            ]
        else:
            ran = any(Variant(v).is_baseline for v in sess["variants"])
            lines += ["Nowhere: it registered to the end of every stride." if ran else "Not run."]
        lines += [
            "",
            "### Agreement",
            "",
            *_agreement_table(sess["agreement"], summary["reference"]),
        ]
    lines += [
        "## Files",
        "",
        "`<session>/<variant>/`: `online.tum`, `smoothed.tum` (stride_T_camera), "
        "`*_world.tum` (world_T_camera)"
        + (", `*.kitti` with `*.kitti.times.txt`" if cfg.kitti else "")
        + ", `frames.csv`, `timing.csv`, `maps/sNN_<poses>.ply|_elevation.csv|_terrain.json`; "
        + ("`recording.rrd` (`graph-slam view`)." if cfg.rrd else "no rerun recording."),
        "",
    ]
    return "\n".join(lines)
