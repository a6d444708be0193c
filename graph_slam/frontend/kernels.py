"""Compiled per-pixel and per-voxel loops of the real-time front end (numba).

The projective preset (:mod:`graph_slam.frontend.projective`) spends its time in three
passes over a decimated depth image that no library offers in the form it needs: the
organised back-projection, the per-pixel normals and intensity gradients from neighbouring
pixels, and the pixel → voxel means on the house's fixed-origin grid with the voxel's row for
every pixel. Written with numpy they are a dozen temporaries each (5–6 ms per 424×240 frame
on one core); here each is one loop, the same arithmetic in the same order, so the results
equal the numpy formulation to rounding (the voxels in the order the pixels reach them, not
sorted by key) (``tests/test_frontend_kernels.py`` checks them
against it). Open3D's organised normal map has no validity or depth-jump test and no
intensity gradient; small_gicp's voxel maps have no pixel → voxel map.

Compiled on first use and cached on disk next to this file (``cache=True``): the first call in
a fresh checkout takes a few seconds, later processes load the cache.
"""

from __future__ import annotations

import numba
import numpy as np

#: bits per axis of a packed voxel key (as :mod:`graph_slam.frontend.cloud`)
KEY_BITS = 21
KEY_OFFSET = 1 << (KEY_BITS - 1)


@numba.njit(cache=True, nogil=True)
def organize(depth, step, fx, fy, cx, cy, min_depth, max_depth, color, has_color):
    """The decimated image (every ``step``-th pixel of ``depth``) back-projected: component
    planes 3×h×w (zeros where invalid), the valid mask (``min_depth ≤ z ≤ max_depth``; NaN
    invalid), the valid pixels' points K×3 (row-major order) with their flat pixel indices,
    and, with ``has_color``, the intensity h×w (mean of R, G, B in [0, 1])."""
    h = (depth.shape[0] + step - 1) // step
    w = (depth.shape[1] + step - 1) // step
    planes = np.zeros((3, h, w))
    valid = np.zeros((h, w), np.bool_)
    intensity = np.zeros((h, w) if has_color else (0, 0))
    xs = np.empty(w)
    for u in range(w):
        xs[u] = (u - cx) / fx
    rows = np.empty(h * w, np.int64)
    count = 0
    for v in range(h):
        ys = (v - cy) / fy
        for u in range(w):
            z = np.float64(depth[v * step, u * step])
            if z >= min_depth and z <= max_depth:
                valid[v, u] = True
                planes[0, v, u] = z * xs[u]
                planes[1, v, u] = z * ys
                planes[2, v, u] = z
                rows[count] = v * w + u
                count += 1
            if has_color:
                vs, us = v * step, u * step
                total = np.float64(color[vs, us, 0]) + np.float64(color[vs, us, 1])
                total += np.float64(color[vs, us, 2])
                intensity[v, u] = total * (1.0 / (3.0 * 255.0))
    points = np.empty((count, 3))
    for i in range(count):
        v, u = rows[i] // w, rows[i] % w
        for j in range(3):
            points[i, j] = planes[j, v, u]
    return planes, valid, points, rows[:count].copy(), intensity


