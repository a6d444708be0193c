"""The per-stride reference: ground truth in each stride's own frame (one builder for all).

The comparison report, the benchmarks and the tests score a pipeline's ``stride_T_camera``
against :func:`stride_references`: for every *complete* stride (started at a foot strike,
the next foot strike known, and the run not stopped inside it by ``max_frames``) the true
camera poses in the true stride frame (:func:`truth_world_T_stride`), the stance mask and
the position in the gait cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.strides.events import StrideEvents
from graph_slam.strides.joints import interp_q


def truth_world_T_stride(world_T_camera: np.ndarray, foot_T_camera: np.ndarray) -> np.ndarray:
    """The true stride frame: heel contact point as origin, z up, x the sole's horizontal x.

    ``world_T_foot = world_T_camera · foot_T_camera(q)⁻¹`` with the true camera pose and the
    encoder angles at the stride's first frame (the pipelines anchor their stride there, from
    the same leg model; the simulated heel is pinned during stance). Definition as in
    ``kinematics.stride_frame``.
    """
    world_T_foot = np.asarray(world_T_camera) @ np.linalg.inv(np.asarray(foot_T_camera))
    x = world_T_foot[:3, 0].copy()
    x[2] = 0.0
    norm = float(np.linalg.norm(x))
    if norm < 0.1:
        raise EvaluationError("truth_world_T_stride: the foot's x axis is near vertical")
    x /= norm
    z = np.array([0.0, 0.0, 1.0])
    out = np.eye(4)
    out[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    out[:3, 3] = world_T_foot[:3, 3]
    return out


def stance_mask(t_s: np.ndarray, toe_off_s: float | None) -> np.ndarray:
    """True for frames before the stride's toe-off (stance), False after (swing).

    With no toe-off known (``None``) every frame counts as stance.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if toe_off_s is None:
        return np.ones(t.shape, dtype=bool)
    return t < toe_off_s


def gait_cycle_percent(t_s: np.ndarray, t_strike_s: float, t_next_strike_s: float) -> np.ndarray:
    """Position in the gait cycle (0 at this foot strike, 100 at the next), linear in time."""
    if not t_next_strike_s > t_strike_s:
        raise EvaluationError(
            f"gait_cycle_percent: the next foot strike ({t_next_strike_s}) must follow this one "
            f"({t_strike_s})"
        )
    return 100.0 * (np.asarray(t_s, dtype=np.float64) - t_strike_s) / (t_next_strike_s - t_strike_s)


@dataclass(frozen=True, eq=False)
class StrideReference:
    """Ground truth of one complete stride, in its own true stride frame."""

    stride_index: int
    """Index of the stride in the pipeline's results (``PipelineResults.strides``)."""
    frame_indices: np.ndarray
    t_s: np.ndarray
    world_T_stride: np.ndarray
    stride_T_camera: np.ndarray
    """len(frame_indices)×4×4 true camera poses in the true stride frame."""
    t_strike_s: float
    t_next_strike_s: float
    toe_off_s: float | None

    @property
    def in_stance(self) -> np.ndarray:
        return stance_mask(self.t_s, self.toe_off_s)

    @property
    def cycle_pct(self) -> np.ndarray:
        return gait_cycle_percent(self.t_s, self.t_strike_s, self.t_next_strike_s)

    @property
    def toe_off_pct(self) -> float:
        if self.toe_off_s is None:
            return float("nan")
        return float(
            gait_cycle_percent(np.array([self.toe_off_s]), self.t_strike_s, self.t_next_strike_s)[0]
        )


def _cut_short(idx: np.ndarray, frame_t_s: np.ndarray, session) -> bool:
    """The run stopped inside this stride: its last frame is the run's last, and the run
    ended before the session's frames did (``max_frames``)."""
    if idx[-1] + 1 < frame_t_s.size:
        return False
    times = getattr(session, "frame_times_s", None)
    return times is None or frame_t_s[-1] < float(np.asarray(times)[-1]) - 1e-9


def stride_references(
    session, frame_t_s: np.ndarray, strides: Sequence, events: StrideEvents, leg_model
) -> list[StrideReference]:
    """The reference of every complete stride of a run (see the module docstring).

    ``frame_t_s``: the run's frame times (its frames are the session's first
    ``frame_t_s.size``); ``strides``: the run's strides (anything with ``index``, ``start``,
    ``frame_indices``); ``events``: the events that cut them; ``leg_model``: the leg model of
    the session's calibration (``foot_T_camera`` at the stride's first frame).
    Raises :class:`EvaluationError` without ground truth or joints, or when the ground truth
    is not at the frame times.
    """
    gt = session.ground_truth
    if gt is None:
        raise EvaluationError(f"{session.path}: scoring needs ground truth (groundtruth.txt)")
    joints = session.joints
    if joints is None:
        raise EvaluationError(f"{session.path}: scoring needs joints.csv for the stride frame")
    calib = session.calibration
    t_joint = np.asarray(joints.t_s) + calib.joints_time_offset_s
    q_rad = np.asarray(joints.q_rad)
    t_gt = np.asarray(gt.t_s)
    world_T_camera = np.asarray(gt.parent_T_child)
    frame_t_s = np.asarray(frame_t_s, float)
    out: list[StrideReference] = []
    for s in strides:
        idx = np.asarray(s.frame_indices, dtype=int)
        if s.start != "foot_strike" or idx.size < 2 or _cut_short(idx, frame_t_s, session):
            continue  # not started at a strike, or the run stopped inside it
        t = frame_t_s[idx]
        t_strike = events.last_strike_at_or_before(float(t[0]))
        t_next = events.next_strike_after(float(t[-1]))
        if t_strike is None or t_next is None:
            continue
        gi = np.clip(np.searchsorted(t_gt, t), 0, t_gt.size - 1)
        if not np.allclose(t_gt[gi], t, atol=1e-6):
            raise EvaluationError(f"{session.path}: groundtruth.txt is not at the frame times")
        q0 = interp_q(float(t[0]), t_joint, q_rad)
        if q0 is None:
            raise EvaluationError(
                f"{session.path}: joints.csv has no sample around the stride start t={t[0]:.3f} s"
            )
        w_T_s = truth_world_T_stride(world_T_camera[gi[0]], leg_model.foot_T_camera(q0))
        out.append(
            StrideReference(
                stride_index=int(s.index),
                frame_indices=idx,
                t_s=t,
                world_T_stride=w_T_s,
                stride_T_camera=np.linalg.inv(w_T_s) @ world_T_camera[gi],
                t_strike_s=t_strike,
                t_next_strike_s=t_next,
                toe_off_s=events.toe_off_between(t_strike, t_next),
            )
        )
    return out
