"""The ``graph-slam`` command line: thin, lazy, and never a traceback for bad input.

Each command parses its arguments, calls one library function, prints the result and maps the
library's typed errors to a one-line message and exit code 2. Heavy libraries (open3d, gtsam,
pinocchio, rerun) are imported inside the commands so that ``graph-slam --help`` is instant.

Commands that belong to a sub-package live in ``graph_slam/commands/<name>.py`` and expose
``register(app)``; they are listed in :data:`COMMAND_MODULES`.
"""

from __future__ import annotations

import importlib
import sys
from typing import Annotated

import typer

from graph_slam._version import __version__

app = typer.Typer(
    name="graph-slam",
    help="Per-stride factor-graph SLAM for a thigh-mounted RGB-D camera on a prosthesis.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# Modules under graph_slam/commands/ that add commands to the app (each: register(app)).
COMMAND_MODULES: tuple[str, ...] = (
    "session",
    "gait",
    "convert",
    "simulate",
    "planar",
    "bench",
    "compare",
    "run",
    "batch",
    "live",
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"graph-slam {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version_callback, is_eager=True, help="Print the version."
        ),
    ] = False,
) -> None:
    """Per-stride factor-graph SLAM for a thigh-mounted RGB-D camera on a prosthesis."""


for _name in COMMAND_MODULES:
    importlib.import_module(f"graph_slam.commands.{_name}").register(app)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point: run the app, turning library errors into exit code 2."""
    from graph_slam.commands._common import run_app

    sys.exit(run_app(app, argv))