@numba.njit(cache=True, nogil=True)
def pixel_normals(planes, valid, max_jump_ratio, intensity, has_intensity):
    """Per interior pixel (3×(h−2)×(w−2) component planes): the cross product of the central
    differences ``∂P/∂v × ∂P/∂u`` oriented towards the camera (unnormalised, area-weighted),
    defined where the pixel and its four neighbours are valid and their depths differ by at
    most ``max_jump_ratio · z``; with ``has_intensity`` the 3D intensity gradient in the
    tangent plane (``d·∂P/∂u = ∂I/∂u``, ``d·∂P/∂v = ∂I/∂v``, ``d·n = 0``)."""
    h, w = valid.shape
    hi, wi = max(h - 2, 0), max(w - 2, 0)
    normals = np.zeros((3, hi, wi))
    defined = np.zeros((hi, wi), np.bool_)
    grads = np.zeros((3, hi, wi) if has_intensity else (3, 0, 0))
    for i in range(hi):
        v = i + 1
        for j in range(wi):
            u = j + 1
            if not (valid[v, u] and valid[v, u + 1] and valid[v, u - 1]):
                continue
            if not (valid[v + 1, u] and valid[v - 1, u]):
                continue
            du0 = planes[0, v, u + 1] - planes[0, v, u - 1]
            du1 = planes[1, v, u + 1] - planes[1, v, u - 1]
            du2 = planes[2, v, u + 1] - planes[2, v, u - 1]
            dv0 = planes[0, v + 1, u] - planes[0, v - 1, u]
            dv1 = planes[1, v + 1, u] - planes[1, v - 1, u]
            dv2 = planes[2, v + 1, u] - planes[2, v - 1, u]
            limit = max_jump_ratio * planes[2, v, u]
            if not (abs(du2) <= limit and abs(dv2) <= limit):
                continue
            n0 = dv1 * du2 - dv2 * du1
            n1 = dv2 * du0 - dv0 * du2
            n2 = dv0 * du1 - dv1 * du0
            dot = n0 * planes[0, v, u] + n1 * planes[1, v, u] + n2 * planes[2, v, u]
            sign = -1.0 if dot > 0 else 1.0
            n0, n1, n2 = n0 * sign, n1 * sign, n2 * sign
            if n0 == 0 and n1 == 0 and n2 == 0:
                continue
            defined[i, j] = True
            normals[0, i, j], normals[1, i, j], normals[2, i, j] = n0, n1, n2
            if has_intensity:
                di_u = intensity[v, u + 1] - intensity[v, u - 1]
                di_v = intensity[v + 1, u] - intensity[v - 1, u]
                # rows (du, dv, n): the inverse's columns are (dv×n, n×du, du×dv) / det
                a0 = dv1 * n2 - dv2 * n1
                a1 = dv2 * n0 - dv0 * n2
                a2 = dv0 * n1 - dv1 * n0
                b0 = n1 * du2 - n2 * du1
                b1 = n2 * du0 - n0 * du2
                b2 = n0 * du1 - n1 * du0
                det = du0 * a0 + du1 * a1 + du2 * a2
                if abs(det) > 1e-30:
                    scale = 1.0 / det
                    grads[0, i, j] = (di_u * a0 + di_v * b0) * scale
                    grads[1, i, j] = (di_u * a1 + di_v * b1) * scale
                    grads[2, i, j] = (di_u * a2 + di_v * b2) * scale
    return normals, defined, grads


@numba.njit(cache=True, nogil=True)
def _voxel_ids(points, grid_T_cloud, voxel_m):
    """Each point's voxel id (in the order the points first reach the voxels) on the grid
    fixed in ``grid``, the packed keys of the ids, and whether a point fell outside the key's
    range. An open-addressing hash table; no sort (an argsort of the keys, for numpy's
    ``unique`` order, was a third of the preparation)."""
    count = points.shape[0]
    capacity = 16
    while capacity < 2 * count:
        capacity *= 2
    table_keys = np.full(capacity, -1, np.int64)
    table_ids = np.empty(capacity, np.int64)
    ids = np.empty(count, np.int64)
    keys = np.empty(count, np.int64)
    m = 0
    last_key, last_id = np.int64(-1), np.int64(-1)
    for i in range(count):
        key = np.int64(0)
        for a in range(3):
            g = (
                points[i, 0] * grid_T_cloud[a, 0]
                + points[i, 1] * grid_T_cloud[a, 1]
                + points[i, 2] * grid_T_cloud[a, 2]
                + grid_T_cloud[a, 3]
            )
            cell = np.int64(np.floor(g / voxel_m))
            if cell >= KEY_OFFSET or cell <= -KEY_OFFSET:
                return ids, keys[:0].copy(), True
            key = (key << KEY_BITS) | (cell + KEY_OFFSET)
        if key == last_key:  # neighbouring pixels share voxels: skip the table
            ids[i] = last_id
            continue
        slot = np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(20))
        slot &= capacity - 1
        while table_keys[slot] != -1 and table_keys[slot] != key:
            slot = (slot + 1) & (capacity - 1)
        if table_keys[slot] == -1:
            table_keys[slot] = key
            table_ids[slot] = m
            keys[m] = key
            m += 1
        ids[i] = table_ids[slot]
        last_key, last_id = key, ids[i]
    return ids, keys[:m].copy(), False


