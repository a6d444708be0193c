"""The compiled tangent-plane colour gradients (frontend.neighbourhood.color_gradients) against
the same least squares written with numpy arrays, and a known answer: a linear intensity ramp
on a plane has the ramp's slope as its gradient."""

from __future__ import annotations

import numpy as np

from graph_slam.frontend.neighbourhood import color_gradients
from graph_slam.session.records import Cloud


def _numpy_gradients(points, normals, intensity, index, nbr, found):
    n = normals[index]
    diff = points[nbr] - points[index][:, None, :]
    proj = (diff - np.einsum("mkj,mj->mk", diff, n)[..., None] * n[:, None, :]) * found[..., None]
    b = (intensity[nbr] - intensity[index][:, None]) * found
    count = found.sum(axis=1).astype(float)
    ata = np.einsum("mki,mkj->mij", proj, proj) + (count**2)[:, None, None] * np.einsum(
        "mi,mj->mij", n, n
    )
    atb = np.einsum("mki,mk->mi", proj, b)
    usable = count + 1 >= 4
    grad = np.zeros((len(index), 3))
    grad[usable] = np.linalg.solve(ata[usable] + 1e-12 * np.eye(3), atb[usable][..., None])[..., 0]
    return grad


def _plane(rng, n=400):
    xy = rng.uniform(-0.2, 0.2, (n, 2))
    points = np.column_stack([xy, 1.0 + 0.001 * rng.normal(size=n)])
    normals = np.tile([0.0, 0.0, -1.0], (n, 1))
    return points, normals


def test_a_linear_ramp_has_its_slope_as_gradient():
    rng = np.random.default_rng(1)
    points, normals = _plane(rng)
    grey = 0.5 + 1.0 * points[:, 0] - 0.5 * points[:, 1]  # per metre
    cloud = Cloud(points, np.repeat(grey[:, None], 3, axis=1), normals)
    grad = color_gradients(cloud, np.arange(50), 0.05, 30)
    np.testing.assert_allclose(grad[:, :2], np.tile([1.0, -0.5], (50, 1)), atol=0.03)
    assert np.all(np.abs(grad[:, 2]) < 0.05)


def test_compiled_gradients_match_the_array_formulation():
    from scipy.spatial import cKDTree

    from graph_slam.frontend.neighbourhood import _gradients

    rng = np.random.default_rng(2)
    points, normals = _plane(rng)
    normals = normals + 0.05 * rng.normal(size=normals.shape)
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    intensity = rng.uniform(0, 1, len(points))
    index = np.arange(0, len(points), 3)
    dist, nbr = cKDTree(points).query(points[index], k=30, distance_upper_bound=0.03)
    found = np.isfinite(dist)
    found[:, 0] = False
    nbr = np.where(found, nbr, index[:, None])
    expected = _numpy_gradients(points, normals, intensity, index, nbr, found)
    got = _gradients(points, normals, intensity, index, nbr, found)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9)
