"""Live: what the estimator's thread is handed and what is kept off it — the IMU samples of a
frame given in one call (the same samples, in order, as chunk by chunk), the camera's IMU items
routed past the thread that decodes frames (in time order), and a frame renumbered without
being checked again."""

from __future__ import annotations

import queue
from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.live.camera import ImuItem
from graph_slam.live.loop import LiveRunner
from graph_slam.session.records import RgbdFrame


class _Calls:
    def __init__(self) -> None:
        self.imu: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add_imu(self, t, gyro, accel) -> None:
        self.imu.append((np.array(t), np.array(gyro), np.array(accel)))


def _runner_with(chunks: list[np.ndarray]) -> tuple[LiveRunner, _Calls]:
    runner = LiveRunner.__new__(LiveRunner)  # only the IMU feed's state is needed
    runner.pipe, runner.rec, runner._imu_pending = _Calls(), SimpleNamespace(imu=[]), []
    for t in chunks:
        runner._imu_pending.append(ImuItem(t, np.tile(t[:, None], 3), -np.tile(t[:, None], 3),
                                           0.0))  # fmt: skip
    return runner, runner.pipe


def test_a_frames_imu_is_given_in_one_call_up_to_the_first_sample_at_or_after_it() -> None:
    chunks = [np.array([0.0100]), np.array([0.0125, 0.0150]), np.array([0.0175]),
              np.array([0.0200, 0.0225, 0.0250]), np.array([0.0275])]  # fmt: skip
    runner, calls = _runner_with(chunks)
    runner._feed_imu(0.0210)  # the first sample at or after it: 0.0225, inside a chunk
    (t, gyro, accel), = calls.imu  # fmt: skip
    np.testing.assert_array_equal(t, [0.0100, 0.0125, 0.0150, 0.0175, 0.0200, 0.0225])
    np.testing.assert_array_equal(gyro[:, 2], t)
    np.testing.assert_array_equal(accel[:, 0], -t)
    np.testing.assert_array_equal(runner._imu_pending[0].t_s, [0.0250])  # the rest waits
    np.testing.assert_array_equal(runner.rec.imu[0][0], t)  # recorded as given
    runner._feed_imu(0.0250)  # a sample exactly at the frame's time ends the call
    np.testing.assert_array_equal(calls.imu[1][0], [0.0250])
    np.testing.assert_array_equal(runner._imu_pending[0].t_s, [0.0275])
    runner._feed_imu(0.0260)
    runner._feed_imu(0.0300)  # nothing left: no call
    assert [c[0].tolist() for c in calls.imu[2:]] == [[0.0275]]
    assert runner._imu_pending == []


def test_one_call_a_frame_gives_the_samples_a_call_a_chunk_gave() -> None:
    """Over 40 frames of 400 Hz samples in random chunks: the concatenated calls equal the
    samples themselves, each exactly once, in order (what a chunk-by-chunk feed gave)."""
    rng = np.random.default_rng(5)
    t_all = np.arange(480) * 0.0025
    cuts = np.sort(rng.choice(np.arange(1, t_all.size), 200, replace=False))
    runner, calls = _runner_with(np.split(t_all, cuts))
    frames = np.arange(1, 41) / 90.0
    for t in frames:
        runner._feed_imu(t)
    given = np.concatenate([c[0] for c in calls.imu])
    np.testing.assert_array_equal(given, t_all[: given.size])
    assert len(calls.imu) == frames.size  # one call a frame
    for t, call in zip(frames, calls.imu, strict=True):
        assert call[0][-1] >= t and (call[0].size == 1 or call[0][-2] < t)


def test_imu_items_go_to_the_routed_queue_in_time_order() -> None:
    pytest.importorskip("pyrealsense2")
    from graph_slam.live.camera import RealsenseSource

    source = RealsenseSource()
    rs = SimpleNamespace(stream=SimpleNamespace(accel="accel", gyro="gyro"))

    def motion(kind: str, t_ms: float):
        data = SimpleNamespace(x=t_ms, y=0.0, z=0.0)
        return SimpleNamespace(
            as_motion_frame=lambda: SimpleNamespace(get_motion_data=lambda: data),
            get_timestamp=lambda: t_ms, profile=SimpleNamespace(stream_type=lambda: kind))  # fmt: skip

    inbox: queue.Queue = queue.Queue()
    source.route_imu(inbox)
    sent = sorted([(float(t), "accel") for t in range(0, 41, 4)]
                  + [(float(t), "gyro") for t in np.arange(1, 40, 2.5)])  # fmt: skip
    for t, kind in sent:  # 250 Hz accel, 400 Hz gyro, as they arrive
        source._motion(rs, motion(kind, t), 0.0)
    assert source.items.empty()
    got = [inbox.get_nowait() for _ in range(inbox.qsize())]
    t = np.concatenate([g.t_s for g in got])
    np.testing.assert_allclose(t * 1e3, np.arange(1, 40, 2.5))
    np.testing.assert_allclose(np.concatenate([g.gyro_rad_s[:, 0] for g in got]), t * 1e3)


def test_a_renumbered_frame_keeps_its_checked_arrays() -> None:
    depth = np.full((4, 5), 1.5, np.float32)
    color = np.zeros((4, 5, 3), np.uint8)
    frame = RgbdFrame(0.25, depth, color, 7)
    again = frame.renumbered(3)
    assert (again.index, again.t_s, frame.index) == (3, 0.25, 7)
    assert again.depth_m is frame.depth_m and again.color_rgb is frame.color_rgb
    assert not again.depth_m.flags.writeable
    with pytest.raises(AttributeError):
        again.index = 4  # still frozen
