"""``run``: every requested variant on recordings with or without ground truth; write what came out.

:func:`run` reads as its steps. Before any work: every session opens, the output folder can be
written (replaced only with ``overwrite`` when graph-slam wrote it) and the plausibility checks
(:func:`graph_slam.report.checks.preflight`) find nothing that makes the run meaningless. Then,
into a temporary sibling renamed on success (:mod:`graph_slam.session.atomic`):

1. run every variant on every session (:func:`run_variants`, ``graph_slam.pipelines.
   run_session``);
2. write each variant's artefacts (:mod:`.artefacts`): trajectories, per-stride maps, elevation
   grids and obstacles, per-frame flags and timing;
3. say what can be said without ground truth (:mod:`.summary`): frames registered / partial /
   bridged per stride, the baseline's stop points, timing, the variants' agreement;
4. the rerun recording, ``config.yaml``, ``run.json`` and ``report.md``.

``compare`` (:mod:`.compare`) is steps 1 and 4 of this module plus the scoring against ground
truth; it shares :func:`open_sessions`, :func:`count_progress` and :func:`run_variants`. The
output layout is documented in docs/run.md.

    from graph_slam.report import RunConfig, run
    report = run(["runs/walk"], "runs/walk_out", RunConfig(variants=["icp", "icp+imu+kin"]))
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator

from graph_slam.config import ConfigModel
from graph_slam.errors import EvaluationError
from graph_slam.pipelines import PipelineConfig
from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.plausibility import Finding
from graph_slam.variants import VARIANTS, Variant

ProgressCallback = Callable[[int, int], None]
"""Called after every frame of every variant with (frames done, frames in total)."""


class RunSettings(ConfigModel):
    """What every application that runs the variants shares: the variants, the pipeline and the
    rerun recording."""

    variants: list[Variant] = Field(
        default_factory=lambda: list(VARIANTS), min_length=1, description="variants to run"
    )
    pipeline: PipelineConfig = PipelineConfig()
    rrd: bool = Field(True, description="write recording.rrd (rerun)")
    rrd_frame_step: int = Field(
        6,
        ge=1,
        description="log every n-th frame's images to the .rrd (6: about 6 Hz of the demo's "
        "38 Hz; the images are most of the recording)",
    )
    rrd_image_step: int = Field(
        2, ge=1, le=8, description="subsample the .rrd's depth/colour images by this factor"
    )
    rrd_grid_step: int = Field(
        9,
        ge=1,
        description="log every n-th frame's live elevation grid (height, σ) and its boxes to "
        "the .rrd (9: 10 Hz at 90 Hz)",
    )
    workers: int = Field(
        1,
        ge=1,
        le=64,
        description="run the (session, variant) pairs in this many spawned processes, the "
        "thesis baseline's first (1: one after another in this process; docs/run.md)",
    )

    @field_validator("variants")
    @classmethod
    def _each_variant_once(cls, variants: list[Variant]) -> list[Variant]:
        twice = sorted({str(v) for v in variants if variants.count(v) > 1})
        if twice:
            raise ValueError(f"{', '.join(twice)} listed more than once; list each once")
        return variants

    @field_validator("pipeline")
    @classmethod
    def _pipeline_variant_is_run(cls, pipeline: PipelineConfig, info: ValidationInfo):
        """``pipeline.variant`` is set per run from ``variants``: one set (not the default)
        that is not run is a mistake (it would be silently replaced), never a setting."""
        variants = info.data.get("variants")
        default = PipelineConfig.model_fields["variant"].default
        if variants and pipeline.variant != default and pipeline.variant not in variants:
            raise ValueError(
                f"variant {pipeline.variant} is not among the variants that run "
                f"({', '.join(map(str, variants))}): the variants run are those of 'variants' "
                "(or --variants); list it there and leave pipeline.variant out"
            )
        return pipeline


class RunConfig(RunSettings):
    """What ``run`` runs and writes (docs/run.md)."""

    kitti: bool = Field(
        False, description="also write KITTI trajectories (12 numbers a line) and their times"
    )
    map_dtype: Literal["float32", "float64"] = Field(
        "float32", description="PLY coordinate type of the stride maps"
    )
    reference: Variant | None = Field(
        None,
        description="the variant the others are compared with (agreement); None: icp+imu+kin "
        "when it runs, else the last variant",
    )

    @field_validator("reference")
    @classmethod
    def _reference_is_run(cls, reference: Variant | None, info: ValidationInfo):
        variants = info.data.get("variants")
        if reference is not None and variants is not None and reference not in variants:
            raise ValueError(
                f"{reference} is not among the variants ({', '.join(map(str, variants))}); "
                "add it to 'variants' (or --variants) or choose one of them"
            )
        return reference


@dataclass(frozen=True)
class SessionSpec:
    """A session folder and, optionally, its walking-speed label (else from the ground truth)."""

    path: Path
    speed: str | None = None


@dataclass
class RunReport:
    """What :func:`run` wrote and found; ``summary`` is ``run.json``'s content."""

    out: Path
    sessions: list[str]
    summary: dict
    files: list[Path] = field(default_factory=list)
    wall_s: float = 0.0
    warnings: list[Finding] = field(default_factory=list)


