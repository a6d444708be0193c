"""Known-answer degeneracy on synthetic clouds: a plane, two planes, a corner, a textured plane.

The clouds are sampled analytically (seeded) with noisy normals (about 6° rms, as the far points
of a quarter-resolution floor), one metre in front of the camera; the correspondences are
the identity at the true pose, so the analysis sees exactly the constraint the scene offers.
Expected free directions (a motion that leaves every surface on itself):

* one plane: 3 (two translations along it, the rotation about its normal);
* two perpendicular planes: 1 (the translation along their line of intersection);
* a corner (three perpendicular planes): 0;
* a plane with texture: 0 with the photometric rows, 3 without.
"""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.frontend.config import RegistrationConfig
from graph_slam.frontend.degeneracy import project_information
from graph_slam.frontend.objective import analyse, cloud_rows
from graph_slam.session.records import Cloud

CONFIG = RegistrationConfig(method="point_to_plane")
RNG_SEED = 7


def _plane(rng, normal, origin, u, v, n_points, half_m=0.4, normal_noise=0.1):
    """Points on a square patch of a plane, with normals perturbed by ~normal_noise rad."""
    a = rng.uniform(-half_m, half_m, (n_points, 2))
    points = np.asarray(origin) + a[:, :1] * np.asarray(u) + a[:, 1:] * np.asarray(v)
    normals = np.asarray(normal, float) + normal_noise * rng.normal(size=(n_points, 3))
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _texture(points):
    """A smooth intensity pattern on the plane z = 1 (gradient about 3 per metre)."""
    i = 0.5 + 0.2 * np.sin(15.0 * points[:, 0]) * np.cos(11.0 * points[:, 1])
    return np.repeat(i[:, None], 3, axis=1)


def _gradients(points):
    """The exact tangent-plane gradient of :func:`_texture` on z = 1."""
    gx = 0.2 * 15.0 * np.cos(15.0 * points[:, 0]) * np.cos(11.0 * points[:, 1])
    gy = -0.2 * 11.0 * np.sin(15.0 * points[:, 0]) * np.sin(11.0 * points[:, 1])
    return np.column_stack([gx, gy, np.zeros(len(points))])


def _report(parts, colors=None, gradients=None, config=CONFIG):
    points = np.vstack([p for p, _ in parts])
    normals = np.vstack([n for _, n in parts])
    cloud = Cloud(points, colors, normals)
    corr = np.column_stack([np.arange(len(points))] * 2)
    lam = config.lambda_geometric if gradients is not None else 1.0
    rows = cloud_rows(cloud, cloud, corr, np.eye(4), geo_scale=np.sqrt(lam),
                 pho_scale=np.sqrt(1.0 - lam) if gradients is not None else 0.0,
                 kernel="none", k=1.0, gradients=gradients)  # fmt: skip
    return analyse(rows, config).degeneracy


FLOOR = ((0, 0, -1), (0, 0, 1.0), (1, 0, 0), (0, 1, 0))  # z = 1 m, facing the camera
WALL = ((-1, 0, 0), (0.4, 0, 1.0), (0, 0, 1), (0, 1, 0))  # x = 0.4 m
SIDE = ((0, -1, 0), (0, 0.4, 1.0), (1, 0, 0), (0, 0, 1))  # y = 0.4 m


def _free_translation(report, axis):
    """Stiffness of the report along a unit translation (compare with the threshold)."""
    return report.stiffness(translation=np.asarray(axis, float))


def test_one_plane_leaves_three_directions_free() -> None:
    rng = np.random.default_rng(RNG_SEED)
    report = _report([_plane(rng, *FLOOR, 3000)])
    assert report.dof == 3
    # the free subspace is the plane's: x, y translations and the rotation about z
    free = report.weak_directions  # rows, (L·ω, t)
    for axis in ([0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 1, 0, 0, 0]):
        e = np.asarray(axis, float)
        assert np.linalg.norm(free @ e) == pytest.approx(1.0, abs=0.02)


def test_noise_of_the_normals_alone_looks_constrained_to_the_eigenvalues() -> None:
    """Why the significance test exists: 4 % of the points with random normals (the far,
    noisy points of a floor) give the free directions eigenvalues above the threshold."""
    rng = np.random.default_rng(RNG_SEED)
    points, normals = _plane(rng, *FLOOR, 3000, normal_noise=0.03)
    bad = rng.choice(len(points), 120, replace=False)
    random_normals = rng.normal(size=(120, 3))
    normals[bad] = random_normals / np.linalg.norm(random_normals, axis=1, keepdims=True)
    report = _report([(points, normals)])
    assert (report.eigenvalues >= report.threshold).sum() > 3  # the eigenvalues are fooled
    assert report.dof == 3  # the significance test is not


