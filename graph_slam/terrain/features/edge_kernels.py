"""Compiled loops of the features' edges (numba): the rows where two terraces meet, the
robust line fit per terrace pair, and a single edge's far terrace (the steps of
:mod:`graph_slam.terrain.features.edges` and :mod:`graph_slam.terrain.features.kinds`). The
same arithmetic in the same order as their numpy formulation, sums in numpy's order
(``tests/test_terrain_feature_kernels.py``); compiled on first use and cached on disk, as
:mod:`graph_slam.terrain.features.kernels`."""

from __future__ import annotations

import numba
import numpy as np

from graph_slam.terrain.features.kernels import _nan_to_num, median, psum


@numba.njit(cache=True, nogil=True)
def transitions(
    labels,
    height,
    h,
    var,
    noisy,
    count,
    has_count,
    max_gap,
    min_rise,
    seen_default,
    from_counts,
    count_min,
    sparse_fraction,
    x0,
    cell,
):  # pragma: no cover - compiled
    """Every pair of labelled components met along a grid row (x) within ``max_gap`` cells
    whose heights differ by at least ``min_rise``, rows in order, then x: per pair the two
    labels, its row j, the edge's x and σ, and whether it is occluded, its shadow part came
    from the counts and both its cells were carried (the steps of
    :func:`graph_slam.terrain.features.edges.transitions`)."""
    nx, ny = labels.shape
    width = max_gap + 2
    cap = nx * ny
    out_a = np.empty(cap, np.int64)
    out_b = np.empty(cap, np.int64)
    out_j = np.empty(cap, np.int64)
    out_x = np.empty(cap)
    out_s = np.empty(cap)
    out_flags = np.empty((cap, 3), np.bool_)
    f = np.empty(width)
    noise = np.empty(width)
    inside = np.empty(width, np.bool_)
    unknown = np.empty(width, np.bool_)
    m = 0
    for j in range(ny):
        i1 = -1
        for i2 in range(nx):
            if labels[i2, j] == 0:
                continue
            if i1 < 0:
                i1 = i2
                continue
            la, lb = labels[i1, j], labels[i2, j]
            if la == lb or i2 - i1 > max_gap + 1:
                i1 = i2
                continue
            ha = height[la]
            rise = height[lb] - ha
            if not abs(rise) >= min_rise:
                i1 = i2
                continue
            # beyond a drop, a far cell holding under ``sparse_fraction`` of the two near
            # cells' mean count lies in the shadow for all but a few late viewpoints
            sparse_ref = -1.0
            if has_count and sparse_fraction > 0 and rise < 0:
                c0, c1 = count[i1, j], count[max(i1 - 1, 0), j]
                if min(c0, c1) >= count_min:
                    sparse_ref = sparse_fraction * ((c0 + c1) / 2.0)
            occluded = False
            first_unknown = width
            for k in range(width):
                idx = min(i1 + k, nx - 1)
                inside[k] = i1 + k <= i2
                hw = h[idx, j]
                flying = noisy[idx, j] and rise < 0
                if sparse_ref >= 0 and np.isfinite(hw) and count[idx, j] < sparse_ref:
                    flying = flying or min(max((hw - ha) / rise, 0.0), 1.0) >= 0.5
                unknown[k] = inside[k] and (not np.isfinite(hw) or flying)
                if unknown[k]:
                    f[k] = 1.0
                    if not occluded:
                        occluded = True
                        first_unknown = k
                elif inside[k]:
                    f[k] = min(max((hw - ha) / rise, 0.0), 1.0)
                else:
                    f[k] = 0.0
                if inside[k] and not unknown[k]:
                    noise[k] = _nan_to_num(var[idx, j]) / (rise * rise)
                else:
                    noise[k] = 0.0
            last_near = 0
            for k in range(width):
                if inside[k] and not unknown[k] and f[k] < 0.5 and k < first_unknown:
                    last_near = max(last_near, k)
            if occluded:
                for k in range(last_near + 1, width):
                    if inside[k]:
                        f[k] = 1.0
            x = x0 + (i2 + 1) * cell - cell * psum(f)
            seen, counted = seen_default, False
            if has_count and from_counts:
                i = i1 + last_near
                b1 = count[max(i - 1, 0), j] if i - 1 >= 0 else 0.0
                b2 = count[max(i - 2, 0), j] if i - 2 >= 0 else 0.0
                if min(b1, b2) >= count_min:
                    seen = min(max(count[i, j] / ((b1 + b2) / 2.0), 0.0), 1.0)
                    counted = True
            if occluded:
                x = x - (1.0 - seen) * cell
            out_a[m], out_b[m], out_j[m] = la, lb, j
            out_x[m] = x
            out_s[m] = cell * np.sqrt(psum(noise))
            out_flags[m, 0] = occluded
            out_flags[m, 1] = counted
            out_flags[m, 2] = has_count and count[i1, j] == 0 and count[i2, j] == 0
            m += 1
            i1 = i2
    return out_a[:m], out_b[:m], out_j[:m], out_x[:m], out_s[:m], out_flags[:m]


