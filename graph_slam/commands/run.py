"""``run``: every variant on recordings with or without ground truth (docs/run.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from graph_slam.commands import options
from graph_slam.commands._common import with_workers, workers_option_help


def load_run_config(
    path: Path | None,
    variants: str | None,
    kitti: bool,
    map_dtype: str | None,
    preset: str | None = None,
):
    """The YAML's RunConfig with the command line's choices over it."""
    from graph_slam.report import RunConfig

    extra: dict = {"kitti": True} if kitti else {}
    if map_dtype is not None:
        extra["map_dtype"] = map_dtype
    return options.load_settings(RunConfig, path, variants, preset, extra=extra)


def _print_run(report) -> None:
    for name, sess in report.summary["sessions"].items():
        typer.echo(f"\n{name}: {sess['frames']} frames")
        for variant, v in sess["variants"].items():
            strides = v["strides"]
            total = {c: sum(s[c] for s in strides) for c in ("registered", "partial", "bridged")}
            t = v["timing"]["total"]
            med = "–" if t["median_ms"] is None else f"{t['median_ms']:.1f}"
            p95 = "–" if t["p95_ms"] is None else f"{t['p95_ms']:.1f}"
            stops = len(v["stop_points"])
            typer.echo(
                f"  {variant}: {len(strides)} strides, {total['registered']} registered, "
                f"{total['partial']} partial, {total['bridged']} bridged frames; "
                f"{med} / {p95} ms per frame (median / p95)"
                + (f"; stopped in {stops} strides" if stops else "")
            )
    for warning in report.warnings:
        typer.echo(f"warning: {warning}", err=True)
    typer.echo(
        f"report: {report.out / 'report.md'} ({len(report.files)} files, {report.wall_s:.0f} s)"
    )


def register(app: typer.Typer) -> None:
    @app.command("run")
    def run_cmd(
        sessions: Annotated[
            list[Path], typer.Argument(help="Session folders (ground truth not needed).")
        ],
        out: options.Out,
        variants: options.Variants = None,
        config: options.Config = None,
        preset: options.Preset = None,
        kitti: Annotated[
            bool, typer.Option("--kitti", help="Also write KITTI trajectories.")
        ] = False,
        map_dtype: Annotated[
            str | None,
            typer.Option(help="PLY coordinates of the maps: float32 (default) or float64."),
        ] = None,
        overwrite: options.Overwrite = False,
        workers: Annotated[
            int | None, typer.Option(min=1, max=64, help=workers_option_help("1"))
        ] = None,
    ) -> None:
        """Run the variants on recordings (ground truth optional); write trajectories, maps,
        elevation grids, per-frame flags, timing and a report of what agrees."""
        from graph_slam.commands._common import exit_on_interrupt, progress_bar
        from graph_slam.report import run

        cfg = with_workers(load_run_config(config, variants, kitti, map_dtype, preset), workers)
        with exit_on_interrupt(out), progress_bar("running variants") as update:
            report = run(sessions, out, cfg, progress=update, overwrite=overwrite)
        _print_run(report)
