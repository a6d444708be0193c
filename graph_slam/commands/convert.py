"""``graph-slam convert SRC DST``: a bag, TUM RGB-D folder, EuRoC folder or prosthesis log
→ a session (then ``info``, ``validate`` and the pipelines work on it)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

FORMATS = ("auto", "rosbag", "tum", "euroc", "prosthesis-log", "session", "synthetic")
PRESETS = ("auto", "realsense-sdk", "realsense-ros", "none")


def print_report(report) -> None:
    """The conversion's per-stream counts as a rich table."""
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(100, Console().width))
    table = Table("stream", "source", "found", "used", "dropped")
    for s in report.streams:
        dropped = "; ".join(f"{n} {why}" for why, n in s.dropped.items() if n) or "–"
        table.add_row(s.stream, s.source, str(s.found), str(s.used), dropped)
    console.print(table)
    if report.device:
        console.print("  device: " + ", ".join(f"{k} {v}" for k, v in report.device.items()))
    for note in report.notes + [n for s in report.streams for n in s.notes]:
        console.print(f"  note: {note}")


def register(app: typer.Typer) -> None:
    @app.command()
    def convert(
        src: Annotated[Path, typer.Argument(help="Bag, TUM/EuRoC folder, log CSV or session.")],
        dst: Annotated[Path, typer.Argument(help="Session folder to write.")],
        format: Annotated[str, typer.Option(help=f"Source kind: {', '.join(FORMATS)}.")] = "auto",
        preset: Annotated[
            str | None,
            typer.Option(help=f"Bag topic preset: {', '.join(PRESETS)} (default: config's)."),
        ] = None,
        config: Annotated[
            Path | None, typer.Option(help="YAML of conversion overrides (docs/adapters.md).")
        ] = None,
        overwrite: Annotated[bool, typer.Option(help="Replace an existing session.")] = False,
    ) -> None:
        """Convert a recording into a session; writes conversion.yaml (the resolved config)
        and conversion_report.yaml (counts used/dropped) into it."""
        from graph_slam.commands._common import progress_bar
        from graph_slam.commands.session import print_info
        from graph_slam.config import config_from_dict, load_config
        from graph_slam.errors import ConfigError
        from graph_slam.session import open_session, session_info
        from graph_slam.session.adapters import ConvertConfig
        from graph_slam.session.adapters import convert as run_convert

        if format not in FORMATS:
            raise typer.BadParameter(f"must be one of {', '.join(FORMATS)}", param_hint="--format")
        if preset is not None and preset not in PRESETS:
            raise typer.BadParameter(f"must be one of {', '.join(PRESETS)}", param_hint="--preset")
        cfg = load_config(ConvertConfig, config)
        data = cfg.model_dump(mode="json")
        if format != "auto":
            if cfg.format not in ("auto", format):
                raise ConfigError(
                    f"--format {format} contradicts 'format: {cfg.format}' in {config}"
                )
            data["format"] = format
        if preset is not None:
            data["bag"]["preset"] = preset
        cfg = config_from_dict(ConvertConfig, data, source="command line")
        with progress_bar("converting frames") as update:
            result = run_convert(src, dst, cfg, overwrite=overwrite, progress=update)
        print_report(result.report)
        print_info(session_info(open_session(result.path)))
        typer.echo(
            f"converted {src} → {result.path} ({result.n_frames} frames); "
            f"config: {result.config_path.name}, counts: {result.report_path.name}"
        )
