"""The registration's information against the truth: χ²/dof of consecutive pairs of a fixed
simulated box course (seed 3, quarter resolution) stays within 0.5–2 (calibrated in
``information_scale``; docs/frontend.md, "Calibrated information"). Fails when the information
model or the registration drifts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graph_slam.bench.calibration import chi2_of_pairs, relative_error
from graph_slam.bench.registration_data import session_dataset
from graph_slam.frontend.config import realtime_registration
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def box_course(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("calibration") / "boxes"
    cfg = SimConfig(strides=1, seed=3, fast=True, drops="none", quicklook=False)
    simulate(cfg, out)
    return out


def test_relative_error_is_gtsam_logmap() -> None:
    gtsam = pytest.importorskip("gtsam")
    xi = np.array([0.02, -0.01, 0.03, 0.01, 0.02, -0.005])
    pose = gtsam.Pose3.Expmap(np.array([0.1, 0.2, -0.1, 0.3, 0.1, 0.2])).matrix()
    truth = pose @ gtsam.Pose3.Expmap(xi).matrix()
    np.testing.assert_allclose(relative_error(pose, truth), xi, atol=1e-5)


@pytest.mark.parametrize(
    ("name", "config", "pairs"),
    [("realtime", realtime_registration(), 40), ("accurate", None, 30)],
)
def test_chi2_per_dof_of_the_box_course_is_near_one(box_course, name, config, pairs) -> None:
    config = config or PipelineConfig().graph.registration
    data = session_dataset(box_course, stop=pairs + 1)
    report = chi2_of_pairs(data, config)
    assert report.failed <= 2
    assert report.ratio.size >= pairs - 2
    assert 0.3 <= report.median_ratio <= 3.0, report.line()  # calibrated: 0.5-2


@pytest.fixture(scope="module")
def pico_course(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The depth-only ToF camera (224×171, 45 Hz, 1 cm noise at 1 m) on the box course."""
    out = tmp_path_factory.mktemp("calibration") / "pico"
    cfg = SimConfig(strides=1, seed=3, camera="pico_flexx", drops="none", quicklook=False)
    simulate(cfg, out)
    return out


def test_depth_only_information_is_calibrated(pico_course) -> None:
    """The depth-only settings (``graph.depth_only``) give χ²/dof near 1 on the ToF camera;
    the RGB-D settings on the same pairs were 80 times over-confident."""
    from graph_slam.pipelines.protocol import sensor_registration

    graph = PipelineConfig(preset="accurate").graph  # Open3D's point-to-plane, depth only
    data = session_dataset(pico_course, stop=31)
    assert all(f.color_rgb is None for f in data.frames)
    tuned = chi2_of_pairs(data, sensor_registration(graph.registration, False, graph.depth_only))
    plain = chi2_of_pairs(data, sensor_registration(graph.registration, False))
    assert tuned.failed <= 2 and tuned.ratio.size >= 25
    assert 0.3 <= tuned.median_ratio <= 3.0, tuned.line()  # calibrated: 0.72 on 50 pairs
    assert plain.median_ratio > 10 * tuned.median_ratio, plain.line()


# --------------------------------------------------------------------------- real frames
def _tum_chi2(folder: Path, floor: bool):
    from graph_slam.bench.registration_data import read_tum_sample
    from graph_slam.frontend.config import with_real_camera_floor

    config = PipelineConfig().graph.registration
    return chi2_of_pairs(
        read_tum_sample(folder), with_real_camera_floor(config) if floor else config
    )


def test_real_camera_floor_calibrates_the_copied_tum_frames() -> None:
    """The four copied TUM fr1/xyz frames (3 pairs, the noisiest of the ten): with the
    real-camera floor χ²/dof median 2.4 (measured; 663 without the floor)."""
    from conftest import TEST_DATA

    real = _tum_chi2(TEST_DATA / "tum_fr1_xyz_10", floor=True)
    assert real.failed == 0 and real.ratio.size == 3
    assert 0.5 <= real.median_ratio <= 4.0, real.line()


def test_real_camera_floor_puts_the_tum_chi2_in_the_band() -> None:
    """The ten TUM frames (9 pairs, ../shared/data): χ²/dof median 0.83 with the real-camera
    floor (the issue's band 0.5–2); 663 with the default (no floor)."""
    from conftest import shared_data

    real = _tum_chi2(shared_data("tum_fr1_xyz_10"), floor=True)
    assert real.failed == 0 and real.ratio.size == 9
    assert 0.5 <= real.median_ratio <= 2.0, real.line()
