"""Thesis-style tables as GitHub markdown.

- :func:`table_4_2` (thesis Table 4.2, one block of columns per variant): walking speed (shown on
  a group's first row, as in the thesis), stride number, frames recorded, then per variant the
  frames registered, frames bridged and trajectory RMSE (metres, 3 decimals).
- :func:`table_4_1` (thesis Table 4.1): per box, mean, standard deviation and RMSE of width, depth
  and height in millimetres (mean and std without decimals, RMSE with one, as the thesis).
- :func:`table_box_counts` (beside Table 4.1): per box, the strides in which it was measured,
  skipped (per reason: only boxes seen whole are measured) and missed.

Missing values (NaN, None) print as an en dash.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from graph_slam.evaluation.boxes import DimensionStats

DASH = "–"


@dataclass(frozen=True)
class VariantStride:
    """One variant's figures for one stride."""

    registered: int
    bridged: int
    rmse_m: float | None


@dataclass(frozen=True)
class StrideRow:
    speed: str
    stride_number: int
    frames_recorded: int
    variants: Mapping[str, VariantStride] = field(default_factory=dict)


def _num(value: float | None, fmt: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return DASH
    return format(value, fmt)


def _markdown(header: Sequence[str], rows: Sequence[Sequence[str]], right_from: int) -> str:
    align = [":--" if i < right_from else "--:" for i in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def table_4_2(
    rows: Sequence[StrideRow], variants: Sequence[str], rmse_label: str = "RMSE (m)"
) -> str:
    """Per-stride counts and RMSE, one block of three columns per variant."""
    header = ["Walking speed", "Stride #", "Frames recorded"]
    for v in variants:
        header += [f"{v} registered", f"{v} bridged", f"{v} {rmse_label}"]
    body, previous_speed = [], None
    for row in rows:
        cells = [
            row.speed if row.speed != previous_speed else "",
            str(row.stride_number),
            str(row.frames_recorded),
        ]
        previous_speed = row.speed
        for v in variants:
            figures = row.variants.get(v)
            if figures is None:
                cells += [DASH, DASH, DASH]
            else:
                cells += [
                    str(figures.registered),
                    str(figures.bridged),
                    _num(figures.rmse_m, ".3f"),
                ]
        body.append(cells)
    return _markdown(header, body, right_from=1)


def table_4_1(stats: Mapping[str, Mapping[str, DimensionStats]]) -> str:
    """Obstacle dimension accuracy in mm: Width, Depth, Height × (Mean, Stdev, RMSE)."""
    dims = ("width", "depth", "height")
    header = ["Object"]
    for dim in dims:
        header += [
            f"{dim.capitalize()} mean",
            f"{dim.capitalize()} stdev",
            f"{dim.capitalize()} RMSE",
        ]
    body = []
    for name in sorted(stats):
        cells = [name]
        for dim in dims:
            s = stats[name].get(dim)
            if s is None:
                cells += [DASH, DASH, DASH]
            else:
                cells += [
                    _num(s.mean_m * 1000, ".0f"),
                    _num(s.std_m * 1000, ".0f"),
                    _num(s.rmse_m * 1000, ".1f"),
                ]
        body.append(cells)
    return _markdown(header, body, right_from=1)


SKIP_COLUMNS = (
    ("edge_of_map", "edge of map"),
    ("adjacent", "adjacent"),
    ("top_incomplete", "top in part"),
    ("floor_not_seen", "floor not seen"),
    ("split", "split"),
)
"""Skip reasons as Table 4.1's companion shows them (any other reason gets its own column)."""


def table_box_counts(counts: Mapping[str, Any]) -> str:
    """Per box: strides in which it was measured, skipped (per reason) and missed.

    ``counts`` is :func:`graph_slam.evaluation.boxes.count_outcomes`'s result; a last row
    gives the totals with the obstacles that matched no box (``unmatched``).
    """
    by_box = counts.get("by_box", {})
    reasons = [r for r, _ in SKIP_COLUMNS]
    extra = sorted(
        {r for b in by_box.values() for r in b["skipped"] if r not in reasons}
        | {r for r in counts.get("skipped", {}) if r not in reasons}
    )
    labels = dict(SKIP_COLUMNS)
    columns = reasons + extra
    header = ["Object", "measured", *[f"skipped: {labels.get(r, r)}" for r in columns], "missed"]
    body = []
    for name, box in by_box.items():
        body.append(
            [
                name,
                str(box["measured"]),
                *[str(box["skipped"].get(r, 0)) for r in columns],
                str(box["missed"]),
            ]
        )
    body.append(
        [
            f"all (unmatched obstacles: {counts.get('unmatched', 0)})",
            str(counts.get("measured", 0)),
            *[str(counts.get("skipped", {}).get(r, 0)) for r in columns],
            str(counts.get("missed", 0)),
        ]
    )
    return _markdown(header, body, right_from=1)
