"""The variants of ``run`` and ``compare`` in worker processes (``workers`` > 1).

Every (session, variant) pair is one task: a spawned worker opens the session by its folder,
runs :func:`graph_slam.pipelines.run_session` with the variant's configuration and the
variant's per-frame trace, and returns the results and the filled trace. Tasks are submitted
longest first (the thesis baseline's, a few hundred ms a frame, before the graph variants' few
ms), so two workers finish together; the caller takes the sessions back in order, each as
soon as its variants are done, and scores it while the workers go on with the next. Progress
comes back through a queue as frame counts. Each run is the same as in one process (the same
configuration, the same session, nothing shared): the results do not depend on ``workers``
beyond the thread-level nondeterminism of Open3D's registration. A task that fails raises its
error when its session is taken back; the tasks not started are then cancelled (those running
finish first).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import signal
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager

from graph_slam.pipelines.config import PipelineConfig
from graph_slam.variants import Variant

#: a worker reports progress every this many frames
_TICK_EVERY = 10


def _run_task(path: str, pipeline: dict, trace, ticks) -> tuple[object, object]:
    """One task in a worker: the results of ``pipeline`` (its variant set) on the session at
    ``path`` and the trace, filled."""
    from graph_slam.pipelines import run_session
    from graph_slam.session import open_session

    done = 0

    def tick(_: int, __: int) -> None:
        nonlocal done
        done += 1
        if done % _TICK_EVERY == 0:
            ticks.put(_TICK_EVERY)

    results = run_session(open_session(path), PipelineConfig.model_validate(pipeline), tick, trace)
    ticks.put(done % _TICK_EVERY)
    return results, trace


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while processes are started: they inherit the ignored signal (it
    survives ``exec``), so a Ctrl-C in the terminal interrupts the parent only, which stops
    them itself, and no worker prints a ``KeyboardInterrupt`` traceback. Off the main thread
    (where signals cannot be set) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def worker_init(parent_pid: int) -> None:
    """A worker's initializer: Ctrl-C is the parent's to handle (:func:`sigint_ignored`), and
    the worker ends itself within :data:`PARENT_POLL_S` when its parent is gone (killed,
    SIGTERM): no orphan goes on computing for a report nobody will write."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with_parent, args=(parent_pid,), daemon=True).start()


PARENT_POLL_S = 1.0


def _exit_with_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def _cost(variant: Variant) -> int:
    """Submission order: the thesis baseline first (its frames cost ~50× a graph variant's)."""
    return 0 if variant is Variant.ICP else 1


def run_sessions(
    sessions: Sequence,
    variants: Sequence,
    pipeline: PipelineConfig,
    tick,
    traces: Sequence[dict | None],
    workers: int,
) -> Iterator[dict]:
    """Per session, in order, ``{variant: PipelineResults}`` (as
    :func:`graph_slam.report.run.run_variants` gives it), the variants run by ``workers``
    spawned processes. ``traces[i]``: session i's variant → per-frame trace, replaced in
    place by the filled one a worker returns. ``tick(_, _)``: called once per frame run."""
    order = [Variant(v) for v in variants]
    tasks = sorted(
        ((s, v) for s in range(len(sessions)) for v in order), key=lambda t: (_cost(t[1]), t[0])
    )
    context = mp.get_context("spawn")
    with sigint_ignored():  # the manager process inherits it
        manager = context.Manager()
    with manager, ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=worker_init,
        initargs=(os.getpid(),),
    ) as pool:  # fmt: skip
        ticks = manager.Queue()
        futures: dict[tuple[int, Variant], Future] = {}
        for s, v in tasks:
            trace = None if traces[s] is None else traces[s].get(v)
            data = {**pipeline.model_dump(mode="json"), "variant": str(v)}
            futures[(s, v)] = pool.submit(_run_task, str(sessions[s].path), data, trace, ticks)
        try:
            for s in range(len(sessions)):
                yield _collect(s, order, futures, traces, ticks, tick)
        except BaseException as err:  # a failed task or an interrupt: start nothing more
            running = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            if isinstance(err, KeyboardInterrupt):  # and stop the running ones, quietly
                for process in running:
                    process.terminate()
            raise


def _collect(s: int, order, futures, traces, ticks, tick) -> dict:
    """Session ``s``'s results once its tasks are done (progress drained meanwhile)."""
    mine = [futures[(s, v)] for v in order]
    while not all(f.done() for f in mine):
        wait(mine, timeout=0.5, return_when=FIRST_COMPLETED)
        _drain(ticks, tick)
    _drain(ticks, tick)
    results = {}
    for v, future in zip(order, mine, strict=True):
        results[v], trace = future.result()  # a worker's exception is raised here
        if traces[s] is not None and v in traces[s]:
            traces[s][v] = trace
    return results


def _drain(ticks, tick) -> None:
    while True:
        try:
            n = ticks.get_nowait()
        except queue.Empty:
            return
        for _ in range(n):
            tick(0, 0)
