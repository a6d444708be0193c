"""The noise-aware Tukey kernel of the accurate path (``kernel_noise_sigmas``): the residuals'
robust σ on known noise, and the finest level widened only when the depth is noisier than the
kernel assumes (off by default; 5.5 here) (docs/frontend.md, "Robust kernel from the observed noise")."""

from __future__ import annotations

import numpy as np
import pytest
from test_frontend_registration import A, camera_pose, cloud_at, errors

from graph_slam.frontend import register
from graph_slam.frontend.cloud import Cloud
from graph_slam.frontend.config import LevelConfig, RegistrationConfig
from graph_slam.frontend.registration import noise_sigma_m

RNG_SEED = 11


@pytest.mark.parametrize("sigma_m", [0.001, 0.004])
def test_noise_sigma_of_a_noisy_plane_is_its_noise(sigma_m: float) -> None:
    """A plane z = 1 m with Gaussian noise σ along its normal, 5 % gross outliers: 1.4826·MAD
    of the point-to-plane residuals is σ within 10 %."""
    rng = np.random.default_rng(RNG_SEED)
    xy = rng.uniform(-0.5, 0.5, (4000, 2))
    target = Cloud(np.column_stack([xy, np.ones(4000)]), normals=np.tile([0, 0, -1.0], (4000, 1)))
    source_z = 1.0 + rng.normal(0.0, sigma_m, 4000)
    source_z[:200] += rng.uniform(0.05, 0.2, 200)  # outliers
    source = Cloud(np.column_stack([xy, source_z]))
    corr = np.column_stack([np.arange(4000), np.arange(4000)])
    assert noise_sigma_m(source, target, corr, np.eye(4)) == pytest.approx(sigma_m, rel=0.1)


LEVELS = (
    LevelConfig(voxel_m=0.04, max_correspondence_m=0.04, max_iterations=30),
    LevelConfig(voxel_m=0.02, max_correspondence_m=0.02, max_iterations=20),
)


def test_nominal_noise_leaves_the_kernel_alone() -> None:
    """1 mm depth noise (σ̂ ≈ 1 mm: 5.5 σ̂ < 1 cm = 0.5 voxel): the same result as without."""
    target, source = cloud_at(A, seed=1), cloud_at(camera_pose(0.012, 0.004, 0.505, 41.0), seed=2)
    on = register(source, target, RegistrationConfig(levels=LEVELS, kernel_noise_sigmas=5.5))
    off = register(source, target, RegistrationConfig(levels=LEVELS))
    # (Open3D's parallel sums are not bit-exact from run to run)
    np.testing.assert_allclose(on.target_T_source, off.target_T_source, atol=1e-9)
    np.testing.assert_allclose(on.information, off.information, rtol=1e-6)


def test_noisy_depth_widens_the_kernel_and_keeps_the_answer() -> None:
    """5 mm of extra depth noise (σ̂ well above 1 cm / 5.5): the finest level re-runs with
    k = 5.5 σ̂, and the pose is still recovered within 3 mm / 0.3°."""
    rng = np.random.default_rng(RNG_SEED)
    truth_b = camera_pose(0.012, 0.004, 0.505, 41.0)
    target, source = cloud_at(A, seed=1), cloud_at(truth_b, seed=2)

    def noisy(cloud: Cloud) -> Cloud:
        ray = cloud.points_m / np.linalg.norm(cloud.points_m, axis=1, keepdims=True)
        return Cloud(cloud.points_m + ray * rng.normal(0, 0.005, (len(cloud), 1)), cloud.colors)

    target, source = noisy(target), noisy(source)
    on = register(source, target, RegistrationConfig(levels=LEVELS, kernel_noise_sigmas=5.5))
    off = register(source, target, RegistrationConfig(levels=LEVELS))
    assert np.abs(on.target_T_source - off.target_T_source).max() > 1e-7  # it did re-run
    t_mm, r_deg = errors(on.target_T_source, np.linalg.solve(A, truth_b))
    assert t_mm < 3.0 and r_deg < 0.3, (t_mm, r_deg)
