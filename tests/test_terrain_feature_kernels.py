"""The features' compiled loops (graph_slam.terrain.features.kernels, ramp_kernels,
edge_kernels, and the local planes of extract) against the numpy formulations they replaced,
on seeded synthetic grids (a flight of stairs, a ramp, a box, seeded noise, unseen blobs,
flying-pixel cells, cells carried with no point). Everything equal bit for bit (the kernels
take sums in numpy's pairwise order), except the ramp's plane fit: its 3×3 normal matrix is
summed in order rather than by BLAS, within 1e-9 relative. The clearance's loops:
tests/test_terrain_clearance_kernels.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from graph_slam.terrain.features import edge_kernels as E
from graph_slam.terrain.features import kernels as K
from graph_slam.terrain.features import ramp_kernels as R
from graph_slam.terrain.features.config import FeatureConfig
from graph_slam.terrain.features.extract import _plane_kernel
from graph_slam.terrain.features.model import _Grid

NX, NY, CELL, X0, Y0 = 100, 60, 0.02, -0.2, -0.6
CFG = FeatureConfig()
SEEDS = (0, 1, 2)


def scene(seed: int) -> _Grid:
    """Stairs up from x 0.5 m (y < 0), a 8° ramp (y > 0.1), a box; noise, unseen blobs,
    flying-pixel cells behind the nosings, counts with carried (0) cells."""
    rng = np.random.default_rng(seed)
    x = X0 + (np.arange(NX)[:, None] + 0.5) * CELL + 0 * np.arange(NY)[None, :]
    y = Y0 + (np.arange(NY)[None, :] + 0.5) * CELL + 0 * x
    h = np.where(y < 0, np.clip(np.floor((x - 0.5) / 0.28) + 1, 0, 4) * 0.17, 0.0)
    h = np.where(y > 0.1, math.tan(math.radians(8.0)) * np.clip(x - 0.6, 0.0, 0.8), h)
    h = np.where((x > 0.3) & (x < 0.5) & (y > -0.05) & (y < 0.05), 0.15, h)
    h = h + rng.normal(0.0, 0.0015, h.shape)
    var = (0.0015 + rng.uniform(0, 0.002, h.shape)) ** 2
    unseen = ndimage.binary_dilation(rng.uniform(size=h.shape) < 0.01, iterations=2)
    h[unseen] = np.nan
    var[unseen] = np.nan
    noisy = np.isfinite(h) & (rng.uniform(size=h.shape) < 0.02)
    corr = rng.uniform(0.0, 0.002, h.shape)
    count = rng.integers(0, 30, h.shape).astype(np.float64)
    count[rng.uniform(size=h.shape) < 0.05] = 0.0
    return _Grid(h, var, corr, X0, Y0, CELL, noisy, count)


def classify(g: _Grid):
    tan = [math.tan(math.radians(d)) for d in (CFG.level_max_deg, CFG.ramp_min_deg,
                                               CFG.ramp_max_deg)]  # fmt: skip
    return _plane_kernel(g.h, g.known, 2, CFG.min_window_cells, g.cell, *tan, CFG.fit_rms_max_m)


# ------------------------------------------------------------------ numpy references
def ref_planes(h, known, half, min_cells):
    """The window planes as the loop over every window cell (slope per cell, RMS, valid)."""
    nx, ny = h.shape
    slope, rms, valid = np.zeros((nx, ny)), np.zeros((nx, ny)), np.zeros((nx, ny), bool)
    for i, j in zip(*np.nonzero(known), strict=True):
        n = sx = sy = sz = sxx = sxy = syy = sxz = syz = szz = 0.0
        z0 = h[i, j]
        for a in range(max(i - half, 0), min(i + half + 1, nx)):
            for b in range(max(j - half, 0), min(j + half + 1, ny)):
                if known[a, b]:
                    xx, yy, z = float(a - i), float(b - j), float(h[a, b] - z0)
                    n += 1.0
                    sx, sy, sz = sx + xx, sy + yy, sz + z
                    sxx, sxy, syy = sxx + xx * xx, sxy + xx * yy, syy + yy * yy
                    sxz, syz, szz = sxz + xx * z, syz + yy * z, szz + z * z
        if n < min_cells:
            continue
        mx, my, mz = sx / n, sy / n, sz / n
        cxx, cxy, cyy = sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my
        cxz, cyz, czz = sxz / n - mx * mz, syz / n - my * mz, szz / n - mz * mz
        det = cxx * cyy - cxy * cxy
        if det <= 1e-9:
            continue
        gx, gy = (cyy * cxz - cxy * cyz) / det, (cxx * cyz - cxy * cxz) / det
        slope[i, j] = math.sqrt(gx * gx + gy * gy)
        rms[i, j] = math.sqrt(max(czz - gx * cxz - gy * cyz, 0.0))
        valid[i, j] = True
    return slope, rms, valid


def ref_grow(known, h, labels, height, steps, tol):
    lab = labels.copy()
    nx, ny = lab.shape
    hk = np.where(known, h, np.nan)
    for _ in range(steps):
        free = known & (lab == 0)
        if not free.any():
            break
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nb = np.zeros_like(lab)
            nb[max(di, 0) : nx + min(di, 0), max(dj, 0) : ny + min(dj, 0)] = lab[
                max(-di, 0) : nx + min(-di, 0), max(-dj, 0) : ny + min(-dj, 0)
            ]
            with np.errstate(invalid="ignore"):
                take = free & (nb > 0) & (np.abs(hk - height[nb]) <= tol)
            lab[take] = nb[take]
            free &= ~take
    return lab


def ref_transitions(g: _Grid, labels, height, cfg: FeatureConfig):
    jj, ii = np.nonzero(labels.T)
    lab = labels[ii, jj]
    cand = np.flatnonzero((jj[:-1] == jj[1:]) & (lab[:-1] != lab[1:])
                          & (ii[1:] - ii[:-1] <= cfg.max_gap_cells + 1))  # fmt: skip
    ha, rise = height[lab[cand]], height[lab[cand + 1]] - height[lab[cand]]
    ok = np.abs(rise) >= cfg.min_rise_m
    cand, ha, rise = cand[ok], ha[ok], rise[ok]
    i1, i2, j = ii[cand], ii[cand + 1], jj[cand]
    width = cfg.max_gap_cells + 2
    idx = i1[:, None] + np.arange(width)[None, :]
    inside = idx <= i2[:, None]
    idx = np.minimum(idx, g.h.shape[0] - 1)
    hw, vw = g.h[idx, j[:, None]], g.var[idx, j[:, None]]
    flying = g.noisy[idx, j[:, None]] & (rise < 0)[:, None]
    with np.errstate(invalid="ignore"):
        f = np.clip((hw - ha[:, None]) / rise[:, None], 0.0, 1.0)
    if cfg.shadow_sparse_fraction > 0:  # the far cells seen only sparsely beyond a drop
        c = g.count
        near = np.stack([c[np.maximum(i1 - k, 0), j] for k in (0, 1)], axis=1).astype(float)
        ok = (near.min(axis=1) >= cfg.shadow_count_min) & (rise < 0)
        ref = near.mean(axis=1)[:, None]
        with np.errstate(invalid="ignore"):
            sparse = (f >= 0.5) & (c[idx, j[:, None]] < cfg.shadow_sparse_fraction * ref)
        flying |= ok[:, None] & sparse
    unknown = inside & (~np.isfinite(hw) | flying)
    f = np.where(unknown, 1.0, np.where(inside, f, 0.0))
    occluded = unknown.any(axis=1)
    pos = np.arange(width)[None, :]
    first_unknown = np.where(occluded, np.argmax(unknown, axis=1), width)[:, None]
    near = inside & ~unknown & (f < 0.5) & (pos < first_unknown)
    last_near = np.max(np.where(near, pos, 0), axis=1)[:, None]
    f = np.where(occluded[:, None] & (pos > last_near) & inside, 1.0, f)
    x = g.x0 + (i2 + 1) * g.cell - g.cell * f.sum(axis=1)
    c, i = g.count, i1 + last_near[:, 0]
    before = np.stack([c[np.maximum(i - k, 0), j] for k in (1, 2)], axis=1)
    before = np.where((i[:, None] - np.array([1, 2])) >= 0, before, 0.0)
    counted = before.min(axis=1) >= cfg.shadow_count_min
    with np.errstate(invalid="ignore", divide="ignore"):
        part = np.clip(c[i, j] / before.mean(axis=1), 0.0, 1.0)
    seen = np.where(counted, part, cfg.shadow_cell_seen)
    x = x - np.where(occluded, 1.0 - seen, 0.0) * g.cell
    noise = np.where(inside & ~unknown, np.nan_to_num(vw) / rise[:, None] ** 2, 0.0).sum(axis=1)
    carried = (c[i1, j] == 0) & (c[i2, j] == 0)
    flags = np.stack([occluded, counted, carried], axis=1)
    return lab[cand], lab[cand + 1], j, x, g.cell * np.sqrt(noise), flags


def ref_fit_line(y, x, s):
    keep = np.ones(len(y), bool)
    for _ in range(2):
        yy, xx = y[keep], x[keep]
        ym = yy.mean()
        syy = float(((yy - ym) ** 2).sum())
        b = float(((yy - ym) * (xx - xx.mean())).sum() / syy) if syy > 0 else 0.0
        res = x - (xx.mean() + b * (y - ym))
        scale = max(1.4826 * float(np.median(np.abs(res[keep]))), float(np.median(s)), 1e-4)
        new = np.abs(res) <= 3 * scale
        if new.sum() < 2 or (new == keep).all():
            break
        keep = new
    yy, xx, ss = y[keep], x[keep], s[keep]
    n = len(yy)
    ym, xm = float(yy.mean()), float(xx.mean())
    syy = float(((yy - ym) ** 2).sum())
    b = float(((yy - ym) * (xx - xm)).sum() / syy) if syy > 0 else 0.0
    res = xx - (xm + b * (yy - ym))
    var = max(float((res**2).sum()) / max(n - 2, 1), float(np.mean(ss**2)))
    return ym, xm, b, syy, var, n, float(yy.min()), float(yy.max())


def terraces_of(g: _Grid):
    level, _ = classify(g)
    labels, n = K.label4(level)
    sizes, sw, swh, _, _ = K.terrace_sums(labels, n, g.h, g.var, g.corr)
    height = swh / np.maximum(sw, 1e-300)
    keep = sizes >= CFG.min_terrace_cells
    keep[0] = False
    lab = np.where(keep[labels], labels, 0)
    return K.grow(lab, g.known, g.h, height, CFG.grow_cells, CFG.grow_tol_m), height


# ------------------------------------------------------------------ tests
def test_sums_and_medians_are_numpys():
    rng = np.random.default_rng(3)
    for n in [*range(1, 300), 1000, 4097]:
        a = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3, n)
        assert K.psum(a) == a.sum()
        assert K.median(a) == np.median(a)


@pytest.mark.parametrize("density", [0.2, 0.5, 0.6, 0.8])
def test_components_numbered_as_scipy(density):
    mask = np.random.default_rng(int(density * 10)).uniform(size=(NX, NY)) < density
    labels, n = K.label4(mask)
    ref, n_ref = ndimage.label(mask)
    assert n == n_ref and np.array_equal(labels, ref)


@pytest.mark.parametrize("density", [0.5, 0.65])
def test_big_components_and_their_cells(density):
    mask = np.random.default_rng(int(density * 100)).uniform(size=(NX, NY)) < density
    comp, ks, starts, ci, cj = R.big_components(mask, 20)
    ref, n = ndimage.label(mask)
    sizes = np.bincount(ref.ravel(), minlength=n + 1)
    want = [k for k in np.flatnonzero(sizes >= 20) if k > 0]
    assert np.array_equal(comp, ref) and list(ks) == want and len(want) > 0
    for q, k in enumerate(ks):
        i, j = np.nonzero(ref == k)
        assert np.array_equal(ci[starts[q] : starts[q + 1]], i)
        assert np.array_equal(cj[starts[q] : starts[q + 1]], j)
        ring = ndimage.binary_dilation(ref == k, iterations=4) & (ref != k)  # grid edges too
        assert np.array_equal(np.stack(R.ring(comp, k, 4)), np.stack(np.nonzero(ring)))


def test_slope_sigmas_as_numpy():
    rng = np.random.default_rng(4)
    for _ in range(50):
        m = rng.normal(size=(3, 3))
        cov = m @ m.T * 1e-6
        gx, gy, tilt = rng.normal(0.1, 0.05), rng.normal(0.0, 0.05), rng.uniform(0, 1e-3)
        grad = math.hypot(gx, gy)
        jac = np.array([gx, gy]) / grad
        perp = np.array([-gy, gx]) / grad**2
        want = (
            math.hypot(math.sqrt(float(jac @ cov[1:, 1:] @ jac)), tilt) / (1 + grad * grad),
            math.sqrt(max(float(perp @ cov[1:, 1:] @ perp), 0.0)),
        )
        np.testing.assert_allclose(R.slope_sigmas(gx, gy, cov, tilt), want, rtol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_planes_as_the_window_loop(seed):
    g = scene(seed)
    level, sloped = classify(g)
    slope, rms, valid = ref_planes(g.h, g.known, 2, CFG.min_window_cells)
    slope = slope / g.cell
    tan = [math.tan(math.radians(d)) for d in (CFG.level_max_deg, CFG.ramp_min_deg,
                                               CFG.ramp_max_deg)]  # fmt: skip
    ok = valid & (rms < CFG.fit_rms_max_m)
    assert np.array_equal(level, ok & (slope < tan[0]))
    assert np.array_equal(sloped, ok & (slope >= tan[1]) & (slope <= tan[2]))
    assert level.sum() > 1000 and sloped.sum() > 300  # the scene has both


@pytest.mark.parametrize("seed", SEEDS)
def test_terrace_sums_growth_and_extents(seed):
    g = scene(seed)
    level, _ = classify(g)
    labels, n = K.label4(level)
    sizes, sw, swh, sind, scorr = K.terrace_sums(labels, n, g.h, g.var, g.corr)
    flat = labels.ravel()
    w = np.where(level, 1.0 / np.maximum(g.var, 1e-12), 0.0).ravel()
    var_ind = np.maximum(g.var - g.corr**2, 0.0).ravel()
    hv = np.where(level, g.h, 0.0).ravel()
    assert np.array_equal(sizes, np.bincount(flat, minlength=n + 1))
    for got, want in ((sw, w), (swh, w * hv), (sind, w * w * var_ind), (scorr, w * g.corr.ravel())):
        assert np.array_equal(got[1:], np.bincount(flat, want, n + 1)[1:])
    height = swh / np.maximum(sw, 1e-300)
    keep = sizes >= CFG.min_terrace_cells
    keep[0] = False
    lab = np.where(keep[labels], labels, 0)
    for steps, tol in ((CFG.grow_cells, CFG.grow_tol_m), (6, 0.05)):
        grown = K.grow(lab, g.known, g.h, height, steps, tol)
        assert np.array_equal(grown, ref_grow(g.known, g.h, lab, height, steps, tol))
    grown = K.grow(lab, g.known, g.h, height, CFG.grow_cells, CFG.grow_tol_m)
    assert (grown > 0).sum() > (lab > 0).sum()  # it grew
    ext = K.extents(grown, n)
    for k, box in enumerate(ndimage.find_objects(grown, n), start=1):
        if box is None:
            assert (ext[k - 1] == -1).all()
        else:
            assert tuple(ext[k - 1]) == (
                box[0].start,
                box[0].stop - 1,
                box[1].start,
                box[1].stop - 1,
            )


@pytest.mark.parametrize("sparse", [0.0, 0.25])
@pytest.mark.parametrize("seed", SEEDS)
def test_edge_rows_and_line_fits(seed, sparse):
    g = scene(seed)
    if sparse:  # mirrored along x: the steps become drops, where the sparse rule applies
        g = _Grid(*(a[::-1].copy() for a in (g.h, g.var, g.corr)), g.x0, g.y0, g.cell,
                  g.noisy[::-1].copy(), g.count[::-1].copy())  # fmt: skip
    labels, height = terraces_of(g)
    cfg = CFG.model_copy(update={"shadow_sparse_fraction": sparse})
    args = (labels, height, g.h, g.var, g.noisy, g.count, True, cfg.max_gap_cells,
            cfg.min_rise_m, cfg.shadow_cell_seen, True, float(cfg.shadow_count_min),
            cfg.shadow_sparse_fraction, g.x0, g.cell)  # fmt: skip
    got = E.transitions(*args)
    want = ref_transitions(g, labels, height, cfg)
    if sparse:  # the rule moved some edges
        off = E.transitions(*args[:12], 0.0, *args[13:])
        assert (got[3] != off[3]).sum() >= 3
    assert len(got[0]) > 20 and got[5][:, 0].any() and got[5][:, 1].any()
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b)
    a, b, j, x, s, flags = got
    y = g.y_of(j)
    pairs, fits = E.edge_groups(a, b, y, x, s, flags, len(height), CFG.min_edge_rows)
    key = list(dict.fromkeys(zip(a.tolist(), b.tolist(), strict=True)))
    assert [tuple(p[:2]) for p in pairs] == [k for k in key if
                                             ((a == k[0]) & (b == k[1])).sum() >= CFG.min_edge_rows]  # fmt: skip
    for p, fit in zip(pairs, fits, strict=True):
        rows = (a == p[0]) & (b == p[1])
        assert tuple(fit) == ref_fit_line(y[rows], x[rows], s[rows])
        assert p[2] == (flags[rows, 0].mean() > 0.5) and p[4] == (flags[rows, 2].mean() > 0.5)
    rng = np.random.default_rng(seed)  # with outliers: the rejection rounds
    yy, xx, ss = rng.uniform(-0.3, 0.3, 40), rng.normal(0.5, 0.002, 40), rng.uniform(0, 0.003, 40)
    xx[::7] += 0.03
    assert E.fit_line(yy, xx, ss) == ref_fit_line(yy, xx, ss)


@pytest.mark.parametrize("seed", SEEDS)
def test_far_end_and_further_rise(seed):
    g = scene(seed)
    labels, height = terraces_of(g)
    for t in np.unique(labels)[1:6]:
        i, j = np.nonzero(labels == t)
        y = g.y_of(j)
        lo, hi = float(np.median(y)) - 0.1, float(np.median(y)) + 0.1
        rows = (y >= lo) & (y <= hi)
        x_far, y_mid = E.far_end(labels, t, lo, hi, g.x0, g.y0, g.cell)
        if rows.any():
            assert x_far == (g.x_of(i[rows]) + g.cell / 2).max() and y_mid == np.median(y[rows])
        else:
            assert math.isnan(x_far)
        for sign in (1.0, -1.0):
            want = 0
            for jj in range(0, NY):
                ii = np.flatnonzero(labels[:, jj] == t)
                if ii.size:
                    beyond = g.h[ii[-1] + 1 : ii[-1] + 12, jj]
                    beyond = beyond[np.isfinite(beyond)]
                    want += bool(beyond.size and (sign * (beyond - height[t])).max() >= 0.03)
            got = E.rows_rising_on(labels, t, g.h, 0, NY - 1, 11, sign, height[t], 0.03)
            assert got == want


@pytest.mark.parametrize("seed", SEEDS)
def test_ramp_plane_and_ring(seed):
    g = scene(seed)
    labels, _ = terraces_of(g)
    _, sloped = classify(g)
    comp, _ = K.label4(sloped)
    k = int(np.argmax(np.bincount(comp.ravel())[1:])) + 1  # the ramp
    i, j = np.nonzero(comp == k)
    out = R.ramp_plane(i, j, g.h, g.var, g.corr, g.x0, g.y0, g.cell, 0.06, 0.2)
    status, xm, ym, coef, cov, tilt, rms = out[:7]
    x, yv, z = g.x_of(i), g.y_of(j), g.h[i, j]
    w = 1.0 / np.maximum(g.var[i, j], 1e-12)
    assert status == 2 and xm == np.average(x, weights=w) and ym == np.average(yv, weights=w)
    a = np.column_stack([np.ones_like(x), x - xm, yv - ym])
    normal = a.T @ (a * w[:, None])
    want = np.linalg.solve(normal, a.T @ (w * z))
    res = z - a @ want
    want_cov = np.linalg.inv(normal) * float((w * res**2).sum() / (i.size - 3))
    along = ((x - xm) * want[1] + (yv - ym) * want[2]) / math.hypot(want[1], want[2])
    want_tilt = abs(float(np.polyfit(along, g.corr[i, j], 1)[0]))
    np.testing.assert_allclose(coef, want, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(cov, want_cov, rtol=1e-9, atol=1e-18)
    assert tilt == pytest.approx(want_tilt, rel=1e-9) and rms == pytest.approx(
        float(np.sqrt(np.mean(res**2))), rel=1e-9
    )
    assert abs(math.degrees(math.atan(math.hypot(coef[1], coef[2]))) - 8.0) < 1.0
    line = np.zeros_like(comp)  # known cells along one line: no plane
    line[40:70, 30] = g.known[40:70, 30]
    assert (
        R.ramp_plane(*np.nonzero(line), g.h, g.var, g.corr, g.x0, g.y0, g.cell, 0.06, 0.2)[0] == 0
    )
    mask = comp == k
    ring = ndimage.binary_dilation(mask, iterations=4) & ~mask
    ri, rj = R.ring(comp, k, 4)
    assert np.array_equal(np.stack([ri, rj]), np.stack(np.nonzero(ring)))
    found, mean_x, j_lo, j_hi, rows = R.ring_terraces(comp, k, labels, 4, g.x0, g.cell)
    assert (j_lo, j_hi, rows) == (j.min(), j.max(), np.unique(j).size)
    assert np.array_equal(found, np.unique(labels[ring]))
    for t, mx in zip(found, mean_x, strict=True):
        assert mx == np.mean(g.x_of(np.nonzero(ring & (labels == t))[0]))
