"""The numbers of an evaluation, per variant and stride, and their ``metrics.json`` form.

Schema (``schema_version`` 4; every length in metres, every time in seconds; NaN is written as
``null``; documented in docs/evaluation.md)::

    {
      "schema": "graph_slam.metrics", "schema_version": 4,
      "session": str,
      "preset": str,   (the pipeline preset the run started from; compare writes it)
      "variants": {
        "<variant>": {
          "strides": [
            {"index": int, "speed": str, "number": int,
             "frames": {"recorded": int, "registered": int, "bridged": int, "other": int,
                        "partial": int},
             "trajectory": null | {"n_frames", "n_evaluated", "rmse_unaligned_m", "rmse_aligned_m",
                                   "rmse_by_phase_m": {"stance"|"swing": {"unaligned", "aligned", "n"}},
                                   "rpe_rmse_m"},
             "terrain"?: str, "anchor"?: str, "slope_deg"?: float, "up_source"?: str,
             "grid_frames_fused"?: int, "grid_frames_held"?: int}
          ],
          "summary": {"strides": int, "frames_recorded": int, "frames_registered": int,
                      "frames_bridged": int, "frames_partial": int,
                      "rmse_unaligned_m": {"mean", "median", "max"},
                      "rmse_aligned_m": {"mean", "median", "max"},
                      "by_terrain"?: {"<label>": {"strides", "rmse_unaligned_m", "rmse_aligned_m"}}},
          "timing": null | {"n", "median_s", "p95_s", "mean_s", "max_s"},
          "obstacles": {"<box>": {"depth"|"width"|"height": {"n", "truth_m", "mean_m", "std_m", "rmse_m"}}}
        }
      },
      "maps": {
        "<variant> | ground truth": {
          "poses": "smoothed" | "online" | "ground truth",
          "counts": {"measured": int, "skipped": {"<reason>": int}, "missed": int,
                     "unmatched": int, "no_map": int,
                     "by_box": {"<box>": {"measured": int, "skipped": {"<reason>": int}, "missed": int}}},
          "obstacles": {"<box>": {"depth"|"width"|"height": {...}}},
          "strides": [
            {"index": int, "speed": str, "number": int,
             "measured": int, "skipped": {...}, "missed": int, "unmatched": int, "no_map": int,
             "error": null | str,
             "boxes": [{"box": str, "status": "measured"|"skipped"|"missed", "reason": null | str,
                        "detail": str, "size_m": null | [depth, width, height],
                        "leading_edge_x_m": null | float, "yaw_rad": null | float}]}
          ]
        }
      },
      "terrain_deadlines": {
        "<variant>": {
          "all": {"n", "n_known", "n_before_toe_off", "fraction_before_toe_off",
                  "lead_s_median", "lead_s_min"},
          "by_speed": {"<speed>": {...as "all"}},
          "strides": [
            {"index": int, "speed": str, "number": int, "toe_off_pct": float,
             "obstacles": [{"stride_index", "obstacle_index", "final_leading_edge_x_m",
                            "final_height_m", "known_t_s", "toe_off_s", "lead_s",
                            "known_pct"}]}
          ]
        }
      },
      "terrain_features": {
        "<variant>": {
          "grids": int,
          "steps": {"matched": int, "rise_m"|"nosing_m"|"tread_m": {"n", "rmse", "bias",
                                                                  "std_error_over_sigma"}},
          "ramps": {"matched": int, "slope_rad"|"start_m": {...}},
          "curbs": {"matched": int, "height_m"|"edge_m": {...}},
          "boxes": {"matched": int, "height_m"|"leading_m"|"depth_m": {...}},
          "swing_clearance": {"n", "missed", "rmse", "bias", "within_5mm_fraction",
                              "std_error_over_sigma"},
          "edge_clearance": {...as swing_clearance: over the edges each swing crossed},
          "deadlines": {"n", "n_known", "n_before_toe_off", "n_at_least_0_5_s",
                        "lead_s_median", "lead_s_min", "by_kind": {"step"|"curb"|"box"|"ramp": int},
                        "swing": {...the same over the features whose edge lies within the
                                  measured toe's x range in mid-swing: those it must clear}},
          "warnings": {"swings", "true_below_margin", "flagged_below_margin", "false_warnings"}
        }
      }
    }

Keys with ``?`` are written only when known: ``terrain`` (the stance foot's terrain, from a
simulated session's ``strides_truth.csv``) and ``by_terrain``; ``anchor`` and ``slope_deg``
(the stride anchor's case and measured slope, graph variants).

Version 1 (before the completeness filter) had no ``maps`` and measured every box, whole or
not; version 2 had no ``terrain_deadlines`` (when the online map knew each obstacle of a
stride's final map, relative to toe-off: :mod:`graph_slam.evaluation.terrain_deadline`);
version 3 had no ``terrain_features`` (each stride's final grid's stairs, ramps, curbs and
boxes against the scene's, :mod:`graph_slam.evaluation.features`, and the measured swing
clearance against the true one); :func:`read_metrics_json` reads all four.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.evaluation.boxes import DimensionStats, StrideObstacles, count_outcomes
from graph_slam.evaluation.counts import FrameCounts
from graph_slam.evaluation.tables import StrideRow, VariantStride
from graph_slam.evaluation.terrain_deadline import StrideDeadlines, deadline_summary
from graph_slam.evaluation.timing import TimingStats
from graph_slam.evaluation.trajectory import StrideTrajectoryMetrics

SCHEMA = "graph_slam.metrics"
SCHEMA_VERSION = 4
READABLE_VERSIONS = (1, 2, 3, 4)


@dataclass(frozen=True, eq=False)
class StrideEvaluation:
    index: int
    speed: str
    number: int
    """Stride number within its speed group (thesis Table 4.2's 'Stride #')."""
    frames: FrameCounts
    trajectory: StrideTrajectoryMetrics | None
    terrain: str | None = None
    """The terrain under the stance foot (a simulated session's ``strides_truth.csv``:
    level, stairs_up, ramp_down, ...); None when the session does not say."""
    anchor: dict | None = None
    """The stride anchor's case and slope (``{"anchor": ..., "slope_deg": ...}``, graph
    variants), its up vector's source where not the IMU (``up_source``) and its online
    grid's frames fused / held back by the settling gate (``grid_frames_fused``,
    ``grid_frames_held``)."""

    def to_dict(self) -> dict[str, Any]:
        out = {
            "index": self.index,
            "speed": self.speed,
            "number": self.number,
            "frames": self.frames.to_dict(),
            "trajectory": None if self.trajectory is None else self.trajectory.to_dict(),
        }
        if self.terrain is not None:
            out["terrain"] = self.terrain
        if self.anchor:
            out.update(self.anchor)
        return out


@dataclass(frozen=True, eq=False)
class VariantEvaluation:
    strides: list[StrideEvaluation]
    timing: TimingStats | None = None
    obstacles: dict[str, dict[str, DimensionStats]] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        def stats(name: str) -> dict[str, float]:
            values = np.array(
                [getattr(s.trajectory, name) for s in self.strides if s.trajectory is not None],
                dtype=np.float64,
            )
            values = values[np.isfinite(values)]
            if values.size == 0:
                return {"mean": math.nan, "median": math.nan, "max": math.nan}
            return {
                "mean": float(values.mean()),
                "median": float(np.median(values)),
                "max": float(values.max()),
            }

        out = {
            "strides": len(self.strides),
            "frames_recorded": sum(s.frames.recorded for s in self.strides),
            "frames_registered": sum(s.frames.registered for s in self.strides),
            "frames_bridged": sum(s.frames.bridged for s in self.strides),
            "frames_partial": sum(s.frames.partial for s in self.strides),
            "rmse_unaligned_m": stats("rmse_unaligned_m"),
            "rmse_aligned_m": stats("rmse_aligned_m"),
        }
        if any(s.terrain is not None for s in self.strides):
            out["by_terrain"] = self.by_terrain()
        return out

    def by_terrain(self) -> dict[str, dict[str, Any]]:
        """Per terrain label (strides that carry one): stride count and RMSE statistics."""
        out: dict[str, dict[str, Any]] = {}
        labels = sorted({s.terrain for s in self.strides if s.terrain is not None})
        for label in labels:
            group = VariantEvaluation(
                [replace(s, terrain=None) for s in self.strides if s.terrain == label]
            )
            full = group.summary()
            out[label] = {
                "strides": full["strides"],
                "rmse_unaligned_m": full["rmse_unaligned_m"],
                "rmse_aligned_m": full["rmse_aligned_m"],
            }
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "strides": [s.to_dict() for s in self.strides],
            "summary": self.summary(),
            "timing": None if self.timing is None else self.timing.to_dict(),
            "obstacles": {
                box: {dim: s.to_dict() for dim, s in dims.items()}
                for box, dims in self.obstacles.items()
            },
        }


