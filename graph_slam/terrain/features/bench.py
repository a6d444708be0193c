"""The per-frame cost of the terrain features (and the clearance prediction) on a session.

``python -m graph_slam.terrain.features.bench SESSION [--strides N]`` replays a simulated
session's frames into the online grid placed by its true poses (one grid per true stride, as
the pipelines' live grid) and times, per frame, :func:`features_of_view` and the stance-time
clearance prediction; prints the median and p95 (ms) and how many features it found.
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np


def _strides(session):
    ev = session.events
    strikes = [float(t) for t, k in zip(ev.t_s, ev.kind, strict=True) if k == "foot_strike"]
    return list(itertools.pairwise(strikes))


def run(path: str, max_strides: int = 3) -> dict:
    from graph_slam.session.format import open_session
    from graph_slam.terrain.features.extract import features_of_view
    from graph_slam.terrain.features.prediction import predict_clearance
    from graph_slam.terrain.grid.kernels import frame_point_terms
    from graph_slam.terrain.grid.online import (
        OnlineElevationMap,
        OnlineTerrainConfig,
        fallback_covariance,
    )

    session = open_session(path)
    cfg = OnlineTerrainConfig(keep_clouds=False)
    gt = session.ground_truth
    t = session.frame_times_s
    world_T_camera = np.asarray(gt.parent_T_child)[np.searchsorted(gt.t_s, t - 1e-7)]
    cov = fallback_covariance(cfg.fallback_pose_sigma)
    feature_ms, clearance_ms, found = [], [], []
    for a, b in _strides(session)[:max_strides]:
        idx = np.flatnonzero((t >= a) & (t < b))
        world_T_stride = np.eye(4)
        world_T_stride[:2, 3] = world_T_camera[idx[0], :2, 3] - [0.1, 0.0]
        emap = OnlineElevationMap(cfg, 0)
        for i in idx:
            frame = session.frame(int(i))
            pose = np.linalg.inv(world_T_stride) @ world_T_camera[i]
            _, ranges, terms = frame_point_terms(
                cfg, frame.depth_m, session.intrinsics, (cfg.min_depth_m, cfg.max_depth_m),
                pose, cov,
            )  # fmt: skip
            view = emap.fuse(terms, float(frame.t_s), None, ranges)
            t0 = time.perf_counter()
            feats = features_of_view(view)
            t1 = time.perf_counter()
            predict_clearance(view, feats)
            t2 = time.perf_counter()
            feature_ms.append((t1 - t0) * 1e3)
            clearance_ms.append((t2 - t1) * 1e3)
            found.append(feats.count())
    f, c = np.array(feature_ms), np.array(clearance_ms)
    return {
        "frames": int(f.size),
        "features_ms_median": float(np.median(f)),
        "features_ms_p95": float(np.percentile(f, 95)),
        "clearance_ms_median": float(np.median(c)),
        "clearance_ms_p95": float(np.percentile(c, 95)),
        "total_ms_p95": float(np.percentile(f + c, 95)),
        "frames_with_features": int(np.count_nonzero(found)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("session")
    parser.add_argument("--strides", type=int, default=3)
    args = parser.parse_args()
    for key, value in run(args.session, args.strides).items():
        print(f"{key:>24}: {value:.3f}" if isinstance(value, float) else f"{key:>24}: {value}")


if __name__ == "__main__":
    main()
