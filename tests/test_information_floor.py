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


def test_the_pipeline_floors_a_recorded_session_and_not_a_simulated_one() -> None:
    """``graph.real_camera_floor`` None is decided per session (provenance), explicit values
    and explicit floors are kept, and only the accurate registration gets a floor."""
    from types import SimpleNamespace

    from graph_slam.frontend.config import (
        REAL_CAMERA_FLOOR_M,
        REAL_CAMERA_FLOOR_RAD,
        RegistrationConfig,
        gicp_registration,
        realtime_registration,
    )
    from graph_slam.pipelines import PipelineConfig
    from graph_slam.pipelines.protocol import with_camera_floor
    from graph_slam.pipelines.runner import for_session
    from graph_slam.session.manifest import Provenance

    def session(generator: str):
        return SimpleNamespace(manifest=SimpleNamespace(provenance=Provenance(generator=generator)))

    assert Provenance(generator="graph_slam.sim").synthetic
    assert Provenance(generator="graph_slam.session.synthetic").synthetic
    assert not Provenance(generator="graph_slam.session.adapters (tum)").synthetic
    assert not Provenance().synthetic  # unknown: a recording
    auto = PipelineConfig()
    assert auto.graph.real_camera_floor is None
    assert for_session(auto, session("graph_slam.sim")).graph.real_camera_floor is False
    assert for_session(auto, session("graph_slam.session.adapters (tum)")).graph.real_camera_floor
    off = PipelineConfig.model_validate({"graph": {"real_camera_floor": False}})
    assert for_session(off, session("recorder")).graph.real_camera_floor is False

    reg = RegistrationConfig()
    floored = with_camera_floor(reg, None)  # None: a pipeline made without a session
    assert (floored.information_floor_m, floored.information_floor_rad) == (
        REAL_CAMERA_FLOOR_M,
        REAL_CAMERA_FLOOR_RAD,
    )
    assert with_camera_floor(reg, False) is reg
    own = reg.model_copy(update={"information_floor_m": 0.004})
    assert with_camera_floor(own, True) is own  # a floor of its own wins
    realtime = with_camera_floor(realtime_registration(), True)
    assert realtime.information_floor_m == REAL_CAMERA_FLOOR_M  # the projective preset too
    gicp = gicp_registration()
    assert with_camera_floor(gicp, True) is gicp  # GICP has no floor
