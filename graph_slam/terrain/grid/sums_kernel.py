"""The online grid's per-frame cell sums, compiled (numba).

:meth:`graph_slam.terrain.grid.online.CellSums.plus` adds a frame's points to the cells: per
cell the count and the weighted sums of the inverse-variance weights ``w = 1/(σ²_depth +
σ²_pose)``. Written with numpy that was seven ``bincount`` passes over the points and as many
temporaries; here one pass, each sum accumulated in the points' order from zero as
``bincount`` does, so the sums are the same numbers
(``tests/test_terrain_online.py`` checks them against the numpy formulation bit for bit).
Compiled on first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def cell_terms(flat, z_m, var_depth_m2, var_pose_m2, n):
    """Per cell (``n`` cells, the points' flat indices ``flat``): the point count and the
    sums of ``w``, ``w·z``, ``w²·σ²_depth``, ``w·σ_pose``, ``w·z²`` and ``w·σ²_depth``."""
    touched = np.zeros(n, np.int64)
    w_sum = np.zeros(n)
    wz = np.zeros(n)
    a = np.zeros(n)
    b = np.zeros(n)
    wz2 = np.zeros(n)
    d = np.zeros(n)
    for i in range(flat.shape[0]):
        c = flat[i]
        w = 1.0 / (var_depth_m2[i] + var_pose_m2[i])
        z = z_m[i]
        touched[c] += 1
        w_sum[c] += w
        wz[c] += w * z
        a[c] += w * w * var_depth_m2[i]
        b[c] += w * np.sqrt(var_pose_m2[i])
        wz2[c] += w * (z * z)
        d[c] += w * var_depth_m2[i]
    return touched, w_sum, wz, a, b, wz2, d
