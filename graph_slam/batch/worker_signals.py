"""A Dask worker plugin: the local workers ignore SIGINT (imports distributed: load it only
once :func:`graph_slam.batch.cluster.require_dask` passed)."""

from __future__ import annotations

import signal
import threading

from distributed.diagnostics.plugin import WorkerPlugin


class IgnoreSigint(WorkerPlugin):
    """Every local worker, also one the nanny starts again later (after a memory kill), ignores
    SIGINT: a Ctrl-C in the terminal reaches the whole process group, and the batch (the
    parent) stops the workers itself, so none prints a ``KeyboardInterrupt`` traceback."""

    name = "graph-slam-ignore-sigint"

    def setup(self, worker) -> None:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
