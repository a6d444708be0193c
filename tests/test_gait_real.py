"""Gait events on a real thigh IMU (the Xsens walk of ../shared/data/real_thigh_imu, skipped when
absent), the Xsens text reader, and the 24 right-handed axis arrangements."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import REAL_THIGH_IMU
from scipy.spatial.transform import Rotation

from kinematics.errors import GaitInputError
from kinematics.gait_events import detect_from_thigh_imu, match_events
from kinematics.gait_online import estimate_online
from kinematics.gait_phase_metrics import score_online
from kinematics.gait_real import (
    read_reference_strikes,
    read_xsens_txt,
    rearranged,
    right_handed_arrangements,
)

DATA = REAL_THIGH_IMU
XSENS = DATA / "walking_xsens_upperLeg.txt"
needs_data = pytest.mark.skipif(
    not XSENS.exists(), reason=f"real thigh walk not found ({XSENS}; ../shared/data is absent)"
)


def test_the_24_right_handed_arrangements():
    mats = right_handed_arrangements()
    assert len(mats) == 24
    assert len({m.tobytes() for m in mats}) == 24
    for m in mats:
        np.testing.assert_allclose(m @ m.T, np.eye(3))
        assert np.linalg.det(m) == pytest.approx(1.0)
        assert set(np.abs(m).sum(axis=0)) == {1.0}


def _xsens_text(rows: list[str], header: str, rate: str = "// Update Rate: 100.0Hz") -> str:
    return "\n".join(["// Start Time: Unknown", rate, header, *rows]) + "\n"


def test_xsens_reader_gyro_from_orientation_known_answer(tmp_path):
    # a sensor turning at 2 rad/s about its own y axis, standing upright
    rate_hz, w = 100.0, 2.0
    cols = [f"Mat[{i}][{j}]" for j in (1, 2, 3) for i in (1, 2, 3)]
    header = "\t".join(["PacketCounter", "Acc_X", "Acc_Y", "Acc_Z", *cols])
    rows = []
    for k in range(50):
        r = Rotation.from_rotvec([0.0, w * k / rate_hz, 0.0]).as_matrix()
        mat = [r[i, j] for j in range(3) for i in range(3)]  # column by column
        rows.append("\t".join([f"{k + 10:05d}", "0", "0", "9.81", *(f"{x:.9f}" for x in mat)]))
    path = tmp_path / "femur.txt"
    path.write_text(_xsens_text(rows, header))
    imu = read_xsens_txt(path)
    np.testing.assert_allclose(imu.t_s[:3], [0.0, 0.01, 0.02])
    np.testing.assert_allclose(imu.gyro_rad_s, np.tile([0.0, w, 0.0], (50, 1)), atol=1e-6)


def test_xsens_reader_errors_name_the_file_and_rule(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text(_xsens_text(["1\t0\t0\t9.81"], "Counter\tAcc_X\tAcc_Y\tAcc_Z"))
    with pytest.raises(GaitInputError, match=r"bad\.txt.*Gyr_X\.\.Z or the orientation"):
        read_xsens_txt(path)
    path.write_text(_xsens_text([], "Counter", rate="// nothing"))
    with pytest.raises(GaitInputError, match="Sample rate"):
        read_xsens_txt(path)


@pytest.fixture(scope="module")
def walk():
    if not XSENS.exists():
        pytest.skip(f"real thigh walk not found ({XSENS})")
    return read_xsens_txt(XSENS), read_reference_strikes(DATA / "reference_events.csv")


@needs_data
def test_real_walk_offline_meets_the_targets_on_every_mounting(walk):
    imu, ref = walk
    assert ref.size == 20
    for r in right_handed_arrangements()[::3]:  # 8 of the 24, flipped axes among them
        ev = detect_from_thigh_imu(rearranged(imu, r))
        err, missed, extra = match_events(ev.foot_strikes_s, ref)
        assert (missed, extra) == (0, 0)
        assert np.median(np.abs(err)) <= 0.030 and np.max(np.abs(err)) <= 0.060, err
        assert np.all(ev.foot_strikes_s > 3.5) and np.all(ev.toe_offs_s > 3.5)  # standing
        assert ev.details["sign_disagreement"] == 0.0


@needs_data
def test_real_walk_online_meets_the_targets(walk):
    imu, ref = walk
    for r in (np.eye(3), right_handed_arrangements()[7]):
        res = estimate_online(rearranged(imu, r))
        sc = score_online(res, ref, np.zeros(0))
        assert (sc.foot_strike.missed, sc.foot_strike.extra) == (0, 0)
        err = np.abs(sc.foot_strike.errors_s)
        assert np.median(err) <= 0.030 and err.max() <= 0.060, err
        assert np.percentile(sc.foot_strike.latencies_s, 95) <= 0.100
        assert sc.phase_rmse_cyc <= 0.03
        assert all(e.detected_t_s > 3.5 for e in res.events)  # none while standing
        assert res.counts["impact_strikes"] >= 15
        assert not math.isnan(res.phase_cyc[-1])