@dataclass(frozen=True, eq=False)
class MapStride:
    """One stride's box outcomes in one map source."""

    index: int
    speed: str
    number: int
    obstacles: StrideObstacles

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "speed": self.speed,
            "number": self.number,
            **self.obstacles.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class MapEvaluation:
    """The boxes found in one source's stride maps (a variant's poses, or the true poses)."""

    poses: str
    """Which poses fused the maps: ``smoothed``, ``online`` or ``ground truth``."""
    strides: list[MapStride]
    accuracy: dict[str, dict[str, DimensionStats]] = field(default_factory=dict)
    """Table 4.1 figures over the measured (whole) boxes."""

    def counts(self) -> dict[str, Any]:
        return count_outcomes([s.obstacles for s in self.strides])

    def to_dict(self) -> dict[str, Any]:
        return {
            "poses": self.poses,
            "counts": self.counts(),
            "obstacles": {
                box: {dim: s.to_dict() for dim, s in dims.items()}
                for box, dims in self.accuracy.items()
            },
            "strides": [s.to_dict() for s in self.strides],
        }


def table_rows(variants: dict[str, VariantEvaluation], aligned: bool = True) -> list[StrideRow]:
    """Table 4.2 rows (frames recorded from the first variant; RMSE aligned by default)."""
    if not variants:
        return []
    first = next(iter(variants.values()))
    rows = []
    for k, stride in enumerate(first.strides):
        figures = {}
        for name, variant in variants.items():
            if k >= len(variant.strides):
                continue
            s = variant.strides[k]
            rmse = None
            if s.trajectory is not None:
                rmse = s.trajectory.rmse_aligned_m if aligned else s.trajectory.rmse_unaligned_m
            figures[name] = VariantStride(s.frames.registered, s.frames.bridged, rmse)
        rows.append(StrideRow(stride.speed, stride.number, stride.frames.recorded, figures))
    return rows


