"""Encoder validation: channel mapping, NaN, limits and impossible jumps are flagged and counted."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from kinematics.encoders import check_encoders
from kinematics.errors import EncoderError, LegModelError
from kinematics.leg_model import LegModel


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel()


def clean(n: int = 200, rate: float = 500.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) / rate
    knee = 0.6 + 0.5 * np.sin(2 * np.pi * 0.9 * t)  # < 3 rad/s, well below the 12 rad/s limit
    ankle = 0.05 * np.sin(2 * np.pi * 0.9 * t + 1.0)
    return t, np.column_stack([knee, ankle])


def test_clean_signal_all_usable_and_channel_order(model: LegModel) -> None:
    t, q = clean()
    check = check_encoders(t, q[:, ::-1], ["ankle", "knee"], model)
    assert check.n_usable == check.n_samples == 200
    np.testing.assert_array_equal(check.q_rad, q)  # reordered to knee, ankle
    assert all(n == 0 for c in check.counts.values() for n in c.values())


def test_each_fault_flagged_and_counted(model: LegModel, caplog: pytest.LogCaptureFixture) -> None:
    t, q = clean()
    q[10, 0] = np.nan  # NaN knee
    q[50, 1] = 0.9  # ankle beyond +0.349 rad dorsiflexion limit
    q[100, 0] += 0.4  # knee spike: 0.4 rad in 2 ms = 200 rad/s
    q[150:153, 1] -= 0.2  # ankle step held 3 samples, then back
    with caplog.at_level(logging.WARNING, logger="kinematics.encoders"):
        check = check_encoders(t, q, ["knee", "ankle"], model)
    counts = check.counts
    assert counts["nan"] == {"knee": 1, "ankle": 0}
    assert counts["out_of_limits"] == {"knee": 0, "ankle": 1}
    assert counts["jump"] == {"knee": 1, "ankle": 3}  # the spike once; the held step 3 times
    assert check.n_usable == 200 - 6
    assert not check.usable[[10, 50, 100, 150, 151, 152]].any()
    assert check.usable[
        [101, 153]
    ].all()  # the sample after a spike is compared to the last good one
    assert "194/200 samples usable" in caplog.text


def test_slow_large_motion_is_not_a_jump(model: LegModel) -> None:
    t = np.arange(0, 1, 0.002)
    knee = np.clip(10.0 * t, 0, 2.0)  # 10 rad/s: fast but under the 12 rad/s limit
    check = check_encoders(t, np.column_stack([knee, np.zeros_like(t)]), ["knee", "ankle"], model)
    assert check.counts["jump"]["knee"] == 0


def test_channel_mismatch_lists_both(model: LegModel) -> None:
    t, q = clean()
    with pytest.raises(LegModelError, match=r"\['knee', 'foot'\].*\['knee', 'ankle'\]"):
        check_encoders(t, q, ["knee", "foot"], model)


def test_bad_time_and_shapes(model: LegModel) -> None:
    t, q = clean()
    t[5] = t[4]
    with pytest.raises(EncoderError, match="row 5"):
        check_encoders(t, q, ["knee", "ankle"], model)
    with pytest.raises(EncoderError, match="3 columns but 2 channel names"):
        check_encoders(np.arange(3.0), np.zeros((3, 3)), ["knee", "ankle"], model)
