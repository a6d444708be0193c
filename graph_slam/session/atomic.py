"""Atomic output folders: written whole under a temporary sibling, renamed on success.

Every command that writes a folder (``simulate``, ``convert``, ``compare``, ``demo``) goes
through :func:`atomic_folder`. The rules, checked by :func:`check_output` before any work:

- the target's parent must be a writable folder, and the target must not be a file;
- an existing target is replaced only with ``--overwrite``, and only when the tool wrote it:
  it holds the marker file :data:`MARKER_NAME` (every folder written here gets one), or it is
  empty, or (``session=True``) it holds a ``session.yaml`` written by an older version;
  a user's own folder is never removed;
- an interrupted run (an exception, Ctrl-C) removes its temporary folder, so nothing
  half-written is ever left at the target; a run killed outright leaves only a hidden sibling
  ``.<name>.partial-<pid>`` that the next run at the same target removes.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from graph_slam.errors import OutputError

MARKER_NAME = ".graph-slam-output"
"""The marker file in every folder this package writes (``--overwrite`` replaces only those)."""
PARTIAL_INFIX = ".partial-"


def written_by_us(path: Path, *, session: bool = False) -> bool:
    """True for a folder this package wrote (marker; or a session's manifest when ``session``)."""
    if (path / MARKER_NAME).is_file():
        return True
    return session and (path / "session.yaml").is_file()


def check_output(path: str | Path, *, overwrite: bool, session: bool = False) -> Path:
    """Refuse, before any work, a target that cannot be written or must not be replaced."""
    path = Path(path)
    parent = path.absolute().parent
    existing = parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputError(f"{path}: {existing} is a file, not a folder; choose another --out")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write in {existing} (permission denied)")
    if path.is_symlink() or (path.exists() and not path.is_dir()):
        raise OutputError(f"{path}: is a file, not a folder; choose another --out")
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: cannot write in this folder (permission denied)")
        empty = not any(path.iterdir())
        if not empty and not written_by_us(path, session=session):
            raise OutputError(
                f"{path}: exists, is not empty and was not written by graph-slam (no "
                f"{MARKER_NAME}); refusing to write into or replace it, choose another --out"
            )
        if not empty and not overwrite:
            raise OutputError(f"{path}: already exists (pass --overwrite to replace it)")
    return path


def _remove_stale_partials(path: Path) -> None:
    """Remove temporary siblings left by a run of this target that was killed outright."""
    if not path.parent.is_dir():
        return
    for stale in path.parent.glob(f".{path.name}{PARTIAL_INFIX}*"):
        if stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale, ignore_errors=True)


@contextmanager
def atomic_folder(
    path: str | Path, *, overwrite: bool = False, session: bool = False, create: bool = True
) -> Iterator[Path]:
    """Yield a temporary sibling of ``path`` to write into; on success it replaces ``path``.

    ``create=False`` yields a path that does not exist yet (for writers that create their
    folder themselves, e.g. :class:`graph_slam.session.SessionWriter`). On any exception,
    including ``KeyboardInterrupt``, the temporary folder is removed and ``path`` is untouched.
    """
    path = check_output(path, overwrite=overwrite, session=session)
    _remove_stale_partials(path)
    tmp = path.parent / f".{path.name}{PARTIAL_INFIX}{os.getpid()}"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if create:
            tmp.mkdir()
    except OSError as err:
        raise OutputError(f"{path}: cannot create the output folder ({err.strerror})") from None
    try:
        yield tmp
        if not tmp.is_dir():
            raise OutputError(f"{path}: nothing was written")
        (tmp / MARKER_NAME).write_text(
            "written by graph-slam; --overwrite may replace this folder\n", encoding="utf-8"
        )
        check_output(path, overwrite=overwrite, session=session)  # still ours at the end?
        if path.exists():
            shutil.rmtree(path)
        tmp.rename(path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def mark_folder(path: str | Path) -> Path:
    """Create ``path`` (a container such as the demo's output) with the marker; checked first."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        (path / MARKER_NAME).write_text(
            "written by graph-slam; --overwrite may replace this folder\n", encoding="utf-8"
        )
    except OSError as err:
        raise OutputError(f"{path}: cannot create the output folder ({err.strerror})") from None
    return path
