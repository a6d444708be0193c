"""The clearance's compiled loops (graph_slam.terrain.features.clearance_kernels), the view's
heights and the features' view cells against the numpy formulations they replaced (equal bit
for bit), on seeded synthetic grids (:func:`test_terrain_feature_kernels.scene`); and the live
warm-up's made-up grid reaching every compiled loop of the features and the prediction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_terrain_feature_kernels import CELL, NX, NY, SEEDS, X0, Y0, scene

from graph_slam.terrain.features import clearance_kernels as ck
from graph_slam.terrain.features import edge_kernels as E
from graph_slam.terrain.features import kernels as K
from graph_slam.terrain.features import ramp_kernels as R


@pytest.mark.parametrize("seed", SEEDS)
def test_view_cells_and_heights(seed):
    from graph_slam.terrain.grid.view import _height_variance

    rng = np.random.default_rng(seed)
    n = NX * NY
    w = np.where(rng.uniform(size=n) < 0.3, 0.0, rng.uniform(1e3, 1e6, n))
    wz = w * rng.normal(0.1, 0.2, n)
    a, b = w * w * rng.uniform(1e-8, 1e-3, n), w * rng.uniform(0, 3e-3, n)
    b[rng.uniform(size=n) < 0.1] = 0.0
    wz2, d = wz**2 / np.where(w > 0, w, 1.0) * 1.0001, w * rng.uniform(0, 1e-6, n)
    h, v = _height_variance(w, wz, a, b, wz2, d)
    with np.errstate(invalid="ignore", divide="ignore"):
        hh = wz / w
        excess = np.maximum(0.0, wz2 / w - hh**2 - d / w)
        assert np.array_equal(h, np.where(w > 0, hh, np.nan), equal_nan=True)
        assert np.array_equal(v, np.where(w > 0, a / w**2 + (b / w) ** 2 + excess, np.nan),
                              equal_nan=True)  # fmt: skip
        corr = np.nan_to_num(b / w).reshape(NX, NY)
        noise = (np.sqrt(a) / w).reshape(NX, NY)
    h2, v2 = h.reshape(NX, NY), v.reshape(NX, NY)
    got = K.view_cells(h2, v2, *(q.reshape(NX, NY) for q in (a, b, w)), 0.001)
    noisy = np.isfinite(h2) & ~(noise <= 0.001)
    assert 0 < noisy.sum() < np.isfinite(h2).sum()
    assert np.array_equal(got[0], corr) and np.array_equal(got[1], noisy)
    assert np.array_equal(got[2], np.isfinite(h2) & np.isfinite(v2) & ~noisy)


@pytest.mark.parametrize("seed", SEEDS)
def test_toe_cells_and_edge_profile(seed):
    from graph_slam.terrain.features.clearance import _OFFSETS, _profile

    g = scene(seed)
    rng = np.random.default_rng(seed)
    b = rng.uniform(0, 3e-3, g.h.shape) * 1e5
    b[rng.uniform(size=b.shape) < 0.1] = 0.0
    w = np.where(np.isfinite(g.h), 1e5, 0.0)
    xy = np.column_stack([rng.uniform(-0.3, 1.9, 200), rng.uniform(-0.7, 0.7, 200)])
    ground, sigma, _ = ck.highest_cells(xy, 0.01, _OFFSETS, X0, Y0, CELL, g.h, g.var, b, w)
    q = (xy[:, None, :] + 0.01 * _OFFSETS[None]) - np.array([X0, Y0])
    ij = np.floor(q / CELL).astype(np.int64)
    on = (ij[..., 0] >= 0) & (ij[..., 0] < NX) & (ij[..., 1] >= 0) & (ij[..., 1] < NY)
    i, j = np.where(on, ij[..., 0], 0), np.where(on, ij[..., 1], 0)
    hh = np.where(on, g.h[i, j], np.nan)
    hh = np.where(np.isfinite(hh), hh, -np.inf)
    k = np.argmax(hh, axis=1)
    rows = np.arange(len(xy))
    best = hh[rows, k]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        s = np.sqrt(np.maximum(g.var - np.nan_to_num(b / w) ** 2, 0.0))
    found = np.isfinite(best)
    assert 0 < found.sum() < len(xy)
    assert np.array_equal(ground, np.where(found, best, np.nan), equal_nan=True)
    assert np.array_equal(sigma, np.where(found, s[i[rows, k], j[rows, k]], np.nan), equal_nan=True)
    px, py = rng.uniform(0.3, 0.7, 300), rng.uniform(-0.2, 0.2, 300)
    pz = rng.uniform(-0.05, 0.25, 300)
    for near, far in ((0.0, 0.17), (0.17, 0.0)):
        yaw = 0.05
        c, sn = math.cos(yaw), math.sin(yaw)
        d = (px - 0.5) * c + (py - 0.01) * sn
        band = (np.abs(d) <= 0.04) & (py >= -0.15 - 0.02) & (py <= 0.15 + 0.02)
        dist, by_x, by_h = _profile(d[band], pz[band], near, far)
        m = int(np.argmin(dist))
        got = ck.edge_profile_min(px, py, pz, 0.5, 0.01, c, sn, -0.15, 0.15, 0.04, near, far)
        assert got == (int(np.flatnonzero(band)[m]), dist[m], by_x[m], by_h[m])
    # two overlapping edges: the later one's step model wins, as the per-edge numpy passes
    rows = np.array([[0.5, 0.01, c, sn, -0.15, 0.15, 0.0, 0.17, 0.003],
                     [0.52, 0.0, 1.0, 0.0, -0.1, 0.3, 0.17, 0.34, 0.004]])  # fmt: skip
    g0, s0 = rng.uniform(0, 0.2, 300), rng.uniform(0, 0.01, 300)
    ground, sigma, which = ck.edge_bands(px, py, rows, 0.04, g0, s0)
    want_g, want_s, want_w = g0.copy(), s0.copy(), np.full(300, -1)
    for e, (x_m, y_m, ce, se, lo, hi, near, far, rs) in enumerate(rows):
        d = (px - x_m) * ce + (py - y_m) * se
        band = (np.abs(d) <= 0.04) & (py >= lo - 0.02) & (py <= hi + 0.02)
        want_g = np.where(band, np.where(d >= 0, far, near), want_g)
        want_s, want_w = np.where(band, rs, want_s), np.where(band, e, want_w)
    assert (want_w == 0).any() and (want_w == 1).any()
    assert np.array_equal(ground, want_g) and np.array_equal(sigma, want_s)
    assert np.array_equal(which, want_w)


def test_resampled_path_as_numpy():
    def ref(p, step):
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        if not math.isfinite(s[-1]) or s[-1] <= 0:
            return p
        u = np.unique(np.concatenate([s, np.arange(0.0, s[-1], step)]))
        return np.column_stack([np.interp(u, s, p[:, k]) for k in range(3)])

    rng = np.random.default_rng(5)
    for t in range(200):
        n = int(rng.integers(2, 80))
        p = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0)
        if t % 4 == 0:  # repeated points: zero-length segments
            p[1 : min(4, n)] = p[0]
        got = ck.resample(p, 0.005)
        assert got.shape == ref(p, 0.005).shape and np.array_equal(got, ref(p, 0.005))
    still = np.zeros((5, 3))
    assert np.array_equal(ck.resample(still, 0.005), still)


def test_warm_up_takes_every_compiled_loop():
    """The live warm-up's made-up grid reaches every kernel the features and the prediction
    call (each has a compiled signature after it) and finds what it was made of."""
    from graph_slam.terrain.features import extract
    from graph_slam.terrain.features.warm import warm_up
    from graph_slam.terrain.grid import view

    features, clearance = warm_up()
    assert [s.n_steps for s in features.stairs] == [3] and len(features.curbs) == 1
    assert len(features.ramps) == 1 and features.ramps[0].start is not None
    assert clearance.terrain == "curb" and math.isfinite(clearance.edge_m)
    called = {  # the loops the features and the prediction call from Python
        K: ("terraces", "view_cells"),
        R: ("big_components", "ring_terraces", "ramp_plane", "slope_sigmas"),
        E: ("transitions", "edge_groups", "far_end", "rows_rising_on"),
        ck: ("highest_cells", "edge_bands", "edge_profile_min", "resample"),
        extract: ("_plane_kernel",),
        view: ("_height_variance",),
    }
    for module, names in called.items():
        for name in names:
            assert getattr(module, name).signatures, f"{module.__name__}.{name} not compiled"
