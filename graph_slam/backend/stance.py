"""Stance factors: what the loaded foot says about the IMU pose, gated against the prediction.

Two strategies, chosen by :func:`make_stance_model` from ``kinematics.stance_model``:

* :class:`ContactPointStance` (``contact_points``, needs a leg model): the foot rolls over its
  heel, lies flat, then rolls over its toe, so a *point* stays put, not the foot's
  orientation. Heel at the stride origin until heel-off, toe at its foot-flat position
  (level ground) while the foot is not pitched toe-up; each a 3-D contact-point factor. The
  foot pitch (against the ground's slope under the foot, given at the strike; 0: level)
  comes from the predicted IMU orientation and the encoders: below
  ``-contact_pitch_rad`` the heel has lifted, for the rest of the stride (the state machine:
  :attr:`ContactPointStance.heel_off`). A point farther than ``max_mahalanobis`` from the
  prediction (its σ combined with the predicted covariance) is not added
  (``kin_inconsistent:heel|toe``); no point down: ``no_contact``.
* :class:`FootPoseStance` (``foot_pose``): the camera pose ``stride_T_foot(strike) ·
  foot_T_camera(q)`` as a prior, gated by its own sigmas (``kin_inconsistent``).

A caller-given :class:`~graph_slam.backend.measurements.KinematicMeasurement` always takes
the ``foot_pose`` path. In a stride started by a missed foot strike (``missed_foot_strike``:
the foothold is unknown) no stance factor is added (``kin_unanchored``); a foot strike without
an anchor (flag ``no_anchor``) is not refused this way, only by the Mahalanobis gate
(docs/backend.md, "Known quirk"). Without any measurement: ``no_kinematics``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig, KinematicFactorConfig
from graph_slam.backend.measurements import KinematicMeasurement

log = logging.getLogger(__name__)

Tagged = list[tuple[str, object]]


class FootPoseStance:
    """``foot_pose`` stance factors (module docstring); ``leg`` may be None (caller-given
    measurements only)."""

    def __init__(self, cfg: KinematicFactorConfig, leg, camera_T_imu: np.ndarray):
        self.cfg = cfg
        self.leg = leg
        self.camera_T_imu = np.asarray(camera_T_imu, float)

    def start_stride(self, contact_slope_rad: float = 0.0) -> None:
        """Nothing per stride: the struck foot is the leg kinematics' last anchor."""

    def factors(
        self,
        t_s: float,
        k: int,
        pred: gtsam.Pose3,
        pred_cov: Callable[[], np.ndarray | None],
        anchored: bool,
        kinematics: KinematicMeasurement | None = None,
    ) -> tuple[Tagged, list[str]]:
        """Stance factor on ``X(k)`` and the frame's flags."""
        if kinematics is None and self.leg is not None:
            kinematics = self.leg.foot_pose(t_s)
        if kinematics is None:
            return [], ["no_kinematics"]
        if not anchored:
            return [], ["kin_unanchored"]  # the foothold of this stride is unknown
        d = self.mahalanobis(kinematics, pred)
        if d > self.cfg.max_mahalanobis:
            log.info("t=%.3f s: stance factor %.1f sigmas off: not added", t_s, d)
            return [], ["kin_inconsistent"]
        f = factors.kinematic_prior_factor(
            k,
            kinematics.stride_T_camera,
            kinematics.covariance * self.cfg.sigma_scale**2,
            self.camera_T_imu,
            self.cfg.robust_kernel,
            self.cfg.robust_k,
        )
        return [("kin", f)], []

    def mahalanobis(self, kin: KinematicMeasurement, stride_T_imu_pred: gtsam.Pose3) -> float:
        """Distance (in sigmas of the measurement) of a stance measurement from the prediction."""
        pred_camera = gtsam.Pose3(stride_T_imu_pred.matrix() @ np.linalg.inv(self.camera_T_imu))
        e = gtsam.Pose3.Logmap(gtsam.Pose3(kin.stride_T_camera).between(pred_camera))
        cov = kin.covariance * self.cfg.sigma_scale**2
        return float(np.sqrt(e @ np.linalg.solve(cov, e)))


