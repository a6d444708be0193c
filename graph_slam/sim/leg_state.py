"""The sagittal leg at a gait phase, from the gait reference curves.

The leg is the chain of :class:`kinematics.leg_params.LegParams` (hip → thigh → knee → shank →
ankle → rigid foot with heel and toe), driven by :mod:`kinematics.gait_curves`. The foot's
pitch passes through a C2 "flat band" (:func:`graph_slam.sim.shapes.flatten_pitch`): the foot
lies exactly flat while the curves' pitch is within ``flat_foot_deg``, and the ankle angle
absorbs the difference (that ankle angle is what an encoder reads). The walking motion
(:mod:`graph_slam.sim.motion`) places two such legs in the world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from graph_slam.sim.config import MotionConfig
from graph_slam.sim.shapes import bump, flatten_pitch
from kinematics import gait_curves
from kinematics.leg_params import LegParams


@dataclass(frozen=True)
class LegState:
    """Sagittal state of one leg at given times (hip at the origin; x forward, z up)."""

    thigh_rad: np.ndarray
    knee_rad: np.ndarray
    ankle_rad: np.ndarray  # after the flat band (what an encoder reads)
    foot_pitch_rad: np.ndarray  # γ, toe up +
    heel_xz: np.ndarray  # (n, 2)
    toe_xz: np.ndarray  # (n, 2)


def leg_state(phase: np.ndarray, speed_m_s: float, leg: LegParams, cfg: MotionConfig) -> LegState:
    """Angles and sole points of a leg at gait ``phase`` (cycles) — the URDF's geometry."""
    q = gait_curves.joint_angles(phase, speed_m_s)
    phi = gait_curves.thigh_angle(phase, speed_m_s)
    knee = q["knee"]
    sf = gait_curves.stance_fraction(speed_m_s)
    swing = (np.mod(phase, 1.0) - sf) / (1.0 - sf)
    ankle_curve = q["ankle"] + math.radians(cfg.swing_dorsiflexion_deg) * bump(swing)
    gamma_curve = phi - knee + ankle_curve
    gamma = flatten_pitch(
        gamma_curve, math.radians(cfg.flat_foot_deg), math.radians(cfg.flat_blend_deg)
    )
    ankle = ankle_curve + gamma - gamma_curve
    psi = phi - knee
    ankle_xz = leg.thigh_length_m * np.column_stack(
        [np.sin(phi), -np.cos(phi)]
    ) + leg.shank_length_m * np.column_stack([np.sin(psi), -np.cos(psi)])
    cg, sg = np.cos(gamma), np.sin(gamma)

    def on_foot(x: float, z: float) -> np.ndarray:  # foot-frame (x, z) point -> hip frame
        return ankle_xz + np.column_stack([x * cg - z * sg, x * sg + z * cg])

    heel = on_foot(-leg.heel_behind_ankle_m, -leg.ankle_height_m)
    toe = on_foot(leg.foot_length_m - leg.heel_behind_ankle_m, -leg.ankle_height_m)
    return LegState(phi, knee, ankle, gamma, heel, toe)
