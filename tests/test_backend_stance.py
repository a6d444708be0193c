"""Stance models on hand-made foot geometry: the contact points' heel-off state machine, the
Mahalanobis gate against the prediction, the foot-pose path, the strategy factory."""

from __future__ import annotations

import gtsam
import numpy as np

from graph_slam.backend import BackendConfig, KinematicMeasurement
from graph_slam.backend.stance import ContactPointStance, FootPoseStance, make_stance_model
from graph_slam.strides.kinematics import ContactGeometry

TOE = np.array([0.2, 0.0, 0.0])


class FakeLeg:
    """The foot frame is the IMU frame; the toe 20 cm ahead of the heel."""

    model = object()

    def __init__(self):
        self.geometry = ContactGeometry(np.eye(4), TOE)

    def contact_geometry(self, t_s):
        return self.geometry

    def foot_pose(self, t_s):
        return None


def pitched(pitch_rad: float, pivot: np.ndarray) -> gtsam.Pose3:
    """IMU (= foot) pose pitched toe-up by ``pitch_rad`` about the foot point ``pivot``."""
    rot = gtsam.Rot3.Ry(-pitch_rad)
    return gtsam.Pose3(rot, pivot - rot.matrix() @ pivot)


def names(stance, pose, anchored=True):
    tagged, flags = stance.factors(0.0, 1, pose, lambda: None, anchored)
    return len(tagged), flags


def test_contact_points_heel_off_state_machine():
    stance = make_stance_model(BackendConfig(), FakeLeg(), np.eye(4))
    assert isinstance(stance, ContactPointStance)
    assert names(stance, pitched(0.0, np.zeros(3))) == (2, [])  # foot flat: heel and toe
    assert names(stance, pitched(0.1, np.zeros(3))) == (1, [])  # toe up: heel only
    assert not stance.heel_off
    assert names(stance, pitched(-0.1, TOE)) == (1, [])  # toe down: the heel has lifted
    assert stance.heel_off
    assert names(stance, pitched(0.0, np.zeros(3))) == (1, [])  # for the rest of the stride
    assert names(stance, pitched(0.1, np.zeros(3))) == (0, ["no_contact"])
    stance.start_stride()
    assert not stance.heel_off
    assert names(stance, pitched(0.0, np.zeros(3))) == (2, [])


def test_contact_points_gate_and_unanchored():
    stance = make_stance_model(BackendConfig(), FakeLeg(), np.eye(4))
    far = gtsam.Pose3(gtsam.Rot3(), np.array([0.5, 0.0, 0.0]))  # 50 σ of 1 cm
    assert names(stance, far) == (0, ["kin_inconsistent:heel", "kin_inconsistent:toe"])
    # the predicted covariance widens the gate: 0.5 m within 10 σ of a 10 cm prediction
    tagged, flags = stance.factors(0.0, 1, far, lambda: np.eye(6) * 0.1**2, True)
    assert len(tagged) == 2 and flags == []
    assert names(stance, far, anchored=False) == (0, ["kin_unanchored"])
    leg = FakeLeg()
    leg.geometry = None
    assert names(make_stance_model(BackendConfig(), leg, np.eye(4)), far) == (0, ["no_kinematics"])


def test_foot_pose_stance_with_a_measurement():
    cfg = BackendConfig(kinematics={"stance_model": "foot_pose"})
    stance = make_stance_model(cfg, FakeLeg(), np.eye(4))
    assert isinstance(stance, FootPoseStance)
    cov = np.diag([1e-4] * 3 + [1e-4] * 3)  # 0.6°, 1 cm
    meas = KinematicMeasurement(np.eye(4), cov)
    near = gtsam.Pose3(gtsam.Rot3(), np.array([0.02, 0.0, 0.0]))
    far = gtsam.Pose3(gtsam.Rot3(), np.array([0.2, 0.0, 0.0]))
    assert np.isclose(stance.mahalanobis(meas, near), 2.0)
    tagged, flags = stance.factors(0.0, 3, near, lambda: None, True, meas)
    assert [t for t, _ in tagged] == ["kin"] and flags == []
    assert stance.factors(0.0, 3, far, lambda: None, True, meas) == ([], ["kin_inconsistent"])
    assert stance.factors(0.0, 3, near, lambda: None, False, meas) == ([], ["kin_unanchored"])
    assert stance.factors(0.0, 3, near, lambda: None, True) == ([], ["no_kinematics"])
    # contact_points hands a caller-given measurement to the foot-pose path
    contact = make_stance_model(BackendConfig(), FakeLeg(), np.eye(4))
    tagged, _ = contact.factors(0.0, 3, near, lambda: None, True, meas)
    assert isinstance(tagged[0][1], gtsam.PriorFactorPose3)
