"""Shared fixtures. Real third-party data lives in ../shared/data (skip cleanly when absent)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from graph_slam.session.synthetic import SyntheticConfig, write_synthetic_session

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
TEST_DATA = Path(__file__).resolve().parent / "data"
REAL_THIGH_IMU = Path(os.environ.get("GAIT_REAL_DATA", SHARED_DATA / "real_thigh_imu"))
"""The real walks with thigh IMUs (``GAIT_REAL_DATA`` may point elsewhere, e.g. from a checkout
whose ../shared is not beside it)."""

SMALL_SYNTHETIC = SyntheticConfig(duration_s=2.4, camera_rate_hz=30.0, seed=7)


@pytest.fixture(scope="session")
def _synthetic_master(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_synthetic_session(
        tmp_path_factory.mktemp("synthetic") / "session", SMALL_SYNTHETIC
    )


@pytest.fixture
def synthetic_session(_synthetic_master: Path, tmp_path: Path) -> Path:
    """A fresh, writable copy of a small synthetic session (tests may break it)."""
    copy = tmp_path / "session"
    shutil.copytree(_synthetic_master, copy)
    return copy


def shared_data(relative: str) -> Path:
    """Path into ../shared/data, or skip the test with the reason."""
    path = SHARED_DATA / relative
    if not path.exists():
        pytest.skip(f"real data {relative} not available (../shared/data is absent)")
    return path
