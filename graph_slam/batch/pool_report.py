"""The study's files: ``study.json``, ``report.md`` and ``plots/error_by_speed.png``.

``study.json`` (schema ``graph_slam.study`` version 1)::

    {"schema", "schema_version", "spec": str, "variants": [...], "configurations": {name: resolved},
     "counts": {"done", "failed", "not_run"},
     "tasks": [{"id", "session", "variant", "configuration", "hash", "status", "error",
                "wall_s", "peak_rss_mib", "attempts", "metrics": null | <the task's metrics.json>}],
     "pooled": {configuration: <graph_slam.batch.pool.pool_study>}}
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.batch.pool import pool_study
from graph_slam.batch.spec import ResolvedSpec
from graph_slam.batch.tasks import DONE, FAILED, Task, task_summary
from graph_slam.evaluation.report import _nan_to_none, read_metrics_json
from graph_slam.evaluation.tables import table_box_counts

STUDY_SCHEMA = "graph_slam.study"
STUDY_VERSION = 1


def write_pooled_report(
    out: Path, resolved: ResolvedSpec, tasks: list[Task], states: dict[str, dict[str, Any]]
) -> list[Path]:
    """Pool every done task of this spec and write the study's files into ``out``."""
    docs = {
        t.id: read_metrics_json(t.report / "metrics.json")
        for t in tasks
        if states.get(t.id, {}).get("status") == DONE
    }
    pooled = pool_study(resolved, tasks, docs)
    study = {
        "schema": STUDY_SCHEMA,
        "schema_version": STUDY_VERSION,
        "spec": str(resolved.path),
        "variants": [str(v) for v in resolved.variants],
        "configurations": {
            n: c.model_dump(mode="json") for n, c in resolved.configurations.items()
        },
        "counts": {
            "done": sum(s.get("status") == DONE for s in states.values()),
            "failed": sum(s.get("status") == FAILED for s in states.values()),
            "not_run": sum(t.id not in states for t in tasks),
        },
        "tasks": [
            {**task_summary(states.get(t.id, {"id": t.id})), "metrics": docs.get(t.id)}
            for t in tasks
        ],
        "pooled": pooled,
    }
    files = [out / "study.json"]
    files[0].write_text(
        json.dumps(_nan_to_none(study), indent=2, allow_nan=False) + "\n", encoding="utf-8"
    )
    plot = _plot_error_by_speed(out / "plots" / "error_by_speed.png", pooled)
    files += [plot] if plot else []
    (out / "report.md").write_text(_markdown(resolved, tasks, states, pooled, plot, out))
    files.append(out / "report.md")
    return files


def _plot_error_by_speed(path: Path, pooled: dict[str, Any]) -> Path | None:
    """Box plot of the aligned per-stride RMSE (mm), grouped by speed, one box per
    configuration and variant (online poses)."""
    series = {
        f"{cfg} / {key}": by_speed
        for cfg, p in pooled.items()
        for key, by_speed in p["rmse_by_speed_m"].items()
        if not key.endswith("smoothed")
    }
    speeds = sorted({s for by_speed in series.values() for s in by_speed})
    if not speeds:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6, 1.5 * len(speeds) * max(1, len(series)) ** 0.5), 4))
    width = 0.8 / len(series)
    for j, (label, by_speed) in enumerate(series.items()):
        data, pos = [], []
        for i, speed in enumerate(speeds):
            v = np.array([x for x in by_speed.get(speed, []) if x is not None], dtype=float) * 1e3
            if v.size:
                data.append(v)
                pos.append(i - 0.4 + width * (j + 0.5))
        if data:
            parts = ax.boxplot(data, positions=pos, widths=width * 0.9, patch_artist=True)
            colour = plt.get_cmap("tab10")(j % 10)
            for box in parts["boxes"]:
                box.set_facecolor(colour)
            ax.plot([], [], "s", color=colour, label=label)
    ax.set_xticks(range(len(speeds)), speeds)
    ax.set_ylabel("per-stride RMSE, aligned (mm)")
    ax.set_title("Error by walking speed (online poses; configuration / variant)")
    ax.legend(fontsize="small")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _mm(value: float | None) -> str:
    return "–" if value is None else f"{value * 1e3:.1f}"


