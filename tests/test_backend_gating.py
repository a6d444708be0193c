"""RegistrationGate: ICP measurement -> factor or a recorded rejection, on hand-made frames."""

from __future__ import annotations

import gtsam
import numpy as np

from graph_slam.backend import BackendConfig
from graph_slam.backend.gating import make_registration_gate
from graph_slam.backend.keys import X
from graph_slam.backend.measurements import IcpMeasurement


def icp(source, target, fitness=0.9, step_m=0.01):
    t = np.eye(4)
    t[0, 3] = step_m
    return IcpMeasurement(source, target, t, np.diag([1e4] * 3 + [1e6] * 3), fitness, 0.002, 5000)


def test_gate_accepts_a_good_registration_into_an_icp_factor():
    gate = make_registration_gate(BackendConfig(), np.eye(4))
    gate.start_stride()
    gate.add_frame(10, 0)
    gate.add_frame(11, 1)
    decision, f = gate.factor(icp(12, 10), 12, 2)
    assert decision.accepted and decision.reason == "ok"
    assert isinstance(f, gtsam.BetweenFactorPose3)
    assert list(f.keys()) == [X(0), X(2)]  # target frame 10 is state 0, this frame state 2
    np.testing.assert_allclose(f.measured().translation(), [0.01, 0.0, 0.0], atol=1e-12)


def test_gate_rejects_with_the_reason():
    gate = make_registration_gate(BackendConfig(), np.eye(4))
    gate.add_frame(3, 0)
    cases = {
        "source_index 4 is not this frame (5)": icp(4, 3),
        "target frame not in this stride": icp(5, 2),
        "low_fitness": icp(5, 3, fitness=0.1),
        "implausible_step": icp(5, 3, step_m=0.5),
    }
    for reason, meas in cases.items():
        decision, f = gate.factor(meas, 5, 1)
        assert not decision.accepted and decision.reason.startswith(reason), decision.reason
        assert f is None
    gate.start_stride()  # a new stride: earlier frames are no targets
    decision, _ = gate.factor(icp(5, 3), 5, 1)
    assert decision.reason == "target frame not in this stride"


def test_a_frames_record_keeps_the_verdict_without_the_matrices():
    """What a long run keeps per frame: the verdict, rank and dropped directions; the 6×6
    information and its square root stay with the factor only."""
    gate = make_registration_gate(BackendConfig(), np.eye(4))
    gate.start_stride()
    gate.add_frame(10, 0)
    decision, _ = gate.factor(icp(11, 10), 11, 1)
    assert decision.information is not None and decision.sqrt_information is not None
    kept = decision.record()
    assert (kept.accepted, kept.reason, kept.rank) == (decision.accepted, decision.reason, 6)
    assert kept.information is None and kept.sqrt_information is None
    assert decision.information is not None  # the decision itself is unchanged
