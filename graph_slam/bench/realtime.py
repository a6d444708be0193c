"""Real-time benchmark: each pipeline row replayed causally on a session
(:func:`graph_slam.pipelines.replay.replay_session`), side by side.

A row is a variant (``icp`` = the thesis baseline, ``icp+imu+kin`` = today's graph) or
``VARIANT:PRESET``: the variant with a pipeline preset (``pipelines.config.PIPELINE_PRESETS``;
``icp+imu+kin:realtime`` = the real-time configuration: its registration preset, the IMU's
initial guess, deferred smoothing, online-only terrain). Each row
runs in a fresh process (its peak memory is its own) and reports per-stage latency, the full
update, frames delivered / processed / skipped, the achieved rate, CPU time per frame, memory,
and the online and smoothed stride-frame accuracy of the frames it processed
(:func:`graph_slam.bench.accuracy.score`: frames are matched by time, so a subset is scored
against the same truth). The headline: speed-ups against the thesis baseline.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.config import config_from_dict
from graph_slam.errors import ConfigError
from graph_slam.pipelines import PipelineConfig
from graph_slam.pipelines.config import parse_row, with_preset

BASELINE_ROW = "icp"
"""The variant of the rows the speed-ups are taken against (the first such row)."""
DEFAULT_ROWS: tuple[str, ...] = ("icp:accurate", "icp+imu+kin:accurate", "icp+imu+kin:realtime")
"""The thesis baseline on every pixel, the accurate graph and the default (real-time) one."""


def _is_baseline(row: str) -> bool:
    return row.partition(":")[0] == BASELINE_ROW


STAGES: tuple[tuple[str, str], ...] = (
    ("cloud", "depth->cloud"),
    ("preprocess", "preprocessing"),
    ("registration", "registration"),
    ("floor", "floor"),
    ("graph", "graph update"),
    ("terrain", "terrain update"),
    ("stride_close", "stride close"),
)
"""``FrameOutput.stages_s`` keys and their names in the report."""


def row_config(row: str, base: PipelineConfig | None = None) -> PipelineConfig:
    """The pipeline configuration of a row ``VARIANT`` or ``VARIANT:PRESET`` (a
    :data:`~graph_slam.pipelines.config.PIPELINE_PRESETS` name, applied over ``base``,
    ``--config``; without one: ``base``'s preset, the default one when None). Raises
    :class:`ConfigError` naming the row when the variant or the preset is unknown."""
    variant, preset = parse_row(row)
    data = (base or PipelineConfig()).model_dump(mode="json")
    data["variant"] = str(variant)
    if preset:
        data = with_preset(data, preset)
    return config_from_dict(PipelineConfig, data, source=f"row {row!r}")


@dataclass(frozen=True)
class Stat:
    """Milliseconds over the frames where a stage ran."""

    median_ms: float
    p95_ms: float
    max_ms: float
    n: int

    @classmethod
    def of(cls, seconds: np.ndarray) -> Stat:
        ms = np.asarray(seconds, float) * 1e3
        if ms.size == 0:
            return cls(float("nan"), float("nan"), float("nan"), 0)
        return cls(
            float(np.median(ms)), float(np.percentile(ms, 95)), float(ms.max()), int(ms.size)
        )

    def text(self) -> str:
        return f"{self.median_ms:7.1f} {self.p95_ms:7.1f} {self.max_ms:7.1f}  (n {self.n})"


@dataclass
class RealtimeRow:
    """One row on one session."""

    session: str
    row: str
    pace: str
    stages: dict[str, Stat]
    update: Stat
    """The full update: ``add_frame`` wall time."""
    latency: Stat
    """Arrival to result (waiting included)."""
    delivered: int
    processed: int
    skipped: int
    delivered_hz: float
    achieved_hz: float
    cpu_ms_per_frame: float
    finish_ms: float
    """Closing the last stride (``finish``)."""
    rss_start_mb: float
    peak_rss_mb: float
    rss_mb: list[tuple[float, float]]
    """(session time s, resident MB) at the start, the 1/5/10 min marks and the end."""
    strides_scored: int
    online_rmse_mm: float
    smoothed_rmse_mm: float
    """Median over complete strides of the per-stride stride-frame RMSE."""
    frames_without_pose: int
    wall_s: float
    machine: dict = field(default_factory=dict)
    scored: bool = True
    """False for a long run that kept only its latest frame records (``--minutes``)."""
    frames_imu_only: int = 0
    """Processed frames flagged ``imu_only`` (their stride had no accepted registration yet:
    :mod:`graph_slam.pipelines.bridge`); their poses are not registered ones."""


#: the frame records a ``--minutes`` run keeps (10 s at 90 Hz)
LONG_RUN_KEEP_FRAMES = 900


def run_row(
    session_path: str | Path,
    row: str,
    base: PipelineConfig | None = None,
    pace: str = "virtual",
    minutes: float | None = None,
) -> RealtimeRow:
    """Replay one row on one session and score what it processed (in this process).
    ``minutes``: the session looped to that length (:class:`~graph_slam.session.looped.
    LoopedSession`: memory over a long run, with ``terrain.online.keep_stride_grids: 2`` and
    ``keep_frames``: :data:`LONG_RUN_KEEP_FRAMES`; not scored)."""
    from graph_slam.bench.accuracy import score
    from graph_slam.pipelines.replay import MEASURED, replay_session
    from graph_slam.session import open_session
    from graph_slam.session.looped import LoopedSession
    from graph_slam.strides.kinematics import session_leg_model

    cfg = row_config(row, base)
    session = open_session(session_path)
    if minutes is not None:
        session = LoopedSession(session, minutes, cfg.event_source)
        # a long run as a controller runs it: only the latest strides' grids and the latest
        # frames' records kept (the run is then not scored: scoring needs every frame)
        data = cfg.model_dump(mode="json")
        data["terrain"]["online"]["keep_stride_grids"] = 2
        data["keep_frames"] = LONG_RUN_KEEP_FRAMES
        cfg = PipelineConfig.model_validate(data)
    t0 = time.perf_counter()
    # a timing study: the virtual clock advances by the measured time (the skipped frames
    # then depend on the machine's load; the poses of the frames processed do not)
    cost = MEASURED if pace == "virtual" else None
    res = replay_session(session, cfg, pace=pace, compute_cost=cost)  # type: ignore[arg-type]
    wall = time.perf_counter() - t0
    leg, _ = session_leg_model(
        session, cfg.mount_pitch_deg, cfg.mount_estimate, event_source=cfg.event_source
    )
    strides = score(session, res.results, leg) if cfg.keep_frames is None else []
    on = np.array([s.online_rmse_m for s in strides]) * 1e3
    sm = np.array([s.smoothed_rmse_m for s in strides]) * 1e3
    return RealtimeRow(
        session=session.name,
        row=row,
        pace=pace,
        stages={key: Stat.of(res.stage_s(key)) for key, _ in STAGES},
        update=Stat.of(res.compute_s),
        latency=Stat.of(res.latency_s),
        delivered=res.n_delivered,
        processed=res.n_processed,
        skipped=res.n_skipped,
        delivered_hz=res.delivered_rate_hz,
        achieved_hz=res.achieved_rate_hz,
        cpu_ms_per_frame=float(np.mean(res.cpu_s) * 1e3) if res.frames else float("nan"),
        finish_ms=res.finish_call_s * 1e3,
        rss_start_mb=res.rss[0].rss_mb,
        peak_rss_mb=res.peak_rss_mb,
        rss_mb=[(s.session_s, s.rss_mb) for s in res.rss],
        strides_scored=len(strides),
        online_rmse_mm=float(np.nanmedian(on)) if np.isfinite(on).any() else float("nan"),
        smoothed_rmse_mm=float(np.nanmedian(sm)) if np.isfinite(sm).any() else float("nan"),
        frames_without_pose=res.results.n_frames - res.results.n_with_pose,
        wall_s=wall,
        machine=machine(),
        scored=cfg.keep_frames is None,
        frames_imu_only=sum(
            any(flag.startswith("imu_only:") for flag in f.flags) for f in res.results.frames
        ),
    )


def machine() -> dict:
    return {
        "cpus_visible": len(os.sched_getaffinity(0)),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }


def _run_row_isolated(session_path, row, base, pace, minutes) -> RealtimeRow:
    """:func:`run_row` in a fresh process, so that its peak memory is its own."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("spawn")) as pool:
        return pool.submit(run_row, str(session_path), row, base, pace, minutes).result()


def run_realtime_bench(
    sessions: Sequence[str | Path],
    rows: Sequence[str] = DEFAULT_ROWS,
    base: PipelineConfig | None = None,
    pace: str = "virtual",
    *,
    isolate: bool = True,
    minutes: float | None = None,
    on_start: Callable[[str, str], None] | None = None,
    on_row: Callable[[RealtimeRow], None] | None = None,
) -> list[RealtimeRow]:
    """Every row on every session. Every row's configuration is built first (an unknown
    variant or preset fails before any work). ``isolate``: each row in a fresh process.
    ``minutes``: each session looped to that length (:func:`run_row`)."""
    from graph_slam.pipelines.replay import PACES

    if pace not in PACES:
        raise ConfigError(f"pace {pace!r}: choose virtual or wall")
    if minutes is not None and not minutes > 0:
        raise ConfigError(f"minutes: must be > 0, got {minutes}")
    for row in rows:
        row_config(row, base)
    out = []
    for path in sessions:
        for row in rows:
            if on_start is not None:
                on_start(Path(path).name, row)
            run = _run_row_isolated if isolate else run_row
            result = run(path, row, base, pace, minutes)
            out.append(result)
            if on_row is not None:
                on_row(result)
    return out


# --------------------------------------------------------------------------- report
def row_lines(r: RealtimeRow) -> list[str]:
    lines = [
        f"  {r.row}: frames delivered {r.delivered} ({r.delivered_hz:.1f} Hz), processed "
        f"{r.processed}, skipped {r.skipped}; achieved {r.achieved_hz:.1f} Hz; CPU "
        f"{r.cpu_ms_per_frame:.1f} ms/frame; peak memory {r.peak_rss_mb:.0f} MB (start "
        f"{r.rss_start_mb:.0f} MB); replay wall {r.wall_s:.1f} s",
        f"    {'ms':22s}  median     p95     max",
        f"    {'full update':22s}{r.update.text()}",
        f"    {'latency (with waiting)':22s}{r.latency.text()}",
    ]
    for key, name in STAGES:
        if r.stages[key].n:
            lines.append(f"    {'  ' + name:22s}{r.stages[key].text()}")
    lines.append(f"    {'  finish (last stride)':22s}{r.finish_ms:7.1f}")
    if r.scored:
        lines.append(
            f"    accuracy of the processed frames: {r.strides_scored} complete strides, "
            f"stride-frame RMSE median online {r.online_rmse_mm:.1f} mm, smoothed "
            f"{r.smoothed_rmse_mm:.1f} mm; frames without pose {r.frames_without_pose}, "
            f"IMU-only (flagged) {r.frames_imu_only}"
        )
    else:
        lines.append(
            f"    not scored: a long run keeps only its latest {LONG_RUN_KEEP_FRAMES} frame "
            "records (keep_frames)"
        )
    if len(r.rss_mb) > 2:
        lines.append(
            "    resident memory: "
            + ", ".join(f"{mb:.0f} MB at {t / 60:.0f} min" for t, mb in r.rss_mb[1:-1])
        )
    return lines


def markdown_table(rows: Sequence[RealtimeRow], command: str) -> str:
    """The rows as the markdown table docs/benchmarks.md holds ("Real time"), with its
    caption (:func:`graph_slam.bench.caption.caption`); times are load-dependent: the
    caption's machine and the run's conditions belong with them."""
    from graph_slam.bench.caption import caption

    lines = [
        f"({caption(command)})",
        "",
        "| session | row | full update ms median / p95 | delivered | processed | skipped "
        "| CPU ms / frame | peak MB | smoothed mm (median) |",
        "| :-- | :-- | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for r in rows:
        lines.append(
            f"| {r.session} | {r.row} | {r.update.median_ms:.1f} / {r.update.p95_ms:.1f} "
            f"| {r.delivered} | {r.processed} | {r.skipped} | {r.cpu_ms_per_frame:.1f} "
            f"| {r.peak_rss_mb:.0f} | {r.smoothed_rmse_mm:.1f} |"
        )
    return "\n".join(lines)


def speedups(rows: Sequence[RealtimeRow]) -> list[dict]:
    """Per session and row: the thesis baseline's figures over the row's."""
    out = []
    for r in rows:
        base = next((b for b in rows if b.session == r.session and _is_baseline(b.row)), None)
        if base is None or r is base:
            continue
        out.append(
            {
                "session": r.session,
                "row": r.row,
                "update_median": base.update.median_ms / r.update.median_ms,
                "update_p95": base.update.p95_ms / r.update.p95_ms,
                "cpu_per_frame": base.cpu_ms_per_frame / r.cpu_ms_per_frame,
                "achieved_rate": r.achieved_hz / base.achieved_hz,
            }
        )
    return out


def headline_lines(rows: Sequence[RealtimeRow]) -> list[str]:
    ups = speedups(rows)
    if not ups:
        return [f"(no {BASELINE_ROW!r} row: no speed-ups)"]
    first = next(r.row for r in rows if _is_baseline(r.row))
    lines = [f"== speed-up vs the thesis baseline ({first})"]
    for u in ups:
        lines.append(
            f"  {u['session']} {u['row']}: full update {u['update_median']:.3g}x (median), "
            f"{u['update_p95']:.3g}x (p95); CPU per frame {u['cpu_per_frame']:.3g}x; "
            f"achieved rate {u['achieved_rate']:.3g}x"
        )
    return lines


def write_json(rows: Sequence[RealtimeRow], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "machine": machine(),
        "rows": [asdict(r) for r in rows],
        "speedups": speedups(rows),
    }
    path.write_text(json.dumps(data, indent=2, allow_nan=True) + "\n", encoding="utf-8")
    return path


def header_line(pace: str) -> str:
    return f"real-time benchmark, {pace} pace ({len(os.sched_getaffinity(0))} CPUs visible)"
