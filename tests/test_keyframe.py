"""Keyframes: which earlier frame a frame registers against (the rule of
graph_slam.pipelines.keyframe), and the graph pipeline registering against them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.pipelines.keyframe import KeyframeConfig, Keyframes


def pose(x_m: float = 0.0, yaw_rad: float = 0.0) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = Rotation.from_rotvec([0.0, 0.0, yaw_rad]).as_matrix()
    t[0, 3] = x_m
    return t


def keyframes_of(config: KeyframeConfig, rate_hz: float, n: int = 10, step_m: float = 0.005):
    """Frames at ``rate_hz`` moving ``step_m`` each, every registration accepted: the indices
    that became keyframes."""
    keys = Keyframes(config)
    became = []
    for i in range(n):
        if keys.update(i, f"target {i}", pose(i * step_m), i / rate_hz, keep=i > 0):
            became.append(i)
    return became


def test_interval_zero_registers_every_frame_against_the_previous_one():
    assert keyframes_of(KeyframeConfig(interval_s=0.0), 90.0) == list(range(10))


@pytest.mark.parametrize(("rate_hz", "every"), [(90.0, 5), (45.0, 3), (30.0, 2)])
def test_the_default_interval_is_every_fifth_frame_at_90_hz(rate_hz, every):
    assert keyframes_of(KeyframeConfig(), rate_hz) == list(range(0, 10, every))


def test_motion_beyond_the_limits_makes_a_new_keyframe():
    config = KeyframeConfig(interval_s=1.0, max_translation_m=0.012)
    assert keyframes_of(config, 90.0, n=7, step_m=0.005) == [0, 3, 6]  # 15 mm > 12 mm
    assert keyframes_of(KeyframeConfig(interval_s=1.0), 90.0, n=24, step_m=0.005) == [0, 11, 22]
    keys = Keyframes(KeyframeConfig(interval_s=1.0, max_rotation_rad=0.1))
    keys.update(0, "a", pose(), 0.0, keep=False)
    assert not keys.update(1, "b", pose(yaw_rad=0.09), 0.01, keep=True)
    assert keys.update(2, "c", pose(yaw_rad=0.11), 0.02, keep=True)
    assert keys.key.index == 2 and keys.key.target == "c"


def test_a_frame_not_accepted_becomes_the_keyframe_and_none_clears_it():
    keys = Keyframes(KeyframeConfig(interval_s=1.0))
    keys.update(0, "a", pose(), 0.0, keep=False)
    assert not keys.update(1, "b", pose(0.01), 0.01, keep=True)
    assert keys.key.index == 0
    assert keys.update(2, "c", pose(0.02), 0.02, keep=False)  # rejected, or a new stride
    assert keys.key.index == 2
    assert not keys.update(3, None, pose(0.03), 0.03, keep=True)
    assert keys.key is None


def test_the_guess_against_the_keyframe_composes_through_the_previous_frame():
    keys = Keyframes(KeyframeConfig(interval_s=1.0))
    keys.update(0, "a", pose(0.1, 0.2), 0.0, keep=False)
    prev, prev_T_current = pose(0.3, 0.5), pose(0.02, 0.05)
    guess = keys.target_T_current(prev, prev_T_current)
    np.testing.assert_allclose(pose(0.1, 0.2) @ guess, prev @ prev_T_current, atol=1e-12)


def test_the_graph_pipeline_registers_against_keyframes(tmp_path):
    """Within a stride, frames register against earlier frames of the same stride, several
    against one keyframe; with ``interval_s: 0`` each registers against the previous frame."""
    from graph_slam.pipelines import PipelineConfig, run_session
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path / "sim"
    simulate(SimConfig(strides=1, seed=2, fast=True, drops="none", quicklook=False), out)
    spans = {}
    for interval in (0.0, 0.05):
        cfg = PipelineConfig(variant="icp+imu+kin", max_frames=40)
        cfg = cfg.model_copy(
            update={
                "graph": cfg.graph.model_copy(
                    update={"keyframe": KeyframeConfig(interval_s=interval)}
                )
            }
        )
        res = run_session(out, cfg)
        assert res.config["graph"]["real_camera_floor"] is False  # the simulator's session
        pairs = [(f.frame_index, f.registered_to, f.stride_index) for f in res.frames]
        targets = {p[1] for p in pairs if p[1] is not None}
        stride_of = {p[0]: p[2] for p in pairs}
        assert targets, "no frame was registered"
        for index, target, stride in pairs:
            if target is not None:
                assert target < index and stride_of[target] == stride
        spans[interval] = [i - t for i, t, _ in pairs if t is not None]
    assert set(spans[0.0]) == {1}
    assert max(spans[0.05]) == 5 and 1 in spans[0.05]  # 90 Hz: keyframes 5 frames apart