@numba.njit(cache=True, nogil=True)
def _line(y, x):  # pragma: no cover - compiled
    """Means and slope of x = x̄ + b (y - ȳ) (numpy's sums), and Σ(y - ȳ)²."""
    n = y.size
    ym = psum(y) / n
    xm = psum(x) / n
    dy = y - ym
    syy = psum(dy * dy)
    b = psum(dy * (x - xm)) / syy if syy > 0 else 0.0
    return ym, xm, b, syy


@numba.njit(cache=True, nogil=True)
def fit_line(y, x, s):  # pragma: no cover - compiled
    """The robust line fit of :func:`graph_slam.terrain.features.edges.fit_line` (two rounds
    of 3σ rejection): the rows kept's mean y and x, slope, Σ(y - ȳ)², residual variance
    (at least their mean σ²), count and y range."""
    keep = np.ones(y.size, np.bool_)
    med_s = median(s)
    for _ in range(2):
        ym, xm, b, _syy = _line(y[keep], x[keep])
        res = np.abs(x - (xm + b * (y - ym)))
        scale = max(1.4826 * median(res[keep]), med_s, 1e-4)
        new = res <= 3 * scale
        if new.sum() < 2 or (new == keep).all():
            break
        keep = new
    yy, xx, ss = y[keep], x[keep], s[keep]
    n = yy.size
    ym, xm, b, syy = _line(yy, xx)
    res = xx - (xm + b * (yy - ym))
    var = max(psum(res * res) / max(n - 2, 1), psum(ss * ss) / n)
    return ym, xm, b, syy, var, n, yy.min(), yy.max()


@numba.njit(cache=True, nogil=True)
def edge_groups(a, b, y, x, s, flags, n_labels, min_rows):  # pragma: no cover - compiled
    """The rows of :func:`transitions` grouped by terrace pair (pairs in the order first met,
    rows in order), those of at least ``min_rows`` rows fitted (:func:`fit_line`): per pair
    kept its two labels, whether most rows are occluded, most occluded ones counted and most
    carried, and the fit (ȳ, x̄, slope, Σ(y - ȳ)², variance, rows, y range) as a row of
    ``fits``."""
    m = a.size
    key = a * (n_labels + 1) + b
    order = np.argsort(key, kind="mergesort")
    starts = np.empty(m + 1, np.int64)
    g = 0
    for k in range(m):
        if k == 0 or key[order[k]] != key[order[k - 1]]:
            starts[g] = k
            g += 1
    starts[g] = m
    first = np.empty(g, np.int64)
    for q in range(g):
        first[q] = order[starts[q]]
    pairs = np.empty((g, 5), np.int64)
    fits = np.empty((g, 8))
    kept = 0
    for q in np.argsort(first, kind="mergesort"):
        rows = np.sort(order[starts[q] : starts[q + 1]])
        n = rows.size
        if n < min_rows:
            continue
        n_oc = n_ct = n_ca = 0
        for r in rows:
            n_oc += flags[r, 0]
            n_ct += flags[r, 0] and flags[r, 1]
            n_ca += flags[r, 2]
        occluded = n_oc / n > 0.5
        pairs[kept, 0], pairs[kept, 1] = a[rows[0]], b[rows[0]]
        pairs[kept, 2] = occluded
        pairs[kept, 3] = occluded and n_ct / n_oc > 0.5
        pairs[kept, 4] = n_ca / n > 0.5
        ym, xm, slope, syy, var, nk, lo, hi = fit_line(y[rows], x[rows], s[rows])
        fits[kept, 0], fits[kept, 1], fits[kept, 2], fits[kept, 3] = ym, xm, slope, syy
        fits[kept, 4], fits[kept, 5], fits[kept, 6], fits[kept, 7] = var, nk, lo, hi
        kept += 1
    return pairs[:kept], fits[:kept]


