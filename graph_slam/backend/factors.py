"""Factor builders. Variables are IMU poses ``stride_T_imu`` (see :mod:`.imu`); camera
measurements are carried into the IMU frame *exactly* by the fixed extrinsic ``camera_T_imu``:

* a camera pose ``stride_T_camera`` with covariance ``Σc`` (camera local coordinates) becomes
  ``stride_T_imu = stride_T_camera · camera_T_imu`` with ``Σi = Ad(imu_T_camera) Σc Ad(...)ᵀ``;
* a relative camera motion ``cam_i_T_cam_j`` with square-root information ``Rc`` becomes
  ``imu_i_T_imu_j = imu_T_camera · cam_i_T_cam_j · camera_T_imu`` with ``Ri = Rc · Ad(camera_T_imu)``.

Both are GTSAM's own ``PriorFactorPose3``/``BetweenFactorPose3`` (so their Jacobians are
GTSAM's); ``tests/test_backend_factors.py`` checks the whitened errors and Jacobians against
numerical derivatives of the camera-frame definitions.
"""

from __future__ import annotations

import functools

import gtsam
import numpy as np

from graph_slam.backend import noise
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.noise import RobustKernel
from kinematics.conversions import adjoint_rot_first


def fixed_transforms(camera_T_imu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(imu_T_camera, adjoint_rot_first(camera_T_imu))`` of the fixed extrinsic, computed once
    per distinct matrix (read-only arrays: the same numbers as computing them per frame)."""
    m = np.ascontiguousarray(camera_T_imu, dtype=float)
    return _fixed_transforms(m.tobytes())


@functools.lru_cache(maxsize=8)
def _fixed_transforms(key: bytes) -> tuple[np.ndarray, np.ndarray]:
    m = np.frombuffer(key, dtype=float).reshape(4, 4).copy()
    inverse, ad = np.linalg.inv(m), adjoint_rot_first(m)
    inverse.flags.writeable = False
    ad.flags.writeable = False
    return inverse, ad


def camera_pose_to_imu(
    stride_T_camera: np.ndarray, cov_camera: np.ndarray, camera_T_imu: np.ndarray
) -> tuple[gtsam.Pose3, np.ndarray]:
    """The IMU pose and its covariance (IMU local coordinates) from a camera pose."""
    stride_T_imu = gtsam.Pose3(np.asarray(stride_T_camera, float) @ camera_T_imu)
    ad = adjoint_rot_first(np.linalg.inv(camera_T_imu))
    return stride_T_imu, ad @ cov_camera @ ad.T


def imu_cov_to_camera(cov_imu: np.ndarray, camera_T_imu: np.ndarray) -> np.ndarray:
    """Covariance of ``stride_T_imu`` (IMU local) → of ``stride_T_camera`` (camera local)."""
    ad = adjoint_rot_first(camera_T_imu)
    return ad @ cov_imu @ ad.T


def kinematic_prior_factor(
    k: int,
    stride_T_camera: np.ndarray,
    cov_camera: np.ndarray,
    camera_T_imu: np.ndarray,
    kernel: RobustKernel = "none",
    robust_k: float = 2.0,
) -> gtsam.PriorFactorPose3:
    """Leg-kinematic factor on ``X(k)``: the camera pose in the stride frame from FK."""
    mean, cov = camera_pose_to_imu(stride_T_camera, cov_camera, camera_T_imu)
    return gtsam.PriorFactorPose3(X(k), mean, noise.robust(noise.covariance(cov), kernel, robust_k))


def contact_point_residual(
    stride_T_imu: np.ndarray, imu_p_point: np.ndarray, stride_p_point: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Residual ``R·p_imu + t − p_stride`` (m) of a contact point and its 3×6 Jacobian with
    respect to the IMU pose (right perturbation, rotation first): ``[−R·[p]×, R]``."""
    rot = np.asarray(stride_T_imu, float)[:3, :3]
    p = np.asarray(imu_p_point, float)
    err = rot @ p + np.asarray(stride_T_imu, float)[:3, 3] - np.asarray(stride_p_point, float)
    skew = np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])
    return err, np.hstack([-rot @ skew, rot])


