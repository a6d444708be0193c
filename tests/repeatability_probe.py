"""Run a session through compare, a pipeline and the causal replay and print what they
produced as JSON (the report's numbers without timings, hashes of the trajectories and poses,
the replay's processed frames): tests/test_determinism.py runs it in separate processes and
compares the outputs."""

from __future__ import annotations

import hashlib
import json
import sys

import numpy as np


def _digest(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array, dtype=np.float64).tobytes()).hexdigest()


def _config(variant: str, preset: str | None, **over):
    from graph_slam.pipelines.config import PipelineConfig, with_preset

    data = {"variant": variant, **over}
    if preset is not None:
        data = with_preset(data, preset)
    return PipelineConfig.model_validate(data)


def _without_timing(value):
    """``metrics.json`` without its timing fields (the only ones a run may change)."""
    if isinstance(value, dict):
        return {k: _without_timing(v) for k, v in value.items() if k != "timing"}
    if isinstance(value, list):
        return [_without_timing(v) for v in value]
    return value


def probe(session: str, max_frames: int, out: str) -> dict:
    """``compare`` (the thesis baseline and the full graph on the default preset: the report's
    numbers and trajectories), the full graph on the ``accurate`` preset (Open3D's colored
    ICP) and the causal replay at virtual pace."""
    from pathlib import Path

    from graph_slam.pipelines import run_session
    from graph_slam.pipelines.replay import replay_session
    from graph_slam.report import CompareConfig, compare

    cfg = CompareConfig.model_validate(
        {
            "variants": ["icp", "icp+imu+kin"],
            "rrd": False,
            "plot_maps_per_session": 0,
            "map_files": "none",
            # the whole session (its stride is scored), the baseline with one coarse ICP
            # level on every 2nd pixel (its cost; Open3D's sums all the same)
            "pipeline": {
                "baseline": {
                    "pixel_step": 2,
                    "registration": {
                        "levels": [
                            {"voxel_m": 0.04, "max_correspondence_m": 0.04, "max_iterations": 15}
                        ]
                    },
                }
            },
        }
    )
    compare([session], out, cfg)
    metrics = json.loads((Path(out) / "metrics.json").read_text())
    tums = sorted((Path(out) / "trajectories").rglob("*.tum"))
    result: dict = {
        "metrics": _without_timing(metrics),
        "trajectories": {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in tums},
        "preset": metrics["preset"],
    }
    accurate = _config("icp+imu+kin", "accurate", max_frames=max_frames)
    res = run_session(session, accurate)
    result["icp+imu+kin:accurate"] = {
        "online": _digest(res.online_world_T_camera),
        "smoothed": _digest(res.smoothed_world_T_camera),
        "statuses": res.statuses,
        "counts": {k: v for k, v in res.counts.items() if isinstance(v, int)},
    }
    realtime = _config("icp+imu+kin", None, max_frames=max_frames)
    replay = replay_session(session, realtime, warmup_frames=1)
    result["replay"] = {
        "processed": replay.session_indices.tolist(),
        "online": _digest(replay.results.online_world_T_camera),
    }
    return result


if __name__ == "__main__":
    print(json.dumps(probe(sys.argv[1], int(sys.argv[2]), sys.argv[3]), sort_keys=True))
