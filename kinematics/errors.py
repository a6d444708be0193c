"""Exceptions of the kinematics package (which never imports graph_slam)."""

from __future__ import annotations


class KinematicsError(Exception):
    """Base class of every error the kinematics package raises on purpose."""
