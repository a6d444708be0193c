"""Compiled loops of the feature extraction (numba): the view's cells, the terraces
(components, weighted sums, growth, extents) and the ramps (their plane, the ring of cells
around them). The edges' loops are in :mod:`graph_slam.terrain.features.edge_kernels`, the
clearance's in :mod:`graph_slam.terrain.features.clearance_kernels`.

The grid is small (100 × 60 cells) and the features' numpy formulation spent its time in
dozens of whole-grid temporaries and per-edge calls, not in arithmetic. Here each step is one
loop with the same arithmetic in the same order, so the results equal the numpy formulation
bit for bit: sums are taken in numpy's own pairwise order (:func:`psum`), medians as numpy
takes them, components numbered as :func:`scipy.ndimage.label` numbers them
(``tests/test_terrain_feature_kernels.py`` checks each against it). The one exception is the
ramp's plane (:func:`ramp_plane`): its 3×3 normal matrix is summed in order, not by BLAS
(within 1e-9 relative; the ramps' values move by about 1e-15).

Compiled on first use and cached on disk next to this file (``cache=True``): the first call in
a fresh checkout takes a few seconds, later processes load the cache; a live run loads them
in its warm-up (:mod:`graph_slam.live.warmup`, :func:`graph_slam.terrain.features.warm.warm_up`).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def psum(a):  # pragma: no cover - compiled
    """Sum of a 1-D float array in numpy's order (its pairwise summation: blocks of 128, eight
    running sums inside a block), so that it equals ``a.sum()`` bit for bit."""
    n = a.size
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[0], a[1], a[2], a[3]
        r4, r5, r6, r7 = a[4], a[5], a[6], a[7]
        i = 8
        stop = n - n % 8
        while i < stop:
            r0 += a[i]
            r1 += a[i + 1]
            r2 += a[i + 2]
            r3 += a[i + 3]
            r4 += a[i + 4]
            r5 += a[i + 5]
            r6 += a[i + 6]
            r7 += a[i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return psum(a[:n2]) + psum(a[n2:])


@numba.njit(cache=True, nogil=True)
def median(a):  # pragma: no cover - compiled
    """``np.median`` of a 1-D float array without NaN (the middle one, or the mean of the
    middle two)."""
    s = np.sort(a)
    n = s.size
    if n % 2 == 1:
        return s[n // 2]
    return (s[n // 2 - 1] + s[n // 2]) / 2.0


@numba.njit(cache=True, nogil=True)
def label4(mask):  # pragma: no cover - compiled
    """4-connected components of a 2-D mask, numbered 1… in the order of their first cell in
    row-major order (as :func:`scipy.ndimage.label` with its default structure); 0 outside."""
    nx, ny = mask.shape
    labels = np.zeros((nx, ny), np.int64)
    si = np.empty(nx * ny, np.int64)
    sj = np.empty(nx * ny, np.int64)
    n = 0
    for i0 in range(nx):
        for j0 in range(ny):
            if not mask[i0, j0] or labels[i0, j0] != 0:
                continue
            n += 1
            labels[i0, j0] = n
            si[0], sj[0] = i0, j0
            top = 1
            while top > 0:
                top -= 1
                i, j = si[top], sj[top]
                for d in range(4):
                    a = i + (1 if d == 0 else -1 if d == 1 else 0)
                    b = j + (1 if d == 2 else -1 if d == 3 else 0)
                    if 0 <= a < nx and 0 <= b < ny and mask[a, b] and labels[a, b] == 0:
                        labels[a, b] = n
                        si[top], sj[top] = a, b
                        top += 1
    return labels, n


@numba.njit(cache=True, nogil=True)
def terrace_sums(labels, n, h, var, corr):  # pragma: no cover - compiled
    """Per component 0…n: its cells, and the inverse-variance weighted sums of height, of the
    squared weights times the variance less its pose part, and of the pose part (the cells in
    row-major order, as ``np.bincount`` takes them)."""
    sizes = np.zeros(n + 1, np.int64)
    sw = np.zeros(n + 1)
    swh = np.zeros(n + 1)
    sind = np.zeros(n + 1)
    scorr = np.zeros(n + 1)
    nx, ny = labels.shape
    for i in range(nx):
        for j in range(ny):
            k = labels[i, j]
            sizes[k] += 1
            if k == 0:
                continue
            w = 1.0 / max(var[i, j], 1e-12)
            sw[k] += w
            swh[k] += w * h[i, j]
            sind[k] += w * w * max(var[i, j] - corr[i, j] * corr[i, j], 0.0)
            scorr[k] += w * corr[i, j]
    return sizes, sw, swh, sind, scorr


@numba.njit(cache=True, nogil=True)
def _add_free_neighbours(lab, known, queued, ci, cj, n, i, j):  # pragma: no cover - compiled
    """Queue the known unlabelled 4-neighbours of cell (i, j) not queued yet."""
    nx, ny = lab.shape
    for d in range(4):
        a = i + (1 if d == 0 else -1 if d == 1 else 0)
        b = j + (1 if d == 2 else -1 if d == 3 else 0)
        if 0 <= a < nx and 0 <= b < ny and known[a, b] and lab[a, b] == 0 and not queued[a, b]:
            queued[a, b] = True
            ci[n], cj[n] = a, b
            n += 1
    return n


@numba.njit(cache=True, nogil=True)
def grow(labels, known, h, height, steps, tol):  # pragma: no cover - compiled
    """Each labelled component grown by up to ``steps`` cells into the known unlabelled cells
    within ``tol`` of its ``height``: per step the four neighbours in turn (+x, -x, +y, -y),
    each pass reading the labels as the previous pass left them (a pass's own writes land
    after it: they fill only unlabelled cells, which it reads as 0). A pass can only take a
    free cell next to a labelled one: those are the candidates it visits (the free
    neighbours of the labelled cells, and of each cell it labels), in any order (its writes
    land after it)."""
    lab = labels.copy()
    nx, ny = lab.shape
    queued = np.zeros((nx, ny), np.bool_)
    ci = np.empty(nx * ny, np.int64)
    cj = np.empty(nx * ny, np.int64)
    n = 0
    for i in range(nx):
        for j in range(ny):
            if lab[i, j] > 0:
                n = _add_free_neighbours(lab, known, queued, ci, cj, n, i, j)
    ti = np.empty(nx * ny, np.int64)
    tj = np.empty(nx * ny, np.int64)
    value = np.empty(nx * ny, np.int64)
    for _ in range(steps):
        if n == 0:
            break
        for d in range(4):
            di = 1 if d == 0 else -1 if d == 1 else 0
            dj = 1 if d == 2 else -1 if d == 3 else 0
            m = 0
            for k in range(n):
                a, b = ci[k] - di, cj[k] - dj
                if a < 0 or a >= nx or b < 0 or b >= ny:
                    continue
                nb = lab[a, b]
                if nb > 0 and abs(h[ci[k], cj[k]] - height[nb]) <= tol:
                    ti[m], tj[m], value[m] = ci[k], cj[k], nb
                    m += 1
            if m == 0:
                continue
            for q in range(m):
                lab[ti[q], tj[q]] = value[q]
            kept = 0  # the candidates still free
            for k in range(n):
                if lab[ci[k], cj[k]] == 0:
                    ci[kept], cj[kept] = ci[k], cj[k]
                    kept += 1
            n = kept
            for q in range(m):  # and the new cells' free neighbours
                n = _add_free_neighbours(lab, known, queued, ci, cj, n, ti[q], tj[q])
    return lab


@numba.njit(cache=True, nogil=True)
def extents(labels, n):  # pragma: no cover - compiled
    """Per component 1…n (row k-1): first and last i, first and last j (-1: no cell)."""
    out = np.full((n, 4), -1, np.int64)
    nx, ny = labels.shape
    for i in range(nx):
        for j in range(ny):
            k = labels[i, j] - 1
            if k < 0:
                continue
            if out[k, 0] < 0:
                out[k, 0], out[k, 1], out[k, 2], out[k, 3] = i, i, j, j
            else:
                out[k, 1] = max(out[k, 1], i)
                out[k, 2] = min(out[k, 2], j)
                out[k, 3] = max(out[k, 3], j)
    return out


@numba.njit(cache=True, nogil=True)
def _nan_to_num(v):  # pragma: no cover - compiled
    if np.isnan(v):
        return 0.0
    if np.isinf(v):
        return np.finfo(np.float64).max if v > 0 else -np.finfo(np.float64).max
    return v


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


@numba.njit(cache=True, nogil=True)
def view_cells(h, var, a, b, w, max_noise):  # pragma: no cover - compiled
    """Per cell of a grid's sums: the pose part of its σ ``b/w`` (0 where not finite, as
    ``np.nan_to_num``; ±inf as the largest float), whether only a depth edge's flying pixels
    hold it (a height, and its depth-noise σ ``√a/w`` not at most ``max_noise``) and whether
    it is known (finite height and variance, not noisy)."""
    nx, ny = h.shape
    corr = np.empty((nx, ny))
    noisy = np.zeros((nx, ny), np.bool_)
    known = np.zeros((nx, ny), np.bool_)
    for i in range(nx):
        for j in range(ny):
            corr[i, j] = (
                _nan_to_num(b[i, j] / w[i, j])
                if w[i, j] != 0
                else _nan_to_num(
                    np.nan if b[i, j] == 0 or np.isnan(b[i, j]) else np.copysign(np.inf, b[i, j])
                )
            )
            if np.isfinite(h[i, j]):
                noise = np.sqrt(a[i, j]) / w[i, j] if w[i, j] != 0 else np.inf
                noisy[i, j] = not noise <= max_noise
                known[i, j] = np.isfinite(var[i, j]) and not noisy[i, j]
    return corr, noisy, known


@numba.njit(cache=True, nogil=True)
def terraces(level, known, h, var, corr, min_cells, steps, tol):  # pragma: no cover - compiled
    """The terraces of the level cells in one call: their components (:func:`label4`), per
    component its cells, inverse-variance height, σ parts (independent, pose) and whether it
    has ``min_cells`` (the others' cells unlabelled), the kept ones grown (:func:`grow`), and
    their extents after it (:func:`extents`)."""
    labels, n = label4(level)
    sizes, sw, swh, sind, scorr = terrace_sums(labels, n, h, var, corr)
    height = np.empty(n + 1)
    ind = np.empty(n + 1)
    pose = np.empty(n + 1)
    keep = np.zeros(n + 1, np.bool_)
    for k in range(n + 1):
        d = max(sw[k], 1e-300)
        height[k] = swh[k] / d
        ind[k] = np.sqrt(sind[k]) / d
        pose[k] = scorr[k] / d
        keep[k] = k > 0 and sizes[k] >= min_cells
    nx, ny = labels.shape
    for a in range(nx):
        for b in range(ny):
            if not keep[labels[a, b]]:
                labels[a, b] = 0
    grown = grow(labels, known, h, height, steps, tol)
    return grown, sizes, height, ind, pose, keep, extents(grown, n)
