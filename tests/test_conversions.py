"""Pose conversions between 4x4 arrays, pinocchio.SE3 and gtsam.Pose3; twist ordering."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinematics import conversions as cv
from kinematics.errors import KinematicsError


def random_pose(rng: np.random.Generator) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    m[:3, 3] = rng.normal(size=3)
    return m


def test_round_trips_all_types() -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        m = random_pose(rng)
        se3 = cv.matrix4_to_se3(m)
        pose3 = cv.matrix4_to_pose3(m)
        np.testing.assert_allclose(cv.se3_to_matrix4(se3), m, atol=1e-12)
        np.testing.assert_allclose(cv.pose3_to_matrix4(pose3), m, atol=1e-12)
        np.testing.assert_allclose(cv.as_matrix4(cv.se3_to_pose3(se3)), m, atol=1e-12)
        np.testing.assert_allclose(cv.as_matrix4(cv.pose3_to_se3(pose3)), m, atol=1e-12)


def test_composition_agrees_between_libraries() -> None:
    rng = np.random.default_rng(2)
    a, b = random_pose(rng), random_pose(rng)
    by_pin = cv.se3_to_matrix4(cv.matrix4_to_se3(a) * cv.matrix4_to_se3(b))
    by_gtsam = cv.pose3_to_matrix4(cv.matrix4_to_pose3(a).compose(cv.matrix4_to_pose3(b)))
    np.testing.assert_allclose(by_pin, a @ b, atol=1e-12)
    np.testing.assert_allclose(by_gtsam, a @ b, atol=1e-12)
    # transformFrom maps points from b to a (a_T_b convention)
    p = rng.normal(size=3)
    np.testing.assert_allclose(cv.matrix4_to_pose3(a).transformFrom(p), a[:3, :3] @ p + a[:3, 3])


def test_twist_order_and_exp_log_match_gtsam_and_pinocchio() -> None:
    import gtsam
    import pinocchio as pin

    xi = np.array([0.1, -0.2, 0.3, 0.5, -0.4, 0.2])  # [w; v]
    m = cv.expmap_rot_first(xi)
    np.testing.assert_allclose(m, gtsam.Pose3.Expmap(xi).matrix(), atol=1e-12)
    np.testing.assert_allclose(
        m, pin.exp6(pin.Motion(cv.swap_twist_order(xi))).homogeneous, atol=1e-12
    )
    np.testing.assert_allclose(cv.logmap_rot_first(m), xi, atol=1e-12)
    np.testing.assert_allclose(cv.swap_twist_order(cv.swap_twist_order(xi)), xi)
    cov = np.diag(np.arange(1.0, 7.0))
    np.testing.assert_allclose(np.diag(cv.swap_twist_order(cov)), [4, 5, 6, 1, 2, 3])


def test_adjoint_matches_gtsam() -> None:

    rng = np.random.default_rng(3)
    m = random_pose(rng)
    np.testing.assert_allclose(
        cv.adjoint_rot_first(m), cv.matrix4_to_pose3(m).AdjointMap(), atol=1e-12
    )


def test_bad_matrices_rejected() -> None:
    with pytest.raises(KinematicsError, match="4x4"):
        cv.matrix4_to_pose3(np.eye(3))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(KinematicsError, match="not a rotation"):
        cv.matrix4_to_se3(bad)
    nan = np.eye(4)
    nan[0, 3] = np.nan
    with pytest.raises(KinematicsError, match="NaN"):
        cv.as_matrix4(nan)
