"""``LegModel``: forward kinematics, Jacobians and camera-pose covariance on Pinocchio.

Joint vector ``q = [knee, ankle]`` (rad): knee flexion +, ankle dorsiflexion +. The thigh is
the root of the model, so every pose here is relative (``foot_T_camera``, ``foot_T_imu``) and
does not depend on how the thigh is oriented in the world.

Twist and Jacobian convention (matches GTSAM ``Pose3`` local coordinates):

* 6-vectors are ordered **[rotation; translation]** (ω then v);
* Jacobians are **right (body) perturbations**: for a small joint change δq,
  ``a_T_b(q + δq) ≈ a_T_b(q) · Exp(J δq)``, i.e. the twist is expressed in the *child*
  frame b (the camera for ``foot_T_camera``). This is what a GTSAM factor on the camera pose
  linearises with. ``perturbation="left"`` gives ``Exp(J δq) · a_T_b(q)`` instead (twist in
  frame a); the two are related by the adjoint, ``J_left = Ad(a_T_b) J_right``.
* Covariances are 6x6 in the same tangent space, so they can be passed straight to
  ``gtsam.noiseModel.Gaussian.Covariance`` for a prior on the camera ``Pose3``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from kinematics.conversions import adjoint_rot_first, swap_twist_order
from kinematics.errors import EncoderError, LegModelError
from kinematics.leg_params import JOINT_NAMES, LegParams, leg_urdf

logger = logging.getLogger(__name__)

REQUIRED_FRAMES: tuple[str, ...] = ("thigh", "camera_optical", "imu", "heel", "toe")
FOOT_FRAME = "heel"
"""The URDF frame that is the conventions' "foot" frame (heel contact point, sole axes)."""

Contact = Literal["heel_strike", "foot_flat"]
Perturbation = Literal["right", "left"]


@dataclass(frozen=True)
class ContactNoise:
    """Uncertainty (1 sigma) of the foot's pose on the ground, per contact type.

    Expressed in the foot (heel) frame, rotation first: roll, pitch, yaw (rad) then x, y, z
    (m). At heel strike only the heel touches: the foot may still rotate about the heel
    (large pitch), and the contact point on the rounded heel is uncertain along the sole.
    With the foot flat, the sole fixes roll and pitch to the ground's.
    """

    heel_strike: tuple[float, float, float, float, float, float] = (
        np.radians(2.0),
        np.radians(5.0),
        np.radians(2.0),
        0.010,
        0.005,
        0.003,
    )
    foot_flat: tuple[float, float, float, float, float, float] = (
        np.radians(1.0),
        np.radians(1.0),
        np.radians(1.0),
        0.004,
        0.004,
        0.002,
    )

    def covariance(self, contact: Contact) -> np.ndarray:
        """6x6 diagonal covariance of the foot pose for ``contact``."""
        if contact not in ("heel_strike", "foot_flat"):
            raise LegModelError(f"contact={contact!r}: must be 'heel_strike' or 'foot_flat'")
        sigmas = np.asarray(getattr(self, contact), dtype=float)
        if sigmas.shape != (6,) or not np.all(np.isfinite(sigmas)) or np.any(sigmas < 0):
            raise LegModelError(f"ContactNoise.{contact}: need 6 finite sigmas >= 0")
        return np.diag(sigmas**2)


