"""``run_batch``: plan the grid, skip what is finished, run the rest on Dask, pool the report.

Its steps:

1. load and check the spec (:func:`~graph_slam.batch.spec.load_spec`) and the output folder
   (:func:`check_study_folder`: new, empty, or a study batch wrote) — every bad input stops
   here, before a worker starts;
2. plan the tasks and their input hashes; a task whose folder holds ``done`` with the same hash
   is skipped (a re-run after Ctrl-C resumes);
3. submit the rest to the cluster, one Dask task each and no more at once than the cluster
   has threads (so a worker that dies takes only its own running tasks with it), and record
   every outcome as it comes (done, a typed error, a bug's traceback after ``retries``,
   ``KilledWorker`` after as many worker deaths, a cancelled task);
4. write the pooled report (:mod:`graph_slam.batch.pool`) over every finished task.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from graph_slam.batch.spec import ResolvedSpec, load_spec
from graph_slam.batch.tasks import (
    DONE,
    FAILED,
    SKIPPED,
    Task,
    execute_task,
    is_finished,
    plan_tasks,
    read_state,
    write_state,
)
from graph_slam.errors import BatchError

STUDY_MARKER = ".graph-slam-batch"
"""Written into a study folder when a batch starts: a re-run may resume only such a folder."""

TaskCallback = Callable[[Task, dict[str, Any], int, int], None]
"""Called as ``(task, state, finished so far, to run)`` when a task ends."""
ClusterCallback = Callable[[Any], None]
"""Called with the :class:`~graph_slam.batch.cluster.ClusterInfo` once the cluster is up."""


@dataclass
class ClusterOptions:
    """Command-line overrides of the spec's ``cluster:`` (None: the spec's value)."""

    scheduler: str | None = None
    workers: int | None = None
    threads_per_worker: int | None = None
    memory_limit: str | None = None


@dataclass
class BatchResult:
    """What a batch did: every task's state, the pooled report's files, the wall time."""

    out: Path
    states: dict[str, dict[str, Any]]
    files: list[Path] = field(default_factory=list)
    wall_s: float = 0.0
    cluster: str = ""

    def count(self, status: str) -> int:
        return sum(s["status"] == status for s in self.states.values())

    @property
    def ok(self) -> bool:
        return self.count(FAILED) == 0


def run_batch(
    spec_path: str | Path,
    out: str | Path,
    options: ClusterOptions | None = None,
    on_task: TaskCallback | None = None,
    on_cluster: ClusterCallback | None = None,
    preset: str | None = None,
) -> BatchResult:
    """Run the study ``spec_path`` into ``out`` (created, or resumed when batch wrote it);
    ``preset``: the pipeline preset where the spec names none (:func:`load_spec`)."""
    from graph_slam.batch.cluster import check_cluster_options, require_dask
    from graph_slam.batch.pool_report import write_pooled_report
    from graph_slam.session.atomic import mark_folder

    t0 = time.perf_counter()
    options = options or ClusterOptions()
    require_dask()
    resolved = load_spec(spec_path, preset)
    memory_limit = options.memory_limit or resolved.spec.cluster.memory_limit
    where = (
        "--memory-limit" if options.memory_limit else f"{spec_path}: field 'cluster.memory_limit'"
    )
    check_cluster_options(options.scheduler, memory_limit, where)
    out = check_study_folder(out, [s.path for s in resolved.sessions])
    mark_folder(out, command="batch")
    (out / STUDY_MARKER).write_text("a graph-slam batch study; a re-run resumes it\n")
    tasks = plan_tasks(resolved, out)
    states: dict[str, dict[str, Any]] = {}
    pending = []
    for task in tasks:
        if is_finished(task):
            states[task.id] = {**(read_state(task) or {}), "status": DONE, "this_run": SKIPPED}
        else:
            pending.append(task)
    result = BatchResult(out, states)
    if pending:
        result.cluster = _run_pending(resolved, pending, options, states, on_task, on_cluster)
    result.files = write_pooled_report(out, resolved, tasks, states)
    result.wall_s = time.perf_counter() - t0
    return result


def is_study_folder(path: Path) -> bool:
    """True for a folder a batch wrote: its marker, or (older studies) its ``study.json``."""
    from graph_slam.batch.pool_report import STUDY_SCHEMA

    if (path / STUDY_MARKER).is_file():
        return True
    try:
        study = json.loads((path / "study.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(study, dict) and study.get("schema") == STUDY_SCHEMA


def check_study_folder(out: str | Path, inputs: Sequence[str | Path] = ()) -> Path:
    """The study folder ``out``, before any work: missing, empty, or a study a batch wrote
    (resumed), and neither inside nor around a session of the study (``inputs``); any other
    folder is refused with :class:`BatchError` or :class:`OutputError` and left untouched."""
    from graph_slam.session.atomic import check_inputs, check_output, written_by_us

    out = Path(out)
    check_inputs(out, inputs)
    if out.is_dir() and not out.is_symlink() and any(out.iterdir()) and not is_study_folder(out):
        why = (
            "it holds another graph-slam command's output (compare, run, demo, ...)"
            if written_by_us(out)
            else "it holds files graph-slam did not write"
        )
        raise BatchError(
            f"{out}: not a batch study folder ({why}; no {STUDY_MARKER} or batch study.json); "
            "a batch writes into a new or empty folder or resumes its own study, choose another "
            "--out"
        )
    return check_output(out, overwrite=True, command="batch", inputs=inputs)


def _run_pending(
    resolved: ResolvedSpec,
    pending: list[Task],
    options: ClusterOptions,
    states: dict[str, dict[str, Any]],
    on_task: TaskCallback | None,
    on_cluster: ClusterCallback | None,
) -> str:
    """Step 3: submit, then record each outcome as it arrives (in the order they finish).

    Tasks are submitted only while the cluster has a free thread: Dask would otherwise hand a
    worker several tasks at once (its queuing applies only to large groups), and a worker that
    dies counts a death against every task it holds, so a crashing task could use up the
    retries of the tasks queued beside it.
    """
    from distributed import as_completed

    from graph_slam.batch.cluster import open_client

    spec_cluster = resolved.spec.cluster
    retries = resolved.spec.retries
    with open_client(
        options.scheduler,
        workers=options.workers or spec_cluster.workers,
        threads_per_worker=options.threads_per_worker or spec_cluster.threads_per_worker,
        memory_limit=options.memory_limit or spec_cluster.memory_limit,
        retries=retries,
    ) as (client, info):
        if on_cluster is not None:
            on_cluster(info)
        queue = list(pending)
        by_key: dict[str, Task] = {}
        running = as_completed()

        def submit_while_threads_free() -> None:
            threads = max(1, sum(client.nthreads().values()))
            while queue and running.count() < threads:
                task = queue.pop(0)
                future = client.submit(
                    execute_task, task, key=f"graph-slam-{task.id}", retries=retries, pure=False
                )
                by_key[future.key] = task
                running.add(future)

        submit_while_threads_free()
        for n, future in enumerate(running, start=1):
            task = by_key[future.key]
            state = _outcome(task, future, retries)
            states[task.id] = {**state, "this_run": state["status"]}
            if on_task is not None:
                on_task(task, state, n, len(pending))
            submit_while_threads_free()
        return info.description


def _outcome(task: Task, future, retries: int) -> dict[str, Any]:
    """The task's state: what the worker wrote, or the exception Dask gave back (a cancelled
    task is recorded as failed: its ``exception()`` raises rather than returns)."""
    import asyncio
    import concurrent.futures
    import traceback

    if future.status == "finished":
        return future.result()
    cancelled = (concurrent.futures.CancelledError, asyncio.CancelledError)
    try:
        err = None if future.status == "cancelled" else future.exception()
    except cancelled:
        err = None
    if err is None or isinstance(err, cancelled):
        reason = (
            "cancelled: Dask cancelled the task before it finished (the scheduler lost it or "
            "it was cancelled); run the batch again to resume"
        )
        return write_state(task, FAILED, error=reason)
    name = type(err).__name__
    if name == "KilledWorker":
        reason = (
            f"KilledWorker: the task's worker died {retries + 1} time(s) (native crash, "
            "out of memory or killed); see the worker logs"
        )
    else:
        tb = "".join(traceback.format_exception(err, value=err, tb=future.traceback()))
        reason = f"{name}: {err} (a bug, after {retries + 1} attempt(s))\n{tb}"
    return write_state(task, FAILED, error=reason, attempts=retries + 1)
