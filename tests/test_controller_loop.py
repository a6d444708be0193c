"""The controller's loop is causal: replaying a session with its streams interleaved in time
order gives the same per-frame readouts as pushing every stream first, frame by frame."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from graph_slam.pipelines import PipelineConfig
from graph_slam.pipelines.controller import ControllerTap
from graph_slam.pipelines.runner import make_pipeline, open_pipeline

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "controller_loop.py"


@pytest.fixture(scope="module")
def session_path(tmp_path_factory):
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("controller") / "sim"
    simulate(SimConfig(strides=1, seed=2, resolution="212x120", drops="none", quicklook=False), out)
    return out


def _example():
    spec = importlib.util.spec_from_file_location("controller_loop", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _all_streams_first(path, config):
    """Every IMU and encoder sample pushed before the first frame (as run_session)."""
    session, streams, pipe = open_pipeline(
        path, config, lambda *a, **k: ControllerTap(make_pipeline(*a, **k))
    )
    pipe.add_imu(streams.imu_t_s, streams.gyro_rad_s, streams.accel_m_s2)
    pipe.add_joints(streams.joints_t_s, streams.knee_rad, streams.ankle_rad)
    t_prev = -np.inf
    for frame in session.iter_frames(0, config.max_frames):
        for t in (t for t in streams.foot_strikes_s if t_prev < t <= frame.t_s):
            pipe.foot_strike(t)
        pipe.add_frame(frame, streams.foot_loaded(frame.t_s))
        t_prev = frame.t_s
    return pipe.readouts


def test_controller_readouts_are_the_same_interleaved_or_all_at_once(session_path):
    # imu+kin: every stream the graph reads, deterministic (no Open3D threaded sums); every
    # frame: its session's first anchored stride has no plane to settle the encoders' up
    # (σ 0.1 rad), the grid's settling gate holds it back, the next stride's stance has a grid
    config = PipelineConfig(variant="imu+kin", backend={"covariances": True})
    online = _example().controller_readouts(session_path, config, compute_cost=lambda i, s: 0.0)
    offline = _all_streams_first(session_path, config)
    assert [r.line() for r in online] == [r.line() for r in offline]
    phases = {r.phase.split()[0] for r in online}
    assert {"none", "stance"} <= phases
    assert any(r.has_pose for r in online)
    # stance frames with a grid carry the coming swing's predicted clearance (level ground)
    stance = [r for r in online if r.phase.startswith("stance") and np.isfinite(r.clearance_m)]
    assert stance and all("clearance" in r.line() for r in stance)
    assert all(0.0 < r.clearance_m < 0.2 for r in stance)


def test_realtime_final_grid_is_the_online_one_and_old_grids_are_released(session_path):
    """The real-time preset keeps no clouds: a stride's final grid is its online grid (the
    report's deadlines need one); ``keep_stride_grids`` releases all but the latest."""
    from graph_slam.pipelines import PipelineConfig, run_session
    from graph_slam.pipelines.config import with_preset

    data = with_preset({"variant": "icp+imu+kin"}, "realtime")
    res = run_session(session_path, PipelineConfig.model_validate(data))
    assert len(res.strides) >= 2
    for s in res.strides:
        assert s.online_grid is not None and s.smoothed_grid is s.online_grid
    data["terrain"]["online"]["keep_stride_grids"] = 1
    kept = run_session(session_path, PipelineConfig.model_validate(data))
    assert [s.online_grid is not None for s in kept.strides] == [False] * (
        len(kept.strides) - 1
    ) + [True]
    assert all(s.smoothed_grid is None for s in kept.strides[:-1])
    np.testing.assert_array_equal(
        kept.strides[-1].online_grid.height_m, res.strides[-1].online_grid.height_m
    )


def test_the_example_on_its_defaults_prints_every_frame(session_path):
    """The default preset on the deterministic virtual clock: one readout per frame, whatever
    the machine's load (the measured clock would skip frames that arrive while it works)."""
    example = _example()
    config = example.row_config("icp+imu+kin").model_copy(update={"max_frames": 30})
    assert config.preset == "realtime"
    readouts = example.controller_readouts(session_path, config)
    assert len(readouts) == 30
