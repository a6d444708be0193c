"""Compiled loops of the ramps (numba): the large components of sloped cells, their
weighted plane and its σ, and the ring of cells around a ramp with the terraces met there (the
ramp steps of :mod:`graph_slam.terrain.features.extract`). As
:mod:`graph_slam.terrain.features.kernels`: the numpy formulation's arithmetic in its order
(the plane's 3×3 normal matrix summed in order rather than by BLAS: within 1e-9 relative;
``tests/test_terrain_feature_kernels.py``), compiled on first use and cached on disk."""

from __future__ import annotations

import numba
import numpy as np

from graph_slam.terrain.features.kernels import label4, psum


@numba.njit(cache=True, nogil=True)
def ring(comp, k, reach):  # pragma: no cover - compiled
    """The cells not in component ``k`` of ``comp`` within ``reach`` 4-neighbour steps of it
    (its ``scipy.ndimage.binary_dilation`` by the cross, ``reach`` times, less itself),
    row-major: their i and j. The steps are the city-block distance to the component (two
    passes over its extent and ``reach`` cells around it, where the ring lies)."""
    nx, ny = comp.shape
    lo_i, hi_i, lo_j, hi_j = nx, -1, ny, -1
    for i in range(nx):
        for j in range(ny):
            if comp[i, j] == k:
                lo_i, hi_i = min(lo_i, i), max(hi_i, i)
                lo_j, hi_j = min(lo_j, j), max(hi_j, j)
    if hi_i < 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    i0, i1 = max(lo_i - reach, 0), min(hi_i + reach + 1, nx)
    j0, j1 = max(lo_j - reach, 0), min(hi_j + reach + 1, ny)
    far = reach + 1
    d = np.empty((i1 - i0, j1 - j0), np.int64)
    for i in range(i0, i1):
        for j in range(j0, j1):
            v = 0 if comp[i, j] == k else far
            if i > i0:
                v = min(v, d[i - 1 - i0, j - j0] + 1)
            if j > j0:
                v = min(v, d[i - i0, j - 1 - j0] + 1)
            d[i - i0, j - j0] = v
    for i in range(i1 - 1, i0 - 1, -1):
        for j in range(j1 - 1, j0 - 1, -1):
            v = d[i - i0, j - j0]
            if i < i1 - 1:
                v = min(v, d[i + 1 - i0, j - j0] + 1)
            if j < j1 - 1:
                v = min(v, d[i - i0, j + 1 - j0] + 1)
            d[i - i0, j - j0] = v
    out_i = np.empty(d.size, np.int64)
    out_j = np.empty(d.size, np.int64)
    m = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if 0 < d[i - i0, j - j0] <= reach:
                out_i[m], out_j[m] = i, j
                m += 1
    return out_i[:m], out_j[:m]


@numba.njit(cache=True, nogil=True)
def ring_terraces(comp, k, labels, reach, x0, cell):  # pragma: no cover - compiled
    """The labels met in component ``k``'s :func:`ring` (sorted, 0 included when met) and per
    label the mean x of its ring cells (numpy's sum, row-major order); and the component's
    first and last row j and how many rows it spans."""
    ri, rj = ring(comp, k, reach)
    lab = np.empty(ri.size, np.int64)
    for q in range(ri.size):
        lab[q] = labels[ri[q], rj[q]]
    found = np.unique(lab)
    mean_x = np.empty(found.size)
    xs = np.empty(ri.size)
    for u in range(found.size):
        m = 0
        for q in range(ri.size):
            if lab[q] == found[u]:
                xs[m] = x0 + (ri[q] + 0.5) * cell
                m += 1
        mean_x[u] = psum(xs[:m]) / m
    nx, ny = comp.shape
    in_row = np.zeros(ny, np.bool_)
    for i in range(nx):
        for j in range(ny):
            if comp[i, j] == k:
                in_row[j] = True
    rows = np.flatnonzero(in_row)
    return found, mean_x, rows[0], rows[-1], rows.size


