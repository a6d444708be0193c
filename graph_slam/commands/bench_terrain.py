"""``graph-slam bench`` commands that measure the terrain map: the elevation grid against the
scene's truth, and the full graph on the terrain walker's scenes (registered under ``bench``
by :mod:`graph_slam.commands.bench`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from graph_slam.commands import options


def terrain_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Simulated sessions with a scene (graph-slam simulate).")
    ],
    rows: Annotated[
        str,
        typer.Option(
            help="Comma-separated rows: VARIANT, VARIANT:PRESET, and a /nocarry suffix (the "
            "grid starts empty at every stride, the thesis behaviour)."
        ),
    ] = "icp,icp+imu+kin,icp+imu+kin/nocarry,icp+imu+kin:realtime",
    covariances: Annotated[
        bool,
        typer.Option(help="Graph rows: per-frame marginal covariances in the grid's variance."),
    ] = True,
    out: Annotated[Path | None, typer.Option("--out", help="Write the figures as JSON.")] = None,
    markdown: options.Markdown = False,
) -> None:
    """Terrain: the per-frame elevation grid against the scene's truth (docs/terrain.md):
    box sightings at toe-off, the carried map, σ-consistency, update time, deadlines."""
    import json

    from graph_slam.bench import terrain as bt

    names = tuple(r.strip() for r in rows.split(",") if r.strip())
    for name in names:  # an unknown variant, preset or suffix fails before any work
        bt.row_config(name, None, covariances)
    results = []
    for session in sessions:
        typer.echo(f"== {session}")
        typer.echo(bt.HEADER)
        for name in names:
            results.append(bt.run_terrain_row(session, name, covariances=covariances))
            typer.echo(bt.row_line(results[-1].figures()))
        med, p95 = bt.update_cost_ms(session)
        typer.echo(
            f"grid update alone (least of 5 per frame): median {med:.2f} ms, p95 {p95:.2f} ms"
        )
    pooled = bt.pooled(results)
    typer.echo("== all sessions")
    typer.echo(bt.HEADER)
    for r in pooled:
        typer.echo(bt.row_line(r.figures()))
    if markdown:
        from graph_slam.bench.caption import invoked_command

        figures = [r.figures() for r in results + pooled]
        typer.echo("\n" + bt.markdown_table(figures, invoked_command()))
    if out is not None:
        figures = [r.figures() for r in results + pooled]
        out.write_text(json.dumps(figures, indent=1, default=float))
        typer.echo(f"wrote {out}")


#: ``bench terrain-walk --angles``: the walker's joint angles only.
_AnglesOnly = Annotated[
    bool,
    typer.Option(
        "--angles", help="Only the walker's joint-angle peaks per terrain (no rendering)."
    ),
]
#: ``bench terrain-walk --compare-level``: the level-ground anchor beside the terrain one.
_CompareLevel = Annotated[
    bool,
    typer.Option(
        "--compare-level/--no-compare-level",
        help="Also run the level-ground anchor on every scene (its ramp tilt beside the "
        "new anchor's); off: half the time.",
    ),
]


def terrain_walk_bench(
    scenes: Annotated[
        str,
        typer.Option(help="Comma-separated scenes of the terrain-following walker."),
    ] = "stairs-ascent,ramp-up-8,ramp-down-8,curb-up,step-over,terrain-course",
    speeds: Annotated[str, typer.Option(help="Comma-separated: slow,normal,fast.")] = "normal",
    strides: Annotated[int, typer.Option(help="Strides simulated per session.")] = 2,
    resolution: Annotated[str, typer.Option(help="Image size WxH.")] = "424x240",
    preset: Annotated[str, typer.Option(help="Pipeline preset ('' for the defaults).")] = (
        "realtime"
    ),
    seed: Annotated[int, typer.Option(help="Simulator seed.")] = 3,
    angles: _AnglesOnly = False,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="YAML of PipelineConfig overrides for every run."),
    ] = None,
    compare_level: _CompareLevel = True,
    markdown: options.Markdown = False,
) -> None:
    """The full graph on the terrain walker's scenes (stairs, ramps, curbs, boxes): per-stride
    RMSE beside level walking, the anchor's tilt error with the level-ground anchor beside it,
    the anchor's case and slope, every frame posed (docs/benchmarks.md)."""
    from graph_slam.bench import terrain_walk as tw
    from graph_slam.config import load_config, read_yaml
    from graph_slam.pipelines import PipelineConfig
    from graph_slam.sim import SPEEDS_M_S

    load_config(PipelineConfig, config)  # a bad file fails before any simulation
    overrides = None if config is None else read_yaml(config)
    names = [s.strip() for s in scenes.split(",") if s.strip()]
    chosen = [v.strip() for v in speeds.split(",") if v.strip()]
    if unknown := [v for v in chosen if v not in SPEEDS_M_S]:
        raise typer.BadParameter(f"unknown speeds {unknown}; choose from slow, normal, fast")
    if angles:
        for line in tw.angle_lines(names, chosen, max(strides, 4), seed):
            typer.echo(line)
        return
    runs = tw.run_terrain_bench(
        names, chosen, strides, resolution, preset or None, seed, progress=typer.echo,
        overrides=overrides, compare_level=compare_level,
    )  # fmt: skip
    typer.echo(
        "== summary (median per stride, each session's first stride left out; × level: over "
        "flat-floor at the same speed)"
    )
    for line in tw.summary_lines(runs):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + tw.markdown_table(runs, invoked_command()))
