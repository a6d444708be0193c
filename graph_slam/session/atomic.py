"""Atomic output folders: written whole under a temporary sibling, renamed on success.

Every command that writes a folder (``simulate``, ``convert``, ``run``, ``compare``, ``demo``,
``batch``) goes through :func:`check_output` before any work and :func:`atomic_folder` (or
:func:`mark_folder` for a container) to write. The rules:

- the target's parent must be a writable folder; the target must not be a file or a symbolic
  link;
- the target must not be an input of the run, lie inside one, or contain one (``inputs``);
- an existing target is replaced only with ``--overwrite``, and only when the same command
  wrote it: its marker file :data:`MARKER_NAME` names the command (every folder written here
  gets one; an older graph-slam's marker names none, and the folder's files tell it:
  :data:`LEGACY_SIGNS`). A folder another command wrote (a session, a study, a report), one
  whose command cannot be told, and a user's own folder are never replaced; an empty folder is
  fine;
- an interrupted run (an exception, Ctrl-C) removes its temporary folder, so nothing
  half-written is ever left at the target; a run killed outright leaves only a hidden sibling
  ``.<name>.partial-<pid>`` that the next run at the same target removes.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from graph_slam.errors import OutputError

MARKER_NAME = ".graph-slam-output"
"""The marker file in every folder this package writes; it names the command that wrote it
(``--overwrite`` replaces only a folder the same command wrote)."""
PARTIAL_INFIX = ".partial-"
_COMMAND_KEY = "command: "


def marker_text(command: str) -> str:
    """The marker file's content for a folder ``command`` wrote."""
    return (
        f"written by `graph-slam {command}`; only the same command may replace this folder, "
        f"never another one\n{_COMMAND_KEY}{command}\n"
    )


LEGACY_SIGNS = (
    ("batch", (".graph-slam-batch",)),
    ("batch", ("study.json",)),
    ("demo", ("sessions", "report")),
    ("run", ("run.json",)),
    ("compare", ("metrics.json", "report.md")),
    ("convert", ("session.yaml", "conversion_report.yaml")),
    ("simulate", ("session.yaml", "sim_config.yaml")),
    ("simulate --export realsense-sdk-bag", ("export.yaml",)),
)
"""For a marker an older graph-slam wrote (it names no command): the command whose files the
folder holds, first match (every entry must be present)."""


def written_by(path: str | Path) -> str | None:
    """The command whose marker ``path`` holds; for a marker an older graph-slam wrote (no
    command in it) the command its files show (:data:`LEGACY_SIGNS`), else ``""``; None when
    there is no marker (not written by graph-slam)."""
    path = Path(path)
    marker = path / MARKER_NAME
    if not marker.is_file():
        return None
    try:
        text = marker.read_text(encoding="utf-8", errors="replace")
    except OSError:
        text = ""
    for line in text.splitlines():
        if line.startswith(_COMMAND_KEY):
            return line[len(_COMMAND_KEY) :].strip()
    for command, names in LEGACY_SIGNS:
        if all((path / name).exists() for name in names):
            return command
    return ""


def written_by_us(path: Path) -> bool:
    """True for a folder this package wrote (it holds the marker, whatever the command)."""
    return written_by(path) is not None


def check_inputs(path: Path, inputs: Iterable[str | Path]) -> None:
    """Refuse an output folder that is an input, lies inside one or contains one."""
    target = path.resolve()
    for given in inputs:
        source = Path(given).resolve()
        if target == source:
            rule = "is an input of this run"
        elif target.is_relative_to(source):
            rule = f"lies inside the input {given}"
        elif source.is_relative_to(target):
            rule = f"contains the input {given}"
        else:
            continue
        raise OutputError(
            f"{path}: {rule}; the output folder must be outside every input and hold none "
            "(inputs are never modified), choose another --out"
        )


