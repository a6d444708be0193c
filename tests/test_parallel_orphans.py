"""Workers of ``compare``/``demo`` end themselves when their parent is killed
(graph_slam.report.parallel.worker_init): no orphan goes on computing."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

PARENT = textwrap.dedent(
    """
    import multiprocessing as mp, os, sys, time
    from concurrent.futures import ProcessPoolExecutor
    from graph_slam.report.parallel import worker_init

    def task(path):
        with open(path, "a") as f:
            f.write(f"{os.getpid()}\\n")
        time.sleep(120)

    if __name__ == "__main__":
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(2, mp_context=ctx, initializer=worker_init,
                                 initargs=(os.getpid(),)) as pool:
            futures = [pool.submit(task, sys.argv[1]) for _ in range(2)]
            time.sleep(120)
    """
)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").exists() and "Z" not in _state(pid)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return "Z"


def test_workers_exit_when_the_parent_is_killed(tmp_path: Path) -> None:
    script, pids = tmp_path / "parent.py", tmp_path / "pids.txt"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script), str(pids)])
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if pids.exists() and len(pids.read_text().split()) == 2:
                break
            time.sleep(0.1)
        workers = [int(p) for p in pids.read_text().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    assert not [p for p in workers if _alive(p)], "workers outlived their parent"
