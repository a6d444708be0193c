"""``graph-slam bench`` commands that measure the pipelines: accuracy of every variant,
real-time replay, and the fixed list of scenarios (registered under ``bench`` by
:mod:`graph_slam.commands.bench`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from graph_slam.commands import options


def pipelines_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Simulated sessions (graph-slam simulate), one per speed.")
    ],
    variants: Annotated[
        str,
        typer.Option(
            help="Comma-separated: icp, icp+imu, imu+kin, icp+imu+kin, bridge "
            "(icp+imu+kin without ICP in swing); a graph row may name a pipeline preset: "
            "icp+imu+kin:realtime (accurate, thesis, realtime, realtime-gicp; docs/pipelines.md)."
        ),
    ] = "icp,icp+imu,imu+kin,icp+imu+kin,bridge",
    markdown: options.Markdown = False,
) -> None:
    """Accuracy figures: every variant on simulated sessions (RMSE, swing, counts, timing),
    and the bridging experiment (no ICP in swing). Prints each variant as it finishes."""
    from graph_slam.bench import accuracy as bp

    names = tuple(v.strip() for v in variants.split(",") if v.strip())
    from graph_slam.pipelines.config import PIPELINE_PRESETS

    known = (*bp.VARIANTS, bp.BRIDGE)
    graph_rows = (*(v for v in bp.VARIANTS if v != "icp"), bp.BRIDGE)
    if unknown := [
        v
        for v in names
        if v.partition(":")[0] not in known
        or (v.partition(":")[2] and (v.partition(":")[2] not in PIPELINE_PRESETS
                                     or v.partition(":")[0] not in graph_rows))
    ]:  # fmt: skip
        raise typer.BadParameter(
            f"unknown {unknown}; choose from {', '.join(known)}, a graph row optionally with "
            f":{'/'.join(PIPELINE_PRESETS)}"
        )
    typer.echo(bp.header_line())

    def show(sc, v: str) -> None:
        if len(sc.variants) == 1:
            typer.echo(f"== {sc.name} ({sc.speed})")
        for line in bp.variant_lines(v, sc.variants[v]):
            typer.echo(line)
        if len(sc.variants) == len(names):
            for line in bp.swing_lines(sc):
                typer.echo(line)

    scores = bp.run_pipelines_bench({p.name: p for p in sessions}, names, on_variant=show)
    for line in bp.summary_lines(scores):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + bp.markdown_table(scores, invoked_command()))


#: ``bench realtime --variants``: the rows, each a variant or VARIANT:PRESET.
_RealtimeRows = Annotated[
    str,
    typer.Option(
        help="Comma-separated rows: a variant (icp = the thesis baseline) or "
        "VARIANT:PRESET (a pipeline preset, e.g. icp+imu+kin:realtime: the real-time "
        "registration, IMU guess, deferred smoothing; docs/pipelines.md)."
    ),
]
#: ``bench realtime --minutes``: loop each session to this length.
_LoopMinutes = Annotated[
    float | None,
    typer.Option(
        help="Loop each session's strides to this many minutes (memory over a long run; "
        "resident memory printed at 1, 5 and 10 min)."
    ),
]


def realtime_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Sessions (e.g. graph-slam simulate --drops none).")
    ],
    variants: _RealtimeRows = "icp:accurate,icp+imu+kin:accurate,icp+imu+kin:realtime",
    pace: Annotated[
        str, typer.Option(help="virtual (as fast as it runs, deterministic skips) or wall.")
    ] = "virtual",
    config: Annotated[
        Path | None, typer.Option("--config", help="YAML of PipelineConfig overrides (base).")
    ] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Write the figures as JSON.")] = None,
    markdown: options.Markdown = False,
    minutes: _LoopMinutes = None,
) -> None:
    """Real time: every row replayed causally (streams in timestamp order, newest frame taken
    when the estimator is free): per-stage latency, frames processed / skipped, rate, CPU,
    memory, accuracy of what was processed, speed-ups vs the thesis baseline."""
    from graph_slam.bench import realtime as rt
    from graph_slam.config import load_config
    from graph_slam.pipelines import PipelineConfig

    base = load_config(PipelineConfig, config)
    rows = tuple(v.strip() for v in variants.split(",") if v.strip())
    for row in rows:  # an unknown variant or preset fails before any work
        rt.row_config(row, base)
    typer.echo(rt.header_line(pace))
    current: list[str] = []

    def start(session: str, row: str) -> None:
        if session not in current:
            current.append(session)
            typer.echo(f"== {session}")
        typer.echo(f"  ... {row}")

    def show(r) -> None:
        for line in rt.row_lines(r):
            typer.echo(line)

    results = rt.run_realtime_bench(
        sessions, rows, base, pace, minutes=minutes, on_start=start, on_row=show
    )
    for line in rt.headline_lines(results):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + rt.markdown_table(results, invoked_command()))
    if out is not None:
        typer.echo(f"wrote {rt.write_json(results, out)}")


def scenarios_bench(
    only: Annotated[
        str | None, typer.Option(help="Comma-separated scenario names (default: all).")
    ] = None,
    strides: Annotated[int, typer.Option(help="Strides simulated per scenario.")] = 2,
    seed: Annotated[int, typer.Option(help="Simulator seed.")] = 3,
    speeds: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated walking speeds (slow,normal,fast): every scenario at each "
            "(default: each scenario's own)."
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="YAML of PipelineConfig overrides for both pipelines."),
    ] = None,
    markdown: options.Markdown = False,
) -> None:
    """Scenarios: a fixed list of scenes and conditions (flat floor and box course with and
    without texture, Pico Flexx, fast walk, double noise, stairs): coverage, frames registered
    / partial / bridged, smoothed and online per-stride RMSE, the baseline beside them."""
    from graph_slam.bench import scenarios as sc
    from graph_slam.config import load_config
    from graph_slam.pipelines import PipelineConfig

    base = load_config(PipelineConfig, config)  # a bad file fails before any simulation
    if seed < 0 or strides < 1:
        raise typer.BadParameter(f"--seed {seed} must be >= 0 and --strides {strides} >= 1")
    names = None if only is None else tuple(n.strip() for n in only.split(",") if n.strip())
    known = {s.name for s in sc.SCENARIOS}
    if names and (unknown := [n for n in names if n not in known]):
        raise typer.BadParameter(f"unknown {unknown}; choose from {', '.join(sorted(known))}")
    chosen = None if speeds is None else tuple(v.strip() for v in speeds.split(",") if v.strip())
    typer.echo(sc.HEADER)
    scores = sc.run_scenarios(
        names, strides, seed, on_score=lambda s: typer.echo(s.line()), speeds=chosen, base=base
    )
    pooled = sc.pooled(scores)  # the targets are over the speeds
    for score in pooled:
        typer.echo(score.line())
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + sc.markdown_table(scores + pooled, invoked_command()))
