"""Time graph-slam batch against the same tasks one after another in one process.

    python examples/batch_timing.py [WORKDIR]

Simulates two tiny sessions (one quarter-resolution stride each), then runs the study's four
tasks (2 sessions × icp, imu+kin) four ways: sequentially in this process (compare per task,
as a batch task does), as a batch on 2 workers × 1 thread, on 1 worker × 2 threads, and a
re-run with nothing changed. Prints one line per way (docs/benchmarks.md, "Batch").
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import yaml

from graph_slam.batch import ClusterOptions, load_spec, run_batch
from graph_slam.batch.tasks import plan_tasks
from graph_slam.report.compare import CompareConfig, compare
from graph_slam.sim import SimConfig, simulate

SPEC = {
    "sessions": ["s/*"],
    "variants": ["icp", "imu+kin"],
    "config": {"pipeline": {"terrain": {"pixel_step": 2}}},
}


def main(work: Path) -> None:
    for seed, name in ((3, "a"), (4, "b")):
        cfg = SimConfig(strides=1, fast=True, drops="bursty", seed=seed, quicklook=False)
        simulate(cfg, work / "s" / name, overwrite=True)
    spec = work / "spec.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    t0 = time.perf_counter()
    for task in plan_tasks(load_spec(spec), work / "seq"):
        compare([task.session], task.report, CompareConfig.model_validate(task.config))
    print(f"one process, one task after another: {time.perf_counter() - t0:.1f} s")
    for workers, threads in ((2, 1), (1, 2)):
        out = work / f"batch_{workers}x{threads}"
        shutil.rmtree(out, ignore_errors=True)
        result = run_batch(spec, out, ClusterOptions(workers=workers, threads_per_worker=threads))
        print(f"batch {workers} worker(s) x {threads} thread(s): {result.wall_s:.1f} s")
    result = run_batch(spec, work / "batch_2x1")
    print(f"re-run, nothing changed: {result.wall_s:.1f} s ({result.count('done')} skipped)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="batch_")))
