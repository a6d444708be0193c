"""Time graph-slam batch against the same tasks one after another in one process.

    python examples/batch_timing.py [WORKDIR]            # two tiny sessions × icp, imu+kin
    python examples/batch_timing.py WORKDIR --demo N     # the demo's study, N strides a speed

Simulates the sessions (default: two one-stride quarter-resolution sessions; ``--demo N``: the
demo's three speeds at 424×240 with bursty drops, N strides each, its four variants and its
configuration — the real-time preset for the graph, the baseline on the 212×120 cloud), then
runs the study's tasks four ways: sequentially in this process (compare per task, as a batch
task does), as a batch on 2 workers × 1 thread, on 1 worker × 2 threads, and a re-run with
nothing changed. Prints one line per way (docs/benchmarks.md, "Batch").
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


def demo_spec(work: Path, strides: int) -> dict:
    """The demo's sessions (three speeds, 424×240, bursty drops, seed 1) and configuration
    (the defaults: the realtime preset, the baseline on the 212×120 cloud, the stride maps)."""
    from graph_slam.sim import SPEEDS_M_S

    for speed in ("slow", "normal", "fast"):
        cfg = SimConfig(
            scene="thesis-boxes", speed_m_s=SPEEDS_M_S[speed], strides=strides, seed=1,
            drops="bursty", resolution="424x240", quicklook=False,
        )  # fmt: skip
        simulate(cfg, work / "s" / speed, overwrite=True)
    return {
        "sessions": ["s/*"],
        "variants": ["icp", "icp+imu", "imu+kin", "icp+imu+kin"],
        "config": {},
    }


def main(work: Path, demo_strides: int | None = None) -> None:
    if demo_strides is None:
        for seed, name in ((3, "a"), (4, "b")):
            cfg = SimConfig(strides=1, fast=True, drops="bursty", seed=seed, quicklook=False)
            simulate(cfg, work / "s" / name, overwrite=True)
        study = SPEC
    else:
        study = demo_spec(work, demo_strides)
    spec = work / "spec.yaml"
    spec.write_text(yaml.safe_dump(study))
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
    args = sys.argv[1:]
    demo = None
    if "--demo" in args:
        i = args.index("--demo")
        demo = int(args[i + 1])
        del args[i : i + 2]
    main(Path(args[0]) if args else Path(tempfile.mkdtemp(prefix="batch_")), demo)