@numba.njit(cache=True, nogil=True)
def voxel_means(
    points, rows, shape_hw, grid_T_cloud, voxel_m, normals, defined, grads, intensity,
    has_intensity, normal_step, min_pixel_normals,
):  # fmt: skip
    """Voxel means of the valid pixels' ``points`` (flat pixel indices ``rows`` of an image
    ``shape_hw``) on the grid fixed in ``grid`` (``grid_T_cloud``, edge ``voxel_m``), in the
    order the pixels (row-major) first reach them; per voxel the normalised sum of the pixel normals (and the
    mean of the intensity gradients) of the interior pixels whose normal is ``defined``
    (pixels ``normal_step`` apart), and the mean intensity. Voxels with fewer than
    ``min_pixel_normals`` normals (or a zero sum) are dropped. Returns the kept voxels'
    points, unit normals, intensity and gradients, the h×w pixel → kept-voxel row (−1: none)
    and whether a point fell outside the key's range."""
    h, w = shape_hw
    ids, keys, outside = _voxel_ids(points, grid_T_cloud, voxel_m)
    pixel_voxel = np.full(h * w, -1, np.int64)
    if outside:
        z3 = np.zeros((0, 3))
        return z3, z3, np.zeros(0), z3, pixel_voxel.reshape(h, w), True
    m = keys.shape[0]
    count = np.zeros(m)
    psum = np.zeros((m, 3))
    isum = np.zeros(m)
    flat_intensity = intensity.ravel()
    for i in range(points.shape[0]):
        r = ids[i]
        pixel_voxel[rows[i]] = r
        count[r] += 1.0
        for j in range(3):
            psum[r, j] += points[i, j]
        if has_intensity:
            isum[r] += flat_intensity[rows[i]]
    n_defined = np.zeros(m, np.int64)
    nsum = np.zeros((m, 3))
    gsum = np.zeros((m, 3))
    hi, wi = defined.shape
    for i in range(hi):
        for j in range(wi):
            if not defined[i, j]:
                continue
            r = pixel_voxel[(i + 1) * normal_step * w + (j + 1) * normal_step]
            n_defined[r] += 1
            for a in range(3):
                nsum[r, a] += normals[a, i, j]
            if has_intensity:
                for a in range(3):
                    gsum[r, a] += grads[a, i, j]
    new_row = np.full(m, -1, np.int64)
    norm = np.empty(m)
    kept = 0
    for r in range(m):
        norm[r] = np.sqrt(
            nsum[r, 0] * nsum[r, 0] + nsum[r, 1] * nsum[r, 1] + nsum[r, 2] * nsum[r, 2]
        )
        if n_defined[r] >= min_pixel_normals and norm[r] > 0:
            new_row[r] = kept
            kept += 1
    out_points = np.empty((kept, 3))
    out_normals = np.empty((kept, 3))
    out_intensity = np.empty(kept if has_intensity else 0)
    out_grads = np.empty((kept if has_intensity else 0, 3))
    for r in range(m):
        k = new_row[r]
        if k < 0:
            continue
        for a in range(3):
            out_points[k, a] = psum[r, a] / count[r]
            out_normals[k, a] = nsum[r, a] / norm[r]
        if has_intensity:
            out_intensity[k] = isum[r] / count[r]
            for a in range(3):
                out_grads[k, a] = gsum[r, a] / n_defined[r]
    for i in range(rows.shape[0]):
        pixel_voxel[rows[i]] = new_row[pixel_voxel[rows[i]]]
    return out_points, out_normals, out_intensity, out_grads, pixel_voxel.reshape(h, w), False


