"""Session commands: ``info`` and ``validate`` (``demo`` lives in commands/compare.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

SessionArg = Annotated[Path, typer.Argument(help="Session folder (holds session.yaml).")]


def _fmt(value: float | None, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def print_info(info) -> None:
    """Print a SessionInfo as rich tables (gaps: intervals > 2× the median interval)."""
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(100, Console().width))
    if info.image_size is None:
        camera = "no camera"
    else:
        camera = (
            f"camera '{info.camera_profile}' {info.image_size[0]}×{info.image_size[1]}"
            f"{' + colour' if info.has_color else ''}, depth unit {info.depth_unit_m * 1e3:g} mm"
        )
    console.print(
        f"[bold]{info.name}[/bold]  ({info.path})  schema v{info.schema_version}, {camera}"
    )
    table = Table(
        "stream", "samples", "start s", "span s", "mean Hz", "median Hz", "gaps", "max gap s"
    )
    for s in info.streams:
        table.add_row(
            s.name.replace("ground_truth", "gt"),
            str(s.count),
            _fmt(s.start_s, ".3f"),
            f"{s.duration_s:.3f}",
            _fmt(s.mean_rate_hz, ".2f"),
            _fmt(s.median_rate_hz, ".2f"),
            str(s.gaps),
            f"{s.longest_gap_s:.3f}" if s.gaps else "–",
        )
    console.print(table)
    st = info.strides
    if st is None:
        console.print("strides: no gait events in this session")
    else:
        console.print(
            f"strides ({st.source or 'every source'}): {st.strides} complete "
            f"({st.foot_strikes} foot strikes, {st.toe_offs} toe-offs); "
            f"duration mean {_fmt(st.mean_stride_s, '.3f')} s, min {_fmt(st.min_stride_s, '.3f')} s, "
            f"max {_fmt(st.max_stride_s, '.3f')} s; frames per stride "
            f"{', '.join(map(str, st.frames_per_stride)) or '–'}"
        )


def register(app: typer.Typer) -> None:
    @app.command()
    def info(
        session: SessionArg,
        event_source: Annotated[
            str | None,
            typer.Option(
                help="Cut strides at this events.csv source (e.g. load_cell); default all."
            ),
        ] = None,
    ) -> None:
        """Streams, counts, rates, durations, gaps and strides of a session."""
        from graph_slam.session import open_session, session_info

        print_info(session_info(open_session(session), event_source))

    @app.command()
    def validate(
        session: SessionArg,
        quick: Annotated[
            bool, typer.Option(help="Decode only the first, middle and last frame.")
        ] = False,
        variants: Annotated[
            str | None,
            typer.Option(help="Also check the streams these variants need (as compare does)."),
        ] = None,
    ) -> None:
        """Check a session completely (manifest, streams, every frame, what compare would
        refuse); exit 2 on any problem; caveats are printed as warnings."""
        from graph_slam.commands._common import progress_bar
        from graph_slam.session import validate_session
        from graph_slam.variants import parse_variants

        names = None if variants is None else [str(v) for v in parse_variants(variants)]
        with progress_bar("decoding frames") as update:
            report = validate_session(
                session, every_frame=not quick, progress=update, variants=names
            )
        for warning in report.warnings:
            typer.echo(f"warning: {warning}", err=True)
        if report.ok:
            counts = ", ".join(f"{k} {v}" for k, v in report.counts.items())
            typer.echo(f"valid: {session} ({counts}; {report.frames_checked} frames decoded)")
            return
        for problem in report.problems:
            typer.echo(f"error: {problem}", err=True)
        typer.echo(f"invalid: {session}: {len(report.problems)} problem(s)", err=True)
        raise typer.Exit(2)
