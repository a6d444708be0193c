"""The compiled loops of the real-time front end (graph_slam.frontend.kernels) against the
numpy formulation they replaced (tests.frontend_reference.py).

The kernels do the same arithmetic in the same order, so the prepared frame equals the numpy
one to rounding, its voxels in another order (measured: bit-identical on these frames; bound
1e-12), the rows of one
iteration likewise, and the Gauss-Newton step from the one-pass normal equations equals the
one from numpy's sums to 1e-9 relative. The frames are the
synthetic box course of test_frontend_projective (seeded), with and without colour, with
normals at every pixel and at every 2nd, on a grid offset and rotated from the camera's.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_frontend_gicp import off
from test_frontend_projective import JUMP, A, frame_at, pair
from test_frontend_registration import K

from graph_slam.errors import RecordError
from graph_slam.frontend import kernels
from graph_slam.frontend.config import ProjectiveConfig
from graph_slam.frontend.objective import analyse
from graph_slam.frontend.projective import associated_rows, prepare_depth
from graph_slam.session.records import RgbdFrame
from tests.frontend_reference import (
    associate_reference,
    prepare_depth_reference,
    rows_reference,
)

FIELDS = ("points_m", "normals", "intensity", "gradients", "pixel_voxel", "pixel_points_m")


def _match_rows(ours: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``order`` with ``ours[order] == ref`` (rows of distinct voxel means)."""
    a, b = np.lexsort(ours.T[::-1]), np.lexsort(ref.T[::-1])
    order = np.empty(len(ref), np.int64)
    order[b] = a
    return order


@pytest.mark.parametrize("color", [True, False], ids=["rgbd", "depth"])
@pytest.mark.parametrize("normal_step,min_normals", [(1, 1), (2, 2)])
def test_prepared_frame_equals_the_numpy_formulation(color, normal_step, min_normals) -> None:
    config = ProjectiveConfig(normal_step=normal_step, min_pixel_normals=min_normals)
    rendered = frame_at(A, seed=3, color=color)
    depth = rendered.depth_m.copy()
    depth[5, 7] = depth[30, 40] = 0.0  # no depth: never a point or a neighbour
    frame = RgbdFrame(rendered.t_s, depth, rendered.color_rgb, rendered.index)
    grid_T_cloud = off(np.eye(4), (0.0037, -0.0051, 0.0023), 7.0)
    ours = prepare_depth(frame, K, config, None, grid_T_cloud)
    ref = prepare_depth_reference(frame, K, config, None, grid_T_cloud)
    assert len(ours) > 200
    # the same voxels in another order (the numpy path sorts them by key): match by row
    order = _match_rows(ours.points_m, ref.points_m)
    for name in FIELDS[:4]:
        a, b = getattr(ours, name), getattr(ref, name)
        if b is None:
            assert a is None, name
            continue
        assert a.shape == b.shape, name
        np.testing.assert_allclose(a[order], b, rtol=0, atol=1e-12, err_msg=name)
    ref_to_ours = np.append(order, -1)  # -1 (no voxel) stays -1
    np.testing.assert_array_equal(ours.pixel_voxel, ref_to_ours[ref.pixel_voxel])
    np.testing.assert_array_equal(ours.pixel_points_m, ref.pixel_points_m)
    assert ours.camera == ref.camera


