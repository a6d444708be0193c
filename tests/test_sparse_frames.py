"""Sparse frames (an estimator too slow for the camera skips most of them): every processed
frame's pose is either close to the truth or flagged ``imu_only`` (its stride has no accepted
registration yet), never a confident metre-scale error."""

from __future__ import annotations

import numpy as np
import pytest

#: a registered or kinematically anchored pose is within a few mm of the truth on this walk;
#: an IMU-only pose of this sparse replay is 1.2 m off (frame 90: its stride's velocity prior
#: came out of a stride with one frame, |v| 3.0 m/s against 0.7 m/s true, σ 3.2 m/s)
BOUND_M = 0.25
#: processed frames: every 45th (0.5 s at 90 Hz: no two of them overlap enough to register)
STEP = 45


@pytest.fixture(scope="module")
def sparse_session(tmp_path_factory):
    """Two strides at 212x120 without frame drops."""
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("sparse") / "sim"
    simulate(SimConfig(strides=2, seed=3, resolution="212x120", drops="none", quicklook=False), out)
    return out


def test_subset_cost_processes_exactly_the_kept_frames():
    from graph_slam.errors import EstimationError
    from graph_slam.pipelines.schedule import schedule, subset_cost

    arrival = np.arange(20) / 90.0
    keep = [0, 3, 4, 11, 17]
    cost = subset_cost(arrival, keep)
    # the schedule's pure rule with the cost each processed frame would charge, in order
    processed, i, free_at = [], 0, -np.inf
    from graph_slam.pipelines.schedule import pick_frame

    while i < arrival.size:
        j, start = pick_frame(arrival, i, free_at)
        processed.append(j)
        free_at = start + cost(j, 0.0)
        i = j + 1
    assert processed == [*keep, 19]
    assert schedule(arrival, np.zeros(20)).processed.size == 20  # no cost: every frame
    with pytest.raises(EstimationError, match="start at frame 0"):
        subset_cost(arrival, [2, 5])


@pytest.mark.parametrize("row", ["icp+imu+kin:realtime", "icp+imu+kin:accurate"])
def test_sparse_frames_are_close_to_the_truth_or_flagged(sparse_session, row):
    from graph_slam.bench.realtime import row_config
    from graph_slam.pipelines.replay import ready_times, replay_session
    from graph_slam.pipelines.schedule import subset_cost
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import session_leg_model
    from graph_slam.strides.reference import stride_references
    from graph_slam.strides.streams import session_streams

    session = open_session(sparse_session)
    cfg = row_config(row)
    streams = session_streams(session, cfg.event_source)
    arrival = ready_times(np.asarray(session.frame_times_s, float), streams)
    keep = np.arange(0, session.n_frames, STEP)
    res = replay_session(
        session, cfg, compute_cost=subset_cost(arrival, keep), warmup_frames=0, freeze_gc=False
    )
    np.testing.assert_array_equal(res.session_indices, np.unique([*keep, session.n_frames - 1]))
    results = res.results
    leg, _ = session_leg_model(
        session, cfg.mount_pitch_deg, cfg.mount_estimate, event_source=cfg.event_source
    )
    events = session_streams(session, "load_cell").events
    refs = stride_references(session, results.t_s, results.strides, events, leg)
    assert refs, "no complete stride to score"
    checked = 0
    for ref in refs:
        for i, truth in zip(ref.frame_indices, ref.stride_T_camera, strict=True):
            frame = results.frames[i]
            for pose in (results.online_stride_T_camera[i], results.smoothed_stride_T_camera[i]):
                err_m = float(np.linalg.norm(pose[:3, 3] - truth[:3, 3]))
                is_flagged = any(f.startswith("imu_only:") for f in frame.flags)
                assert err_m < BOUND_M or is_flagged, (
                    f"{row}: frame {res.session_indices[i]} is {err_m:.2f} m off, unflagged "
                    f"({frame.flags})"
                )
                checked += 1
    assert checked > 0
