"""The Dask side of a batch: a local cluster sized to the machine, or a scheduler's address.

Only this module and :mod:`graph_slam.batch.run` import Dask, and only when a batch starts;
the estimator never does. Workers run with one BLAS/OpenMP thread per Dask thread
(:data:`WORKER_ENV`), so Open3D and numpy do not oversubscribe the cores.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from graph_slam.errors import BatchError

INSTALL_HINT = "graph-slam batch needs the optional extra: pip install 'graph_slam[batch]'"
WORKER_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
    "MPLBACKEND": "Agg",
}
"""Set in every local worker before it starts (remote workers: see docs/batch.md)."""


def require_dask() -> None:
    """A clear error, before any work, when dask.distributed is not installed."""
    if importlib.util.find_spec("distributed") is None or importlib.util.find_spec("dask") is None:
        raise BatchError(INSTALL_HINT)


def has_bokeh() -> bool:
    """The dashboard needs bokeh (optional: without it there is no dashboard)."""
    return importlib.util.find_spec("bokeh") is not None


def check_cluster_options(scheduler: str | None, memory_limit: str, source: str) -> None:
    """Before any work: ``scheduler`` is a Dask address (``tcp://host:port``, ``host:port``,
    ``tls://``, ``inproc://``) and ``memory_limit`` a size (``4GiB``, ``500MB``) or ``auto``."""
    require_dask()
    from dask.utils import parse_bytes
    from distributed.comm.addressing import parse_address, parse_host_port

    if scheduler is not None:
        try:
            protocol, location = parse_address(scheduler)
            if protocol != "inproc":
                port = parse_host_port(location)[1]
                if not 0 < port < 65536:
                    raise ValueError(f"port {port} outside 1-65535")
        except (ValueError, TypeError) as err:
            raise BatchError(
                f"--scheduler {scheduler!r}: not a Dask scheduler address ({err}); give "
                "tcp://host:port, e.g. tcp://10.0.0.5:8786"
            ) from None
    if memory_limit != "auto":
        try:
            if parse_bytes(memory_limit) <= 0:
                raise ValueError("not > 0")
        except (ValueError, TypeError) as err:
            raise BatchError(
                f"{source}: memory limit {memory_limit!r} is not a size ({err}); give e.g. 4GiB"
            ) from None


def ignore_sigint_plugin():
    """A Dask worker plugin: every local worker, also one the nanny starts again later (after a
    memory kill), ignores SIGINT. A Ctrl-C in the terminal reaches the whole process group; the
    batch (the parent) stops the workers itself, so none prints a ``KeyboardInterrupt``
    traceback. (Defined here, on demand: Dask is imported only once a batch starts.)"""
    from distributed.diagnostics.plugin import WorkerPlugin

    class IgnoreSigint(WorkerPlugin):
        name = "graph-slam-ignore-sigint"

        def setup(self, worker) -> None:
            ignore_sigint_here()

    return IgnoreSigint()


def ignore_sigint_here() -> None:
    """SIGINT ignored in this process (from its main thread; elsewhere nothing)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def quiet_dask_logs(client=None) -> None:
    """After a Ctrl-C: Dask's warnings about the tasks and workers it is told to stop (a
    cancelled task, a worker killed on close) are expected, not news: silenced here and, via
    ``client``, in the workers."""
    _silence_dask_loggers()
    if client is not None:
        with contextlib.suppress(Exception):  # a worker already gone has nothing left to say
            client.run(_silence_dask_loggers)


def _silence_dask_loggers() -> None:
    import logging

    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _is_sync_cancel_race(record) -> bool:
    """Dask's ``sync()`` answers a Ctrl-C by scheduling a ``cancel`` on its event loop; when
    the Ctrl-C lands before the awaited future exists, that callback raises ``NameError``
    (free variable ``future``) and tornado logs it as an error: a race inside Dask at
    interruption, not a failure of the batch."""
    exc = record.exc_info[1] if record.exc_info else None
    if not isinstance(exc, NameError) or "future" not in str(exc):
        return False
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    code = tb.tb_frame.f_code if tb is not None else None
    return code is not None and code.co_name == "cancel" and "distributed" in code.co_filename


def drop_sync_cancel_race() -> None:
    """Keep that one known log record (:func:`_is_sync_cancel_race`) out of stderr; every
    other error of tornado's callbacks is still logged. Idempotent."""
    import logging

    log = logging.getLogger("tornado.application")
    if not any(getattr(f, "_graph_slam_sync_cancel", False) for f in log.filters):
        flt = logging.Filter()
        flt.filter = lambda record: not _is_sync_cancel_race(record)  # type: ignore[method-assign]
        flt._graph_slam_sync_cancel = True  # type: ignore[attr-defined]
        log.addFilter(flt)


@dataclass(frozen=True)
class ClusterInfo:
    """What the batch runs on, for the user: a description and the dashboard (or why none)."""

    description: str
    dashboard: str


def default_workers(threads_per_worker: int) -> int:
    """Workers of a local cluster sized to the machine: usable cores / threads per worker."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, (cores or 1) // threads_per_worker)


@contextmanager
def open_client(
    scheduler: str | None,
    *,
    workers: int | None,
    threads_per_worker: int,
    memory_limit: str,
    retries: int,
) -> Iterator[tuple[object, ClusterInfo]]:
    """A ``distributed.Client`` on a new local cluster (no ``scheduler``) or on ``scheduler``.

    ``retries`` is also the scheduler's ``allowed-failures`` (a task whose worker died is
    re-run that many times, then fails with ``KilledWorker``); on a remote scheduler that
    setting is the scheduler's own (docs/batch.md). Workers get at most as many tasks as
    threads (``worker-saturation`` 1.0), so one crash does not take queued tasks with it.
    """
    require_dask()
    import dask
    from distributed import Client, LocalCluster

    drop_sync_cancel_race()

    from graph_slam.report.parallel import sigint_ignored

    settings = {
        "distributed.scheduler.allowed-failures": retries,
        "distributed.scheduler.worker-saturation": 1.0,
        "distributed.worker.daemon": False,
    }
    with dask.config.set(settings):
        if scheduler is not None:
            try:
                client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as err:
                raise BatchError(f"--scheduler {scheduler}: cannot connect ({err})") from None
            n = len(client.scheduler_info().get("workers", {}))
            info = ClusterInfo(f"scheduler {scheduler} ({n} workers now)", _dashboard(client))
            try:
                yield client, info
            finally:
                client.close()
            return
        n_workers = workers or default_workers(threads_per_worker)
        with sigint_ignored():  # the workers inherit it: a Ctrl-C stops the batch, not them
            cluster = LocalCluster(
                n_workers=n_workers,
                threads_per_worker=threads_per_worker,
                processes=True,
                memory_limit=memory_limit,
                dashboard_address=":0" if has_bokeh() else None,
                env=WORKER_ENV,
            )
        client = Client(cluster)
        client.register_plugin(ignore_sigint_plugin())  # also in workers started again
        info = ClusterInfo(
            f"local cluster: {n_workers} worker(s) × {threads_per_worker} thread(s), "
            f"memory limit {memory_limit} each",
            _dashboard(client),
        )
        try:
            yield client, info
        except KeyboardInterrupt:
            quiet_dask_logs(client)  # the running tasks are cancelled on purpose
            raise
        finally:
            client.close()
            cluster.close()


def _dashboard(client) -> str:
    if not has_bokeh():
        return "none (install bokeh for the Dask dashboard)"
    return client.dashboard_link or "none"
