"""Typed parameters of the transfemoral prosthetic leg, and the URDF they generate.

The URDF in ``models/urdf/transfemoral_leg.urdf`` is :func:`leg_urdf` of the defaults. To
change the camera mount or the segment lengths, do not edit XML: build a :class:`LegParams`
(or :meth:`LegParams.from_mapping` of a YAML/JSON mapping) and give it to
:class:`kinematics.leg_model.LegModel`, which passes :func:`leg_urdf` to Pinocchio's
``buildModelFromXML``.

Frames (all right-handed; with the leg straight and standing, thigh/shank/foot frames are
parallel): x forward, y to the wearer's left, z up.

- ``thigh``: root link (the socket), origin at the hip joint centre; the knee is at
  (0, 0, -thigh_length).
- ``shank``: after the ``knee`` joint (axis +y: positive angle = flexion, foot moves back).
- ``foot``: after the ``ankle`` joint at (0, 0, -shank_length) (axis -y: positive angle =
  dorsiflexion, toe moves up).
- ``heel``: on the sole, below and behind the ankle: the heel contact point; axes parallel
  to the sole (x toward the toe, z normal to the sole, up). This is the "foot" frame of the
  conventions: ``foot_T_camera`` is the camera pose in it.
- ``toe``: the toe contact point on the sole, same axes as ``heel``.
- ``camera_optical``: the depth camera's optical frame (x right in the image, y down in the
  image, z along the optical axis), on the front of the thigh ``mount_height_above_knee_m``
  above the knee, optical axis ``mount_pitch_down_rad`` below horizontal with the leg
  straight. Portrait (default): the long image axis (image x) lies in the sagittal plane,
  pointing up toward the horizon; image y points to the wearer's right. Landscape: image x
  to the wearer's right, image y down-and-back in the sagittal plane.
- ``imu``: the thigh IMU, ``imu_height_above_knee_m`` above the knee on the lateral side;
  orientation given by ``imu_rpy_rad`` relative to the thigh frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from kinematics.errors import LegModelError

JOINT_NAMES: tuple[str, ...] = ("knee", "ankle")


@dataclass(frozen=True)
class LegParams:
    """Geometry of the prosthetic leg (SI units, radians). Defaults: adult proportions.

    Segment lengths follow adult anthropometry (thigh ≈ shank ≈ 0.245 x height for a
    1.8 m adult; foot ≈ 0.15 x height; cf. the ``human.urdf`` of example-robot-data).
    """

    thigh_length_m: float = 0.44
    """Hip joint centre to knee axis."""
    shank_length_m: float = 0.44
    """Knee axis to ankle axis (prosthetic pylon)."""
    ankle_height_m: float = 0.08
    """Ankle axis above the sole."""
    heel_behind_ankle_m: float = 0.06
    """Heel contact point behind the ankle axis (along the sole)."""
    foot_length_m: float = 0.26
    """Heel contact point to toe contact point."""
    mount_height_above_knee_m: float = 0.20
    """Camera optical centre above the knee axis, along the thigh."""
    mount_forward_m: float = 0.08
    """Camera optical centre in front of the thigh axis."""
    mount_pitch_down_rad: float = math.radians(35.0)
    """Optical axis below horizontal with the leg straight (allowed 30-45 deg)."""
    camera_orientation: Literal["portrait", "landscape"] = "portrait"
    imu_height_above_knee_m: float = 0.15
    imu_lateral_m: float = 0.06
    """IMU on the lateral side of the socket (-y for a right leg)."""
    imu_rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """IMU orientation in the thigh frame (URDF roll-pitch-yaw)."""
    knee_limits_rad: tuple[float, float] = (math.radians(-5.0), math.radians(120.0))
    ankle_limits_rad: tuple[float, float] = (math.radians(-30.0), math.radians(20.0))
    knee_velocity_limit_rad_s: float = 12.0
    """Fastest physically possible knee speed (prosthesis actuator / human swing < 10)."""
    ankle_velocity_limit_rad_s: float = 8.0

    def __post_init__(self) -> None:
        lengths = (
            "thigh_length_m",
            "shank_length_m",
            "ankle_height_m",
            "foot_length_m",
            "mount_height_above_knee_m",
            "knee_velocity_limit_rad_s",
            "ankle_velocity_limit_rad_s",
        )
        for name in lengths:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise LegModelError(f"LegParams.{name}={value!r}: must be a finite number > 0")
        for name in (
            "heel_behind_ankle_m",
            "mount_forward_m",
            "imu_height_above_knee_m",
            "imu_lateral_m",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise LegModelError(f"LegParams.{name}={value!r}: must be a finite number")
        pitch_deg = math.degrees(self.mount_pitch_down_rad)
        if not 30.0 - 1e-9 <= pitch_deg <= 45.0 + 1e-9:
            raise LegModelError(
                f"LegParams.mount_pitch_down_rad={self.mount_pitch_down_rad!r} "
                f"({pitch_deg:.1f} deg): must be 30-45 deg below horizontal"
            )
        if self.mount_height_above_knee_m >= self.thigh_length_m:
            raise LegModelError(
                "LegParams.mount_height_above_knee_m must be below the hip "
                f"(< thigh_length_m={self.thigh_length_m})"
            )
        if not 0 <= self.heel_behind_ankle_m < self.foot_length_m:
            raise LegModelError(
                "LegParams.heel_behind_ankle_m must be in [0, foot_length_m) "
                "(the ankle lies between heel and toe)"
            )
        if self.camera_orientation not in ("portrait", "landscape"):
            raise LegModelError(
                f"LegParams.camera_orientation={self.camera_orientation!r}: "
                "must be 'portrait' or 'landscape'"
            )
        for name in ("knee_limits_rad", "ankle_limits_rad"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise LegModelError(f"LegParams.{name}=({lo}, {hi}): need finite lower < upper")
        if len(self.imu_rpy_rad) != 3 or not all(math.isfinite(a) for a in self.imu_rpy_rad):
            raise LegModelError(f"LegParams.imu_rpy_rad={self.imu_rpy_rad!r}: 3 finite angles")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "<mapping>") -> LegParams:
        """Build from a (partial) mapping, e.g. ``yaml.safe_load`` output; unknown keys fail."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise LegModelError(
                f"{source}: unknown leg parameter(s) {sorted(unknown)}; known: {sorted(known)}"
            )
        values = dict(data)
        for name in ("imu_rpy_rad", "knee_limits_rad", "ankle_limits_rad"):
            if name in values:
                values[name] = tuple(float(v) for v in values[name])
        try:
            return cls(**values)
        except LegModelError as err:
            raise LegModelError(f"{source}: {err}") from None
        except (TypeError, ValueError) as err:
            raise LegModelError(f"{source}: {err}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping of every parameter (for writing the resolved config)."""
        return asdict(self)

    # --- derived geometry (thigh frame unless stated) -----------------------------------
    def thigh_R_camera(self) -> np.ndarray:
        """Rotation of the camera optical frame in the thigh frame (leg straight)."""
        p = self.mount_pitch_down_rad
        view = np.array([math.cos(p), 0.0, -math.sin(p)])  # optical axis z
        right = np.array([0.0, -1.0, 0.0])  # wearer's right
        up_in_plane = np.array([math.sin(p), 0.0, math.cos(p)])  # perpendicular to view, up
        if self.camera_orientation == "portrait":
            x_cam, y_cam = up_in_plane, right
        else:
            x_cam, y_cam = right, -up_in_plane
        return np.column_stack([x_cam, y_cam, view])

    def thigh_t_camera(self) -> np.ndarray:
        """Camera optical centre in the thigh frame (m)."""
        return np.array(
            [self.mount_forward_m, 0.0, -self.thigh_length_m + self.mount_height_above_knee_m]
        )


def _rpy(rotation: np.ndarray) -> tuple[float, float, float]:
    """URDF rpy (fixed axes x, y, z) of a rotation matrix."""
    r, p, y = Rotation.from_matrix(rotation).as_euler("xyz")
    return float(r), float(p), float(y)


def _fmt(values: tuple[float, ...] | np.ndarray) -> str:
    return " ".join(f"{float(v):.10g}" for v in values)


def leg_urdf(params: LegParams | None = None, name: str = "transfemoral_leg") -> str:
    """The URDF (XML string) of the leg for ``params`` (defaults when None)."""
    p = params or LegParams()
    cam_xyz = p.thigh_t_camera()
    cam_rpy = _rpy(p.thigh_R_camera())
    imu_xyz = (0.0, -p.imu_lateral_m, -p.thigh_length_m + p.imu_height_above_knee_m)
    heel_xyz = (-p.heel_behind_ankle_m, 0.0, -p.ankle_height_m)
    toe_xyz = (p.foot_length_m - p.heel_behind_ankle_m, 0.0, -p.ankle_height_m)

    def inertial(mass: float, com_z: float, length: float) -> str:
        i_xx = mass * length**2 / 12.0
        return (
            f'    <inertial>\n      <origin xyz="0 0 {com_z:.6g}" rpy="0 0 0"/>\n'
            f'      <mass value="{mass:g}"/>\n'
            f'      <inertia ixx="{i_xx:.6g}" ixy="0" ixz="0" iyy="{i_xx:.6g}" iyz="0" '
            f'izz="{mass * 0.003:.6g}"/>\n    </inertial>\n'
        )

    def fixed(
        link: str, parent: str, xyz: tuple[float, ...] | np.ndarray, rpy: tuple[float, ...]
    ) -> str:
        return (
            f'  <link name="{link}"/>\n'
            f'  <joint name="{link}_joint" type="fixed">\n'
            f'    <parent link="{parent}"/>\n    <child link="{link}"/>\n'
            f'    <origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>\n  </joint>\n'
        )

    kl, ku = p.knee_limits_rad
    al, au = p.ankle_limits_rad
    return (
        '<?xml version="1.0"?>\n'
        "<!-- Transfemoral prosthetic leg for graph_slam, generated by "
        "kinematics.leg_params.leg_urdf; override LegParams instead of editing. Frames: "
        "x forward, y left, z up (leg straight); camera_optical is an optical frame "
        "(x right, y down, z forward in the image). BSD-3-Clause. -->\n"
        f'<robot name="{name}">\n'
        '  <link name="thigh">\n'
        + inertial(2.0, -p.thigh_length_m / 2, p.thigh_length_m)
        + "  </link>\n"
        '  <link name="shank">\n'
        + inertial(1.3, -p.shank_length_m / 2, p.shank_length_m)
        + "  </link>\n"
        '  <link name="foot">\n'
        + inertial(0.8, -p.ankle_height_m / 2, p.foot_length_m)
        + "  </link>\n"
        '  <joint name="knee" type="revolute">\n'
        '    <parent link="thigh"/>\n    <child link="shank"/>\n'
        f'    <origin xyz="0 0 {-p.thigh_length_m:.10g}" rpy="0 0 0"/>\n'
        '    <axis xyz="0 1 0"/>\n'
        f'    <limit lower="{kl:.10g}" upper="{ku:.10g}" effort="150" '
        f'velocity="{p.knee_velocity_limit_rad_s:.10g}"/>\n'
        "  </joint>\n"
        '  <joint name="ankle" type="revolute">\n'
        '    <parent link="shank"/>\n    <child link="foot"/>\n'
        f'    <origin xyz="0 0 {-p.shank_length_m:.10g}" rpy="0 0 0"/>\n'
        '    <axis xyz="0 -1 0"/>\n'
        f'    <limit lower="{al:.10g}" upper="{au:.10g}" effort="150" '
        f'velocity="{p.ankle_velocity_limit_rad_s:.10g}"/>\n'
        "  </joint>\n"
        + fixed("camera_optical", "thigh", cam_xyz, cam_rpy)
        + fixed("imu", "thigh", imu_xyz, p.imu_rpy_rad)
        + fixed("heel", "foot", heel_xyz, (0.0, 0.0, 0.0))
        + fixed("toe", "foot", toe_xyz, (0.0, 0.0, 0.0))
        + "</robot>\n"
    )