def test_rows_of_one_iteration_equal_the_numpy_formulation() -> None:
    config = ProjectiveConfig(normal_step=1, min_pixel_normals=1)
    truth = np.linalg.solve(A, JUMP)
    guess = off(truth)
    target, source, _, _ = pair(A, JUMP, config, guess)
    corr, rows = associated_rows(source, target, guess, config)
    ref_corr = associate_reference(source, target, guess, config)
    np.testing.assert_array_equal(corr, ref_corr)
    assert len(corr) > 500
    ref = rows_reference(source, target, ref_corr, guess, config)
    for name in ("r", "jac", "w", "q", "geo_scale"):
        np.testing.assert_allclose(getattr(rows, name), getattr(ref, name), rtol=0, atol=1e-12)
    assert (rows.n_geo, rows.pho_scale) == (ref.n_geo, ref.pho_scale)
    # the Gauss-Newton step from the one-pass sums, against the sums written with numpy
    report = analyse(rows, config)
    to_unit = report.degeneracy.to_origin()
    jac_n = ref.jac @ to_unit
    norm = float(np.sum(ref.w[: ref.n_geo] * ref.geo_scale**2))
    hess_n = (jac_n * ref.w[:, None]).T @ jac_n / norm
    np.testing.assert_allclose(report.degeneracy.hessian, hess_n, rtol=1e-10, atol=1e-12)
    grad_n = (jac_n * ref.w[:, None]).T @ ref.r / norm
    strong = report.degeneracy.eigenvalues >= config.degeneracy_threshold
    v = report.degeneracy.eigenvectors[:, strong]
    step = to_unit @ (-v @ ((v.T @ grad_n) / report.degeneracy.eigenvalues[strong]))
    np.testing.assert_allclose(report.step_origin, step, rtol=1e-9, atol=1e-15)


def test_normal_equations_are_the_weighted_sums() -> None:
    rng = np.random.default_rng(5)
    jac, r = rng.normal(size=(300, 6)), rng.normal(size=300)
    w = rng.uniform(0, 1, 300)
    w[::7] = 0.0  # a Tukey outlier
    hess, grad = kernels.normal_equations(jac, r, w)
    np.testing.assert_allclose(hess, (jac * w[:, None]).T @ jac, rtol=1e-12)
    np.testing.assert_allclose(grad, (jac * w[:, None]).T @ r, rtol=1e-12)


def test_a_point_beyond_the_voxel_key_is_a_record_error() -> None:
    frame = frame_at(A, color=False)
    far = np.eye(4)
    far[0, 3] = 0.02 * (kernels.KEY_OFFSET + 10)  # beyond ±2^20 voxels of 2 cm
    with pytest.raises(RecordError, match="voxel key"):
        prepare_depth(frame, K, ProjectiveConfig(), None, far)


def test_depth_outside_the_range_is_not_a_point() -> None:
    depth = np.full(K.shape_hw, 1.0, np.float32)
    depth[:10] = 0.05  # nearer than min_depth_m
    depth[-10:] = 50.0  # farther than max_depth_m
    ours = prepare_depth(RgbdFrame(0.0, depth), K, ProjectiveConfig(normal_step=1))
    assert np.all(ours.pixel_points_m[:, 2] == 1.0)
    step = ProjectiveConfig().pixel_step_for(K)
    expected = np.count_nonzero(depth[::step, ::step] == 1.0)
    assert len(ours.pixel_points_m) == expected


@pytest.mark.parametrize("scale", [0.0, 1e-10, 1e-6, 1e-3, 0.5, 3.0])
def test_exp_left_is_the_rotation_vector_exponential(scale) -> None:
    """Rodrigues' formula (and its second-order form below 1e-8 rad) against scipy."""
    from scipy.spatial.transform import Rotation

    from graph_slam.frontend.objective import exp_left

    xi = np.random.default_rng(int(scale * 1e6) + 1).normal(size=6) * scale
    delta = exp_left(xi)
    np.testing.assert_allclose(delta[:3, :3], Rotation.from_rotvec(xi[:3]).as_matrix(), atol=1e-15)
    np.testing.assert_array_equal(delta[:3, 3], xi[3:])
    np.testing.assert_array_equal(delta[3], [0, 0, 0, 1])


