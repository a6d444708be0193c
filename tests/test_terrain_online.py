"""The per-frame elevation grid: incremental equals batch, the variance model against Monte
Carlo, the carried map against an analytic transform, the grid's boxes on synthetic truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.terrain.grid.carry import carry_map
from graph_slam.terrain.grid.live import LiveTerrain
from graph_slam.terrain.grid.online import (
    CellSums,
    OnlineElevationMap,
    OnlineTerrainConfig,
    PointTerms,
    fuse_frames,
    z_variance,
)
from kinematics.conversions import adjoint_rot_first as adjoint


def _camera_pose(x_m=0.0, height_m=0.8, pitch_rad=np.pi / 4):
    """stride_T_camera: optical axis forward and down by ``pitch_rad``, image x to the right."""
    c, s = np.cos(pitch_rad), np.sin(pitch_rad)
    z = np.array([c, 0.0, -s])
    x = np.array([0.0, -1.0, 0.0])
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    pose[:3, 3] = [x_m, 0.0, height_m]
    return pose


def _plane_points(stride_T_camera, n_u=40, n_v=30, f_px=30.0):
    """Camera-frame points of the floor z = 0 seen through an n_u×n_v pinhole."""
    u, v = np.meshgrid(np.arange(n_u) - (n_u - 1) / 2, np.arange(n_v) - (n_v - 1) / 2)
    rays = np.column_stack([u.ravel() / f_px, v.ravel() / f_px, np.ones(u.size)])
    r_z = rays @ stride_T_camera[2, :3]
    lam = -stride_T_camera[2, 3] / r_z
    keep = (r_z < 0) & (lam < 3.0)
    return rays[keep] * lam[keep, None]


def _se3(xi):
    """4×4 exp of a rotation-first twist."""
    m = np.zeros((4, 4))
    w, v = xi[:3], xi[3:]
    m[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    m[:3, 3] = v
    return expm(m)


def _sigma_pose():
    a = np.random.default_rng(7).normal(size=(6, 6))
    corr = a @ a.T / 6 + np.eye(6)
    scale = np.array([2e-3, 2e-3, 2e-3, 3e-3, 3e-3, 3e-3])  # rad, m
    d = np.sqrt(np.diag(corr))
    return corr / np.outer(d, d) * np.outer(scale, scale)


CFG = OnlineTerrainConfig(cell_m=0.1, x_range_m=(-0.2, 2.0), y_range_m=(-1.0, 1.0))


def test_incremental_update_equals_batch_fusion():
    rng = np.random.default_rng(0)
    cov = _sigma_pose()
    poses = [_camera_pose(x_m=0.1 * k) for k in range(4)]
    clouds = [_plane_points(p) * (1 + rng.normal(0, 0.002, (1, 1))) for p in poses]
    covs = [cov * (1 + k) for k in range(4)]
    times = [0.01 * k for k in range(4)]
    m = OnlineElevationMap(CFG)
    for c, p, s, t in zip(clouds, poses, covs, times, strict=True):
        view = m.update(c, p, s, t)
    batch = fuse_frames(CFG, clouds, np.array(poses), covs, times)
    for name in ("w", "wz", "a", "b", "count", "last_t_s", "wz2", "d"):
        np.testing.assert_allclose(getattr(m.sums, name), getattr(batch, name), rtol=1e-12)
    assert view.known.sum() > 50
    # the re-fusion with the same poses is the batch fusion too
    again = m.refuse(np.array(poses), covs)
    np.testing.assert_allclose(again.height_m, view.height_m, atol=1e-6)  # kept as float32
    # views are snapshots: a later update leaves an earlier view as it was
    before = view.height_m.copy()
    m.update(clouds[0], poses[0] @ _se3(np.array([0, 0, 0, 0, 0, 0.05])), cov, 1.0)
    np.testing.assert_array_equal(view.height_m, before)
    with pytest.raises(ValueError):
        view.height_m[0, 0] = 1.0


def test_height_variance_matches_monte_carlo():
    """One frame of a flat floor: the cell heights' spread over 400 draws of the pose error
    (known covariance) and the depth noise equals the predicted σ within 15 %."""
    rng = np.random.default_rng(1)
    cov = _sigma_pose()
    pose = _camera_pose()
    pts = _plane_points(pose)
    noise = CFG.depth_noise
    sigma_z = noise.sigma_m(pts[:, 2])
    chol = np.linalg.cholesky(cov)
    predicted = OnlineElevationMap(CFG).update(pts, pose, cov, 0.0)
    heights = []
    for _ in range(400):
        noisy = pts * (1 + rng.normal(size=len(pts)) * sigma_z / pts[:, 2])[:, None]
        true_pose = pose @ _se3(chol @ rng.normal(size=6))
        heights.append(OnlineElevationMap(CFG).update(noisy, true_pose, cov, 0.0).height_m)
    heights = np.array(heights)
    cells = (predicted.count >= 3) & np.isfinite(heights).all(axis=0)
    assert cells.sum() > 30
    ratio = heights[:, cells].std(axis=0) / predicted.sigma_m[cells]
    assert 0.9 < np.median(ratio) < 1.1
    assert ((ratio > 0.85) & (ratio < 1.15)).mean() > 0.9
    # depth noise alone: the points of a cell average out
    alone = OnlineElevationMap(CFG).update(pts, pose, np.zeros((6, 6)), 0.0)
    assert np.nanmax(alone.sigma_m[cells]) < 0.6 * np.nanmin(predicted.sigma_m[cells])


def _terrain_view(cfg, box_x=(0.8, 1.0), box_h=0.1):
    """A grid of the floor with a box, laid down cell by cell (camera 1 m above, R = I)."""
    nx, ny = cfg.shape
    x = cfg.x_range_m[0] + (np.arange(nx) + 0.5) * cfg.cell_m
    y = cfg.y_range_m[0] + (np.arange(ny) + 0.5) * cfg.cell_m
    xx, yy = np.meshgrid(x, y, indexing="ij")
    zz = np.where((xx > box_x[0]) & (xx < box_x[1]), box_h, 0.0)
    pts = np.column_stack([xx.ravel(), yy.ravel(), zz.ravel() + 1.0])
    camera = np.eye(4)
    camera[2, 3] = -1.0
    return OnlineElevationMap(cfg).update(pts, camera, np.diag([1e-6] * 3 + [4e-6] * 3), 0.0)


def test_carried_map_equals_the_analytic_transform():
    cfg = OnlineTerrainConfig()
    old = _terrain_view(cfg)
    # a shift by whole cells: every carried cell is one old cell, its height + tz
    new_T_old = np.eye(4)
    new_T_old[:3, 3] = [-0.6, 0.04, 0.01]
    carried = carry_map(cfg, old, new_T_old, np.zeros((6, 6)))
    new = OnlineElevationMap(cfg, 1, carried).view()
    h_old, h_new = old.height_m, new.height_m
    np.testing.assert_allclose(h_new[10:50, 2:], h_old[40:80, :-2] + 0.01, atol=1e-12)
    np.testing.assert_allclose(new.variance_m2[10:50, 2:], old.variance_m2[40:80, :-2])
    assert not new.known[:10].any()  # behind the new heel (x < 0): not carried
    assert new.count.sum() == 0  # no point of the new stride yet
    # the relative pose's covariance adds J Σ Jᵀ (z row): rotation about x, y and z translation
    s_rx, s_ry, s_tz = 0.01, 0.02, 0.005
    cov = np.diag([s_rx**2, s_ry**2, 0.0, 0.0, 0.0, s_tz**2])
    grown = OnlineElevationMap(cfg, 1, carry_map(cfg, old, new_T_old, cov)).view()
    xc, yc = old.cell_centers_m()
    px, py = np.meshgrid(xc[40:80], yc[:-2], indexing="ij")
    analytic = py**2 * s_rx**2 + px**2 * s_ry**2 + s_tz**2
    np.testing.assert_allclose(
        grown.variance_m2[10:50, 2:] - old.variance_m2[40:80, :-2], analytic, rtol=1e-9
    )
    # a yawed transform: heights of cells well inside the floor and the box follow the plane
    yaw = 0.2
    rot = np.eye(4)
    rot[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    rot[:3, 3] = [-0.5, 0.1, 0.02]
    view = OnlineElevationMap(cfg, 1, carry_map(cfg, old, rot, np.zeros((6, 6)))).view()
    xn, yn = view.cell_centers_m()
    xx, yy = np.meshgrid(xn, yn, indexing="ij")
    back = np.linalg.inv(rot)
    ox = back[0, 0] * xx + back[0, 1] * yy + back[0, 3]
    oy = back[1, 0] * xx + back[1, 1] * yy + back[1, 3]
    on_old = (ox > -0.15) & (ox < 1.75) & (np.abs(oy) < 0.55)
    inner = on_old & (np.abs(ox - 0.8) > 0.05) & (np.abs(ox - 1.0) > 0.05)
    expect = np.where((ox > 0.8) & (ox < 1.0), 0.1, 0.0) + 0.02
    ok = inner & view.known
    assert ok.sum() > 1000
    np.testing.assert_allclose(view.height_m[ok], expect[ok], atol=1e-9)


def test_adjoint_moves_a_right_perturbation_to_the_left():
    rng = np.random.default_rng(3)
    pose = _se3(rng.normal(size=6) * 0.5)
    xi = rng.normal(size=6) * 1e-3
    np.testing.assert_allclose(pose @ _se3(xi), _se3(adjoint(pose) @ xi) @ pose, atol=1e-12)


def test_z_variance_is_the_numerical_jacobian():
    rng = np.random.default_rng(4)
    pose = _se3(rng.normal(size=6) * 0.5)
    p = rng.normal(size=(1, 3))
    jac = np.zeros(6)
    for k in range(6):
        d = np.zeros(6)
        d[k] = 1e-6
        plus = (pose @ _se3(d))[:3] @ np.append(p, 1)
        minus = (pose @ _se3(-d))[:3] @ np.append(p, 1)
        jac[k] = (plus[2] - minus[2]) / 2e-6
    cov = _sigma_pose()
    np.testing.assert_allclose(z_variance(p, pose[:3, :3], cov)[0], jac @ cov @ jac, rtol=1e-6)


def _frame(t_s, depth):
    return RgbdFrame(index=0, t_s=t_s, depth_m=depth, color_rgb=None)


def test_live_terrain_carries_ahead_only_when_configured():
    intr = CameraIntrinsics(width_px=40, height_px=30, fx_px=30.0, fy_px=30.0, cx_px=19.5,
                            cy_px=14.5)  # fmt: skip
    pose = _camera_pose(x_m=0.0)
    pts = _plane_points(pose)
    depth = np.zeros((30, 40), np.float32)
    u = np.rint(pts[:, 0] / pts[:, 2] * 30 + 19.5).astype(int)
    v = np.rint(pts[:, 1] / pts[:, 2] * 30 + 14.5).astype(int)
    depth[v, u] = pts[:, 2]
    world_T_stride1 = np.eye(4)
    world_T_stride1[0, 3] = 0.5  # the new stride frame 0.5 m ahead
    for carry, expect_known in ((True, True), (False, False)):
        live = LiveTerrain(OnlineTerrainConfig(carry=carry, pixel_step=1), intr, 0.1, 3.0)
        # the session's first stride (no foot strike) is never carried out of
        live.frame(0, _frame(0.0, np.zeros_like(depth)), 0, pose, pose, None)
        first = live.frame(1, _frame(0.05, depth), 1, pose, pose, None)
        assert first.known.sum() > 100 and not live.carried_from
        new = live.frame(
            2, _frame(0.1, np.zeros_like(depth)), 2, pose, world_T_stride1 @ pose, None
        )
        assert new.stride_index == 2
        assert bool(new.known.any()) is expect_known
        if carry:
            assert live.carried_from == {2: 1}
            # what was at old x lies at x - 0.5 now, on the floor (height 0)
            assert np.nanmax(np.abs(new.height_m)) < 1e-6  # float32 depth
            # ... and 0.5 m nearer: the far edge of the known cells moved 25 cells back
            far_first = np.flatnonzero(first.known.any(axis=1)).max()
            far_new = np.flatnonzero(new.known.any(axis=1)).max()
            assert abs((far_first - far_new) - 0.5 / new.cell_m) <= 1, (far_first, far_new)
            assert np.nanmin(new.sigma_m) > np.nanmin(first.sigma_m)


def test_cell_sums_empty_view_is_nan():
    m = OnlineElevationMap(CFG, prior=CellSums.empty(int(np.prod(CFG.shape))))
    v = m.view()
    assert np.isnan(v.height_at(0.5, 0.0)) and np.isnan(v.height_at(50.0, 0.0))
    assert v.obstacles_ahead() == ()


def test_grid_obstacles_find_a_box_on_a_floor():
    """A 10 cm box from x = 0.8 to 1.1 m on a flat floor, seen from 1 m straight above: one
    grid box, leading edge within a cell, height within a millimetre, seen whole."""
    from graph_slam.terrain.grid.grid_obstacles import grid_obstacles

    x, y = np.meshgrid(np.arange(0.0, 1.6, 0.005), np.arange(-0.5, 0.5, 0.005), indexing="ij")
    box = (x >= 0.8) & (x < 1.1) & (np.abs(y) < 0.15)
    pts = np.column_stack([x.ravel(), y.ravel(), np.where(box, 0.1, 0.0).ravel()])
    pose = np.eye(4)  # camera 1 m up, looking down: x_cam = -y, y_cam = -x, z_cam = -z
    pose[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    pose[:3, 3] = [0.8, 0.0, 1.0]
    emap = OnlineElevationMap(OnlineTerrainConfig(), 0)
    view = emap.update((pts - pose[:3, 3]) @ pose[:3, :3], pose, np.eye(6) * 1e-8, 0.0)
    found = grid_obstacles(view).obstacles
    assert len(found) == 1, found
    (ob,) = found
    assert abs(ob.leading_edge_x_m - 0.8) <= view.cell_m
    assert abs(ob.height_m - 0.1) < 1e-3
    assert abs(ob.width_m - 0.3) <= 2 * view.cell_m
    # the whole-boxes-only search gives the same box
    (whole,) = grid_obstacles(view, complete_only=True).obstacles
    assert ob.complete and whole.leading_edge_x_m == ob.leading_edge_x_m
    assert whole.height_m == ob.height_m
    # half the box off the grid's side: seen in part, left out by the whole-boxes search
    part = pts.copy()
    part[:, 1] += 0.45
    view = OnlineElevationMap(OnlineTerrainConfig(), 0).update(
        (part - pose[:3, 3]) @ pose[:3, :3], pose, np.eye(6) * 1e-8, 0.0
    )
    assert [o.complete for o in grid_obstacles(view).obstacles] == [False]
    assert grid_obstacles(view, complete_only=True).obstacles == ()


def _plus_reference(sums, terms, t_s):
    """``CellSums.plus`` written with numpy's bincount (the compiled pass's reference)."""
    n = len(sums.w)
    w = 1.0 / (terms.var_depth_m2 + terms.var_pose_m2)
    touched = np.bincount(terms.flat, minlength=n)
    last = sums.last_t_s.copy()
    last[touched > 0] = t_s
    f = terms.flat
    return CellSums(
        sums.w + np.bincount(f, w, n),
        sums.wz + np.bincount(f, w * terms.z_m, n),
        sums.a + np.bincount(f, w * w * terms.var_depth_m2, n),
        sums.b + np.bincount(f, w * np.sqrt(terms.var_pose_m2), n),
        sums.count + touched,
        last,
        sums.wz2 + np.bincount(f, w * terms.z_m**2, n),
        sums.d + np.bincount(f, w * terms.var_depth_m2, n),
    )


def test_cell_sums_plus_equals_the_bincount_formulation():
    """Two frames of random points (cells hit many times, some never) added by the compiled
    pass give the numpy bincount sums bit for bit; the previous sums are left unchanged."""
    rng = np.random.default_rng(21)
    n = 500
    sums = CellSums.empty(n)
    ref = sums
    for frame, t_s in enumerate((0.5, 0.6)):
        k = 3000 + 500 * frame
        terms = PointTerms(
            rng.integers(0, n - 50, k),
            rng.normal(0.0, 0.05, k),
            rng.uniform(1e-6, 1e-4, k),
            rng.uniform(0.0, 1e-4, k),
        )
        prev, before = sums, sums.w.copy()
        sums, ref = sums.plus(terms, t_s), _plus_reference(ref, terms, t_s)
        np.testing.assert_array_equal(prev.w, before)  # views keep their arrays
        for name in ("w", "wz", "a", "b", "count", "last_t_s", "wz2", "d"):
            np.testing.assert_array_equal(getattr(sums, name), getattr(ref, name), err_msg=name)
    assert np.all(sums.count[n - 50 :] == 0) and sums.count.sum() == 3000 + 3500


def _floor_depth(pose):
    intr = CameraIntrinsics(width_px=40, height_px=30, fx_px=30.0, fy_px=30.0, cx_px=19.5,
                            cy_px=14.5)  # fmt: skip
    pts = _plane_points(pose)
    depth = np.zeros((30, 40), np.float32)
    u = np.rint(pts[:, 0] / pts[:, 2] * 30 + 19.5).astype(int)
    v = np.rint(pts[:, 1] / pts[:, 2] * 30 + 14.5).astype(int)
    depth[v, u] = pts[:, 2]
    return intr, depth


@pytest.mark.parametrize("keep_clouds", [True, False])
def test_the_settling_gate_holds_frames_until_the_pose_is_trustworthy(keep_clouds):
    """A stride's frames with a 5° tilt σ (height σ ~0.1 m at 1-2 m) are held back and
    counted; the first frame at 0.5 mrad (σ ~1 mm) settles the stride and every later frame is
    fused, whatever its σ; a frame without covariance is never checked."""
    pose = _camera_pose()
    intr, depth = _floor_depth(pose)
    loose = np.diag([np.radians(5.0)] * 3 + [0.02] * 3) ** 2
    tight = np.diag([5e-4] * 3 + [1e-3] * 3) ** 2
    cfg = OnlineTerrainConfig(pixel_step=1, keep_clouds=keep_clouds)
    live = LiveTerrain(cfg, intr, 0.1, 3.0)
    assert live.pose_sigma_m(_plane_points(pose), pose, loose) > 0.05
    assert live.pose_sigma_m(_plane_points(pose), pose, tight) < 0.003
    held = live.frame(0, _frame(0.0, depth), 1, pose, pose, None, loose)
    assert not held.known.any() and live.counts(1) == (0, 1) and live.needs_gate(1)
    live.frame(1, _frame(0.01, depth), 1, pose, pose, loose)  # its own covariance decides
    assert live.counts(1) == (0, 2)
    fused = live.frame(2, _frame(0.02, depth), 1, pose, pose, None, tight)
    assert fused.known.sum() > 100 and live.counts(1) == (1, 2) and not live.needs_gate(1)
    live.frame(3, _frame(0.03, depth), 1, pose, pose, loose)  # settled: fused
    assert live.counts(1) == (2, 2)
    if keep_clouds:  # the held frames' clouds are kept for the smoothed poses' re-fusion
        again = live.refuse(1, [0, 1, 2, 3], np.stack([pose] * 4), [tight] * 4)
        assert again.known.sum() == fused.known.sum()
        assert np.allclose(np.nanmax(np.abs(again.height_m)), 0.0, atol=1e-6)
    # the next stride is checked again; a frame with no covariance at all is not
    live.frame(4, _frame(0.04, depth), 2, pose, pose, None)
    assert live.counts(2) == (1, 0)
    off = LiveTerrain(cfg.model_copy(update={"max_pose_sigma_m": None}), intr, 0.1, 3.0)
    off.frame(0, _frame(0.0, depth), 1, pose, pose, loose)
    assert off.counts(1) == (1, 0) and not off.needs_gate(1)