@numba.njit(cache=True, nogil=True)
def projective_rows(
    src_points, src_normals, src_intensity, tgt_points, tgt_normals, tgt_intensity, tgt_grads,
    pixel_voxel, camera, target_T_source, max_distance_m, min_cos, color, geo, pho,
):  # fmt: skip
    """Projective association and colored ICP's rows in one pass. Each source voxel mean,
    moved by ``target_T_source``, is projected into the target's image (``camera``: fx, fy,
    cx, cy); the target voxel of that pixel is its correspondence when within
    ``max_distance_m`` and the normals agree (cosine ≥ ``min_cos``). Per correspondence the
    point-to-plane row ``geo · n·(q − p)`` and, with ``color``, the photometric row
    ``pho · (I_s − (I_t + d·(q_proj − p)))``, Jacobians for a left perturbation ``(ω, t)``
    about the target origin. Returns the K×2 (source, target) rows, the residuals and
    Jacobian (K point-to-plane rows, then K photometric ones with ``color``) and the moved
    source points q (K×3)."""
    fx, fy, cx, cy = camera
    h, w = pixel_voxel.shape
    rot = target_T_source[:3, :3]
    n_src = src_points.shape[0]
    corr = np.empty((n_src, 2), np.int64)
    qs = np.empty((n_src, 3))
    k = 0
    limit = max_distance_m * max_distance_m
    for i in range(n_src):
        x, y, z = src_points[i, 0], src_points[i, 1], src_points[i, 2]
        q0 = x * rot[0, 0] + y * rot[0, 1] + z * rot[0, 2] + target_T_source[0, 3]
        q1 = x * rot[1, 0] + y * rot[1, 1] + z * rot[1, 2] + target_T_source[1, 3]
        q2 = x * rot[2, 0] + y * rot[2, 1] + z * rot[2, 2] + target_T_source[2, 3]
        if not q2 > 1e-6:
            continue
        u = np.rint(fx * q0 / q2 + cx)
        v = np.rint(fy * q1 / q2 + cy)
        if not (u >= 0 and u < w and v >= 0 and v < h):
            continue
        t = pixel_voxel[int(v), int(u)]
        if t < 0:
            continue
        g0, g1, g2 = q0 - tgt_points[t, 0], q1 - tgt_points[t, 1], q2 - tgt_points[t, 2]
        if g0 * g0 + g1 * g1 + g2 * g2 > limit:
            continue
        cos = 0.0
        for a in range(3):
            ns = (
                src_normals[i, 0] * rot[a, 0]
                + src_normals[i, 1] * rot[a, 1]
                + src_normals[i, 2] * rot[a, 2]
            )
            cos += ns * tgt_normals[t, a]
        if cos < min_cos:
            continue
        corr[k, 0], corr[k, 1] = i, t
        qs[k, 0], qs[k, 1], qs[k, 2] = q0, q1, q2
        k += 1
    rows = 2 * k if color else k
    r = np.empty(rows)
    jac = np.empty((rows, 6))
    for c in range(k):
        t = corr[c, 1]
        q0, q1, q2 = qs[c, 0], qs[c, 1], qs[c, 2]
        n0, n1, n2 = tgt_normals[t, 0], tgt_normals[t, 1], tgt_normals[t, 2]
        e0, e1, e2 = q0 - tgt_points[t, 0], q1 - tgt_points[t, 1], q2 - tgt_points[t, 2]
        dist = e0 * n0 + e1 * n1 + e2 * n2
        r[c] = geo * dist
        jac[c, 0] = geo * (q1 * n2 - q2 * n1)
        jac[c, 1] = geo * (q2 * n0 - q0 * n2)
        jac[c, 2] = geo * (q0 * n1 - q1 * n0)
        jac[c, 3], jac[c, 4], jac[c, 5] = geo * n0, geo * n1, geo * n2
        if color:
            d0, d1, d2 = tgt_grads[t, 0], tgt_grads[t, 1], tgt_grads[t, 2]
            # q projected on the target's plane, minus p: (q − p) − dist·n
            i_t = tgt_intensity[t] + (
                d0 * (e0 - dist * n0) + d1 * (e1 - dist * n1) + d2 * (e2 - dist * n2)
            )
            dn = d0 * n0 + d1 * n1 + d2 * n2
            m0, m1, m2 = -(d0 - dn * n0), -(d1 - dn * n1), -(d2 - dn * n2)  # -(I − n nᵀ) d
            row = k + c
            r[row] = pho * (src_intensity[corr[c, 0]] - i_t)
            jac[row, 0] = pho * (q1 * m2 - q2 * m1)
            jac[row, 1] = pho * (q2 * m0 - q0 * m2)
            jac[row, 2] = pho * (q0 * m1 - q1 * m0)
            jac[row, 3], jac[row, 4], jac[row, 5] = pho * m0, pho * m1, pho * m2
    return corr[:k].copy(), r, jac, qs[:k].copy()


