"""One task of a study: one session, one variant, one named configuration.

:func:`execute_task` is what a worker runs. It runs :func:`graph_slam.report.compare` on the
one session with the one variant (the switch to ``graph-slam run`` is this function alone) and
writes ``task.json`` in the task's folder: the input hash, the status and, for a failure, the
typed library error's message. A bug's exception propagates, so Dask retries it and the
client records its traceback. The estimator knows nothing of Dask: nothing here imports it.

Task folder (``OUT/tasks/<session>__<variant>__<configuration>/``)::

    task.json     {"id", "session", "variant", "configuration", "hash", "status",
                   "error", "wall_s", "peak_rss_mib", "attempts"}
    report/       the compare report of this one session and variant (metrics.json, ...)
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from graph_slam.batch.fingerprint import session_fingerprint, task_hash
from graph_slam.batch.spec import ResolvedSpec

TASK_FILE = "task.json"
DONE, FAILED, SKIPPED = "done", "failed", "skipped"


@dataclass(frozen=True)
class Task:
    """Everything a worker needs, as plain data (sent to the worker as such)."""

    id: str
    session: str
    session_key: str
    variant: str
    configuration: str
    config: dict[str, Any]
    """The resolved CompareConfig (JSON form) with ``variants: [variant]``."""
    hash: str
    folder: str
    kill_worker: bool = False
    """Test-only: the task kills its own worker (spec ``test_kill_worker``)."""

    @property
    def report(self) -> Path:
        return Path(self.folder) / "report"


def plan_tasks(resolved: ResolvedSpec, out: Path) -> list[Task]:
    """The grid, in spec order: configurations × sessions × variants, with their hashes."""
    fingerprints = {s.key: session_fingerprint(s.path) for s in resolved.sessions}
    tasks = []
    for name, cfg in resolved.configurations.items():
        for session in resolved.sessions:
            for variant in resolved.variants:
                config = {**cfg.model_dump(mode="json"), "variants": [str(variant)]}
                task_id = f"{session.key}__{variant.tag}__{name}"
                extra = {"variant": str(variant)}
                tasks.append(
                    Task(
                        id=task_id,
                        session=str(session.path.resolve()),
                        session_key=session.key,
                        variant=str(variant),
                        configuration=name,
                        config=config,
                        hash=task_hash(fingerprints[session.key], config, extra),
                        folder=str((out / "tasks" / task_id).resolve()),
                        kill_worker=session.key in resolved.spec.test_kill_worker,
                    )
                )
    return tasks


def read_state(task: Task) -> dict[str, Any] | None:
    """The task's ``task.json``, or None when absent or unreadable (then it runs again)."""
    try:
        return json.loads((Path(task.folder) / TASK_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def is_finished(task: Task) -> bool:
    """Done earlier with the same inputs, and its metrics are still there."""
    state = read_state(task)
    return (
        state is not None
        and state.get("status") == DONE
        and state.get("hash") == task.hash
        and (task.report / "metrics.json").is_file()
    )


def write_state(task: Task, status: str, **fields: Any) -> dict[str, Any]:
    """Write ``task.json`` whole (a temporary file renamed), so a kill leaves the old or the new."""
    state = {
        "id": task.id,
        "session": task.session,
        "variant": task.variant,
        "configuration": task.configuration,
        "hash": task.hash,
        "status": status,
        "error": None,
        **fields,
    }
    folder = Path(task.folder)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".{TASK_FILE}.{os.getpid()}"
    tmp.write_text(json.dumps(state, indent=2) + "\n", encoding="utf-8")
    tmp.replace(folder / TASK_FILE)
    return state


def _peak_rss_mib() -> float:
    """This process's peak resident memory so far (MiB; Linux reports KiB)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1 << 20) if sys.platform == "darwin" else peak / 1024


def execute_task(task: Task) -> dict[str, Any]:
    """Run the task in this (worker) process; return and write its state.

    A typed library error (a corrupt PNG: ``ImageError``) is the input's fault: recorded as
    failed with its message, not retried. Any other exception propagates (Dask retries it,
    then the client records the traceback).
    """
    from graph_slam.errors import library_errors
    from graph_slam.report.compare import CompareConfig, compare

    if task.kill_worker:  # test-only, enabled by the spec and TEST_HOOKS_ENV together
        os.kill(os.getpid(), signal.SIGKILL)
    write_state(task, "running", host=os.uname().nodename, pid=os.getpid())
    t0 = time.perf_counter()
    try:
        compare(
            [task.session],
            task.report,
            CompareConfig.model_validate(task.config),
            overwrite=True,
        )
    except library_errors() as err:
        return write_state(
            task,
            FAILED,
            error=f"{type(err).__name__}: {err}",
            wall_s=time.perf_counter() - t0,
            peak_rss_mib=_peak_rss_mib(),
        )
    return write_state(task, DONE, wall_s=time.perf_counter() - t0, peak_rss_mib=_peak_rss_mib())


def task_summary(state: dict[str, Any]) -> dict[str, Any]:
    """The fields of a task's state that study.json keeps."""
    keys = ("id", "session", "variant", "configuration", "hash", "status", "error", "wall_s")
    return {k: state.get(k) for k in (*keys, "peak_rss_mib", "attempts")}