def test_two_planes_leave_their_line_of_intersection_free() -> None:
    rng = np.random.default_rng(RNG_SEED)
    report = _report([_plane(rng, *FLOOR, 2000), _plane(rng, *WALL, 1000)])
    assert report.dof == 5
    # the free direction: translation along y (the line where z = 1 and x = 0.4 meet)
    assert np.abs(report.weak_directions[0, 4]) == pytest.approx(1.0, abs=0.02)


def test_a_corner_constrains_every_direction() -> None:
    rng = np.random.default_rng(RNG_SEED)
    parts = [_plane(rng, *FLOOR, 2000), _plane(rng, *WALL, 800), _plane(rng, *SIDE, 800)]
    report = _report(parts)
    assert report.dof == 6 and not report.is_degenerate


def test_texture_constrains_a_plane_only_through_the_photometric_rows() -> None:
    rng = np.random.default_rng(RNG_SEED)
    points, normals = _plane(rng, *FLOOR, 3000)
    colors, grads = _texture(points), _gradients(points)
    colored = RegistrationConfig(method="colored")
    assert _report([(points, normals)], colors, grads, colored).dof == 6
    # a flat colour (zero gradient) or a faint one (below degeneracy_min_gradient) does not
    assert _report([(points, normals)], colors, 0.0 * grads, colored).dof == 3
    assert _report([(points, normals)], colors, 0.02 * grads, colored).dof == 3


def test_only_the_constrained_subspace_keeps_information() -> None:
    rng = np.random.default_rng(RNG_SEED)
    report = _report([_plane(rng, *FLOOR, 3000)])
    pose = np.eye(4)
    pose[:3, 3] = [0.01, -0.02, 0.005]
    info = np.diag([4e4, 5e4, 6e4, 1e5, 2e5, 3e5])
    projected = project_information(info, report, pose)
    # right tangent at pose: a free left motion (translation along x, y; yaw about z through
    # the centre) carries zero information; the plane's normal direction keeps it
    from kinematics.conversions import adjoint_rot_first

    ad_inv = np.linalg.inv(adjoint_rot_first(pose))
    for free_left in report.weak_directions:
        xi_right = ad_inv @ report.to_origin() @ free_left
        assert xi_right @ projected @ xi_right == pytest.approx(0.0, abs=1e-6 * info.max())
    z_right = ad_inv @ np.array([0, 0, 0, 0, 0, 1.0])
    assert z_right @ projected @ z_right > 0.5 * 3e5
    assert np.linalg.matrix_rank(projected, tol=1e-6 * info.max()) == 3


def test_significance_pass_equals_the_numpy_formulation() -> None:
    """The compiled significance pass against the numpy one (random rows, point-to-plane and
    photometric, some of zero weight; the displacement written with ``np.cross`` there)."""
    from types import SimpleNamespace

    from graph_slam.frontend.degeneracy import significant_stiffness, unit_coordinates
    from graph_slam.frontend.objective import Rows
    from tests.frontend_reference import displacement_norms, significant_reference

    rng = np.random.default_rng(7)
    lever, vectors = rng.normal(size=(50, 3)), rng.normal(size=(6, 6))
    expected = np.linalg.norm(
        np.cross(vectors[:3].T[None, :, :], lever[:, None, :]) + vectors[3:].T[None, :, :], axis=2
    )
    np.testing.assert_allclose(displacement_norms(lever, vectors), expected, rtol=1e-12)
    n = 400
    w = rng.uniform(0, 1, 2 * n)
    w[::9] = 0.0
    rows = Rows(rng.normal(size=2 * n), rng.normal(size=(2 * n, 6)), w,
                 rng.normal(size=(n, 3)), np.full(n, 0.9), n, 0.4)  # fmt: skip
    config = SimpleNamespace(degeneracy_min_alignment=0.5, degeneracy_min_gradient=1.0)
    center, length, norm = rows.q.mean(axis=0), 1.3, 17.0
    vectors = np.linalg.qr(rng.normal(size=(6, 6)))[0]
    along_map = unit_coordinates(center, length) @ vectors
    ours = significant_stiffness(rows, along_map, vectors, center, length, norm, config)
    ref = significant_reference(rows, rows.jac @ along_map, vectors, center, length, norm, config)
    every_row = w.sum() / w[:n].sum()  # the share if every row counted
    assert ours[1].min() > 0 and ours[1].max() < every_row  # some rows count, not all
    for a, b in zip(ours, ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12)