@numba.njit(cache=True, nogil=True)
def normal_equations(jac, r, w):
    """``JᵀWJ`` (6×6) and ``JᵀWr`` of weighted rows in one pass (rows of zero weight, the
    robust kernel's outliers, skipped)."""
    hess = np.zeros((6, 6))
    grad = np.zeros(6)
    for i in range(r.shape[0]):
        wi = w[i]
        if wi == 0.0:
            continue
        for a in range(6):
            ja = jac[i, a] * wi
            grad[a] += ja * r[i]
            for b in range(a, 6):
                hess[a, b] += ja * jac[i, b]
    for a in range(6):
        for b in range(a):
            hess[a, b] = hess[b, a]
    return hess, grad


@numba.njit(cache=True, nogil=True)
def significance(
    jac, w, q, n_geo, geo_scale, pho_scale, along_map, center, length, vectors,
    min_alignment, min_gradient,
):  # fmt: skip
    """Per eigen-direction ``v`` (the columns of ``vectors``, coordinates ``(L·ω, t)``): the
    weighted squared stiffness ``Σ w (J·v)²`` and the weight ``Σ w`` of the rows that hold
    ``v`` significantly (:func:`graph_slam.frontend.degeneracy.significant_stiffness`). ``along_map``:
    ``U·vectors``, so that a row's stiffness along ``v`` is ``J·along_map[:, j]``; a row's
    point moves by ``|ω × (q − c)/L + t|`` under ``v``. A point-to-plane row (the first
    ``n_geo``) counts when ``|J·v| ≥ min_alignment · geo_scale · |δ|``, a photometric one (row
    ``n_geo + i`` for point i) when ``|J·v| ≥ min_gradient · pho_scale · |δ|``."""
    total = np.zeros(6)
    count = np.zeros(6)
    moved = np.empty(6)
    for i in range(jac.shape[0]):
        wi = w[i]
        if wi == 0.0:
            continue
        geo = i < n_geo
        if not geo and pho_scale <= 0.0:
            continue
        p = i if geo else i - n_geo
        lx = (q[p, 0] - center[0]) / length
        ly = (q[p, 1] - center[1]) / length
        lz = (q[p, 2] - center[2]) / length
        for j in range(6):
            dx = vectors[1, j] * lz - vectors[2, j] * ly + vectors[3, j]
            dy = vectors[2, j] * lx - vectors[0, j] * lz + vectors[4, j]
            dz = vectors[0, j] * ly - vectors[1, j] * lx + vectors[5, j]
            moved[j] = np.sqrt(dx * dx + dy * dy + dz * dz)
        bound = min_alignment * geo_scale[p] if geo else min_gradient * pho_scale
        for j in range(6):
            along = 0.0
            for a in range(6):
                along += jac[i, a] * along_map[a, j]
            if abs(along) >= bound * moved[j]:
                total[j] += wi * along * along
                count[j] += wi
    return total, count


@numba.njit(cache=True, nogil=True)
def tukey_weights(residuals, k):
    """Tukey's IRLS weights ``(1 − (|r|/k)²)²`` for ``|r| ≤ k``, else 0 (NaN: 0): the
    arithmetic of :func:`graph_slam.frontend.objective.kernel_weights` element by element in
    one pass (the same values, without its five temporaries)."""
    w = np.empty(residuals.shape[0])
    for i in range(residuals.shape[0]):
        a = abs(residuals[i])
        if a <= k:
            t = a / k
            u = 1.0 - t * t
            w[i] = u * u
        else:
            w[i] = 0.0
    return w
