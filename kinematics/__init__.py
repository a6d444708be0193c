"""Prosthetic-leg kinematics, gait events and gait reference curves (numpy in, numpy out).

This package never imports ``graph_slam``.
"""

from kinematics.errors import KinematicsError

__all__ = ["KinematicsError"]
