"""The live viewer's process: its messages, its drawing, and a worker that stops."""

import io
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.live import view_worker
from graph_slam.terrain.grid.online import CellSums
from graph_slam.terrain.grid.view import TerrainView


def _frame(index: int, with_view: bool = True, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = 6 * 5
    sums = CellSums(rng.random(n) + 0.5, rng.random(n), rng.random(n), rng.random(n),
                    rng.integers(0, 9, n), rng.random(n), rng.random(n) + 1, rng.random(n))  # fmt: skip
    view = TerrainView(2, 1.25, np.array([0.1, -0.3]), 0.02, sums, (6, 5), 0.25)
    pose = np.eye(4)
    pose[:3, 3] = [0.1 * index, 0.0, 0.6]
    return SimpleNamespace(frame_index=index, stride_index=2, t_s=1.25 + index / 90,
                           stride_T_camera=pose, terrain=view if with_view else None)  # fmt: skip


def test_a_message_carries_the_pose_and_the_grids_sums_exactly():
    out = _frame(9)
    stream = io.BytesIO(view_worker.frame_message(out, with_grid=True))
    back = view_worker.frame_of(*view_worker.read_message(stream))
    assert (back.frame_index, back.stride_index, back.t_s) == (9, 2, out.t_s)
    np.testing.assert_array_equal(back.stride_T_camera, out.stride_T_camera)
    np.testing.assert_array_equal(back.terrain.height_m, out.terrain.height_m)
    np.testing.assert_array_equal(back.terrain.variance_m2, out.terrain.variance_m2)
    np.testing.assert_array_equal(back.terrain.count, out.terrain.count)
    assert back.terrain.cell_m == 0.02 and back.terrain.shape == (6, 5)
    assert view_worker.read_message(stream) is None  # the end


def test_frames_without_a_grid_carry_the_pose_only_and_a_cut_message_ends_the_stream():
    short = view_worker.frame_message(_frame(1), with_grid=False)
    full = view_worker.frame_message(_frame(0), with_grid=True)
    assert len(short) < 400 < len(full)
    back = view_worker.frame_of(*view_worker.read_message(io.BytesIO(short)))
    assert back.terrain is None and back.stride_T_camera[0, 3] == pytest.approx(0.1)
    assert view_worker.read_message(io.BytesIO(full[:-5])) is None


def test_serve_draws_every_message_and_counts_a_failed_frame():
    drawn = []

    class Drawer:
        def draw(self, out):
            if out.frame_index == 3:
                raise ValueError("broken frame")
            drawn.append((out.frame_index, out.terrain is not None))

    stream = io.BytesIO(b"".join(view_worker.frame_message(_frame(i), i % 2 == 0)
                                 for i in range(5)))  # fmt: skip
    counts = view_worker.serve(Drawer(), stream)
    assert counts == {"drawn": 4, "failed": 1}
    assert drawn == [(0, True), (1, False), (2, True), (4, True)]


def test_the_worker_process_writes_a_recording_with_poses_and_grids(tmp_path):
    from graph_slam.live.viewer import LiveViewer, ViewerConfig

    viewer = LiveViewer(tmp_path / "live.rrd", ViewerConfig(pose_hz=0, grid_hz=30))
    assert viewer.wait_ready()
    for i in range(7):
        viewer.frame(_frame(i, seed=i))
    viewer.close()
    assert viewer.counts["drawn"] + viewer.counts["dropped"] == 7
    assert viewer.counts["drawn"] >= 1 and viewer.counts["failed"] == 0
    assert (tmp_path / "live.rrd").stat().st_size > 1000


def test_a_worker_that_stops_stops_the_drawing_not_the_run(tmp_path, monkeypatch):
    from graph_slam.live import viewer as viewer_module

    real = subprocess.Popen

    def dies(cmd, **kw):  # a worker that exits at once without reading anything
        return real([sys.executable, "-c", "import sys; sys.exit(3)"], **kw)

    monkeypatch.setattr(viewer_module.subprocess, "Popen", dies)
    viewer = viewer_module.LiveViewer(tmp_path / "live.rrd", viewer_module.ViewerConfig(
        pose_hz=0, grid_hz=0))  # fmt: skip
    assert not viewer.wait_ready(timeout_s=10)
    for i in range(40):  # more than a pipe holds: writes fail, never block
        viewer.frame(_frame(i, seed=i))
    viewer.close()
    assert viewer.counts["drawn"] == 0
    # every frame accounted for: dropped while waiting, or lost (unwritten, or written into
    # the pipe before the worker's exit was seen, never drawn)
    assert viewer.counts["lost"] + viewer.counts["dropped"] == 40


def test_poses_and_grids_are_sent_at_their_rates_on_the_frames_clock(tmp_path):
    """90 Hz frames, poses at 30 Hz and grids at 5 Hz: every 3rd frame a pose, every 18th a
    grid (with its pose); a gap in the frames restarts the rates from the next frame."""
    from graph_slam.live.viewer import LiveViewer, ViewerConfig

    viewer = object.__new__(LiveViewer)  # the rate alone: no worker process
    viewer.config = ViewerConfig(pose_hz=30, grid_hz=5)
    viewer._next_pose_s = viewer._next_grid_s = -float("inf")
    t = 100.0 + np.arange(90) / 90.0
    due = [viewer.due(float(x)) for x in t]
    poses = [i for i, (p, _) in enumerate(due) if p]
    grids = [i for i, (_, g) in enumerate(due) if g]
    assert grids == list(range(0, 90, 18))
    assert poses == list(range(0, 90, 3))
    assert viewer.due(t[-1] + 2.0) == (True, True)  # after a 2 s gap: at once
    assert viewer.due(t[-1] + 2.0 + 1 / 90) == (False, False)
    every = object.__new__(LiveViewer)
    every.config = ViewerConfig(pose_hz=0, grid_hz=0)
    every._next_pose_s = every._next_grid_s = -float("inf")
    assert all(every.due(float(x)) == (True, True) for x in t[:5])


def test_a_negative_rate_is_refused():
    from graph_slam.config import config_from_dict
    from graph_slam.errors import ConfigError
    from graph_slam.live.viewer import ViewerConfig

    with pytest.raises(ConfigError, match="grid_hz"):
        config_from_dict(ViewerConfig, {"grid_hz": -1.0})


def test_the_cli_refuses_a_negative_rate_before_any_output(tmp_path, capsys):
    pytest.importorskip("pyrealsense2")
    from graph_slam.cli import main

    with pytest.raises(SystemExit) as done:
        main(["live", "--playback", str(tmp_path / "x.db3"), "--out", str(tmp_path / "o"),
              "--rerun", "file", "--rerun-grid-hz", "-1"])  # fmt: skip
    assert done.value.code != 0
    assert "grid_hz" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