@numba.njit(cache=True, nogil=True)
def ramp_plane(i, j, h, var, corr, x0, y0, cell, min_grad, min_length):  # pragma: no cover
    """The inverse-variance weighted plane z = c + gx (x - x̄) + gy (y - ȳ) through cells
    ``(i, j)``: status (0: the cells lie along one line, no plane; 1: too gentle or too short
    up its slope for a ramp; 2: a ramp), the centre (x̄, ȳ), the coefficients, their
    covariance, the change of the cells' pose σ per metre up the slope (its least-squares
    slope; 0 when it is the same everywhere), the RMS residual and the cells' x range."""
    n = i.size
    x, y, z = np.empty(n), np.empty(n), np.empty(n)
    w, c = np.empty(n), np.empty(n)
    for k in range(n):
        x[k] = x0 + (i[k] + 0.5) * cell
        y[k] = y0 + (j[k] + 0.5) * cell
        z[k] = h[i[k], j[k]]
        w[k] = 1.0 / max(var[i[k], j[k]], 1e-12)
        c[k] = corr[i[k], j[k]]
    sw = psum(w)
    xm, ym = psum(x * w) / sw, psum(y * w) / sw
    normal = np.zeros((3, 3))
    rhs = np.zeros(3)
    for k in range(n):
        a = (1.0, x[k] - xm, y[k] - ym)
        for p in range(3):
            rhs[p] += a[p] * w[k] * z[k]
            for q in range(3):
                normal[p, q] += a[p] * a[q] * w[k]
    coef = np.zeros(3)
    cov = np.zeros((3, 3))
    out = (0, xm, ym, coef, cov, 0.0, 0.0, 0.0, 0.0)
    if np.linalg.cond(normal) > 1e12:
        return out
    coef = np.linalg.solve(normal, rhs)
    res = z - (coef[0] + coef[1] * (x - xm) + coef[2] * (y - ym))
    s2 = psum(w * res * res) / max(n - 3, 1)
    cov = np.linalg.inv(normal) * s2
    gx, gy = coef[1], coef[2]
    grad = np.hypot(gx, gy)
    along = ((x - xm) * gx + (y - ym) * gy) / max(grad, 1e-12)
    if grad < min_grad or along.max() - along.min() < min_length:
        return (1, xm, ym, coef, cov, 0.0, 0.0, 0.0, 0.0)
    tilt = 0.0
    if c.max() - c.min() > 0:
        am, cm = psum(along) / n, psum(c) / n
        da = along - am
        tilt = abs(psum(da * (c - cm)) / psum(da * da))
    rms = np.sqrt(psum(res * res) / n)
    return (2, xm, ym, coef, cov, tilt, rms, x.min(), x.max())


@numba.njit(cache=True, nogil=True)
def slope_sigmas(gx, gy, cov, tilt):  # pragma: no cover - compiled
    """σ of a plane's slope angle (its gradient's σ along the gradient, and ``tilt``) and of
    its uphill direction, from the covariance of (c, gx, gy)."""
    grad = np.hypot(gx, gy)
    jx, jy = gx / max(grad, 1e-12), gy / max(grad, 1e-12)
    along = (jx * cov[1, 1] + jy * cov[2, 1]) * jx + (jx * cov[1, 2] + jy * cov[2, 2]) * jy
    slope_sigma = np.hypot(np.sqrt(along), tilt) / (1 + grad * grad)
    px, py = -gy / max(grad * grad, 1e-12), gx / max(grad * grad, 1e-12)
    across = (px * cov[1, 1] + py * cov[2, 1]) * px + (px * cov[1, 2] + py * cov[2, 2]) * py
    return slope_sigma, np.sqrt(max(across, 0.0))


@numba.njit(cache=True, nogil=True)
def big_components(mask, min_cells):  # pragma: no cover - compiled
    """The 4-connected components of ``mask`` (:func:`label4`) and, of those with at least
    ``min_cells`` cells (in label order), the labels and the cells (row-major): component q's
    cells are ``i[starts[q]:starts[q + 1]]``, ``j[…]``."""
    comp, n = label4(mask)
    nx, ny = comp.shape
    sizes = np.zeros(n + 1, np.int64)
    for a in range(nx):
        for b in range(ny):
            sizes[comp[a, b]] += 1
    slot = np.full(n + 1, -1, np.int64)
    ks = np.empty(n, np.int64)
    m = 0
    for k in range(1, n + 1):
        if sizes[k] >= min_cells:
            slot[k] = m
            ks[m] = k
            m += 1
    starts = np.zeros(m + 1, np.int64)
    for q in range(m):
        starts[q + 1] = starts[q] + sizes[ks[q]]
    fill = starts[:m].copy()
    ci = np.empty(starts[m], np.int64)
    cj = np.empty(starts[m], np.int64)
    for a in range(nx):
        for b in range(ny):
            q = slot[comp[a, b]]
            if q >= 0:
                ci[fill[q]], cj[fill[q]] = a, b
                fill[q] += 1
    return comp, ks[:m], starts, ci, cj
