"""The stride stage: the up vector from the IMU, the one rule for stride-cutting events, the
per-stride reference (known answers on hand-made data)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from graph_slam.errors import EvaluationError, SessionError
from graph_slam.session.records import GaitEvents
from graph_slam.strides.events import stride_events
from graph_slam.strides.gravity import GravityEstimator, rotated_mean_accel
from graph_slam.strides.reference import stride_references, truth_world_T_stride


def _spinning_imu(rate_hz=200.0, duration_s=2.0, omega=(0.0, 0.0, 2.0), up=(0.0, 0.0, 9.81)):
    """A static accelerometer reading of gravity while the IMU spins about its own z: the
    reading in the body frame turns with -ω; rotated back into the last frame it is constant."""
    from scipy.spatial.transform import Rotation

    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    w = np.tile(omega, (t.size, 1))
    # body_R_world(t) = Exp(-ω t); the world up vector seen in the body frame
    up_world = np.asarray(up)
    tilt = Rotation.from_rotvec([0.3, 0.0, 0.0])  # up not along the spin axis
    a = np.array(
        [(Rotation.from_rotvec(-np.asarray(omega) * tk) * tilt).apply(up_world) for tk in t]
    )
    return t, w, a, tilt


def test_rotated_mean_is_the_up_vector_in_the_last_frame():
    t, w, a, _ = _spinning_imu()
    up = rotated_mean_accel(t, w, a)
    np.testing.assert_allclose(up, a[-1], atol=2e-3)  # a plain mean would be far off
    assert np.linalg.norm(a.mean(axis=0) - a[-1]) > 1.0


def test_gravity_window_follows_the_strides_and_reads_nothing_after_t():
    t, w, a, _ = _spinning_imu(duration_s=3.0)
    g = GravityEstimator(default_window_s=1.0)
    g.add_imu(t, w, a)
    assert g.window_before(1.5) == 1.0  # no strike known
    g.foot_strike(0.4)
    assert g.window_before(1.5) == pytest.approx(1.1)
    assert g.window_before(0.5) == 1.0  # a strike within 0.3 s is this one, not the last
    up = g.up_at(1.5, 1.1)
    np.testing.assert_allclose(up, a[np.searchsorted(t, 1.5, side="right") - 1], atol=5e-3)
    # the future does not change the answer
    g2 = GravityEstimator(default_window_s=1.0)
    k = np.searchsorted(t, 1.5, side="right")
    g2.add_imu(t[:k], w[:k], a[:k])
    g2.foot_strike(0.4)
    np.testing.assert_array_equal(g2.up_at(1.5, 1.1), up)
    assert g.up_at(0.02, 1.0) is None  # fewer than 10 samples
    assert g.history_s(1.5) == pytest.approx(1.5)


def test_gravity_skips_non_finite_samples_and_forgets_old_ones():
    t, w, a, _ = _spinning_imu(duration_s=3.0)
    w = w.copy()
    w[100:110] = np.nan
    g = GravityEstimator(default_window_s=1.0, keep_s=1.0)
    g.add_imu(t, w, a)
    assert np.isfinite(g.up_at(1.0, 1.0)).all()
    g.foot_strike(2.5)
    assert g.up_at(1.0, 0.5) is None  # older than keep_s before the strike: forgotten


@dataclass(frozen=True)
class StrideCut:
    """What the reference reads of a pipeline's stride."""

    index: int
    start: str
    frame_indices: range


def _events(t, kind, source):
    return GaitEvents(np.asarray(t, float), tuple(kind), tuple(source))


def test_stride_events_one_rule():
    ev = _events(
        [0.1, 0.7, 1.1, 1.2, 1.5],
        ["foot_strike", "toe_off", "foot_strike", "foot_strike", "toe_off"],
        ["load_cell", "load_cell", "load_cell", "thigh_imu", "load_cell"],
    )
    lc = stride_events(ev, "load_cell")
    np.testing.assert_array_equal(lc.foot_strikes_s, [0.1, 1.1])
    assert stride_events(ev, None).foot_strikes_s.size == 3
    assert lc.foot_loaded(0.5) and not lc.foot_loaded(0.8) and lc.foot_loaded(1.3)
    assert not lc.foot_loaded(0.05)
    assert lc.toe_off_between(0.1, 1.1) == 0.7 and lc.next_strike_after(0.2) == 1.1
    with pytest.raises(SessionError, match="no event with source 'truth'"):
        stride_events(ev, "truth", "x/events.csv")
    assert stride_events(None, "load_cell").foot_strikes_s.size == 0