def open_sessions(sessions: Sequence[str | Path | SessionSpec], command: str = "run"):
    """Open every session first: a bad one stops the run before any work."""
    from graph_slam.session import open_session

    specs = [s if isinstance(s, SessionSpec) else SessionSpec(Path(s)) for s in sessions]
    if not specs:
        raise EvaluationError(f"{command}: no session given")
    return specs, [open_session(s.path) for s in specs]


def count_progress(progress: ProgressCallback | None, total: int) -> ProgressCallback:
    """A per-frame callback that counts frames over every variant and session."""
    done = 0

    def tick(_: int, __: int) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    return tick


def run_variants(
    session, variants, pipeline: PipelineConfig, tick, traces: dict | None = None
) -> dict:
    """Step 1: every variant's :class:`~graph_slam.pipelines.PipelineResults` on ``session``.

    ``traces``: variant -> a per-frame callback (``run_session``'s ``on_frame``; a
    :class:`~graph_slam.report.terrain_trace.TerrainTrace`) for the variants that have one."""
    from graph_slam.pipelines import run_session

    results = {}
    for v in variants:
        pcfg = PipelineConfig.model_validate({**pipeline.model_dump(), "variant": v})
        on_frame = None if traces is None else traces.get(Variant(v))
        results[Variant(v)] = run_session(session, pcfg, progress=tick, on_frame=on_frame)
    return results


def session_results(opened, cfg: RunSettings, tick, traces) -> Iterator[dict]:
    """Per opened session, in order: :func:`run_variants`'s results, run here or, with
    ``cfg.workers`` > 1, in worker processes (:mod:`graph_slam.report.parallel`).
    ``traces``: per session, variant → trace (or None), as :func:`run_variants` takes them
    (the filled traces replace them)."""
    if cfg.workers > 1 and len(opened) * len(cfg.variants) > 1:
        from graph_slam.report.parallel import run_sessions

        yield from run_sessions(opened, cfg.variants, cfg.pipeline, tick, traces, cfg.workers)
        return
    for session, session_traces in zip(opened, traces, strict=True):
        yield run_variants(session, cfg.variants, cfg.pipeline, tick, session_traces)


def reference_variant(cfg: RunConfig) -> Variant:
    """The variant the others are compared with."""
    variants = [Variant(v) for v in cfg.variants]
    if cfg.reference is not None:
        if Variant(cfg.reference) not in variants:
            from graph_slam.errors import ConfigError

            raise ConfigError(
                f"field 'reference': {cfg.reference} is not among the variants "
                f"({', '.join(map(str, variants))})"
            )
        return Variant(cfg.reference)
    return Variant.ICP_IMU_KIN if Variant.ICP_IMU_KIN in variants else variants[-1]


def _check_names(opened) -> None:
    names = [s.name for s in opened]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise EvaluationError(
            f"run: sessions named {', '.join(twice)} more than once; their outputs would share "
            "a folder (rename one session folder)"
        )


