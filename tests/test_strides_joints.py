"""JointBuffer: causal encoder buffer, one interpolation, rejections counted by reason."""

from __future__ import annotations

import numpy as np

from graph_slam.strides.joints import JointBuffer, interp_q


def test_interp_q_is_linear_inside_and_none_outside():
    t = np.array([0.0, 0.1, 0.3])
    q = np.array([[0.0, 1.0], [1.0, 0.0], [3.0, 2.0]])
    np.testing.assert_allclose(interp_q(0.05, t, q), [0.5, 0.5])
    np.testing.assert_allclose(interp_q(0.2, t, q), [2.0, 1.0])
    np.testing.assert_allclose(interp_q(0.3, t, q), [3.0, 2.0])
    assert interp_q(-1e-6, t, q) is None
    assert interp_q(0.30001, t, q) is None
    assert interp_q(0.0, np.empty(0), np.empty((0, 2))) is None


def test_buffer_rejects_nonfinite_and_non_monotonic_across_chunks():
    buf = JointBuffer()
    assert buf.q_at(0.0) is None
    assert buf.add([0.0, 0.01, 0.02], [0.1, np.nan, 0.3], [0.0, 0.0, 0.0]) == 2
    # 0.02 repeats the last accepted time (previous chunk), 0.015 goes back in time
    assert buf.add([0.02, 0.015, 0.03, np.inf], [9.0, 9.0, 0.5, 0.0], [0, 0, 0, 0]) == 1
    assert buf.counts == {
        "used": 3,
        "nonfinite": 2,
        "non_monotonic": 2,
        "out_of_limits": 0,
        "jump": 0,
    }
    np.testing.assert_allclose(buf.t_s, [0.0, 0.02, 0.03])
    np.testing.assert_allclose(buf.q_at(0.025), [0.4, 0.0])  # the rejected 9.0 is never used
    assert buf.q_at(0.031) is None


def test_buffer_with_a_leg_model_applies_the_encoder_rules():
    from kinematics.leg_model import LegModel

    model = LegModel()
    lo, hi = model.lower_limits_rad, model.upper_limits_rad
    vmax = model.velocity_limits_rad_s
    buf = JointBuffer(model)
    t = np.arange(5) * 0.01
    knee = np.full(5, 0.5)
    knee[2] = hi[0] + 0.1  # out of limits
    assert buf.add(t, knee, np.zeros(5)) == 4
    # a jump right at the chunk boundary: faster than the knee's velocity limit
    step = vmax[0] * 0.01 + 0.2
    assert buf.add([0.05, 0.06], [0.5 + step, 0.5], [0.0, 0.0]) == 1
    assert buf.counts["out_of_limits"] == 1
    assert buf.counts["jump"] == 1
    assert buf.counts["used"] == 5
    np.testing.assert_allclose(buf.q_at(0.055), [0.5, 0.0])
    assert lo[1] <= 0.0 <= hi[1]


def test_q_at_reads_no_sample_beyond_the_first_after_t():
    """Online, a frame at t waits for the first encoder sample at or after t; q_at(t) is the
    same whether later samples have arrived or not, and None before that sample arrives."""
    t = np.arange(0.0, 0.12, 0.002)
    q = np.column_stack([0.3 + 2.0 * t**2, -0.1 - 0.5 * t])
    full = JointBuffer()
    full.add(t, q[:, 0], q[:, 1])
    for t_s in (0.0305, 0.05, 0.0981):
        k = np.searchsorted(t, t_s, side="left") + 1
        part = JointBuffer()
        part.add(t[:k], q[:k, 0], q[:k, 1])
        np.testing.assert_array_equal(part.q_at(t_s), full.q_at(t_s))
        early = JointBuffer()
        early.add(t[: k - 1], q[: k - 1, 0], q[: k - 1, 1])
        assert t_s == t[k - 1] or early.q_at(t_s) is None
    full.drop_before(0.05)
    np.testing.assert_array_equal(full.q_at(0.0501), JointBuffer.q_at(full, 0.0501))
    assert full.t_s[0] <= 0.05 < full.t_s[1]
