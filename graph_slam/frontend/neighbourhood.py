"""Per-point neighbourhood quantities of the accurate and thesis registrations (the k-NN
paths; the real-time front end gets its own from the organised image, :mod:`.kernels`):
the normals' 3×3 eigen-problems, compiled, and the tangent-plane colour gradients of Open3D's
colored ICP, for the information matrix."""

from __future__ import annotations

import numba
import numpy as np

from graph_slam.session.records import Cloud


@numba.njit(cache=True, nogil=True)
def eig3_smallest(cov):
    """Eigenvalues (ascending, N×3) of symmetric 3×3 matrices ``cov`` (N×3×3) and the unit
    eigenvector of the smallest (N×3, sign arbitrary): the normals of
    :func:`graph_slam.frontend.cloud.estimate_normals`. numpy's batched ``eigh`` calls
    LAPACK once per matrix (33 ms per 50k points, a sixth of the thesis baseline's time);
    here the closed form: eigenvalues by the trigonometric method, the eigenvector as the
    largest cross product of two rows of ``cov − λ₀I``. Accurate where the normal is used
    (``λ₀`` well below ``λ₁``; ``tests/test_frontend_kernels.py`` against ``eigh``); a
    diagonal matrix gives the axis of its smallest entry, as ``eigh`` does."""
    n = cov.shape[0]
    values = np.empty((n, 3))
    vectors = np.empty((n, 3))
    third = 1.0 / 3.0
    for i in range(n):
        a00, a01, a02 = cov[i, 0, 0], cov[i, 0, 1], cov[i, 0, 2]
        a11, a12, a22 = cov[i, 1, 1], cov[i, 1, 2], cov[i, 2, 2]
        p1 = a01 * a01 + a02 * a02 + a12 * a12
        if p1 == 0.0:  # diagonal
            d = (a00, a11, a22)
            lo = 0
            for j in (1, 2):
                if d[j] < d[lo]:
                    lo = j
            hi = 0
            for j in (1, 2):
                if d[j] > d[hi]:
                    hi = j
            if hi == lo:
                hi = 2 if lo != 2 else 1
            values[i, 0] = d[lo]
            values[i, 1] = d[3 - lo - hi]
            values[i, 2] = d[hi]
            vectors[i, 0] = 1.0 if lo == 0 else 0.0
            vectors[i, 1] = 1.0 if lo == 1 else 0.0
            vectors[i, 2] = 1.0 if lo == 2 else 0.0
            continue
        q = (a00 + a11 + a22) * third
        b00, b11, b22 = a00 - q, a11 - q, a22 - q
        p = np.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
        det = (
            b00 * (b11 * b22 - a12 * a12)
            - a01 * (a01 * b22 - a12 * a02)
            + a02 * (a01 * a12 - b11 * a02)
        )
        r = det / (2.0 * p * p * p)
        r = min(1.0, max(-1.0, r))
        phi = np.arccos(r) * third
        e2 = q + 2.0 * p * np.cos(phi)
        e0 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi * third)
        e1 = 3.0 * q - e0 - e2
        values[i, 0], values[i, 1], values[i, 2] = e0, e1, e2
        r0 = (a00 - e0, a01, a02)
        r1 = (a01, a11 - e0, a12)
        r2 = (a02, a12, a22 - e0)
        best = -1.0
        vx = vy = 0.0
        vz = 1.0
        for u, v in ((r0, r1), (r0, r2), (r1, r2)):
            cx = u[1] * v[2] - u[2] * v[1]
            cy = u[2] * v[0] - u[0] * v[2]
            cz = u[0] * v[1] - u[1] * v[0]
            norm2 = cx * cx + cy * cy + cz * cz
            if norm2 > best:
                best, vx, vy, vz = norm2, cx, cy, cz
        if best > 0.0:
            s = 1.0 / np.sqrt(best)
            vx, vy, vz = vx * s, vy * s, vz * s
        vectors[i, 0], vectors[i, 1], vectors[i, 2] = vx, vy, vz
    return values, vectors


def color_gradients(target: Cloud, index: np.ndarray, radius_m: float, max_nn: int) -> np.ndarray:
    """Intensity gradient in the tangent plane at ``target.points_m[index]``, as Open3D's
    colored ICP computes it: least squares over the ≤ ``max_nn`` neighbours within
    ``radius_m``, projected on the tangent plane, with a weighted ``d·n = 0`` row; zero where
    fewer than 4 points (the point included) are found."""
    from scipy.spatial import cKDTree

    points, normals = target.points_m, target.normals
    intensity = target.colors.mean(axis=1)
    dist, nbr = cKDTree(points).query(
        points[index], k=max_nn, distance_upper_bound=radius_m, workers=-1
    )
    found = np.isfinite(dist)
    found[:, 0] = False  # the point itself
    nbr = np.where(found, nbr, index[:, None])
    return _gradients(points, normals, intensity, np.asarray(index), nbr, found)


@numba.njit(cache=True, nogil=True)
def _gradients(points, normals, intensity, index, nbr, found):
    """The least-squares gradient per ``index[m]`` over its ``found`` neighbours ``nbr[m]``:
    the neighbours' offsets projected on the tangent plane, their intensity differences, and
    the ``d·n = 0`` row weighted by the neighbour count (Open3D's construction)."""
    grad = np.zeros((index.shape[0], 3))
    for m in range(index.shape[0]):
        i = index[m]
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        ata = np.zeros((3, 3))
        atb = np.zeros(3)
        count = 0
        for k in range(nbr.shape[1]):
            if not found[m, k]:
                continue
            j = nbr[m, k]
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            dz = points[j, 2] - points[i, 2]
            along = dx * nx + dy * ny + dz * nz
            v = (dx - along * nx, dy - along * ny, dz - along * nz)
            b = intensity[j] - intensity[i]
            for r in range(3):
                atb[r] += v[r] * b
                for c in range(3):
                    ata[r, c] += v[r] * v[c]
            count += 1
        if count + 1 < 4:
            continue
        n = (nx, ny, nz)
        for r in range(3):
            for c in range(3):
                ata[r, c] += count * count * n[r] * n[c] + (1e-12 if r == c else 0.0)
        grad[m] = np.linalg.solve(ata, atb)
    return grad
