"""``batch``: a study spec's sessions × variants × configurations on Dask (docs/batch.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

EXIT_SOME_FAILED = 2
"""Exit code when the batch ran but some tasks failed (also every bad-input error's code)."""
EXIT_INTERRUPTED = 130


def register(app: typer.Typer) -> None:
    @app.command()
    def batch(
        spec: Annotated[Path, typer.Argument(help="Study spec (YAML; docs/batch.md).")],
        out: Annotated[Path, typer.Option(help="Study folder (a re-run resumes it).")],
        preset: Annotated[
            str | None,
            typer.Option(
                "--preset",
                help="Pipeline preset of every configuration whose spec names none "
                "(pipeline: {preset: ...}); default: realtime.",
            ),
        ] = None,
        scheduler: Annotated[
            str | None,
            typer.Option(
                help="Dask scheduler address (tcp://host:8786); default: a local cluster."
            ),
        ] = None,
        workers: Annotated[
            int | None, typer.Option(min=1, help="Local workers (default: cores / threads).")
        ] = None,
        threads_per_worker: Annotated[
            int | None, typer.Option(min=1, help="Tasks at once per local worker (default 1).")
        ] = None,
        memory_limit: Annotated[
            str | None, typer.Option(help="Per local worker, e.g. 4GiB (default 4GiB).")
        ] = None,
    ) -> None:
        """Run every task of the study spec (isolated, retried, resumable) and pool the report.

        Exit 0 when every task succeeded, 2 when some failed (or the input is bad), 130 when
        interrupted (a re-run resumes).
        """
        from graph_slam.batch import ClusterOptions, run_batch
        from graph_slam.batch.cluster import require_dask

        require_dask()  # before any work
        options = ClusterOptions(scheduler, workers, threads_per_worker, memory_limit)
        with _progress() as (on_task, on_cluster):
            try:
                result = run_batch(
                    spec, out, options, on_task=on_task, on_cluster=on_cluster, preset=preset
                )
            except KeyboardInterrupt:
                typer.echo("interrupted: finished tasks are kept; run again to resume", err=True)
                raise typer.Exit(EXIT_INTERRUPTED) from None
        _print_summary(result)
        if not result.ok:
            raise typer.Exit(EXIT_SOME_FAILED)


def _progress():
    """A rich bar of tasks on a terminal; a line per finished task otherwise."""
    from contextlib import contextmanager

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    console = Console(stderr=True)

    @contextmanager
    def _bar():
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            console=console,
            disable=not console.is_terminal,
        ) as progress:
            bar = progress.add_task("tasks", total=None)

            def on_task(task, state, done, total):
                line = f"[{done}/{total}] {task.id}: {state['status']}"
                if state.get("wall_s") is not None:
                    line += f" ({state['wall_s']:.0f} s)"
                if state.get("error"):
                    line += f" — {state['error'].splitlines()[0]}"
                progress.update(bar, completed=done, total=total)
                if console.is_terminal:
                    progress.console.print(line)
                else:
                    typer.echo(line, err=True)

            def on_cluster(info):
                message = f"{info.description}; dashboard: {info.dashboard}"
                if console.is_terminal:
                    progress.console.print(message)
                else:
                    typer.echo(message, err=True)

            yield on_task, on_cluster

    return _bar()


def _print_summary(result) -> None:
    from graph_slam.batch.tasks import DONE, FAILED

    skipped = sum(s.get("this_run") == "skipped" for s in result.states.values())
    typer.echo("\n| done | failed | skipped (finished earlier) |\n| --: | --: | --: |")
    typer.echo(f"| {result.count(DONE) - skipped} | {result.count(FAILED)} | {skipped} |\n")
    for state in result.states.values():
        if state["status"] == FAILED:
            typer.echo(f"failed: {state['id']}: {(state.get('error') or '').splitlines()[0]}")
    typer.echo(f"report: {result.out / 'report.md'} ({result.wall_s:.0f} s)")
