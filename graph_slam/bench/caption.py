"""The caption a printed figure carries: the date, the commit, the machine's cores and the
command that printed it (a table in the docs is pasted from it, never typed)."""

from __future__ import annotations

import datetime
import functools
import os
import shlex
import subprocess
import sys
from pathlib import Path


@functools.cache
def commit() -> str:
    """The checkout's short commit (``+dirty`` with uncommitted changes), or the package
    version when graph_slam does not run from a git checkout. Read once per process: a
    command calls it when it starts (:func:`mark_start`), so a table printed at its end names
    the code that ran, not a commit made meanwhile."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()  # fmt: skip
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        from graph_slam._version import __version__

        return f"graph_slam {__version__}"
    return head + ("+dirty" if dirty else "")


def mark_start() -> None:
    """Read the commit now, at the command's start (see :func:`commit`)."""
    commit()


def cores() -> int:
    """The cores this process may use."""
    return len(os.sched_getaffinity(0))


def caption(command: str) -> str:
    """``YYYY-MM-DD, commit abc1234, N cores: `command` ``."""
    today = datetime.datetime.now(datetime.UTC).date().isoformat()
    return f"{today}, commit {commit()}, {cores()} cores: `{command}`"


def invoked_command() -> str:
    """The command line this process was started with, as ``graph-slam …`` (also under
    ``python -m graph_slam``)."""
    return shlex.join(["graph-slam", *sys.argv[1:]])
