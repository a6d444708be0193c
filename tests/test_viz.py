"""graph_slam.viz: the null logger is the default; the rerun logger writes a .rrd file."""

from __future__ import annotations

import sys

import numpy as np

from graph_slam.session.records import CameraIntrinsics
from graph_slam.terrain import Obstacle
from graph_slam.viz import NullLogger, RerunLogger, make_logger


def _log_a_stride(logger) -> None:
    intrinsics = CameraIntrinsics(
        width_px=8, height_px=6, fx_px=5.0, fy_px=5.0, cx_px=4.0, cy_px=3.0
    )
    rng = np.random.default_rng(0)
    logger.log_stride(np.eye(4))
    for k in range(3):
        logger.set_time(0, 0.1 * k)
        pose = np.eye(4)
        pose[:3, 3] = [0.1 * k, 0.0, 0.5]
        logger.log_camera(
            pose, intrinsics, np.full((6, 8), 1.5), rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
        )
        logger.log_cloud(rng.uniform(0, 1, (50, 3)), rng.integers(0, 256, (50, 3), dtype=np.uint8))
    logger.log_camera(np.full((4, 4), np.nan))  # a frame without pose is skipped
    logger.log_trajectory("truth", np.array([[0, 0, 0.5], [0.1, 0, 0.5], [np.nan] * 3]))
    logger.log_obstacles([Obstacle(0.2, 0.27, 0.19, 0.5, np.array([0.6, -0.3]), 100)], np.eye(4))
    logger.close()


def test_null_logger_is_the_default():
    logger = make_logger(None)
    assert isinstance(logger, NullLogger)
    _log_a_stride(logger)


def test_rerun_logger_writes_a_nonempty_rrd(tmp_path):
    path = tmp_path / "run" / "recording.rrd"
    logger = make_logger(path)
    assert isinstance(logger, RerunLogger) and "rerun" in sys.modules
    _log_a_stride(logger)
    assert path.is_file()
    data = path.read_bytes()
    assert len(data) > 1000 and data[:4] == b"RRF2"


def test_depth_view_is_whole_millimetres_with_unknown_as_zero():
    from graph_slam.viz.rerun_logger import depth_view_mm

    depth = np.array([[0.0, 1.2344, np.nan], [np.inf, -1.0, 70.0]])
    view = depth_view_mm(depth)
    assert view.dtype == np.uint16
    assert view.tolist() == [[0, 1234, 0], [0, 0, 0]]


def test_recording_images_are_compact(tmp_path):
    """Colour goes in as JPEG and depth as uint16: a frame costs well under its raw float size."""
    rng = np.random.default_rng(0)
    color = rng.integers(0, 256, (240, 424, 3), dtype=np.uint8)
    color[:] = np.clip(color.astype(int) // 8 + 100, 0, 255).astype(np.uint8)  # image-like
    depth = np.full((240, 424), 1.5) + rng.normal(0, 0.002, (240, 424))
    path = tmp_path / "r.rrd"
    logger = make_logger(path)
    for i in range(5):
        logger.set_time(0, 0.1 * i)
        logger.log_camera(np.eye(4), None, depth, color)
    logger.close()
    raw_float = 5 * (240 * 424 * 4 + 240 * 424 * 3)
    assert path.stat().st_size < 0.5 * raw_float
