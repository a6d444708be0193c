"""Shared helpers of the CLI commands: error mapping and console output."""

from __future__ import annotations

import sys

import typer


def run_app(app: typer.Typer, argv: list[str] | None = None) -> int:
    """Run the typer app; a library error becomes ``error: <message>`` and exit code 2."""
    from graph_slam.errors import library_errors

    try:
        app(args=argv, standalone_mode=False, prog_name="graph-slam")
    except library_errors() as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except typer.Exit as exc:
        return int(exc.exit_code or 0)
    except typer.Abort:
        print("aborted", file=sys.stderr)
        return 130
    except Exception as exc:  # click usage errors carry their own exit code
        import click

        if isinstance(exc, click.ClickException):
            exc.show()
            return exc.exit_code
        raise
    return 0
