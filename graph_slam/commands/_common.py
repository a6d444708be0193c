"""Shared helpers of the CLI commands: error mapping."""

from __future__ import annotations

import sys

import typer


def run_app(app: typer.Typer, argv: list[str] | None = None) -> int:
    """Run the typer app; a library error becomes ``error: <message>`` and exit code 2.

    Usage errors, ``--help`` and ``typer.Exit`` are handled by click itself (standalone mode,
    which ends with SystemExit); anything else that escapes is a bug and keeps its traceback.
    """
    from graph_slam.errors import library_errors

    try:
        app(args=argv, prog_name="graph-slam")
    except library_errors() as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


def progress_bar(description: str):
    """A rich progress bar on a terminal, silent otherwise; yields ``update(done, total)``.

    Use as ``with progress_bar("rendering") as update: work(progress=update)``.
    """
    from contextlib import contextmanager

    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    @contextmanager
    def _bar():
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeRemainingColumn(),
        )
        with Progress(
            *columns, transient=True, disable=not Console(stderr=True).is_terminal
        ) as progress:
            task = progress.add_task(description, total=None)
            yield lambda done, total: progress.update(task, completed=done, total=total)

    return _bar()
