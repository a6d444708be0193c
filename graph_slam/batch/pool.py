"""The study's pooled numbers, from every finished task's ``metrics.json``.

Pooled per configuration and variant over all sessions, the same figures as the single-session
report (whose code and files are unchanged):

- Table 4.2: each session's strides one after another, one block of columns per variant;
- the per-stride RMSE distribution (aligned; median, quartiles, 95th percentile, max);
- Table 4.1 recomputed from every measured box's size (``obstacle_accuracy`` over the pooled
  measurements, not an average of averages) and the box outcome counts summed; the map fused
  with the true poses is counted once per session (every variant's task scores the same one);
- timing: per-frame mean and max exactly (frame-weighted); the median and 95th percentile of
  per-frame time are not pooled (metrics.json keeps them per task), so the table gives the
  range of the tasks' medians.

:func:`pool_study` returns plain data (``study.json``'s ``pooled``); :mod:`.pool_report` writes
the markdown and the plot.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from graph_slam.batch.spec import ResolvedSpec
from graph_slam.batch.tasks import Task
from graph_slam.evaluation.boxes import DIMENSIONS, base_name, obstacle_accuracy
from graph_slam.evaluation.tables import StrideRow, VariantStride, table_4_1, table_4_2
from graph_slam.variants import Variant

TRUTH = "ground truth"


def variant_keys(variants: Sequence[Variant]) -> tuple[list[str], list[str]]:
    """The report's keys: online (every variant), smoothed (the graph variants)."""
    return [str(v) for v in variants], [f"{v} smoothed" for v in variants if not v.is_baseline]


def table_4_2_rows(
    per_session: Sequence[dict[str, dict[str, Any]]], keys: Sequence[str]
) -> list[StrideRow]:
    """Table 4.2 rows over sessions: each session's strides in order (``per_session``: per
    session, ``{key: metrics.json variant}``; a key missing for a session prints as dashes)."""
    rows = []
    for metrics in per_session:
        present = [k for k in keys if k in metrics]
        if not present:
            continue
        first = metrics[present[0]]["strides"]
        for k, stride in enumerate(first):
            figures = {}
            for key in present:
                strides = metrics[key]["strides"]
                if k < len(strides):
                    s = strides[k]
                    rmse = (s["trajectory"] or {}).get("rmse_aligned_m")
                    figures[key] = VariantStride(
                        s["frames"]["registered"], s["frames"]["bridged"], rmse
                    )
            rows.append(
                StrideRow(stride["speed"], stride["number"], stride["frames"]["recorded"], figures)
            )
    return rows