def _task_lines(tasks: list[Task], states: dict[str, dict[str, Any]]) -> list[str]:
    counts = {s: sum(st.get("status") == s for st in states.values()) for s in (DONE, FAILED)}
    skipped = sum(st.get("this_run") == "skipped" for st in states.values())
    lines = [
        f"Tasks: {len(tasks)} — done {counts[DONE]} (of which {skipped} finished in an earlier "
        f"run), failed {counts[FAILED]}, not run {sum(t.id not in states for t in tasks)}.",
        "",
    ]
    failed = [t for t in tasks if states.get(t.id, {}).get("status") == FAILED]
    if failed:
        lines += ["## Failed tasks", "", "| task | error |", "| :-- | :-- |"]
        for t in failed:
            first = (states[t.id].get("error") or "").splitlines()[0][:300]
            lines.append(f"| {t.id} | {first.replace('|', '/')} |")
        lines += ["", "Full messages and tracebacks: `tasks/<task>/task.json`.", ""]
    return lines


def _markdown(resolved, tasks, states, pooled, plot: Path | None, out: Path) -> str:
    lines = [
        "# graph_slam study report",
        "",
        f"Spec: `{resolved.path}`. Sessions: {len(resolved.sessions)}. Variants: "
        f"{', '.join(map(str, resolved.variants))}. Configurations: "
        f"{', '.join(resolved.configurations)}. Every number: `study.json`; each task's own "
        "report: `tasks/<session>__<variant>__<configuration>/report/`.",
        "",
        *_task_lines(tasks, states),
    ]
    if plot is not None:
        lines += [
            "## Error by walking speed",
            "",
            f"![error by speed]({plot.relative_to(out)})",
            "",
        ]
    for name, p in pooled.items():
        lines += [f"## Configuration `{name}`", ""]
        if p.get("sessions_not_scored"):
            lines += [
                f"Not in the tables below (no stride scored: no ground truth, or every stride "
                f"dropped; see the task reports): {', '.join(p['sessions_not_scored'])}.",
                "",
            ]
        lines += ["### Table 4.2 — online poses", ""]
        lines += [p["table_4_2_online"]]
        if p["table_4_2_smoothed"]:
            lines += ["### Table 4.2 — smoothed poses", "", p["table_4_2_smoothed"]]
        lines += [
            "### Per-stride RMSE (aligned, mm) and per-frame time",
            "",
            "| variant | sessions | strides | p25 | median | p75 | p95 | max | time mean / max (ms) | task medians (ms) |",
            "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: |",
        ]
        for key, v in p["variants"].items():
            r, t = v["rmse_aligned"], v["timing"]
            times = "–" if t is None else f"{t['mean_s'] * 1e3:.1f} / {t['max_s'] * 1e3:.1f}"
            medians = (
                "–"
                if t is None
                else f"{t['task_median_min_s'] * 1e3:.1f}–{t['task_median_max_s'] * 1e3:.1f}"
            )
            lines.append(
                f"| {key} | {v['sessions']} | {r['n']} | {_mm(r.get('p25_m'))} | "
                f"{_mm(r.get('median_m'))} | {_mm(r.get('p75_m'))} | {_mm(r.get('p95_m'))} | "
                f"{_mm(r.get('max_m'))} | {times} | {medians} |"
            )
        lines += [""]
        for source, table in p["tables_4_1"].items():
            lines += [f"### Table 4.1 — obstacle dimensions (mm), maps from {source}", "", table]
            lines += [table_box_counts(p["box_counts"][source])]
    return "\n".join(lines) + "\n"
