"""The pipelines' online terrain component: one :class:`OnlineElevationMap` per stride, updated
at every frame with the frame's online pose, carried across the foot strike, re-fused from the
smoothed poses when they come.

A pipeline calls :meth:`LiveTerrain.frame` once per frame (after its pose estimate) and gets
the read-only :class:`~graph_slam.terrain.grid.view.TerrainView` it puts in
``FrameOutput.terrain``; when a stride closes, :meth:`LiveTerrain.close` gives the stride's
online map at its last frame, and :meth:`LiveTerrain.refuse` its map from the smoothed poses.

Carry (``online.carry``): at a stride's first frame the previous stride's map is moved into the new stride frame through ``new_T_old = inv(world_T_new) @
world_T_old`` of the estimator, the stride frames' world poses read off the frames' estimates
(``world_T_camera @ inv(stride_T_camera)``). The map carried is the one re-fused from the
smoothed poses when the stride was smoothed at its close (the estimator starts the new stride
from the smoothed end state, so the link follows those poses), else (deferred smoothing: the
new stride starts from the iSAM2 estimate) the online map at its last frame. That pose's covariance: the new camera's anchor
covariance Σ_a and the previous stride's last camera covariance Σ_0 (camera local), both
moved to the old stride frame: ``Ad(old_T_camera) (Σ_a + Σ_0) Ad(old_T_camera)ᵀ``
(:func:`kinematics.conversions.adjoint_rot_first`; docs/terrain.md). Without covariances the
configured fallback σ stands for each. Nothing is carried out of the session's first stride:
it began without a foot strike (no anchor, weak priors), and its online map, fused from poses
the estimator corrected later, was measured 0.3–0.5 m off in the carried cells.

Settling gate (``online.max_pose_sigma_m``): from a stride's first frame, a frame whose pose
is not yet trustworthy is held back from the grid: the median, over its map cloud, of the
height σ its pose covariance alone gives (``σ_p`` of :mod:`graph_slam.terrain.grid.online`;
the covariance :meth:`LiveTerrain.frame` is given to decide, the estimator's marginal) above
the limit; a frame without an estimator's covariance (the baseline) is not checked. Once a
frame passes, the stride is settled and every later frame is fused (the
frames of a stride share its anchor: its poses do not unsettle). A held frame's cloud is still
kept for the re-fusion from the smoothed poses (``keep_clouds``). Per stride:
:meth:`LiveTerrain.counts` (frames fused, held back).
"""

from __future__ import annotations

import numpy as np

from graph_slam.terrain.grid.carry import carry_map
from graph_slam.terrain.grid.kernels import frame_point_terms
from graph_slam.terrain.grid.online import (
    OnlineElevationMap,
    OnlineTerrainConfig,
    fallback_covariance,
    z_variance,
)
from graph_slam.terrain.grid.view import TerrainView
from kinematics.conversions import adjoint_rot_first