class _Joints:
    def __init__(self, t, q):
        self.t_s, self.q_rad = t, q


class _Traj:
    def __init__(self, t, poses):
        self.t_s, self.parent_T_child = t, poses


class _Session:
    path = "mem"

    def __init__(self, t, poses, with_gt=True):
        from types import SimpleNamespace

        self.ground_truth = _Traj(t, poses) if with_gt else None
        self.frame_times_s = t
        self.joints = _Joints(t, np.zeros((t.size, 2)))
        self.calibration = SimpleNamespace(joints_time_offset_s=0.0)


class _Leg:
    def foot_T_camera(self, q):
        out = np.eye(4)
        out[:3, 3] = [0.1, 0.0, 0.5]  # camera 0.5 m above, 0.1 m ahead of the heel
        return out


def test_reference_known_answer_and_complete_strides_only():
    t = np.arange(10) * 0.1
    poses = np.tile(np.eye(4), (10, 1, 1))
    poses[:, 0, 3] = 2.0 + t  # walking along world x
    poses[:, 2, 3] = 0.5
    ev = stride_events(
        _events([0.0, 0.3, 0.45, 0.85], ["foot_strike", "toe_off", "foot_strike", "toe_off"],
                ["lc"] * 4), "lc")  # fmt: skip
    strides = [StrideCut(0, "foot_strike", range(0, 5)), StrideCut(1, "foot_strike", range(5, 10))]
    refs = stride_references(_Session(t, poses), t, strides, ev, _Leg())
    assert len(refs) == 1  # the last stride has no next strike (and the run ends in it)
    r = refs[0]
    np.testing.assert_allclose(r.world_T_stride[:3, 3], [1.9, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(r.stride_T_camera[:, 0, 3], 0.1 + t[:5], atol=1e-12)
    np.testing.assert_array_equal(r.in_stance, t[:5] < 0.3)
    assert r.cycle_pct[0] == 0.0 and r.toe_off_pct == pytest.approx(100 * 0.3 / 0.45)
    with pytest.raises(EvaluationError, match="ground truth"):
        stride_references(_Session(t, poses, with_gt=False), t, strides, ev, _Leg())
    with pytest.raises(EvaluationError, match="not at the frame times"):
        stride_references(_Session(t, poses), t + 0.003, strides, ev, _Leg())


def test_a_stride_ending_with_the_session_counts_one_cut_by_max_frames_does_not():
    t = np.arange(10) * 0.1
    poses = np.tile(np.eye(4), (10, 1, 1))
    ev = stride_events(
        _events([0.0, 0.45, 0.95], ["foot_strike"] * 3, ["lc"] * 3), "lc"
    )  # the last strike comes after the session's last frame
    strides = [StrideCut(0, "foot_strike", range(0, 5)), StrideCut(1, "foot_strike", range(5, 10))]
    refs = stride_references(_Session(t, poses), t, strides, ev, _Leg())
    assert [r.stride_index for r in refs] == [0, 1]
    cut = [StrideCut(0, "foot_strike", range(0, 5)), StrideCut(1, "foot_strike", range(5, 8))]
    refs = stride_references(_Session(t, poses), t[:8], cut, ev, _Leg())  # max_frames = 8
    assert [r.stride_index for r in refs] == [0]


def test_truth_stride_frame_is_level_with_x_along_the_sole():
    foot_T_camera = np.eye(4)
    world_T_foot = np.eye(4)
    c, s = np.cos(0.2), np.sin(0.2)
    world_T_foot[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]  # sole pitched 0.2 rad
    out = truth_world_T_stride(world_T_foot @ foot_T_camera, foot_T_camera)
    np.testing.assert_allclose(out[:3, 2], [0, 0, 1])
    np.testing.assert_allclose(out[:3, 0], [1, 0, 0], atol=1e-12)