class ContactPointStance:
    """``contact_points`` stance factors with the heel-off state machine (module docstring).
    A caller-given measurement goes to ``measured`` (a :class:`FootPoseStance`)."""

    def __init__(self, cfg: KinematicFactorConfig, leg, measured: FootPoseStance):
        self.cfg = cfg
        self.leg = leg
        self.measured = measured
        self.heel_off = False
        self.slope_rad = 0.0

    def start_stride(self, contact_slope_rad: float = 0.0) -> None:
        """A new stance on ground pitched ``contact_slope_rad`` along the heading (+ up)."""
        self.heel_off = False
        self.slope_rad = float(contact_slope_rad)

    def factors(
        self,
        t_s: float,
        k: int,
        pred: gtsam.Pose3,
        pred_cov: Callable[[], np.ndarray | None],
        anchored: bool,
        kinematics: KinematicMeasurement | None = None,
    ) -> tuple[Tagged, list[str]]:
        """Contact-point factors on ``X(k)`` and the frame's flags."""
        if kinematics is not None:
            return self.measured.factors(t_s, k, pred, pred_cov, anchored, kinematics)
        if not anchored:
            return [], ["kin_unanchored"]
        cov_pred = pred_cov()  # before anything else: iSAM2 caches marginals, keep its calls
        geometry = self.leg.contact_geometry(t_s)
        if geometry is None:
            return [], ["no_kinematics"]
        points = self.points_down(pred.rotation().matrix(), geometry)
        if not points:
            return [], ["no_contact"]
        tagged, flags = [], []
        for name, imu_p, stride_p in points:
            if self.distance(pred.matrix(), imu_p, stride_p, cov_pred) > self.cfg.max_mahalanobis:
                flags.append(f"kin_inconsistent:{name}")
                continue
            f = factors.contact_point_factor(
                k,
                imu_p,
                stride_p,
                self.cfg.contact_sigma_m,
                self.cfg.robust_kernel,
                self.cfg.robust_k,
            )
            tagged.append(("kin", f))
        return tagged, flags

    def points_down(
        self, stride_R_imu: np.ndarray, geometry
    ) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """``(name, imu_p_point, stride_p_point)`` of the points on the ground, from the foot
        pitch ``stride_R_imu · imu_R_foot``; updates :attr:`heel_off`."""
        imu_T_foot = geometry.imu_T_foot
        x = (stride_R_imu @ imu_T_foot[:3, :3])[:, 0]
        pitch = float(np.arctan2(x[2], np.hypot(x[0], x[1]))) - self.slope_rad  # vs the ground
        if pitch < -self.cfg.contact_pitch_rad:
            self.heel_off = True
        points = []
        if not self.heel_off:
            points.append(("heel", imu_T_foot[:3, 3], np.zeros(3)))
        if pitch < self.cfg.contact_pitch_rad:
            toe = imu_T_foot[:3, :3] @ geometry.foot_p_toe + imu_T_foot[:3, 3]
            c, s = np.cos(self.slope_rad), np.sin(self.slope_rad)  # the foot flat on the slope
            ground_R_foot = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
            points.append(("toe", toe, ground_R_foot @ geometry.foot_p_toe))
        return points

    def distance(self, stride_T_imu, imu_p, stride_p, cov_pred: np.ndarray | None) -> float:
        """Mahalanobis distance of a contact point from the prediction (σ ``contact_sigma_m``
        combined with the predicted pose covariance when known)."""
        err, h = factors.contact_point_residual(stride_T_imu, imu_p, stride_p)
        cov = np.eye(3) * self.cfg.contact_sigma_m**2
        if cov_pred is not None:
            cov = cov + h @ cov_pred @ h.T
        return float(np.sqrt(err @ np.linalg.solve(cov, err)))


def make_stance_model(config: BackendConfig, leg, camera_T_imu: np.ndarray):
    """The stance strategy: ``contact_points`` when configured and a leg model exists, else
    ``foot_pose`` (which also serves caller-given measurements)."""
    measured = FootPoseStance(config.kinematics, leg, camera_T_imu)
    has_model = leg is not None and leg.model is not None
    if config.kinematics.stance_model == "contact_points" and has_model:
        return ContactPointStance(config.kinematics, leg, measured)
    return measured