class LiveTerrain:
    """Per-frame elevation grids for a pipeline (see the module docstring)."""

    def __init__(
        self,
        config: OnlineTerrainConfig,
        intrinsics,
        min_depth_m: float,
        max_depth_m: float,
        link_strides: bool = True,
    ) -> None:
        """``link_strides`` False: the pipeline's stride frames have no estimated relative
        pose (the baseline's world frame restarts at every stride): nothing is carried."""
        self.cfg = config
        self.link_strides = link_strides
        self.intrinsics = intrinsics
        self.min_depth_m = max(float(min_depth_m), config.min_depth_m)
        self.max_depth_m = min(float(max_depth_m), config.max_depth_m)
        self._fallback = fallback_covariance(config.fallback_pose_sigma)
        self.map: OnlineElevationMap | None = None
        self._frames: list[int] = []  # frame indices of the open map's kept clouds
        self._last: tuple[np.ndarray, np.ndarray | None] | None = None  # world_T_stride, Σ
        self._closed: dict[int, tuple[OnlineElevationMap, list[int]]] = {}
        self._refused: tuple[int, TerrainView] | None = None  # the latest re-fused stride
        self._first_stride: int | None = None  # the session's first (no foot strike)
        self.carried_from: dict[int, int] = {}
        """stride index -> the stride its map's prior was carried from."""
        self._counts: dict[int, list[int]] = {}  # stride index -> [fused, held back]
        self._settled = False  # the open stride has fused a frame past the gate

    def counts(self, stride_index: int) -> tuple[int, int]:
        """``(frames fused, frames held back)`` of a stride's grid (the settling gate)."""
        fused, held = self._counts.get(stride_index, (0, 0))
        return fused, held

    def needs_gate(self, stride_index: int) -> bool:
        """Whether the next frame of ``stride_index`` is still to be checked by the settling
        gate (a caller without per-frame covariances computes one for it only then)."""
        if self.cfg.max_pose_sigma_m is None or not self.cfg.enabled:
            return False
        return self.map is None or self.map.stride_index != stride_index or not self._settled

    def pose_sigma_m(self, points_camera_m, stride_T_camera, covariance) -> float:
        """The median height σ the pose covariance alone gives the points (every 4th)."""
        pts = np.asarray(points_camera_m, float)[::4]
        if not len(pts):
            return 0.0
        var = z_variance(pts, np.asarray(stride_T_camera, float)[:3, :3], covariance)
        return float(np.sqrt(max(np.median(var), 0.0)))

    def _covariance(self, covariance):
        if covariance is not None and np.isfinite(covariance).all():
            return np.asarray(covariance, float)
        return self._fallback

    def _start(self, stride_index: int, world_T_stride, covariance) -> None:
        """A new stride's map, with the previous one's cells ahead carried in when possible."""
        prior = None
        old = self.map
        if self._first_stride is None:
            self._first_stride = stride_index
        if old is not None and self.cfg.keep_clouds:
            self._closed[old.stride_index] = (old, self._frames)
        if (
            self.cfg.carry
            and self.link_strides
            and old is not None
            and self._last is not None
            and world_T_stride is not None
            and old.stride_index == stride_index - 1
            and old.stride_index != self._first_stride
        ):
            world_T_old, cov_old = self._last
            new_T_old = np.linalg.inv(world_T_stride[0]) @ world_T_old
            old_T_camera = np.linalg.inv(world_T_old) @ world_T_stride[0] @ world_T_stride[1]
            ad = adjoint_rot_first(old_T_camera)
            cov_rel = ad @ (self._covariance(covariance) + self._covariance(cov_old)) @ ad.T
            source = old.view()
            if self._refused is not None and self._refused[0] == old.stride_index:
                source = self._refused[1]  # the new stride frame follows the smoothed poses
            prior = carry_map(self.cfg, source, new_T_old, cov_rel)
            self.carried_from[stride_index] = old.stride_index
        self.map = OnlineElevationMap(self.cfg, stride_index, prior)
        self._frames = []
        self._settled = False
        self._counts[stride_index] = [0, 0]

    def frame(
        self,
        frame_index: int,
        frame,
        stride_index: int,
        stride_T_camera: np.ndarray | None,
        world_T_camera: np.ndarray | None,
        covariance: np.ndarray | None,
        gate_covariance: np.ndarray | None = None,
    ) -> TerrainView | None:
        """Fuse the frame into its stride's map; the map's view (None before the first stride
        or while the stride has no map). A frame without a pose leaves the map as it is.
        ``gate_covariance``: the pose covariance the settling gate decides on (module text;
        None: ``covariance``, or the fallback σ without one)."""
        if not self.cfg.enabled or stride_index < 0:
            return None
        strides = None
        if stride_T_camera is not None and world_T_camera is not None:
            world_T_stride = world_T_camera @ np.linalg.inv(stride_T_camera)
            strides = (world_T_stride, stride_T_camera)
        if self.map is None or self.map.stride_index != stride_index:
            self._start(stride_index, strides, covariance)
        if stride_T_camera is None:
            return self.map.view()
        points, ranges, terms = frame_point_terms(
            self.cfg, frame.depth_m, self.intrinsics, (self.min_depth_m, self.max_depth_m),
            stride_T_camera, self._covariance(covariance),
        )  # fmt: skip
        self._frames.append(int(frame_index))
        self._last = (strides[0], covariance)
        counts = self._counts.setdefault(stride_index, [0, 0])
        cov = covariance if gate_covariance is None else gate_covariance
        if cov is not None and self.needs_gate(stride_index):
            cov = self._covariance(cov)
            if self.pose_sigma_m(points, stride_T_camera, cov) > self.cfg.max_pose_sigma_m:
                counts[1] += 1
                self.map.keep_cloud(float(frame.t_s), points, ranges)
                return self.map.view()
            self._settled = True
        counts[0] += 1
        return self.map.fuse(terms, float(frame.t_s), points, ranges)

    def close(self, stride_index: int) -> TerrainView | None:
        """The stride's online map as it stood at its last frame (None: never started)."""
        if self.map is not None and self.map.stride_index == stride_index:
            return self.map.view()
        closed = self._closed.get(stride_index)
        return None if closed is None else closed[0].view()

    def refuse(
        self, stride_index: int, frame_indices, stride_T_camera: np.ndarray, covariances
    ) -> TerrainView | None:
        """The stride's map from other poses (``stride_T_camera``: one per frame of
        ``frame_indices``; covariances likewise or None), its kept clouds then forgotten."""
        if self.map is not None and self.map.stride_index == stride_index:
            entry = (self.map, self._frames)
        else:
            entry = self._closed.pop(stride_index, None)
        if entry is None or not self.cfg.keep_clouds:
            return None
        emap, kept = entry
        where = {int(f): i for i, f in enumerate(frame_indices)}
        rows = [where[f] for f in kept]
        poses = np.asarray(stride_T_camera, float)[rows]
        covs = [self._covariance(None if covariances is None else covariances[r]) for r in rows]
        view = emap.refuse(poses, covs)
        emap.clouds = []
        self._refused = (stride_index, view)
        return view