def run(
    sessions: Sequence[str | Path | SessionSpec],
    out: str | Path,
    config: RunConfig | None = None,
    progress: ProgressCallback | None = None,
    *,
    overwrite: bool = False,
    precomputed: dict[str, dict] | None = None,
) -> RunReport:
    """Run every variant on every session and write the output folder ``out`` (docs/run.md).
    ``precomputed``: session name → {variant: PipelineResults} already computed (a live run,
    ``graph_slam.live``): written as a run's without running the variants again."""
    from graph_slam.report.checks import preflight

    t_start = time.perf_counter()
    cfg = config or RunConfig()
    reference = reference_variant(cfg)
    specs, opened = open_sessions(sessions)
    _check_names(opened)
    inputs = [s.path for s in specs]
    out = check_output(out, overwrite=overwrite, command="run", inputs=inputs)
    variants = [str(v) for v in cfg.variants]
    warnings = preflight(opened, variants, cfg.pipeline.event_source, scoring=False)
    with atomic_folder(out, overwrite=overwrite, command="run", inputs=inputs) as tmp:
        report = _write_run(tmp, opened, cfg, reference, progress, warnings, precomputed)
        report.wall_s = time.perf_counter() - t_start
        report.summary["wall_s"] = report.wall_s
        report.files += _write_documents(tmp, report, cfg)
        report.out = out
        report.files = [out / f.relative_to(tmp) for f in report.files]
    return report


def _write_run(
    tmp: Path, opened, cfg: RunConfig, reference, progress, warnings, precomputed=None
) -> RunReport:
    """Steps 1-3 for every session, and the rerun recording, into ``tmp``."""
    from graph_slam.report import views
    from graph_slam.report.artefacts import write_variant
    from graph_slam.report.checks import rejected_samples, write_compare_config
    from graph_slam.report.summary import summarise_session

    files = [write_compare_config(cfg, tmp / "config.yaml")]
    tick = count_progress(progress, sum(len(cfg.variants) * s.n_frames for s in opened))
    logger = views.make_logger(tmp / "recording.rrd" if cfg.rrd else None)
    sessions: dict[str, dict] = {}
    t_offset = 0.0
    main = Variant(cfg.variants[-1])
    traces: list[dict | None] = [None] * len(opened)
    if cfg.rrd and cfg.pipeline.terrain.online.enabled:
        from graph_slam.report.terrain_trace import TerrainTrace

        traces = [{main: TerrainTrace(cfg.rrd_grid_step, every_frame=False)} for _ in opened]
    if precomputed is not None:
        runs = iter([precomputed[s.name] for s in opened])
    else:
        runs = session_results(opened, cfg, tick, traces)
    for session, results, session_traces in zip(opened, runs, traces, strict=True):
        trace = None if session_traces is None else session_traces[main]
        warnings += rejected_samples(session, results)
        leg = _leg_model(session, cfg)
        for variant, res in results.items():
            files += write_variant(tmp / session.name / variant.tag, res, cfg, session, leg)
        sessions[session.name] = summarise_session(session, results, reference)
        if cfg.rrd:
            views.log_run(session, results, cfg, logger, t_offset, trace)
        t_offset += float(session.frame_times_s[-1]) + 1.0 if session.n_frames else 0.0
    logger.close()
    files += [tmp / "recording.rrd"] if cfg.rrd else []
    summary = {
        "preset": cfg.pipeline.preset,
        "variants": [str(v) for v in cfg.variants],
        "reference": str(reference),
        "sessions": sessions,
        "warnings": [w.to_dict() for w in warnings],
    }
    return RunReport(tmp, list(sessions), summary, files, warnings=warnings)


def _leg_model(session, cfg: RunConfig):
    """The session's leg model for the toe clearance (None, logged, when there is none)."""
    import logging

    from graph_slam.errors import GraphSlamError
    from graph_slam.strides.kinematics import session_leg_model

    if session.joints is None:
        return None
    try:
        return session_leg_model(
            session, cfg.pipeline.mount_pitch_deg, cfg.pipeline.mount_estimate
        )[0]
    except GraphSlamError as err:
        logging.getLogger(__name__).info(
            "%s: no leg model for the toe clearance (%s)", session.name, err
        )
        return None


def _write_documents(tmp: Path, report: RunReport, cfg: RunConfig) -> list[Path]:
    """``run.json`` and ``report.md``."""
    import json

    from graph_slam.report.summary import run_markdown

    (tmp / "run.json").write_text(
        json.dumps(report.summary, indent=1, allow_nan=False), encoding="utf-8"
    )
    (tmp / "report.md").write_text(run_markdown(report.summary, cfg), encoding="utf-8")
    return [tmp / "run.json", tmp / "report.md"]
