"""Where a gait phase's error lies (kinematics.gait_phase_metrics) and the thigh's
phase-portrait phase (kinematics.gait_phase_portrait): known answers."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.errors import GaitInputError
from kinematics.gait_phase_metrics import (
    phase_error,
    phase_error_by_stride,
    phase_error_by_true_phase,
    reference_phase,
)
from kinematics.gait_phase_portrait import portrait_phase


def test_reference_phase_is_nan_across_a_swing_without_a_reference_strike():
    """Strides of 1.1 s with the reference strike at 3.2 s missing (its swing, at 2.9 s, has
    none): the span 2.1-4.3 s covers two strides yet passes the 2.5 s rule; a swing without a
    reference inside it makes it NaN, and leaves the other strides as they were."""
    t = np.arange(0.0, 5.0, 0.01)
    strikes = np.array([1.0, 2.1, 4.3])
    plain = reference_phase(t, strikes)
    guarded = reference_phase(t, strikes, unreferenced_s=np.array([0.2, 2.9, 4.6]))
    late = (t >= 2.1) & (t < 4.3)
    early = (t >= 1.0) & (t < 2.1)
    assert np.all(np.isfinite(plain[late]))  # the 2.5 s rule alone scores the double span
    assert np.all(np.isnan(guarded[late]))
    np.testing.assert_allclose(guarded[early], plain[early])  # outside spans: unchanged
    np.testing.assert_allclose(guarded[early], (t[early] - 1.0) / 1.1, atol=1e-12)


def test_phase_error_wraps_across_the_strike():
    assert phase_error(np.array([0.98]), np.array([0.01]))[0] == pytest.approx(-0.03)
    assert phase_error(np.array([0.02]), np.array([0.97]))[0] == pytest.approx(0.05)


def test_error_by_stride_and_by_true_phase_known_answers():
    """Three 1 s strides; the estimate is the reference + 0.05 in the second stride, NaN over
    the first half of the third, exact elsewhere."""
    t = np.arange(0.0, 3.0, 0.01)
    strikes = np.array([0.0, 1.0, 2.0, 3.0])
    ref = reference_phase(t, strikes)
    est = ref.copy()
    est[(t >= 1.0) & (t < 2.0)] += 0.05
    est[(t >= 2.0) & (t < 2.5)] = np.nan
    per = phase_error_by_stride(t, est, ref, strikes)
    assert [p.start_s for p in per] == [0.0, 1.0, 2.0]
    assert per[0].rmse_cyc == pytest.approx(0.0, abs=1e-12)
    assert per[1].rmse_cyc == pytest.approx(0.05) and per[1].mean_cyc == pytest.approx(0.05)
    assert per[2].scored_fraction == pytest.approx(0.5)
    # an estimate ahead in proportion to the phase: each tenth's mean error is 0.1 x its middle
    lin = ref * 1.1
    rmse, mean, count = phase_error_by_true_phase(lin, ref)
    middles = (np.arange(10) + 0.5) / 10
    np.testing.assert_allclose(mean, 0.1 * middles, atol=0.006)  # ±half a bin x 0.1
    assert count.sum() == np.isfinite(ref).sum()
    assert np.all(rmse >= np.abs(mean) - 1e-12)


def _sinusoid_walk(periods_s, rate_hz=100.0):
    """A sinusoid-like thigh (20° cos + 5° second harmonic of the phase), each stride a
    time-scaled copy; (t, angle, strikes, reference phase)."""
    strikes = 0.5 + np.concatenate([[0.0], np.cumsum(periods_s)])
    t = np.arange(0.5, strikes[-1], 1.0 / rate_hz)
    ref = reference_phase(t, strikes)
    angle = np.radians(20.0 * np.cos(2 * np.pi * ref) + 5.0 * np.cos(4 * np.pi * ref + 1.0))
    return t, angle, strikes, ref


def _stride_max_error(t, est, ref, strikes, k):
    m = (t >= strikes[k]) & (t < strikes[k + 1])
    return float(np.nanmax(np.abs(phase_error(est[m], ref[m]))))


def test_portrait_phase_on_a_steady_sinusoid_like_thigh():
    """Steady 1.2 s strides: from the third stride on (the first gives no rate from its strike,
    the second has no map yet) the portrait phase is within 0.005 cycle of the truth."""
    t, angle, strikes, ref = _sinusoid_walk([1.2] * 6)
    est = portrait_phase(t, angle, strikes)
    assert np.all(np.isnan(est[t < strikes[2]]))
    for k in range(2, 6):
        assert _stride_max_error(t, est, ref, strikes, k) < 0.005


def test_portrait_phase_follows_a_time_scaled_stride_that_a_time_phase_cannot():
    """Strides of 1.2 s then 1.5 s, each a time-scaled copy: in the first 1.5 s stride the
    portrait phase is within 0.05 cycle (its rate is still normalised by the 1.2 s stride's);
    a phase linear in time over the last stride is 0.2 cycle off at its end."""
    t, angle, strikes, ref = _sinusoid_walk([1.2, 1.2, 1.2, 1.5, 1.5])
    est = portrait_phase(t, angle, strikes)
    assert _stride_max_error(t, est, ref, strikes, 3) < 0.05
    assert _stride_max_error(t, est, ref, strikes, 4) < 0.01
    m = (t >= strikes[3]) & (t < strikes[4])
    time_phase = np.minimum((t[m] - strikes[3]) / 1.2, 0.999)
    assert np.max(np.abs(phase_error(time_phase, ref[m]))) > 0.15


def test_portrait_phase_is_causal_and_checks_its_input():
    """The phase at a sample is unchanged when later samples and strikes are cut off."""
    t, angle, strikes, _ = _sinusoid_walk([1.2, 1.1, 1.3, 1.2, 1.4, 1.2])
    full = portrait_phase(t, angle, strikes)
    cut = 4.3
    m = t < cut
    part = portrait_phase(t[m], angle[m], strikes[strikes < cut])
    np.testing.assert_array_equal(part, full[m])
    with pytest.raises(GaitInputError):
        portrait_phase(t, angle[:-1], strikes)
