"""The looped session (a long stream from a short recording): every sample and frame is the
recording's, shifted by whole laps; seams fall on foot strikes; a replay runs over it."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.errors import SessionError
from graph_slam.session.looped import LoopedSession


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """Two strides at 212x120 without frame drops."""
    from graph_slam.session import open_session
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("looped") / "sim"
    simulate(SimConfig(strides=2, seed=4, resolution="212x120", drops="none", quicklook=False), out)
    return open_session(out)


def test_the_loop_lasts_the_minutes_asked_and_repeats_whole_laps(recording) -> None:
    loop = LoopedSession(recording, minutes=0.25)
    strikes = np.sort(recording.events.of_source(None, "events.csv").foot_strikes_s)
    assert loop.lap_s == pytest.approx(strikes[-1] - strikes[0])
    assert loop.duration_s >= 15.0 - loop.lap_s  # the last lap may end short of a frame
    assert loop.laps >= 1
    t = loop.frame_times_s
    assert np.all(np.diff(t) > 0)
    src = np.array([loop.source_index(i) for i in range(loop.n_frames)])
    base_t = np.asarray(recording.frame_times_s)[src]
    laps = np.round((t - base_t) / loop.lap_s)
    np.testing.assert_allclose(t, base_t + laps * loop.lap_s, atol=1e-9)
    assert laps.min() == 0 and laps.max() == loop.laps
    # the first pass is the recording up to its last strike; each lap from the first strike
    assert np.all(t[laps == 0] < strikes[-1])
    assert np.all(base_t[laps > 0] >= strikes[0]) and np.all(base_t[laps > 0] < strikes[-1])


def test_frames_and_streams_are_the_recordings_samples_shifted(recording) -> None:
    loop = LoopedSession(recording, minutes=0.25)
    k = loop.n_frames - 1
    f, g = loop.frame(k), recording.frame(loop.source_index(k))
    assert f.t_s == pytest.approx(loop.frame_times_s[k]) and f.index == k
    np.testing.assert_array_equal(f.depth_m, g.depth_m)
    imu = loop.imu
    assert np.all(np.diff(imu.t_s) > 0)
    rows = {tuple(r) for r in np.asarray(recording.imu.gyro_rad_s).round(12)}
    assert all(tuple(r) in rows for r in np.asarray(imu.gyro_rad_s)[::97].round(12))
    n = np.sort(recording.events.of_source(None, "events.csv").foot_strikes_s).size
    looped = loop.events.of_source(None, "events.csv").foot_strikes_s
    assert looped.size == (n - 1) * (loop.laps + 1)
    # every seam is a foot strike: lap k starts exactly k laps after the recording's last one
    for lap in range(1, loop.laps + 1):
        seam = recording.events.of_source(None, "events.csv").foot_strikes_s.max()
        assert np.any(np.isclose(looped, seam + (lap - 1) * loop.lap_s))
    gt = loop.ground_truth
    assert gt.t_s.size == loop.n_frames


def test_a_causal_replay_runs_over_the_loop(recording) -> None:
    from graph_slam.pipelines.replay import replay_session
    from tests.test_replay import RecordingPipeline

    loop = LoopedSession(recording, minutes=0.1)
    res = replay_session(
        loop,
        pace="virtual",
        compute_cost=lambda _j, _s: 0.0,
        warmup_frames=0,
        pipeline_factory=RecordingPipeline,
    )
    assert res.n_processed == loop.n_frames and res.n_skipped == 0
    stamps = [c[1] for c in RecordingPipeline.last.calls if c[0] == "frame"]
    assert np.all(np.diff(stamps) > 0)


def test_the_minutes_to_loop_must_be_positive(recording) -> None:
    with pytest.raises(SessionError, match="minutes to loop"):
        LoopedSession(recording, minutes=0)


@pytest.mark.parametrize("variant", ["icp+imu+kin:realtime", "icp"])
def test_kept_frame_records_are_the_latest_and_the_counts_whole(recording, variant) -> None:
    """``keep_frames``: a long run keeps only about the latest N frame records (both lists:
    the pipeline's and the back end's), counts every frame, and the kept records are those an
    unbounded run gives for the same frames (the run itself does not change)."""
    full, kept = _run(recording, variant, None), _run(recording, variant, 20)
    n = full.n_frames
    assert n == len(full.frames) == 70 and kept.n_frames == n
    assert 20 <= len(kept.frames) <= 40 and kept.frames_released == n - len(kept.frames)
    assert kept.counts["frames"] == full.counts["frames"] == n
    assert kept.counts["with_pose"] == full.counts["with_pose"]
    for a, b in zip(kept.frames, full.frames[kept.frames_released :], strict=True):
        assert a.frame_index == b.frame_index and a.status == b.status
        if variant != "icp":  # deterministic: the same poses
            np.testing.assert_array_equal(a.stride_T_camera, b.stride_T_camera)
    if kept.backend is not None:
        assert 20 <= len(kept.backend.frames) <= 40 and kept.backend.n_frames == n


def _run(session, variant: str, keep: int | None):
    """The first 70 frames (a stride and a half), the baseline with one coarse ICP level."""
    from graph_slam.bench.realtime import row_config
    from graph_slam.pipelines import PipelineConfig, run_session

    data = row_config(variant).model_dump(mode="json")
    data.update(keep_frames=keep, max_frames=70)
    data["baseline"]["registration"]["levels"] = [
        {"voxel_m": 0.04, "max_correspondence_m": 0.04, "max_iterations": 15}
    ]
    return run_session(session, PipelineConfig.model_validate(data))
