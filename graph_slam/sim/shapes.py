"""Smooth shapes and batched axis rotations that the walking motions are built from.

The blends are C2 (zero first and second derivatives where they join), so a motion built from
them has continuous acceleration and its IMU sees no impulses. The rotations take ``(n,)``
angles and return ``(n, 3, 3)`` matrices.
"""

from __future__ import annotations

import numpy as np


def smoothstep(u: np.ndarray) -> np.ndarray:
    """Quintic 0→1 on [0, 1] with zero first and second derivatives at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def bump(u: np.ndarray) -> np.ndarray:
    """64 u³(1-u)³ on [0, 1] (peak 1 at 0.5), 0 outside; C2 at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return 64.0 * u**3 * (1.0 - u) ** 3


def flatten_pitch(gamma: np.ndarray, band_rad: float, blend_rad: float) -> np.ndarray:
    """C2 map that is 0 for |γ| ≤ band and the identity for |γ| ≥ band + blend."""
    if band_rad <= 0.0:
        return np.asarray(gamma, dtype=float)
    a = np.abs(gamma) - band_rad
    out = np.where(a > 0.0, (a + band_rad) * smoothstep(a / blend_rad), 0.0)
    return np.sign(gamma) * out


def rot_y(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.size, 3, 3))
    r[:, 0, 0], r[:, 0, 2], r[:, 1, 1], r[:, 2, 0], r[:, 2, 2] = c, s, 1.0, -s, c
    return r


def rot_x(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.size, 3, 3))
    r[:, 0, 0], r[:, 1, 1], r[:, 1, 2], r[:, 2, 1], r[:, 2, 2] = 1.0, c, -s, s, c
    return r


def rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    r = np.zeros((a.size, 3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1.0
    return r
