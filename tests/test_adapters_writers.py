"""Writers and their symmetric readers: TUM trajectories, PLY point clouds."""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.errors import RecordError, StreamError
from graph_slam.session.adapters import read_ply, write_ply
from graph_slam.session.io import read_tum, write_tum
from graph_slam.session.records import Cloud, PoseTrajectory


def _trajectory(n: int = 25, seed: int = 3) -> PoseTrajectory:
    rng = np.random.default_rng(seed)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    poses[:, :3, 3] = rng.normal(0, 2.0, (n, 3))
    return PoseTrajectory(1305031102.0 + np.arange(n) / 30.0, poses, parent="world", child="imu")


# --------------------------------------------------------------------------- TUM
@pytest.mark.parametrize("use_file_object", [False, True])
def test_tum_round_trip(tmp_path: Path, use_file_object: bool) -> None:
    traj = _trajectory()
    if use_file_object:
        buffer = io.StringIO()
        write_tum(buffer, traj.t_s, traj.parent_T_child)
        buffer.seek(0)
        t_s, poses = read_tum(buffer)
    else:
        write_tum(tmp_path / "t.txt", traj.t_s, traj.parent_T_child)
        t_s, poses = read_tum(tmp_path / "t.txt")
    back = PoseTrajectory(t_s, poses, parent="world", child="imu")
    assert back.name == "world_T_imu"
    np.testing.assert_allclose(back.t_s, traj.t_s, rtol=0, atol=1e-9)
    # 9 decimals per value: positions within 5e-10 m, rotations within ~1e-8.
    np.testing.assert_allclose(back.parent_T_child, traj.parent_T_child, atol=2e-8)


def test_tum_malformed() -> None:
    with pytest.raises(StreamError, match=r"line 2: TUM rows must have 8 entries"):
        read_tum(io.StringIO("# header\n1 2 3\n"))
    with pytest.raises(StreamError, match=r"quaternion norm 2\.000000 is not 1"):
        read_tum(io.StringIO("1 0 0 0 0 0 0 2\n"))


# --------------------------------------------------------------------------- PLY
def _cloud(n: int = 100, color: bool = True) -> Cloud:
    rng = np.random.default_rng(11)
    colors = rng.integers(0, 256, (n, 3), dtype=np.uint8) / 255.0 if color else None
    return Cloud(rng.normal(0, 3.0, (n, 3)), colors)


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("color", [True, False])
def test_ply_round_trip_is_exact(tmp_path: Path, binary: bool, color: bool) -> None:
    cloud = _cloud(color=color)
    write_ply(cloud, tmp_path / "map.ply", binary=binary)
    back = read_ply(tmp_path / "map.ply")
    np.testing.assert_array_equal(back.points_m, cloud.points_m)
    if color:
        np.testing.assert_array_equal(back.colors_rgb, cloud.colors_rgb)
    else:
        assert back.colors_rgb is None
    buffer = io.BytesIO()
    write_ply(cloud, buffer, binary=binary)
    buffer.seek(0)
    np.testing.assert_array_equal(read_ply(buffer).points_m, cloud.points_m)


def test_ply_from_another_tool(caplog) -> None:
    """float32 coordinates, normals (read) and alpha (ignored, logged), big-endian, a face
    element."""
    pts = np.array([[0.5, -1.25, 2.0], [3.0, 4.0, -5.5]], dtype=">f4")
    header = (
        "ply\nformat binary_big_endian 1.0\ncomment other tool\nelement vertex 2\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
        "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
    )
    dtype = np.dtype([("p", ">f4", 3), ("n", ">f4", 3), ("c", "u1", 4)])
    rec = np.zeros(2, dtype=dtype)
    rec["p"] = pts
    rec["n"] = [[0.0, 0.0, 1.0], [0.6, 0.8, 0.0]]
    rec["c"] = [[1, 2, 3, 255], [4, 5, 6, 255]]
    with caplog.at_level(logging.INFO, logger="graph_slam.session.adapters.ply"):
        cloud = read_ply(io.BytesIO(header.encode() + rec.tobytes()))
    np.testing.assert_array_equal(cloud.points_m, pts.astype(np.float64))
    np.testing.assert_array_equal(cloud.colors_rgb, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(cloud.normals, np.float32([[0, 0, 1], [0.6, 0.8, 0]]))
    assert "vertex properties ignored: alpha" in caplog.text


def test_ply_malformed(tmp_path: Path) -> None:
    write_ply(_cloud(), tmp_path / "map.ply")
    data = (tmp_path / "map.ply").read_bytes()
    with pytest.raises(
        StreamError, match=r"100 vertices need 2700 bytes, found \d+ \(file truncated\)"
    ):
        read_ply(io.BytesIO(data[:-10]))
    with pytest.raises(StreamError, match=r"not a PLY file"):
        read_ply(io.BytesIO(b"solid cube\n"))
    with pytest.raises(StreamError, match=r"the first element must be 'vertex'"):
        read_ply(io.BytesIO(b"ply\nformat ascii 1.0\nelement face 0\nend_header\n"))
    bad_ascii = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n"
    with pytest.raises(StreamError, match=r"vertex 1: 0 values, expected 3 \(file truncated\)"):
        read_ply(io.BytesIO(bad_ascii))
    with pytest.raises(RecordError, match=r"NaN or inf"):
        Cloud(np.array([[0.0, np.nan, 1.0]]))
