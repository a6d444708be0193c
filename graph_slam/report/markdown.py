"""``report.md`` of the comparison report, and the summary table the CLI prints."""

from __future__ import annotations

import numpy as np


def _phase_table(variants: dict) -> str:
    lines = [
        "| variant | strides | RMSE aligned median (mm) | stance (mm) | swing (mm) | unaligned median (mm) | time median / p95 (ms) |",
        "| :-- | --: | --: | --: | --: | --: | --: |",
    ]

    def med(values):
        a = np.asarray([x for x in values if x is not None], dtype=float)
        a = a[np.isfinite(a)]
        return f"{np.median(a) * 1e3:.1f}" if a.size else "–"

    for name, v in variants.items():
        traj = [s.trajectory for s in v.strides if s.trajectory is not None]
        phase = {
            p: [t.rmse_by_phase_m.get(p, {}).get("aligned") for t in traj]
            for p in ("stance", "swing")
        }
        timing = f"{v.timing.median_s * 1e3:.1f} / {v.timing.p95_s * 1e3:.1f}" if v.timing else "–"
        lines.append(
            f"| {name} | {len(v.strides)} | {med([t.rmse_aligned_m for t in traj])} | "
            f"{med(phase['stance'])} | {med(phase['swing'])} | "
            f"{med([t.rmse_unaligned_m for t in traj])} | {timing} |"
        )
    return "\n".join(lines) + "\n"


def summary_table(report) -> str:
    """Per variant: median RMSE (aligned, stance, swing, unaligned) and per-frame time."""
    return _phase_table(report.variants)


def terrain_section(variants: dict) -> list[str]:
    """Per variant and terrain label (strides on simulated terrain): median RMSE (mm)."""
    if not any(s.terrain is not None for v in variants.values() for s in v.strides):
        return []
    lines = [
        "## By terrain (the stance foot's terrain, from the simulator's truth)",
        "",
        "| variant | terrain | strides | RMSE unaligned median (mm) | aligned median (mm) |",
        "| :-- | :-- | --: | --: | --: |",
    ]
    for name, v in variants.items():
        for label, g in v.by_terrain().items():
            un, al = g["rmse_unaligned_m"]["median"], g["rmse_aligned_m"]["median"]
            lines.append(
                f"| {name} | {label} | {g['strides']} | "
                + " | ".join("–" if not np.isfinite(x) else f"{x * 1e3:.1f}" for x in (un, al))
                + " |"
            )
    return [*lines, ""]


def _warnings_section(report) -> list[str]:
    """Caveats that apply to the numbers below (also ``warnings`` in metrics.json)."""
    warnings = report.warnings
    lines = ["## Warnings", ""]
    if not warnings:
        return [*lines, "None: no gap, unit, range or dropped-stride caveat applies.", ""]
    lines += [f"- **{w.code}** — `{w.file}`: {w.message}" for w in warnings]
    return [*lines, ""]


def _strides_cut_by(cfg) -> str:
    """The events that cut the strides, in words (``pipeline.event_source``)."""
    source = cfg.pipeline.event_source
    if source is None:
        return "every events.csv source"
    if source == "imu-online":
        return "imu-online (the causal thigh-IMU gait estimator, kinematics.gait_phase)"
    return f"events.csv source {source!r}"


def _fmt_s(x: float) -> str:
    return f"{x:.2f}" if np.isfinite(x) else "–"


def _mm(stats: dict | None, scale: float = 1e3) -> str:
    if not stats or stats.get("rmse") is None:
        return "–"
    z = stats.get("std_error_over_sigma")
    return f"{stats['rmse'] * scale:.1f} ({stats['n']}{'' if z is None else f', z {z:.2f}'})"


def _clearance_cell(c: dict) -> str:
    if not c.get("n"):
        return "–"
    return (
        f"{c['rmse'] * 1e3:.1f}, {c['bias'] * 1e3:+.1f}, {c['within_5mm_fraction']:.0%} of {c['n']}"
    )


