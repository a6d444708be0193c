"""The covariance floor of the ICP information (``floor_information``): known answers on
synthetic informations, full rank and degenerate (docs/frontend.md, "Calibrated
information")."""

from __future__ import annotations

import numpy as np
import pytest
from test_degeneracy import FLOOR, RNG_SEED, _plane, _report

from graph_slam.frontend.degeneracy import floor_information, project_information
from kinematics.conversions import adjoint_rot_first

INFO = np.diag([4e6, 5e6, 6e6, 1e7, 2e7, 3e7])  # rotation first, then translation


def test_a_zero_floor_changes_nothing() -> None:
    assert floor_information(INFO, 0.0, 0.0) is INFO


def test_full_rank_floor_adds_the_covariances() -> None:
    """(I⁻¹ + diag(σ_r², σ_t²))⁻¹ with I full rank (no report, or a report with 6 DoF)."""
    rng = np.random.default_rng(RNG_SEED)
    a = rng.normal(size=(6, 6))
    info = a @ a.T * 1e5 + INFO
    expected = np.linalg.inv(np.linalg.inv(info) + np.diag([1e-6] * 3 + [4e-6] * 3))
    floored = floor_information(info, 2e-3, 1e-3)
    np.testing.assert_allclose(floored, expected, rtol=1e-9)
    # the floor bounds the information: no direction gets more than 1/σ²
    assert np.linalg.eigvalsh(floored).max() < 1.0 / 1e-6


def test_degenerate_floor_keeps_the_weak_directions_free() -> None:
    """A plane (3 free: x, y, yaw): the floor acts in the 3 constrained directions only;
    the weak ones keep exactly zero information, the rank stays 3 and the floored
    information is never above the unfloored one."""
    rng = np.random.default_rng(RNG_SEED)
    report = _report([_plane(rng, *FLOOR, 3000)])
    pose = np.eye(4)
    pose[:3, 3] = [0.01, -0.02, 0.005]
    projected = project_information(INFO, report, pose)
    floored = floor_information(projected, 1e-3, 2e-3, report, pose)
    ad_inv = np.linalg.inv(adjoint_rot_first(pose))
    for free_left in report.weak_directions:
        xi = ad_inv @ report.to_origin() @ free_left
        assert xi @ floored @ xi == pytest.approx(0.0, abs=1e-9 * INFO.max())
    assert np.linalg.matrix_rank(floored, tol=1e-9 * INFO.max()) == 3
    assert np.linalg.eigvalsh(projected - floored).min() > -1e-6 * INFO.max()
    # the plane's normal translation: 1e7 (σ 0.32 mm) with a 1 mm floor gives ≈ 1/(1e-7 + 1e-6)
    z = ad_inv @ np.array([0, 0, 0, 0, 0, 1.0])
    assert 1.0 / (z @ floored @ z) == pytest.approx(1.0 / 3e7 + 1e-6, rel=0.05)
    with pytest.raises(ValueError, match="target_T_source"):
        floor_information(projected, 1e-3, 0.0, report)
