"""Same input, same numbers: a small session run twice in separate processes, with 1 and 2
threads and different hash seeds, gives the same report numbers (timings aside), bit-identical
trajectories and poses, statuses, counts and the same frames processed by the causal replay
(graph_slam.determinism)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PROBE = Path(__file__).resolve().parent / "repeatability_probe.py"
FRAMES = 25
"""The session's first frames for the accurate graph and the replay (compare runs it all)."""


@pytest.fixture(scope="module")
def session_path(tmp_path_factory):
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("determinism") / "sim"
    simulate(SimConfig(strides=1, seed=3, resolution="212x120", drops="none", quicklook=False), out)
    return out


def _start(session: Path, threads: int, hash_seed: int, out: Path) -> subprocess.Popen:
    env = dict(os.environ)
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        env[name] = str(threads)
    env["PYTHONHASHSEED"] = str(hash_seed)
    return subprocess.Popen(
        [sys.executable, str(PROBE), str(session), str(FRAMES), str(out)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _result(process: subprocess.Popen) -> dict:
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == 0, stderr[-2000:]
    return json.loads(stdout)


def test_two_processes_with_1_and_2_threads_give_identical_outputs(session_path, tmp_path):
    pytest.importorskip("evo")  # compare scores with evo
    # both at once: two processes, one core each on a 2-core machine
    runs = [
        _start(session_path, threads=1, hash_seed=1, out=tmp_path / "a"),
        _start(session_path, threads=2, hash_seed=2, out=tmp_path / "b"),
    ]
    first, second = (_result(p) for p in runs)
    assert first["preset"] == "realtime"  # the default, as the report states it
    variants = first["metrics"]["variants"]
    assert {"icp", "icp+imu+kin", "icp+imu+kin smoothed"} <= set(variants)
    for name in ("icp", "icp+imu+kin", "icp+imu+kin smoothed"):  # the stride was scored
        assert variants[name]["summary"]["strides"] == 1, name
        assert variants[name]["summary"]["rmse_aligned_m"]["median"] is not None, name
    assert len(first["trajectories"]) >= 4  # online and smoothed, both variants
    accurate = first["icp+imu+kin:accurate"]
    assert accurate["counts"]["frames"] == FRAMES and accurate["counts"]["with_pose"] > 0
    assert len(first["replay"]["processed"]) == FRAMES  # no frame skipped on the virtual clock
    assert first == second


def test_replay_clock_costs():
    from graph_slam.errors import ConfigError
    from graph_slam.pipelines.replay import MEASURED, clock_cost, no_cost

    assert clock_cost(None, deterministic=True) is no_cost
    assert clock_cost(None, deterministic=False) is None  # measured
    assert clock_cost(MEASURED, deterministic=True) is None
    cost = lambda i, s: 2 * s  # noqa: E731
    assert clock_cost(cost, deterministic=True) is cost
    with pytest.raises(ConfigError, match="measured"):
        clock_cost("wall", deterministic=True)


def test_apply_threads_bounds_open3d():
    from graph_slam.determinism import apply_threads, open3d_threads

    apply_threads(False)
    try:
        assert open3d_threads() == len(os.sched_getaffinity(0))  # TBB's default: the cores
    finally:
        apply_threads(True)
    assert open3d_threads() == 1
