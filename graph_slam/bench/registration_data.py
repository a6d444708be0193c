"""The registration benchmark's datasets: frames with their intrinsics and ground truth.

Synthetic D455-sized frames of the box course (:func:`synthetic_dataset`), sessions written by
``graph-slam simulate`` (:func:`session_dataset`, decimated or not) and the TUM RGB-D sample
(:func:`read_tum_sample`); the error of an estimate against the truth (:func:`pose_error`,
:func:`relative_truth`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graph_slam.errors import SessionError
from graph_slam.session.records import CameraIntrinsics, RgbdFrame

TUM_INTRINSICS = CameraIntrinsics(640, 480, 517.3, 516.5, 318.6, 255.3)
TUM_DEPTH_UNIT_M = 1.0 / 5000.0


@dataclass(frozen=True)
class Dataset:
    """Frames with their intrinsics and ground-truth ``world_T_camera``."""

    name: str
    intrinsics: CameraIntrinsics
    frames: tuple[RgbdFrame, ...]
    world_T_camera: np.ndarray
    synthetic: bool = True
    """Rendered from a model (no systematic sensor error), not recorded by a camera."""


def pose_error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Translation (m) and rotation angle (rad) of ``truth⁻¹ · estimate``."""
    err = np.linalg.solve(truth, estimate)
    cos = np.clip((np.trace(err[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(err[:3, 3])), float(np.arccos(cos))


def relative_truth(world_T_camera: np.ndarray, k: int) -> np.ndarray:
    """``camera_k_T_camera_k+1`` from the ground truth."""
    return np.linalg.solve(world_T_camera[k], world_T_camera[k + 1])


def session_dataset(
    path: str | Path, step: int = 1, start: int = 0, stop: int | None = None
) -> Dataset:
    """Frames ``start:stop`` of a session with ground truth (``graph-slam simulate``), every
    ``step``-th pixel (intrinsics scaled: ``f/step``, ``c/step``, pixel centres at integers)."""
    from graph_slam.session import open_session

    session = open_session(path)
    truth = session.ground_truth
    if truth is None or session.intrinsics is None:
        raise SessionError(f"{path}: the registration benchmark needs frames and ground truth")
    k = session.intrinsics
    intrinsics = CameraIntrinsics(
        k.width_px // step, k.height_px // step, k.fx_px / step, k.fy_px / step,
        k.cx_px / step, k.cy_px / step,
    )  # fmt: skip
    frames = []
    for frame in session.iter_frames(start, stop):
        color = None if frame.color_rgb is None else frame.color_rgb[::step, ::step]
        depth = frame.depth_m[::step, ::step][: intrinsics.height_px, : intrinsics.width_px]
        color = None if color is None else color[: intrinsics.height_px, : intrinsics.width_px]
        frames.append(RgbdFrame(frame.t_s, depth, color, frame.index))
    poses = truth.parent_T_child[start : start + len(frames)]
    name = f"{session.name}, {intrinsics.width_px}×{intrinsics.height_px}, {len(frames) - 1} pairs"
    synthetic = session.manifest.provenance.synthetic
    return Dataset(name, intrinsics, tuple(frames), poses, synthetic)


def synthetic_dataset(
    pairs: int = 10, rate_hz: float = 40.0, width_px: int = 848, height_px: int = 480
) -> Dataset:
    """D455-like frames (87° field of view) of the box course, from the start of the session,
    at ``rate_hz`` (the thesis's effective rate was 35–40 Hz)."""
    from graph_slam.session.synthetic import (
        Motion,
        SyntheticConfig,
        intrinsics_for,
        iter_synthetic_frames,
    )

    cfg = SyntheticConfig(
        width_px=width_px,
        height_px=height_px,
        fov_x_deg=87.0,
        camera_rate_hz=rate_hz,
        duration_s=pairs / rate_hz,
        scene="box_course",
    )
    frames = tuple(iter_synthetic_frames(cfg))
    t_s = np.array([f.t_s for f in frames])
    return Dataset(
        f"synthetic box course, {width_px}×{height_px}, {rate_hz:g} Hz, {pairs} pairs",
        intrinsics_for(cfg),
        frames,
        Motion(cfg).world_T_camera(t_s),
    )


def read_tum_sample(folder: str | Path, ids: Sequence[int] | None = None) -> Dataset:
    """Frames of a ``tum_fr1_xyz_10``-style folder (``rgb/N.png``, ``depth/N.png`` uint16 at
    5000 per metre, ``ground_truth.json`` with 4×4 ``transformation`` = world_T_camera)."""
    from PIL import Image

    folder = Path(folder)
    truth_path = folder / "ground_truth.json"
    try:
        truth = json.loads(truth_path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise SessionError(f"{truth_path}: cannot read ground truth ({err})") from None
    keys = sorted(truth, key=int) if ids is None else [str(i) for i in ids]
    frames, poses = [], []
    for index, key in enumerate(keys):
        if key not in truth:
            raise SessionError(f"{truth_path}: no entry {key!r}")
        entry = truth[key]
        paths = {name: (folder / entry[name]).resolve() for name in ("rgb", "depth")}
        for name, path in paths.items():
            if folder.resolve() not in path.parents:
                raise SessionError(f"{truth_path}: entry {key!r} field {name!r} leaves the folder")
        try:
            color = np.asarray(Image.open(paths["rgb"]).convert("RGB"))
            depth_raw = np.asarray(Image.open(paths["depth"]))
        except OSError as err:
            raise SessionError(f"{folder}: frame {key}: cannot read image ({err})") from None
        if depth_raw.dtype != np.uint16:
            raise SessionError(f"{paths['depth']}: depth must be uint16, got {depth_raw.dtype}")
        depth = (depth_raw * TUM_DEPTH_UNIT_M).astype(np.float32)
        frames.append(RgbdFrame(float(index), depth, color, index))
        poses.append(np.asarray(entry["transformation"], dtype=float))
    return Dataset(
        f"TUM fr1/xyz frames {keys[0]}–{keys[-1]}",
        TUM_INTRINSICS,
        tuple(frames),
        np.stack(poses),
        synthetic=False,
    )


def default_tum_folder() -> Path:
    """``../shared/data/tum_fr1_xyz_10`` next to the repository (absent in a user's clone)."""
    return Path(__file__).resolve().parents[2].parent / "shared" / "data" / "tum_fr1_xyz_10"
