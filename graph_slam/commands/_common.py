"""Shared helpers of the CLI commands: error mapping, progress."""

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


EXIT_INTERRUPTED = 130


def exit_on_interrupt(out) -> object:
    """A context: a Ctrl-C ends with one line and exit code 130 (the output folder ``out`` is
    written whole or not at all, so nothing half-written is left; workers stop quietly)."""
    from contextlib import contextmanager

    @contextmanager
    def _guard():
        try:
            yield
        except KeyboardInterrupt:
            print(f"interrupted: nothing written to {out}", file=sys.stderr)
            raise typer.Exit(EXIT_INTERRUPTED) from None

    return _guard()


PLAIN_PROGRESS_EVERY_S = 5.0
"""How often the plain progress line is printed when stderr is not a terminal (a log file, CI)."""


def plain_progress(description: str, every_s: float = PLAIN_PROGRESS_EVERY_S, stream=None):
    """``update(done, total)`` that prints ``description: done/total (pct %), elapsed`` to
    ``stream`` (stderr) at most every ``every_s`` seconds, and always the last step."""
    import time

    t0 = time.monotonic()
    last = -float("inf")

    def update(done: int, total: int | None) -> None:
        nonlocal last
        now = time.monotonic()
        finished = total is not None and done >= total
        if now - last < every_s and not finished:
            return
        last = now
        of = f"{done}/{total} ({100.0 * done / total:.0f} %)" if total else f"{done}"
        print(f"{description}: {of}, {now - t0:.0f} s", file=stream or sys.stderr, flush=True)

    return update


def progress_bar(description: str, every_s: float = PLAIN_PROGRESS_EVERY_S):
    """A rich progress bar on a terminal; otherwise a plain line every ``every_s`` seconds
    (:func:`plain_progress`), so a long run in a log shows it is alive. Yields
    ``update(done, total)``.

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
        if not Console(stderr=True).is_terminal:
            yield plain_progress(description, every_s)
            return
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeRemainingColumn(),
        )
        with Progress(*columns, transient=True) as progress:
            task = progress.add_task(description, total=None)
            yield lambda done, total: progress.update(task, completed=done, total=total)

    return _bar()


def workers_option_help(default: str) -> str:
    return (
        "Run the (session, variant) pairs in this many processes, the thesis baseline's first "
        f"(default {default}; 1: one after another). Over the config's workers."
    )


def with_workers(cfg, workers: int | None):
    """``cfg`` (a RunSettings) with ``workers`` over it (None: as it is)."""
    from graph_slam.config import config_from_dict

    if workers is None:
        return cfg
    data = {**cfg.model_dump(), "workers": workers}
    return config_from_dict(type(cfg), data, source="--workers")