def test_eig3_smallest_equals_eigh():
    """The closed-form 3×3 eigen-solver of the normals against numpy's ``eigh`` on the
    covariances of planar, linear and isotropic neighbourhoods (random rotations): the
    eigenvalues to 1e-12 of the largest, the smallest's eigenvector to 1e-9 wherever it is
    separated from the next (where a normal is used); a zero and a diagonal matrix as
    ``eigh`` gives them."""
    from graph_slam.frontend.neighbourhood import eig3_smallest

    rng = np.random.default_rng(11)
    covs = []
    for spread in ([0.02, 0.02, 0.0005], [0.02, 0.001, 0.0005], [0.01, 0.01, 0.01]):
        for _ in range(500):
            rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            pts = (rng.normal(size=(30, 3)) * spread) @ rot.T + rng.normal(size=3)
            covs.append(np.cov(pts.T))
    covs += [np.zeros((3, 3)), np.diag([3.0, 1.0, 2.0])]
    covs = np.array(covs)
    values, vectors = eig3_smallest(covs)
    want_values, want_vectors = np.linalg.eigh(covs)
    scale = want_values[:, 2:3] + 1e-300
    assert np.max(np.abs(values - want_values) / scale) < 1e-12
    separated = want_values[:, 1] - want_values[:, 0] > 1e-3 * want_values[:, 2]
    assert separated.sum() > 900  # the planar and linear ones
    dots = np.abs(np.einsum("ij,ij->i", vectors, want_vectors[:, :, 0]))
    assert dots[separated].min() > 1 - 1e-9
    np.testing.assert_array_equal(vectors[-2:], [[1, 0, 0], [0, 1, 0]])


def test_tukey_weights_equal_the_numpy_kernel_weights() -> None:
    """The compiled Tukey weights are numpy's ``kernel_weights(r, "tukey", k)`` bit for bit
    (inside, at, beyond the scale; a NaN residual weighs 0)."""
    from graph_slam.frontend.objective import kernel_weights

    rng = np.random.default_rng(11)
    k = 0.045
    r = rng.normal(scale=k, size=5000)
    r[:4] = [k, -k, 0.0, np.nan]
    ours = kernels.tukey_weights(r, k)
    np.testing.assert_array_equal(ours, kernel_weights(r, "tukey", k))
    assert ours[3] == 0.0 and 0.0 < ours[4:].mean() < 1.0


def test_inner_step_and_reused_system_equal_the_full_analysis() -> None:
    """The inner iterations' step (``unit_system(rows).step``) and the report built from that
    system are exactly :func:`analyse`'s own (the same arithmetic: no tolerance)."""
    from graph_slam.frontend.objective import unit_system

    config = ProjectiveConfig()
    truth = np.linalg.solve(A, JUMP)
    target, source, _, _ = pair(A, JUMP, config, off(truth))
    _, rows = associated_rows(source, target, off(truth), config)
    full = analyse(rows, config)
    system = unit_system(rows)
    np.testing.assert_array_equal(system.step(config.degeneracy_threshold), full.step_origin)
    reused = analyse(rows, config, system=system)
    np.testing.assert_array_equal(reused.step_origin, full.step_origin)
    for name in ("eigenvalues", "eigenvectors", "center_m", "significant", "share"):
        np.testing.assert_array_equal(
            getattr(reused.degeneracy, name), getattr(full.degeneracy, name), err_msg=name
        )


@pytest.mark.parametrize(
    "values",
    [np.full(7, 0.7071), np.full(8, 0.7071), np.full(1, 1.0), np.array([0.5, 0.7, 0.7, 1.0]),
     np.array([0.7, np.nan, 0.7]), np.broadcast_to(0.3, (10,))],
    ids=["constant_odd", "constant_even", "one", "varying", "nan", "broadcast"],
)  # fmt: skip
def test_geo_scale_median_is_numpys(values) -> None:
    """The information's σ floor uses the median of ``geo_scale``; its shortcut for a constant
    array gives numpy's median exactly (NaN as numpy)."""
    from graph_slam.frontend.objective import _median

    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(_median(values), np.median(values))