@numba.njit(cache=True, nogil=True)
def far_end(labels, label, y_lo, y_hi, x0, y0, cell):  # pragma: no cover - compiled
    """The far x edge of component ``label``'s cells whose row's y lies in [y_lo, y_hi] and
    the median of those cells' y (NaN, NaN: none)."""
    nx, ny = labels.shape
    ys = np.empty(nx * ny)
    m = 0
    x_far = -np.inf
    for i in range(nx):
        for j in range(ny):
            if labels[i, j] != label:
                continue
            y = y0 + (j + 0.5) * cell
            if y >= y_lo and y <= y_hi:
                ys[m] = y
                m += 1
                x_far = max(x_far, x0 + (i + 0.5) * cell + cell / 2)
    if m == 0:
        return np.nan, np.nan
    return x_far, median(ys[:m])


@numba.njit(cache=True, nogil=True)
def last_in_row(labels, label, j):  # pragma: no cover
    """The last cell along x of row ``j`` in component ``label`` (-1: none)."""
    last = -1
    for i in range(labels.shape[0]):
        if labels[i, j] == label:
            last = i
    return last


@numba.njit(cache=True, nogil=True)
def rows_rising_on(labels, label, h, j0, j1, look, sign, h_top, min_rise):  # pragma: no cover
    """In how many rows j0…j1 a known cell within ``look`` cells past component ``label``'s
    last cell lies at least ``min_rise`` further on (``sign``: +1 up, -1 down) from ``h_top``."""
    nx = labels.shape[0]
    rows = 0
    for j in range(j0, j1 + 1):
        last = last_in_row(labels, label, j)
        if last < 0:
            continue
        best = -np.inf
        seen = False
        for i in range(last + 1, min(last + 1 + look, nx)):
            v = h[i, j]
            if np.isfinite(v):
                seen = True
                best = max(best, sign * (v - h_top))
        if seen and best >= min_rise:
            rows += 1
    return rows


@numba.njit(cache=True, nogil=True)
def far_end_bridged(labels, label, height, known, j0, j1, look, tol, x0, cell):  # pragma: no cover
    """The far x edge of the surface of component ``label`` in rows j0…j1, followed across
    gaps of at most ``look`` cells not seen into components at its height (within ``tol``):
    beyond a drop the lower surface's first cells lie in the edge's shadow for the views from
    the top, and the surface goes on past them (-inf: the component is in none of the rows)."""
    nx = labels.shape[0]
    h0 = height[label]
    best = -np.inf
    for j in range(j0, j1 + 1):
        cur = last_in_row(labels, label, j)
        if cur < 0:
            continue
        while True:
            k = cur + 1
            while k < nx and k - cur <= look and not known[k, j]:
                k += 1
            if k >= nx or k - cur > look:
                break
            lab = labels[k, j]
            if lab <= 0 or abs(height[lab] - h0) > tol:
                break
            cur = k
            while cur + 1 < nx and labels[cur + 1, j] == lab:
                cur += 1
        best = max(best, x0 + (cur + 1) * cell)
    return best


@numba.njit(cache=True, nogil=True)
def face_share(count, a, b, la, lb, y, x, x0, y0, cell, count_min):  # pragma: no cover
    """The share of the points of the cells about the edge between components ``la`` and
    ``lb`` that lie on its face, the median over its rows (``a``, ``b``, ``y``, ``x``: the
    rows of :func:`transitions`): per row the three cells about the edge hold their surfaces'
    points plus the face's, the surfaces' points per cell taken from the cells two on either
    side (each at least ``count_min``, else a share of 0); 0 where no row is inside the grid."""
    nx, ny = count.shape
    shares = np.empty(a.size)
    m = 0
    for k in range(a.size):
        if a[k] != la or b[k] != lb:
            continue
        i = int(np.floor((x[k] - x0) / cell))
        j = int(np.floor((y[k] - y0) / cell))
        if i < 2 or i >= nx - 2 or j < 0 or j >= ny:
            continue
        c0, c1 = count[i - 2, j], count[i + 2, j]
        ref = (c0 + c1) / 2.0
        face = count[i - 1, j] + count[i, j] + count[i + 1, j] - 3.0 * ref
        share = 0.0
        if min(c0, c1) >= count_min and face > 0:
            share = face / (face + ref)
        shares[m] = share
        m += 1
    if m == 0:
        return 0.0
    return min(max(median(shares[:m]), 0.0), 1.0)
