"""Compiled loops of the feature extraction (numba): the view's cells and the terraces
(components, weighted sums, growth, extents). The ramps' loops are in
:mod:`graph_slam.terrain.features.ramp_kernels`, the edges' in
:mod:`graph_slam.terrain.features.edge_kernels`, the clearance's in
:mod:`graph_slam.terrain.features.clearance_kernels`.

The grid is small (100 × 60 cells) and the features' numpy formulation spent its time in
dozens of whole-grid temporaries and per-edge calls, not in arithmetic. Here each step is one
loop with the same arithmetic in the same order, so the results equal the numpy formulation
bit for bit: sums are taken in numpy's own pairwise order (:func:`psum`), medians as numpy
takes them, components numbered as :func:`scipy.ndimage.label` numbers them
(``tests/test_terrain_feature_kernels.py`` checks each against it). The one exception is the
ramp's plane (:func:`graph_slam.terrain.features.ramp_kernels.ramp_plane`): its 3×3 normal
matrix is summed in order, not by BLAS (within 1e-9 relative; the ramps' values move by about
1e-15).

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
def terrace_centres(labels, n, var):  # pragma: no cover - compiled
    """Per component 0…n: the inverse-variance weighted mean of its cells' index along x (the
    weights of its height: a tilt about y moves that height by the tilt times this point's x)."""
    sw = np.zeros(n + 1)
    swi = np.zeros(n + 1)
    nx, ny = labels.shape
    for i in range(nx):
        for j in range(ny):
            k = labels[i, j]
            if k == 0:
                continue
            w = 1.0 / max(var[i, j], 1e-12)
            sw[k] += w
            swi[k] += w * i
    return swi / np.maximum(sw, 1e-300)


@numba.njit(cache=True, nogil=True)
def terraces(level, known, h, var, corr, min_cells, steps, tol):  # pragma: no cover - compiled
    """The terraces of the level cells in one call: their components (:func:`label4`), per
    component its cells, inverse-variance height, σ parts (independent, pose) and whether it
    has ``min_cells`` (the others' cells unlabelled), the kept ones grown (:func:`grow`), and
    their extents after it (:func:`extents`), and where their heights lie along x
    (:func:`terrace_centres`, in cells)."""
    labels, n = label4(level)
    sizes, sw, swh, sind, scorr = terrace_sums(labels, n, h, var, corr)
    centre = terrace_centres(labels, n, var)
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
    return grown, sizes, height, ind, pose, keep, extents(grown, n), centre