def features_section(features: dict) -> list[str]:
    """Each variant's final grids' stairs, ramps, curbs and boxes against the scene's, and the
    measured swing clearance against the true one (``metrics.json``'s ``terrain_features``)."""
    if not features:
        return []
    lines = [
        "## Terrain features and toe clearance (final grids against the scene)",
        "",
        "Each scored stride's final grid (re-fused from the smoothed poses) gives its stairs, "
        "ramps, curbs and boxes (docs/terrain.md); each is matched to the scene's and scored: "
        "RMSE in mm (slope in degrees), then (n, z = std of error/σ). The swing clearance: the "
        "toe's least height over the terrain in mid-swing from the smoothed poses, the encoders "
        "and the grid, against the true poses over the scene's surface. The edge clearance: "
        "the toe's least distance to the edges the swing crossed (nosings, curbs, box edges; "
        "docs/terrain.md), measured features against the scene's; missed: an edge the true "
        "toe crossed with no measured edge on the measured path.",
        "",
        "| variant | grids | step rise | nosing | tread | ramp slope (°) | ramp start | curb "
        "height | curb edge | box height | box leading edge | box depth | swing clearance "
        "(RMSE mm, bias mm, ≤5 mm) | edge clearance (RMSE mm, bias mm, ≤5 mm; missed) |",
        "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |",
    ]
    deg = 180 / 3.141592653589793
    for name, f in features.items():
        clear = _clearance_cell(f["swing_clearance"])
        e = f.get("edge_clearance") or {"n": 0}
        edge = _clearance_cell(e) + (f"; {e['missed']} missed" if e.get("missed") else "")
        cells = [
            _mm(f["steps"]["rise_m"]), _mm(f["steps"]["nosing_m"]), _mm(f["steps"]["tread_m"]),
            _mm(f["ramps"]["slope_rad"], deg), _mm(f["ramps"]["start_m"]),
            _mm(f["curbs"]["height_m"]), _mm(f["curbs"]["edge_m"]), _mm(f["boxes"]["height_m"]),
            _mm(f["boxes"]["leading_m"]), _mm(f["boxes"]["depth_m"]),
        ]  # fmt: skip
        lines.append(f"| {name} | {f['grids']} | " + " | ".join(cells) + f" | {clear} | {edge} |")
    lines += [
        "",
        "Features known before toe-off: each feature of a stride's final grid is known at the "
        "first searched frame whose online grid had one of its kind with its edge within 2 cm "
        "(along x, where the final edge is reported) and its rise or height within 1 cm (a ramp's slope within 1°); lead = toe-off − then; "
        "the swing's own: those whose edge lies within the measured toe's x range in "
        "mid-swing (the features that swing must clear). "
        "Warnings: a swing is flagged when a stance frame's predicted edge clearance (the "
        "reference swing over the online grid's edges) was under 2 cm before its toe-off; "
        "truly < 2 cm: its true edge clearance was (a swing over level floor has none).",
        "",
        "| variant | features | known | before toe-off | ≥ 0.5 s before | median lead (s) | "
        "the swing's own: features, ≥ 0.5 s before | swings | truly < 2 cm | flagged | false "
        "warnings |",
        "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for name, f in features.items():
        d = f.get("deadlines") or {}
        if not d.get("n"):
            continue
        med = "–" if d["lead_s_median"] is None else f"{d['lead_s_median']:.2f}"
        w = f.get("warnings") or {}
        warn = " | ".join(str(w.get(k, "–")) for k in
                          ("swings", "true_below_margin", "flagged_below_margin", "false_warnings"))  # fmt: skip
        own = d.get("swing") or {}
        own_cell = f"{own.get('n', 0)}, {own.get('n_at_least_0_5_s', 0)}"
        lines.append(f"| {name} | {d['n']} | {d['n_known']} | {d['n_before_toe_off']} | "
                     f"{d['n_at_least_0_5_s']} | {med} | {own_cell} | {warn} |")  # fmt: skip
    return [*lines, ""]


def deadline_section(deadlines: dict) -> list[str]:
    """Per variant and walking speed: the obstacles each stride's final map measured whole,
    how many the online map knew (height ±1 cm, leading edge ±2 cm of the final values), how
    many before toe-off, and the lead before toe-off (docs/terrain.md)."""
    from graph_slam.evaluation.terrain_deadline import deadline_summary

    lines = [
        "## Obstacles known before toe-off (the deadline)",
        "",
        "Per stride, every obstacle its final map measures whole (the graph's grid re-fused "
        "from the smoothed poses, or its online grid at its last frame when it keeps no clouds "
        "for that, as the real-time preset; the baseline's online grid): the first "
        "frame at which the online elevation grid had its height within 1 cm and its leading "
        "edge within 2 cm of the final values. Lead = toe-off − that time (positive: known "
        "before the swing must be planned).",
        "",
    ]
    if not any(deadlines.values()):
        return [*lines, "No scored stride (or the online terrain map is off).", ""]
    lines += [
        "| variant | speed | strides | obstacles | known | before toe-off | lead median (s) "
        "| lead min (s) |",
        "| :-- | :-- | --: | --: | --: | --: | --: | --: |",
    ]
    for name, strides in deadlines.items():
        summary = deadline_summary(strides)
        for speed, d in [*summary["by_speed"].items(), ("all", summary["all"])]:
            n_strides = sum(1 for s in strides if speed in ("all", s.speed))
            lines.append(
                f"| {name} | {speed} | {n_strides} | {d['n']} | {d['n_known']} | "
                f"{d['n_before_toe_off']} | {_fmt_s(d['lead_s_median'])} | "
                f"{_fmt_s(d['lead_s_min'])} |"
            )
    return [*lines, ""]


def report_markdown(report, cfg) -> str:
    """``report.md``: what was run, Tables 4.2 and 4.1, the box counts, plots and files."""
    out = report.out
    plots_dir = out / "plots"
    pngs = sorted(p.relative_to(out) for p in plots_dir.glob("*.png")) if plots_dir.exists() else []
    lines = [
        "# graph_slam comparison report",
        "",
        f"Sessions: {', '.join(report.sessions)}. Variants: {', '.join(cfg.variants)}. "
        f"Preset: {cfg.pipeline.preset}. "
        f"Strides cut by: {_strides_cut_by(cfg)}. "
        f"Wall time {report.wall_s:.0f} s. Resolved config: `config.yaml`; every number: "
        "`metrics.json`; layout: docs/evaluation.md.",
        "",
        "RMSE: camera position in the true stride frame after SE(3) alignment (evo), per stride. "
        "Registered: frames whose pose came from a registration that held all six directions; "
        "partial (metrics.json): a registration that held only some (a plain floor: 3), the "
        "rest bridged; bridged: frames carried by IMU/kinematics factors over a missing, "
        "rejected or degenerate registration; the stride's first (reset) frame is in none.",
        "",
        *(
            [
                f"Not scored (no ground truth): {', '.join(report.unscored)}; their "
                "trajectories and maps are written, the tables leave them out.",
                "",
            ]
            if report.unscored
            else []
        ),
        *_warnings_section(report),
        "## Table 4.2 — online poses",
        "",
        report.table_4_2_online,
    ]
    if report.table_4_2_smoothed:
        lines += [
            "## Table 4.2 — smoothed poses (graph variants, batch per stride)",
            "",
            report.table_4_2_smoothed,
        ]
    lines += ["## Summary", "", summary_table(report)]
    lines += terrain_section(report.variants)
    lines += [
        "## Table 4.1 — obstacle dimensions (mm)",
        "",
        "Each stride's map (the baseline's online poses, the graph's smoothed poses, or the "
        "true poses) measures the boxes it saw **whole**: a box is skipped when its outline "
        "comes near the unobserved area beyond the map (edge of map), another obstacle is "
        "within 4 cm (adjacent), its top was seen in part, too little floor was seen around it, "
        "or it came out in pieces (split); missed: inside the mapped area, no obstacle found. "
        "Counts are strides.",
        "",
    ]
    for name, table in report.tables_4_1.items():
        lines += [f"### {name}", "", table]
        if name in report.box_counts:
            lines += [report.box_counts[name]]
    lines += deadline_section(report.deadlines)
    lines += features_section(getattr(report, "features", {}))
    lines += ["## Plots", ""]
    lines += [f"![{p.stem}]({p.as_posix()})" for p in pngs]
    lines += [
        "",
        "## Files",
        "",
        "`trajectories/<session>/<variant>_{online,smoothed}.tum` and `ground_truth.tum` "
        "(stride_T_camera, each stride restarting at its foot strike: `evo_ape tum "
        "ground_truth.tum icp_imu_kin_online.tum`), `maps/<variant>/<session>_sNN.ply`, "
        "`recording.rrd` (`graph-slam view " + out.as_posix() + "`).",
        "",
    ]
    return "\n".join(lines)