def check_output(
    path: str | Path,
    *,
    overwrite: bool,
    command: str,
    inputs: Iterable[str | Path] = (),
) -> Path:
    """Refuse, before any work, a target that cannot be written or must not be replaced
    (module docstring). ``command``: the command writing it (recorded in its marker)."""
    path = Path(path)
    if path.is_symlink():
        raise OutputError(
            f"{path}: is a symbolic link (to {os.readlink(path)}); give a real folder as --out"
        )
    check_inputs(path, inputs)
    parent = path.absolute().parent
    existing = parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputError(f"{path}: {existing} is a file, not a folder; choose another --out")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write in {existing} (permission denied)")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{path}: is a file, not a folder; choose another --out")
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: cannot write in this folder (permission denied)")
        if any(path.iterdir()):
            _check_replaceable(path, overwrite, command)
    return path


def _check_replaceable(path: Path, overwrite: bool, command: str) -> None:
    """A non-empty existing target: only one ``command`` wrote, and only with ``overwrite``."""
    wrote = written_by(path)
    if wrote is None:
        raise OutputError(
            f"{path}: exists, is not empty and was not written by graph-slam (no "
            f"{MARKER_NAME}); refusing to write into or replace it, choose another --out"
        )
    if wrote != command:
        who = (
            f"`graph-slam {wrote}`, not `graph-slam {command}`"
            if wrote
            else "an older graph-slam that did not record which command wrote it"
        )
        raise OutputError(
            f"{path}: was written by {who}; --overwrite replaces only a folder the same command "
            "wrote, choose another --out (or remove it yourself)"
        )
    if not overwrite:
        raise OutputError(f"{path}: already exists (pass --overwrite to replace it)")


def _remove_stale_partials(path: Path) -> None:
    """Remove temporary siblings left by a run of this target that was killed outright."""
    if not path.parent.is_dir():
        return
    for stale in path.parent.glob(f".{path.name}{PARTIAL_INFIX}*"):
        if stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale, ignore_errors=True)


@contextmanager
def atomic_folder(
    path: str | Path,
    *,
    command: str,
    overwrite: bool = False,
    inputs: Iterable[str | Path] = (),
    create: bool = True,
) -> Iterator[Path]:
    """Yield a temporary sibling of ``path`` to write into; on success it replaces ``path``.

    ``create=False`` yields a path that does not exist yet (for writers that create their
    folder themselves, e.g. :class:`graph_slam.session.SessionWriter`). On any exception,
    including ``KeyboardInterrupt``, the temporary folder is removed and ``path`` is untouched.
    """
    inputs = list(inputs)
    path = check_output(path, overwrite=overwrite, command=command, inputs=inputs)
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
        (tmp / MARKER_NAME).write_text(marker_text(command), encoding="utf-8")
        # still the same command's at the end?
        check_output(path, overwrite=overwrite, command=command, inputs=inputs)
        if path.exists():
            shutil.rmtree(path)
        tmp.rename(path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def mark_folder(path: str | Path, *, command: str) -> Path:
    """Create ``path`` (a container such as the demo's output) with ``command``'s marker;
    :func:`check_output` first."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        (path / MARKER_NAME).write_text(marker_text(command), encoding="utf-8")
    except OSError as err:
        raise OutputError(f"{path}: cannot create the output folder ({err.strerror})") from None
    return path


def check_output_file(path: str | Path, *, inputs: Iterable[str | Path] = ()) -> Path:
    """Refuse, before any work, a file target that cannot be written: a folder, a missing or
    file-shaped parent, no permission, or one of the run's ``inputs``."""
    path = Path(path)
    for given in inputs:
        if path.resolve() == Path(given).resolve():
            raise OutputError(f"{path}: is an input of this run; choose another --out")
    if path.is_dir():
        raise OutputError(f"{path}: is a folder; --out takes a file path (e.g. {path / 'x.csv'})")
    parent = path.absolute().parent
    if not parent.is_dir():
        what = "is a file" if parent.exists() else "does not exist"
        raise OutputError(f"{path}: its folder {parent} {what}; create it or choose another --out")
    if not os.access(parent, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise OutputError(f"{path}: cannot write it (permission denied)")
    return path
