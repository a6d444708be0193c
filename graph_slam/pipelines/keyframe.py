"""Which earlier frame of the stride a frame registers against: the keyframe.

Frame-to-frame registration at 90 Hz chains one registration per frame, and each one's error
(depth noise, not motion: about 1 mm at quarter resolution) adds up along the stride. Several
frames registered against the same keyframe share no chain: the error of a frame's pose is
that of the keyframe plus one registration. :class:`Keyframes` keeps the keyframe and decides,
after each frame's graph update, whether that frame replaces it (:class:`KeyframeConfig`):

* no keyframe yet, a new stride, or this frame's registration was not accepted (failed,
  rejected or bridged: the next frame is better registered against this one than across it);
* ``interval_s`` has passed since the keyframe (0.05 s: every fifth frame at 90 Hz, every
  third at 45 Hz; 0 registers every frame against the previous one);
* the online estimate moved farther than ``max_translation_m`` or ``max_rotation_rad`` from it
  (the overlap shrinks in fast swing).

Online and causal: the decision uses this frame's online estimate only. docs/pipelines.md
("Keyframes") gives the measured effect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel


class KeyframeConfig(ConfigModel):
    """When a registered frame becomes the target of the frames after it."""

    interval_s: float = Field(
        0.05,
        ge=0,
        description="a frame this long after the keyframe becomes the next keyframe "
        "(0: frame-to-frame registration)",
    )
    max_translation_m: float = Field(
        0.05, gt=0, description="a frame this far from the keyframe becomes the next one"
    )
    max_rotation_rad: float = Field(
        0.15, gt=0, description="a frame turned this much from the keyframe becomes the next one"
    )


@dataclass(frozen=True, eq=False)
class Keyframe:
    """A frame that later frames register against."""

    index: int
    target: object  # the registration's prepared target (pyramid, prepared frame)
    stride_T_camera: np.ndarray  # its online estimate when it was chosen
    t_s: float


class Keyframes:
    """The current keyframe and the rule that replaces it (module docstring)."""

    def __init__(self, config: KeyframeConfig) -> None:
        self.config = config
        self.key: Keyframe | None = None

    def target_T_current(self, prev_T_camera: np.ndarray, prev_T_current: np.ndarray):
        """The initial guess against the keyframe, from the previous frame's online pose
        (``prev_T_camera``, stride frame) and the guess relative to the previous frame."""
        assert self.key is not None
        return np.linalg.solve(self.key.stride_T_camera, prev_T_camera) @ prev_T_current

    def update(
        self, index: int, target, stride_T_camera: np.ndarray, t_s: float, *, keep: bool
    ) -> bool:
        """After frame ``index``'s graph update: make it the keyframe unless ``keep`` (its
        registration was accepted and the stride goes on) and the keyframe is still near in
        time and motion. ``target`` None (nothing to register against) clears the keyframe.
        Returns whether the frame became the keyframe."""
        if target is None:
            self.key = None
            return False
        if keep and self.key is not None and not self._expired(stride_T_camera, t_s):
            return False
        self.key = Keyframe(index, target, np.array(stride_T_camera, dtype=float), float(t_s))
        return True

    def _expired(self, stride_T_camera: np.ndarray, t_s: float) -> bool:
        cfg, key = self.config, self.key
        assert key is not None
        if t_s - key.t_s >= cfg.interval_s - 1e-9:
            return True
        key_T_camera = np.linalg.solve(key.stride_T_camera, stride_T_camera)
        cos = np.clip((np.trace(key_T_camera[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
        return bool(
            np.linalg.norm(key_T_camera[:3, 3]) > cfg.max_translation_m
            or np.arccos(cos) > cfg.max_rotation_rad
        )
