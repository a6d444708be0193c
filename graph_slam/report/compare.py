"""``compare``: ``run``'s variants on sessions, scored against their ground truth; a report.

:func:`compare` reads as its steps; step 1 and the recording's writer are shared with
:func:`graph_slam.report.run.run` (which writes more per variant but scores nothing). For every
session (one walking speed each):

1. run every variant (``graph_slam.pipelines.run_session``): poses, and each stride's terrain
   maps from its online and smoothed poses;
2. build the reference of every complete stride (:func:`graph_slam.strides.reference.
   stride_references`) — skipped, with scoring, when the session has no ground truth;
3. score every stride and key (a variant's online or smoothed poses) and every stride's map
   (the graph's smoothed poses, the baseline's online ones, and a map fused with the true
   poses) against the scene's boxes;
4. write TUM trajectories, PLY maps, plots and the rerun recording (:mod:`.views`).

While each variant runs, a :class:`~graph_slam.report.terrain_trace.TerrainTrace` records its
online elevation grid's whole obstacles at every frame (and, for the recording, every
``rrd_grid_step``-th grid of the main variant); step 3 also scores, per stride, when the online
map first knew each obstacle of the stride's final map relative to toe-off (the deadline).

Then ``metrics.json``, ``report.md`` (thesis Tables 4.2 and 4.1, the deadline) and the
resolved config.
The report folder's layout is documented in docs/evaluation.md.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from graph_slam.evaluation.boxes import collect_measurements, obstacle_accuracy
from graph_slam.evaluation.report import (
    MapEvaluation,
    MapStride,
    StrideEvaluation,
    VariantEvaluation,
    metrics_document,
    table_rows,
    write_metrics_json,
)
from graph_slam.evaluation.tables import table_4_1, table_4_2, table_box_counts
from graph_slam.evaluation.timing import timing_stats
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.report.checks import preflight, run_warnings, write_compare_config
from graph_slam.report.feature_scoring import feature_summaries, score_run_features
from graph_slam.report.keys import Kind, MapSource, RunKey, run_keys
from graph_slam.report.run import (
    ProgressCallback,
    RunSettings,
    SessionSpec,
    count_progress,
    open_sessions,
    session_results,
)
from graph_slam.report.scoring import (
    SessionRun,
    score_deadlines,
    score_maps,
    score_session,
    stride_maps,
)
from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.plausibility import Finding
from graph_slam.variants import Variant

log = logging.getLogger(__name__)

SPEED_CLASSES = ((0.95, "Slow"), (1.25, "Normal"), (float("inf"), "Fast"))
"""Walking speed label from the measured speed (m/s): below 0.95 slow, below 1.25 normal."""


class CompareConfig(RunSettings):
    """What ``compare`` runs (the variants, the pipeline and the recording: ``run``'s settings)
    and how it scores and plots. The terrain maps (voxel size, depth range, pixel step) are the
    pipeline's: ``pipeline.terrain``."""

    pipeline: PipelineConfig = Field(
        default_factory=lambda: PipelineConfig(terrain={"enabled": True}),
        description="the default preset with the stride maps on (Table 4.1 scores them)",
    )
    match_margin_m: float = Field(
        0.05,
        gt=0,
        description="an obstacle belongs to the scene box whose footprint grown by this holds "
        "its centre",
    )
    truth_map: bool = Field(
        True, description="also fuse each stride with the true poses (mapping-only accuracy)"
    )
    terrain_deadline: bool = Field(
        True,
        description="score when each variant's online terrain map knew each obstacle, relative "
        "to toe-off (a whole-box search on the grid of every variant: 10-30 ms a search on a "
        "loaded 2-core machine)",
    )
    terrain_deadline_interval_s: float = Field(
        0.03,
        ge=0,
        description="search the grid's whole boxes for the deadline at most this often (0: "
        "every frame); the time known is then up to this late (0.03: every 3rd frame at 90 Hz)",
    )
    map_files: Literal["main", "all", "none"] = Field(
        "main",
        description="which stride maps are written as PLY (float32 coordinates): main (the "
        "main variant's, the last asked for (icp+imu+kin by default), and the ground truth's), "
        "all (every variant's), none; every map is scored either way",
    )
    map_file_voxel_m: float = Field(
        0.01,
        ge=0,
        description="the PLY maps' voxel: the fused map's voxels averaged (by their point "
        "counts) on this coarser grid of the same origin, a whole multiple of "
        "pipeline.terrain's voxel (0: as fused, 5 mm); the scores use the fused map",
    )
    plot_maps_per_session: int = Field(
        1,
        ge=0,
        description="map/elevation plots (last variant and true poses) for the first n strides "
        "of each session",
    )

    @field_validator("pipeline", mode="before")
    @classmethod
    def _stride_maps_on(cls, value: Any) -> Any:
        """Table 4.1 scores the stride maps: ``pipeline.terrain.enabled`` is true unless the
        config says otherwise (the default preset builds none; the check below refuses a
        config that turns them off)."""
        if value is None:
            value = {}
        if isinstance(value, dict):
            terrain = value.get("terrain") or {}
            if isinstance(terrain, dict) and "enabled" not in terrain:
                value = {**value, "terrain": {**terrain, "enabled": True}}
        return value

    @model_validator(mode="after")
    def _maps_to_score(self) -> CompareConfig:
        """Table 4.1 scores each stride's smoothed map: the pipelines must build it (checked
        before minutes of work, not after)."""
        from graph_slam.errors import ConfigError

        terrain = self.pipeline.terrain
        if not terrain.enabled:
            raise ConfigError(
                "field 'pipeline.terrain.enabled': compare scores the stride maps (Table 4.1); "
                "it must be true"
            )
        if "smoothed" not in terrain.poses:
            raise ConfigError(
                "field 'pipeline.terrain.poses': compare scores the maps of the smoothed poses "
                f"(Table 4.1); add 'smoothed' (got {list(terrain.poses)})"
            )
        return self


@dataclass
class CompareReport:
    """What :func:`compare` wrote and measured."""

    out: Path
    variants: dict[str, VariantEvaluation]
    table_4_2_online: str
    table_4_2_smoothed: str
    tables_4_1: dict[str, str]
    box_counts: dict[str, str] = field(default_factory=dict)
    """Per map source: boxes measured, skipped (per reason) and missed (markdown)."""
    maps: dict[str, MapEvaluation] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    wall_s: float = 0.0
    sessions: list[str] = field(default_factory=list)
    unscored: list[str] = field(default_factory=list)
    """Sessions run without scoring (no ground truth)."""
    warnings: list[Finding] = field(default_factory=list)
    """Caveats on the numbers (graph_slam.session.plausibility): gaps, units, dropped strides."""
    deadlines: dict[str, list] = field(default_factory=dict)
    """Per variant: when its online map knew each stride's obstacles (StrideDeadlines)."""
    features: dict[str, dict] = field(default_factory=dict)
    """Per variant: its final grids' terrain features and swing clearances against the scene
    (``metrics.json``'s ``terrain_features``)."""


@dataclass
class _Study:
    """Scores gathered over the sessions, by typed key."""

    keys: list[RunKey]
    sources: list[MapSource]
    strides: dict[RunKey, list[StrideEvaluation]] = field(default_factory=dict)
    durations: dict[RunKey, list[float]] = field(default_factory=dict)
    maps: dict[MapSource, list[MapStride]] = field(default_factory=dict)
    truth_sizes: dict[str, np.ndarray] = field(default_factory=dict)
    curves: dict[Variant, list] = field(default_factory=dict)
    toe_pcts: list[float] = field(default_factory=list)
    deadlines: dict[Variant, list] = field(default_factory=dict)
    """Per variant: :class:`~graph_slam.report.terrain_trace.StrideDeadlines` per stride."""
    features: dict[Variant, list] = field(default_factory=dict)
    """Per variant: the feature scores of each stride's final grid."""
    clearances: dict[Variant, list] = field(default_factory=dict)
    """Per variant: (measured, true, σ) least swing clearance per stride."""
    edge_clearances: dict[Variant, list] = field(default_factory=dict)
    """Per variant: (measured, true, σ) clearance over each edge a swing passed (measured NaN:
    no measured edge matched it on the measured path)."""
    feature_deadlines: dict[Variant, list] = field(default_factory=dict)
    """Per variant: when its online grid knew each feature of a stride's final grid."""
    clearance_flags: dict[Variant, list] = field(default_factory=dict)
    """Per variant and stride: (warned in stance before toe-off, the true edge clearance; NaN:
    the swing crossed no edge)."""
    n_strides: int = 0

    @classmethod
    def empty(cls, cfg: CompareConfig) -> _Study:
        keys = run_keys(cfg.variants)
        sources = [MapSource(Variant(v)) for v in cfg.variants]
        sources += [MapSource()] if cfg.truth_map else []
        return cls(
            keys,
            sources,
            {k: [] for k in keys},
            {k: [] for k in keys},
            {s: [] for s in sources},
            curves={Variant(v): [] for v in cfg.variants},
            deadlines={Variant(v): [] for v in cfg.variants},
        )


def speed_label(speed_m_s: float) -> str:
    for limit, label in SPEED_CLASSES:
        if speed_m_s < limit:
            return label
    return SPEED_CLASSES[-1][1]


def _speed_of(spec: SessionSpec, session) -> str:
    """The spec's label, else from the ground truth's mean horizontal speed, else ``unknown``."""
    if spec.speed is not None:
        return spec.speed
    gt = session.ground_truth
    if gt is None or len(gt.t_s) < 2:
        return "unknown"
    p = np.asarray(gt.parent_T_child)[:, :2, 3]
    t = np.asarray(gt.t_s)
    return speed_label(float(np.linalg.norm(p[-1] - p[0]) / max(t[-1] - t[0], 1e-9)))


def compare(
    sessions: Sequence[str | Path | SessionSpec],
    out: str | Path,
    config: CompareConfig | None = None,
    progress: ProgressCallback | None = None,
    *,
    overwrite: bool = False,
) -> CompareReport:
    """Run every variant on every session and write the report folder ``out``.

    Before any work: every session opens, the output folder can be written (and replaced only
    with ``overwrite`` when compare wrote it), and the plausibility checks
    (:mod:`graph_slam.session.plausibility`) find nothing that makes the result meaningless.
    The folder is written under a temporary sibling and renamed on success.
    """
    from graph_slam.report import views

    t_start = time.perf_counter()
    cfg = config or CompareConfig()
    specs, opened = open_sessions(sessions, "compare")
    inputs = [s.path for s in specs]
    out = check_output(out, overwrite=overwrite, command="compare", inputs=inputs)
    warnings = preflight(opened, [str(v) for v in cfg.variants], cfg.pipeline.event_source)
    with atomic_folder(out, overwrite=overwrite, command="compare", inputs=inputs) as tmp:
        report = _write_report(tmp, specs, opened, cfg, progress, warnings)
        report.wall_s = time.perf_counter() - t_start
        report.files.append(views.write_report_md(tmp / "report.md", report, cfg))
        _relocate(report, tmp, out)
    return report


def _write_report(tmp: Path, specs, opened, cfg: CompareConfig, progress, warnings):
    """Steps 1-4 and the metrics, into the temporary folder ``tmp``."""
    from graph_slam.report import views

    files: list[Path] = [write_compare_config(cfg, tmp / "config.yaml")]
    tick = count_progress(progress, sum(len(cfg.variants) * s.n_frames for s in opened))
    study = _Study.empty(cfg)
    logger = views.make_logger(tmp / "recording.rrd" if cfg.rrd else None)
    t_offset = 0.0
    unscored = []
    traces = [_traces(cfg) for _ in opened]
    runs = session_results(opened, cfg, tick, traces)
    for spec, session, results, session_traces in zip(specs, opened, runs, traces, strict=True):
        label = _speed_of(spec, session)
        run = SessionRun.build(
            session, label, results, cfg.pipeline, study.n_strides, session_traces or {}
        )
        if not run.references:
            unscored.append(session.name)
        warnings += run_warnings(session, run, cfg.pipeline.event_source)
        run.maps = [stride_maps(run, ref, study.sources, cfg.pipeline) for ref in run.references]
        _score(run, study, cfg)
        files += views.write_trajectories(tmp / "trajectories" / session.name, run)
        files += views.write_maps_and_views(tmp, run, cfg, logger, t_offset)
        study.n_strides += len(run.references)
        t_offset += float(session.frame_times_s[-1]) + 1.0 if session.n_frames else 0.0
    logger.close()
    files += [tmp / "recording.rrd"] if cfg.rrd else []
    report = _tables(tmp, cfg, study, [s.name for s in opened], unscored)
    report.warnings = warnings
    deadlines = {v: d for v, d in study.deadlines.items() if d}  # variants scored
    report.features = feature_summaries(study)
    document = metrics_document(
        ", ".join(report.sessions), report.variants, report.maps, deadlines, report.features
    )
    report.deadlines = {str(v): d for v, d in deadlines.items()}
    document["preset"] = cfg.pipeline.preset
    document["warnings"] = [w.to_dict() for w in warnings]
    files.append(write_metrics_json(document, tmp / "metrics.json"))
    files += views.write_plots(tmp, study)
    report.files = files
    return report


def _relocate(report: CompareReport, tmp: Path, out: Path) -> None:
    """The report as it will read once ``tmp`` is renamed to ``out``."""
    md = tmp / "report.md"
    md.write_text(md.read_text(encoding="utf-8").replace(tmp.as_posix(), out.as_posix()))
    report.out = out
    report.files = [out / f.relative_to(tmp) for f in report.files]


def _traces(cfg: CompareConfig) -> dict | None:
    """A session's per-frame terrain traces (variant → trace): every variant's when the
    deadline is scored, the recording's grid for the main variant."""
    from graph_slam.report.terrain_trace import TerrainTrace

    if not cfg.pipeline.terrain.online.enabled:
        return None
    variants = [Variant(v) for v in cfg.variants]
    grid_step = cfg.rrd_grid_step if cfg.rrd else 0  # the recording shows the main variant's
    return {
        v: TerrainTrace(
            grid_step if v == variants[-1] else 0,
            cfg.terrain_deadline,
            cfg.terrain_deadline_interval_s,
        )
        for v in variants
        if cfg.terrain_deadline or (grid_step and v == variants[-1])
    }


def _score(run: SessionRun, study: _Study, cfg: CompareConfig) -> None:
    """Step 3: trajectories and frame counts per stride and key; maps against the boxes."""
    for key, evaluations in score_session(run).items():
        study.strides[key] += evaluations
    for key in study.keys:
        res = run.results[key.variant]
        study.durations[key] += [f.frontend_s + f.backend_s + f.terrain_s for f in res.frames]
    for variant, curve in run.error_curves().items():
        study.curves[variant] += curve
    study.toe_pcts += [ref.toe_off_pct for ref in run.references]
    for source, strides in score_maps(run, study.sources, cfg.match_margin_m).items():
        study.maps[source] += strides
    for variant, strides in score_deadlines(run).items():
        study.deadlines[variant] += strides
    for name, size in run.truth_sizes().items():
        study.truth_sizes.setdefault(name, size)
    score_run_features(run, study, cfg.pipeline)


def _tables(out: Path, cfg: CompareConfig, study: _Study, sessions, unscored) -> CompareReport:
    """The thesis tables from the gathered scores."""
    maps = {
        str(source): MapEvaluation(
            poses=str(source.poses),
            strides=strides,
            accuracy=obstacle_accuracy(
                collect_measurements([m.obstacles for m in strides]), study.truth_sizes
            ),
        )
        for source, strides in study.maps.items()
    }
    variants = {
        str(key): VariantEvaluation(
            strides=study.strides[key],
            timing=timing_stats(np.asarray(study.durations[key])) if study.durations[key] else None,
            obstacles=maps[str(key.variant)].accuracy,
        )
        for key in study.keys
    }
    online = {str(k): variants[str(k)] for k in study.keys if k.kind is Kind.ONLINE}
    smoothed = {str(k): variants[str(k)] for k in study.keys if k.kind is Kind.SMOOTHED}
    return CompareReport(
        out=out,
        variants=variants,
        table_4_2_online=table_4_2(table_rows(online), list(online)),
        table_4_2_smoothed=table_4_2(table_rows(smoothed), list(smoothed)) if smoothed else "",
        tables_4_1={s.title: table_4_1(maps[str(s)].accuracy) for s in study.sources},
        box_counts={s.title: table_box_counts(maps[str(s)].counts()) for s in study.sources},
        maps=maps,
        sessions=list(sessions),
        unscored=list(unscored),
    )