def metrics_document(
    session: str,
    variants: dict[str, VariantEvaluation],
    maps: dict[str, MapEvaluation] | None = None,
    deadlines: dict[str, Sequence[StrideDeadlines]] | None = None,
    features: dict[str, dict] | None = None,
) -> dict[str, Any]:
    """``metrics.json``'s content (the schema above); ``deadlines``: per variant, its strides'
    :class:`~graph_slam.evaluation.terrain_deadline.StrideDeadlines`."""
    return {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "session": session,
        "variants": {name: v.to_dict() for name, v in variants.items()},
        "maps": {name: m.to_dict() for name, m in (maps or {}).items()},
        "terrain_deadlines": {
            str(name): deadline_summary(strides) for name, strides in (deadlines or {}).items()
        },
        "terrain_features": {str(name): f for name, f in (features or {}).items()},
    }


def _nan_to_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_nan_to_none(v) for v in value]
    return value


def write_metrics_json(document: dict[str, Any], path: str | Path) -> Path:
    """Write ``metrics.json`` (NaN and inf as null, keys in insertion order)."""
    path = Path(path)
    path.write_text(
        json.dumps(_nan_to_none(document), indent=2, allow_nan=False) + "\n", encoding="utf-8"
    )
    return path


def read_metrics_json(path: str | Path) -> dict[str, Any]:
    """Read and check a ``metrics.json`` (schema name, version and top-level fields)."""
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise EvaluationError(f"{path}: cannot read metrics JSON ({err})") from None
    if not isinstance(document, dict) or document.get("schema") != SCHEMA:
        raise EvaluationError(f"{path}: field 'schema' must be {SCHEMA!r}")
    if document.get("schema_version") not in READABLE_VERSIONS:
        raise EvaluationError(
            f"{path}: field 'schema_version' is {document.get('schema_version')!r}; this reader "
            f"knows {', '.join(map(str, READABLE_VERSIONS))}"
        )
    if not isinstance(document.get("variants"), dict):
        raise EvaluationError(
            f"{path}: field 'variants' must be a mapping of variant name to metrics"
        )
    if document["schema_version"] >= 2 and not isinstance(document.get("maps"), dict):
        raise EvaluationError(f"{path}: field 'maps' must be a mapping of map source to boxes")
    if document["schema_version"] >= 3 and not isinstance(document.get("terrain_deadlines"), dict):
        raise EvaluationError(
            f"{path}: field 'terrain_deadlines' must be a mapping of variant to deadlines"
        )
    if document["schema_version"] >= 4 and not isinstance(document.get("terrain_features"), dict):
        raise EvaluationError(
            f"{path}: field 'terrain_features' must be a mapping of variant to feature scores"
        )
    return document
