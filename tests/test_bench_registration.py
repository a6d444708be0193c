"""The registration benchmark's pieces: the box-course renderer, the TUM sample reader, a run."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import TEST_DATA

from graph_slam.bench.registration import run_config
from graph_slam.bench.registration_data import pose_error, read_tum_sample, synthetic_dataset
from graph_slam.errors import SessionError
from graph_slam.frontend import fast_point_to_plane
from graph_slam.session.reader import open_session
from graph_slam.session.synthetic import (
    SyntheticConfig,
    box_on_floor,
    render_frame,
    scene_truth,
    write_synthetic_session,
)


def test_box_depth_is_exact_from_above() -> None:
    cfg = SyntheticConfig(width_px=33, height_px=33, depth_noise_m=0.0, with_color=False)
    box = box_on_floor("b", (1.0, 0.5), (0.2, 0.3, 0.19))
    world_T_camera = np.eye(4)  # looking straight down: optical z = world -z, x = world -y
    world_T_camera[:3, :3] = [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]
    world_T_camera[:3, 3] = [1.0, 0.5, 0.5]
    rng = np.random.default_rng(0)
    frame = render_frame(cfg, world_T_camera, 0.0, 0, rng, np.zeros((3, 4)), (box,))
    assert frame.depth_m[16, 16] == pytest.approx(0.5 - 0.19, abs=1e-6)  # the box top
    assert frame.depth_m[0, 0] == pytest.approx(0.5, abs=1e-6)  # the floor beside it


def test_box_course_scene_is_written_with_the_session(tmp_path: Path) -> None:
    cfg = SyntheticConfig(duration_s=0.2, scene="box_course")
    assert [o.name for o in scene_truth(cfg).objects] == ["box1", "box2", "box3"]
    session = open_session(write_synthetic_session(tmp_path / "s", cfg))
    scene = session.scene
    assert scene is not None and scene.name == "box_course"
    np.testing.assert_allclose(scene.object("box2").size_m, [0.2667, 0.3556, 0.0762])
    assert scene_truth(SyntheticConfig()).objects == ()


def test_run_config_times_every_stage_and_measures_the_error() -> None:
    data = synthetic_dataset(pairs=2, rate_hz=40.0, width_px=160, height_px=120)
    summary = run_config("fast", fast_point_to_plane(), data)
    assert summary.pairs == 2 and sum(summary.statuses.values()) == 2
    assert all(summary.stage_ms[s] > 0 for s in ("cloud", "voxel", "normals", "icp"))
    assert (
        summary.translation_err_mm.size
        + sum(v for k, v in summary.statuses.items() if k.startswith("failed"))
        == 2
    )
    assert "per pair (ms)" in summary.line()


def test_pose_error() -> None:
    truth = np.eye(4)
    estimate = np.eye(4)
    estimate[:3, 3] = [0.003, 0.004, 0.0]
    c, s = np.cos(0.01), np.sin(0.01)
    estimate[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    t_m, r_rad = pose_error(estimate, truth)
    assert t_m == pytest.approx(0.005) and r_rad == pytest.approx(0.01)


def test_tum_reader_reads_the_copied_frames() -> None:
    data = read_tum_sample(TEST_DATA / "tum_fr1_xyz_10")
    assert len(data.frames) == 4 and data.world_T_camera.shape == (4, 4, 4)
    depth = data.frames[0].depth_m
    assert depth.shape == (480, 640) and 0.5 < np.median(depth[depth > 0]) < 3.0


def test_tum_reader_names_the_bad_file_or_entry(tmp_path: Path) -> None:
    folder = tmp_path / "tum"
    shutil.copytree(TEST_DATA / "tum_fr1_xyz_10", folder)
    truth = json.loads((folder / "ground_truth.json").read_text())
    with pytest.raises(SessionError, match="no entry '7'"):
        read_tum_sample(folder, ids=[1, 7])
    truth["2"]["depth"] = "../../etc/passwd"
    (folder / "ground_truth.json").write_text(json.dumps(truth))
    with pytest.raises(SessionError, match="leaves the folder"):
        read_tum_sample(folder)
    (folder / "ground_truth.json").write_text("{not json")
    with pytest.raises(SessionError, match=r"ground_truth\.json"):
        read_tum_sample(folder)
    truth["2"]["depth"] = "rgb/2.png"  # an 8-bit RGB image where depth belongs
    (folder / "ground_truth.json").write_text(json.dumps(truth))
    with pytest.raises(SessionError, match="uint16"):
        read_tum_sample(folder)
