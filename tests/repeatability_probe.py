"""Run a few pipelines on a session and print what they produced as JSON (hashes of the
poses, the replay's processed frames): tests/test_determinism.py runs it in separate
processes and compares the outputs."""

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


def probe(session: str, max_frames: int) -> dict:
    from graph_slam.pipelines import run_session
    from graph_slam.pipelines.replay import replay_session

    rows = {
        "icp": _config("icp", None, max_frames=max_frames, baseline={"pixel_step": 2}),
        "icp+imu+kin:accurate": _config("icp+imu+kin", "accurate", max_frames=max_frames),
        "icp+imu+kin:realtime": _config("icp+imu+kin", "realtime", max_frames=max_frames),
    }
    out = {}
    for name, cfg in rows.items():
        res = run_session(session, cfg)
        out[name] = {
            "online": _digest(res.online_world_T_camera),
            "smoothed": _digest(res.smoothed_world_T_camera),
            "statuses": res.statuses,
            "counts": {k: v for k, v in res.counts.items() if isinstance(v, int)},
        }
    replay = replay_session(session, rows["icp+imu+kin:realtime"], warmup_frames=1)
    out["replay"] = {
        "processed": replay.session_indices.tolist(),
        "online": _digest(replay.results.online_world_T_camera),
    }
    return out


if __name__ == "__main__":
    print(json.dumps(probe(sys.argv[1], int(sys.argv[2])), sort_keys=True))
