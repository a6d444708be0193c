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