def rmse_distribution(strides: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Aligned per-stride RMSE (m) over the pooled strides: n and quantiles; None when none."""
    values = np.array([(s["trajectory"] or {}).get("rmse_aligned_m") for s in strides], dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"n": 0}
    q = np.percentile(values, [25, 50, 75, 95])
    return {
        "n": int(values.size),
        "p25_m": float(q[0]),
        "median_m": float(q[1]),
        "p75_m": float(q[2]),
        "p95_m": float(q[3]),
        "max_m": float(values.max()),
    }


def add_counts(total: dict[str, Any], counts: dict[str, Any]) -> dict[str, Any]:
    """Sum metrics.json's box ``counts`` (measured, skipped per reason, missed, by box, ...)."""
    for name in ("measured", "missed", "unmatched", "no_map"):
        total[name] = total.get(name, 0) + counts.get(name, 0)
    skipped = total.setdefault("skipped", {})
    for reason, n in counts.get("skipped", {}).items():
        skipped[reason] = skipped.get(reason, 0) + n
    by_box = total.setdefault("by_box", {})
    for box, c in counts.get("by_box", {}).items():
        add_counts(by_box.setdefault(box, {"measured": 0, "skipped": {}, "missed": 0}), c)
        for extra in ("unmatched", "no_map"):
            by_box[box].pop(extra, None)
    total["by_box"] = dict(sorted(by_box.items()))
    return total


def pooled_boxes(maps: Sequence[dict[str, Any]]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Table 4.1 and the outcome counts over several tasks' ``maps.<source>`` entries."""
    sizes: dict[str, list[np.ndarray]] = {}
    truth: dict[str, np.ndarray] = {}
    counts: dict[str, Any] = {}
    for source in maps:
        add_counts(counts, source["counts"])
        for box, dims in source["obstacles"].items():
            truth[box] = np.array([dims[d]["truth_m"] for d in DIMENSIONS])
        for stride in source["strides"]:
            for b in stride["boxes"]:
                if b["status"] == "measured" and b["size_m"] is not None:
                    sizes.setdefault(base_name(b["box"]), []).append(np.asarray(b["size_m"]))
    return obstacle_accuracy(sizes, truth), counts


def timing(tasks: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """Per-frame time over tasks' ``timing`` entries: frame-weighted mean, max, median range.

    A task that timed no frame (``n`` 0) has no figures to pool and is left out; None when
    no task timed a frame."""
    stats = [t for t in tasks if t and t.get("n")]
    if not stats:
        return None
    n = sum(t["n"] for t in stats)
    return {
        "n": n,
        "mean_s": sum(t["mean_s"] * t["n"] for t in stats) / n,
        "max_s": max(t["max_s"] for t in stats),
        "task_median_min_s": min(t["median_s"] for t in stats),
        "task_median_max_s": max(t["median_s"] for t in stats),
    }


def pool_study(
    resolved: ResolvedSpec, tasks: Sequence[Task], docs: dict[str, dict[str, Any]]
) -> dict[str, Any]:
    """Per configuration: the pooled tables (markdown) and figures, from the done tasks'
    metrics documents ``docs`` (by task id)."""
    online, smoothed = variant_keys(resolved.variants)
    pooled: dict[str, Any] = {}
    for name in resolved.configurations:
        mine = [t for t in tasks if t.configuration == name]
        per_session, sources, speeds, not_scored = [], {}, {}, []
        for session in resolved.sessions:
            metrics: dict[str, Any] = {}
            truth_seen = False
            done = [t for t in mine if t.session_key == session.key and t.id in docs]
            if done and not any(
                s.get("trajectory") for t in done for v in docs[t.id]["variants"].values()
                for s in v.get("strides", [])
            ):  # fmt: skip
                not_scored.append(session.key)
            for t in done:
                doc = docs[t.id]
                metrics.update(doc["variants"])
                for source, entry in doc.get("maps", {}).items():
                    if source == TRUTH and truth_seen:
                        continue  # the same truth map in every variant's task
                    sources.setdefault(source, []).append(entry)
                truth_seen = truth_seen or TRUTH in doc.get("maps", {})
            per_session.append(metrics)
        by_key: dict[str, Any] = {}
        for key in online + smoothed:
            strides = [s for m in per_session if key in m for s in m[key]["strides"]]
            for s in strides:
                speeds.setdefault(key, {}).setdefault(s["speed"], []).append(
                    (s["trajectory"] or {}).get("rmse_aligned_m")
                )
            by_key[key] = {
                "sessions": sum(key in m for m in per_session),
                "rmse_aligned": rmse_distribution(strides),
                "timing": timing([m[key].get("timing") for m in per_session if key in m]),
            }
        boxes = {src: pooled_boxes(entries) for src, entries in sources.items()}
        pooled[name] = {
            "sessions_not_scored": not_scored,
            "variants": by_key,
            "rmse_by_speed_m": speeds,
            "table_4_2_online": table_4_2(table_4_2_rows(per_session, online), online),
            "table_4_2_smoothed": (
                table_4_2(table_4_2_rows(per_session, smoothed), smoothed) if smoothed else ""
            ),
            "tables_4_1": {src: table_4_1(acc) for src, (acc, _) in boxes.items()},
            "box_counts": {src: counts for src, (_, counts) in boxes.items()},
            "box_accuracy": {
                src: {b: {d: s.to_dict() for d, s in dims.items()} for b, dims in acc.items()}
                for src, (acc, _) in boxes.items()
            },
        }
    return pooled