class LegModel:
    """Kinematics of the prosthetic leg from its URDF (generated from :class:`LegParams`).

    Build with ``LegModel()`` (defaults), ``LegModel(LegParams(mount_pitch_down_rad=0.7))``,
    or ``LegModel.from_urdf(path)`` for a hand-written URDF with the same joint and frame
    names (``knee``, ``ankle``; frames thigh, camera_optical, imu, heel, toe).
    """

    def __init__(
        self,
        params: LegParams | None = None,
        *,
        urdf_xml: str | None = None,
        source: str = "<generated>",
    ) -> None:
        import pinocchio as pin

        self.params = params if urdf_xml is None else None
        self.urdf_xml = urdf_xml if urdf_xml is not None else leg_urdf(params or LegParams())
        self.source = source
        try:
            self.model = pin.buildModelFromXML(self.urdf_xml)
        except (RuntimeError, ValueError) as err:
            raise LegModelError(f"{source}: Pinocchio cannot parse the URDF ({err})") from None
        names = tuple(self.model.names[1:])
        self._joint_names = names  # pinocchio's names list costs ~40 µs a read
        if names != JOINT_NAMES or self.model.nq != 2 or self.model.nv != 2:
            raise LegModelError(
                f"{source}: the leg URDF must have exactly the revolute joints {list(JOINT_NAMES)} "
                f"(in this order); it has {list(names)} (nq={self.model.nq})"
            )
        self._frame_ids: dict[str, int] = {}
        for frame in REQUIRED_FRAMES:
            if not self.model.existFrame(frame, pin.BODY):
                raise LegModelError(f"{source}: the URDF lacks the link/frame {frame!r}")
            self._frame_ids[frame] = self.model.getFrameId(frame, pin.BODY)
        self.data = self.model.createData()
        self.lower_limits_rad = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper_limits_rad = np.array(self.model.upperPositionLimit, dtype=float)
        self.velocity_limits_rad_s = np.array(self.model.velocityLimit, dtype=float)

    @classmethod
    def from_urdf(cls, path: str | Path) -> LegModel:
        """Load a URDF file (e.g. the shipped ``urdf/transfemoral_leg.urdf``)."""
        path = Path(path)
        try:
            xml = path.read_text(encoding="utf-8")
        except OSError as err:
            raise LegModelError(f"{path}: cannot read URDF ({err.strerror})") from None
        return cls(urdf_xml=xml, source=str(path))

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in the order of q."""
        return self._joint_names

    def channel_order(self, channel_names: Sequence[str]) -> np.ndarray:
        """Indices that take encoder channels (in ``channel_names`` order) to q order.

        Raises :class:`LegModelError` listing both sets when they do not match one-to-one.
        """
        channels = list(channel_names)
        joints = list(self.joint_names)
        if sorted(channels) != sorted(joints) or len(set(channels)) != len(channels):
            raise LegModelError(
                f"encoder channels {channels} do not match the URDF joints {joints} "
                f"({self.source}); missing: {sorted(set(joints) - set(channels))}, "
                f"unexpected: {sorted(set(channels) - set(joints))}"
            )
        return np.array([channels.index(j) for j in joints])

    # --- forward kinematics ------------------------------------------------------------
    def check_q(self, q: Sequence[float] | np.ndarray, check_limits: bool = True) -> np.ndarray:
        """Validate a joint vector: shape (2,), finite, within the URDF limits."""
        q_arr = np.asarray(q, dtype=float)
        if q_arr.shape != (2,):
            raise EncoderError(f"q must be [knee, ankle] (shape (2,)), got shape {q_arr.shape}")
        if not np.all(np.isfinite(q_arr)):
            raise EncoderError(f"q={q_arr.tolist()} contains NaN or inf")
        if check_limits:
            bad = (q_arr < self.lower_limits_rad - 1e-12) | (q_arr > self.upper_limits_rad + 1e-12)
            if np.any(bad):
                j = int(np.flatnonzero(bad)[0])
                raise EncoderError(
                    f"joint {self.joint_names[j]!r} = {q_arr[j]:.4f} rad is outside its URDF "
                    f"limits [{self.lower_limits_rad[j]:.4f}, {self.upper_limits_rad[j]:.4f}]"
                )
        return q_arr

    def _placements(self, q: np.ndarray) -> None:
        import pinocchio as pin

        pin.framesForwardKinematics(self.model, self.data, q)

    def frame_T_frame(
        self, a: str, b: str, q: Sequence[float] | np.ndarray, check_limits: bool = True
    ) -> np.ndarray:
        """``a_T_b`` (4x4) between two URDF frames at joint angles ``q``."""
        q_arr = self.check_q(q, check_limits)
        ia, ib = self._frame_id(a), self._frame_id(b)
        self._placements(q_arr)
        return np.array((self.data.oMf[ia].inverse() * self.data.oMf[ib]).homogeneous)

    def foot_T_camera(
        self, q: Sequence[float] | np.ndarray, check_limits: bool = True
    ) -> np.ndarray:
        """Camera optical frame in the foot (heel contact) frame, 4x4."""
        return self.frame_T_frame(FOOT_FRAME, "camera_optical", q, check_limits)

    def foot_T_imu(self, q: Sequence[float] | np.ndarray, check_limits: bool = True) -> np.ndarray:
        """Thigh IMU frame in the foot (heel contact) frame, 4x4."""
        return self.frame_T_frame(FOOT_FRAME, "imu", q, check_limits)

    def thigh_T_frame(self, frame: str) -> np.ndarray:
        """Fixed pose of a thigh-mounted frame (camera_optical, imu) in the thigh frame."""
        return self.frame_T_frame("thigh", frame, np.zeros(2), check_limits=False)

    # --- Jacobians -----------------------------------------------------------------------
    def jacobian(
        self,
        a: str,
        b: str,
        q: Sequence[float] | np.ndarray,
        perturbation: Perturbation = "right",
        check_limits: bool = True,
    ) -> np.ndarray:
        """6x2 Jacobian of ``a_T_b`` w.r.t. q, rows [rotation; translation] (GTSAM order).

        ``right``: ``a_T_b(q+δ) ≈ a_T_b(q) Exp(J δ)`` (twist in frame b, the default);
        ``left``: ``a_T_b(q+δ) ≈ Exp(J δ) a_T_b(q)`` (twist in frame a).
        """
        import pinocchio as pin

        q_arr = self.check_q(q, check_limits)
        ia, ib = self._frame_id(a), self._frame_id(b)
        pin.computeJointJacobians(self.model, self.data, q_arr)
        pin.updateFramePlacements(self.model, self.data)
        j_a = pin.getFrameJacobian(self.model, self.data, ia, pin.LOCAL)
        j_b = pin.getFrameJacobian(self.model, self.data, ib, pin.LOCAL)
        b_M_a = self.data.oMf[ib].inverse() * self.data.oMf[ia]
        # Body velocity of b relative to a, in b: V_b - Ad(b_T_a) V_a  (Pinocchio: [v; w]).
        j_rel_b = j_b - b_M_a.action @ j_a
        jac = swap_twist_order(j_rel_b)
        if perturbation == "right":
            return jac
        if perturbation == "left":
            a_T_b = np.array((self.data.oMf[ia].inverse() * self.data.oMf[ib]).homogeneous)
            return adjoint_rot_first(a_T_b) @ jac
        raise LegModelError(f"perturbation={perturbation!r}: must be 'right' or 'left'")

    def foot_T_camera_jacobian(
        self, q: Sequence[float] | np.ndarray, perturbation: Perturbation = "right"
    ) -> np.ndarray:
        """6x2 Jacobian of :meth:`foot_T_camera` (see :meth:`jacobian` for the convention)."""
        return self.jacobian(FOOT_FRAME, "camera_optical", q, perturbation)

    def foot_T_imu_jacobian(
        self, q: Sequence[float] | np.ndarray, perturbation: Perturbation = "right"
    ) -> np.ndarray:
        """6x2 Jacobian of :meth:`foot_T_imu` (see :meth:`jacobian` for the convention)."""
        return self.jacobian(FOOT_FRAME, "imu", q, perturbation)

    # --- covariance ----------------------------------------------------------------------
    def camera_covariance(
        self,
        q: Sequence[float] | np.ndarray,
        encoder_cov_rad2: float | Sequence[float] | np.ndarray,
        contact: Contact | None = None,
        contact_noise: ContactNoise | None = None,
    ) -> np.ndarray:
        """6x6 covariance of the camera pose on the ground, rotation first, right perturbation.

        ``encoder_cov_rad2``: a variance (both joints), 2 variances, or a 2x2 covariance of the
        joint angles. The encoder part is ``J Σq Jᵀ`` with J = :meth:`foot_T_camera_jacobian`.
        With ``contact`` set, the uncertainty of the foot's pose on the ground (heel strike or
        foot flat, :class:`ContactNoise`, in the foot frame) is added, carried to the camera by
        the adjoint: ``Ad(camera_T_foot) Σc Ad(camera_T_foot)ᵀ`` (a right perturbation of the
        foot pose, ``ground_T_foot Exp(ε)``, moves the camera by ``Exp(Ad(camera_T_foot) ε)``).
        The result is the covariance of ``stride_T_camera`` in the camera's local coordinates.
        """
        cov_q = self._encoder_cov(encoder_cov_rad2)
        jac = self.foot_T_camera_jacobian(q)
        cov = jac @ cov_q @ jac.T
        if contact is not None:
            noise = contact_noise or ContactNoise()
            camera_T_foot = np.linalg.inv(self.foot_T_camera(q))
            ad = adjoint_rot_first(camera_T_foot)
            cov = cov + ad @ noise.covariance(contact) @ ad.T
        return 0.5 * (cov + cov.T)

    # --- helpers -------------------------------------------------------------------------
    def _frame_id(self, name: str) -> int:
        if name in self._frame_ids:
            return self._frame_ids[name]
        import pinocchio as pin

        if not self.model.existFrame(name, pin.BODY):
            known = [f.name for f in self.model.frames if f.type == pin.BODY]
            raise LegModelError(f"unknown frame {name!r}; the leg model has {known}")
        self._frame_ids[name] = self.model.getFrameId(name, pin.BODY)
        return self._frame_ids[name]

    @staticmethod
    def _encoder_cov(encoder_cov_rad2: float | Sequence[float] | np.ndarray) -> np.ndarray:
        c = np.asarray(encoder_cov_rad2, dtype=float)
        if c.ndim == 0:
            c = np.eye(2) * float(c)
        elif c.shape == (2,):
            c = np.diag(c)
        if c.shape != (2, 2) or not np.all(np.isfinite(c)):
            raise EncoderError(
                f"encoder_cov_rad2: need a variance, 2 variances or a 2x2 matrix, got {c.shape}"
            )
        if not np.allclose(c, c.T) or np.any(np.linalg.eigvalsh(c) < -1e-15):
            raise EncoderError("encoder_cov_rad2 must be symmetric positive semi-definite")
        return c