def contact_point_factor(
    k: int,
    imu_p_point: np.ndarray,
    stride_p_point: np.ndarray,
    sigma_m: float,
    kernel: RobustKernel = "huber",
    robust_k: float = 2.0,
) -> gtsam.CustomFactor:
    """Stance factor on ``X(k)``: a point of the foot in contact (heel or toe, given in the IMU
    frame by FK of the encoders) is at ``stride_p_point``. Constrains 3 of the 6 pose
    directions: the foot may pivot about the point (heel rocker, toe rocker)."""
    imu_p = np.asarray(imu_p_point, float).copy()
    stride_p = np.asarray(stride_p_point, float).copy()
    skew = np.array(
        [[0.0, -imu_p[2], imu_p[1]], [imu_p[2], 0.0, -imu_p[0]], [-imu_p[1], imu_p[0], 0.0]]
    )

    # GTSAM calls this at every relinearisation: contact_point_residual without its checks
    # and allocations (more than half of the time of linearising a stride at its close)
    def error(this: gtsam.CustomFactor, values: gtsam.Values, jac: list | None):
        pose = values.atPose3(this.keys()[0])
        rot = pose.rotation().matrix()
        if jac is not None:
            h = np.empty((3, 6))
            h[:, :3] = -rot @ skew
            h[:, 3:] = rot
            jac[0] = h
        return rot @ imu_p + pose.translation() - stride_p

    model = noise.robust(noise.vector_sigmas(sigma_m), kernel, robust_k)
    return gtsam.CustomFactor(model, [X(k)], error)


def icp_between_factor(
    k_target: int,
    k_source: int,
    target_T_source: np.ndarray,
    sqrt_info_camera: np.ndarray,
    camera_T_imu: np.ndarray,
    kernel: RobustKernel = "huber",
    robust_k: float = 1.5,
) -> gtsam.BetweenFactorPose3:
    """ICP odometry factor between ``X(k_target)`` and ``X(k_source)``.

    ``sqrt_info_camera`` may have zero rows (degenerate directions carry no information).
    """
    imu_T_camera, ad = fixed_transforms(camera_T_imu)
    meas = gtsam.Pose3(imu_T_camera @ np.asarray(target_T_source, float) @ camera_T_imu)
    r_imu = np.asarray(sqrt_info_camera, float) @ ad
    model = noise.robust(noise.sqrt_information(r_imu), kernel, robust_k)
    return gtsam.BetweenFactorPose3(X(k_target), X(k_source), meas, model)


def imu_factor(i: int, j: int, pim: gtsam.PreintegratedCombinedMeasurements):
    """``CombinedImuFactor`` between frames ``i`` and ``j`` (pose, velocity and bias)."""
    return gtsam.CombinedImuFactor(X(i), V(i), X(j), V(j), B(i), B(j), pim)


def gap_bridge_factors(
    i: int,
    j: int,
    dt_s: float,
    velocity_body_m_s: np.ndarray,
    rot_sigma_rad: float,
    trans_sigma_m: float,
    gravity_m_s2: float,
    accel_rw: float,
    gyro_rw: float,
) -> list:
    """Weak constant-velocity links for an interval without usable IMU samples.

    They keep the graph well-posed (a pose, a velocity and a bias between-factor) with
    deliberately large uncertainty: they are not a measurement.
    """
    pose_delta = gtsam.Pose3(gtsam.Rot3(), np.asarray(velocity_body_m_s, float) * dt_s)
    dt = max(dt_s, 1e-3)
    return [
        gtsam.BetweenFactorPose3(
            X(i), X(j), pose_delta, noise.pose_sigmas(rot_sigma_rad, trans_sigma_m)
        ),
        gtsam.BetweenFactorVector(
            V(i), V(j), np.zeros(3), noise.vector_sigmas(gravity_m_s2 * dt + 0.1)
        ),
        gtsam.BetweenFactorConstantBias(
            B(i),
            B(j),
            gtsam.imuBias.ConstantBias(),
            noise.bias_sigmas(accel_rw * np.sqrt(dt) + 1e-3, gyro_rw * np.sqrt(dt) + 1e-4),
        ),
    ]


def pose_prior(k: int, stride_T_imu: gtsam.Pose3, cov: np.ndarray) -> gtsam.PriorFactorPose3:
    return gtsam.PriorFactorPose3(X(k), stride_T_imu, noise.covariance(cov))


def velocity_prior(k: int, v_m_s: np.ndarray, cov: np.ndarray) -> gtsam.PriorFactorVector:
    return gtsam.PriorFactorVector(V(k), np.asarray(v_m_s, float), noise.covariance(cov))


def bias_prior(
    k: int, bias: gtsam.imuBias.ConstantBias, cov: np.ndarray
) -> gtsam.PriorFactorConstantBias:
    return gtsam.PriorFactorConstantBias(B(k), bias, noise.covariance(cov))
