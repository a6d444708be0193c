"""The thesis baseline (variant ``icp``) against the thesis's Table 4.2 pattern.

Scenario: one simulated stride on the thesis box course (``graph_slam.sim``: thesis-boxes,
1.4 m/s, seed 8, quarter resolution 212×120), frames dropped from the D455's 90 Hz at random
(independently, keep probability 0.42, the profile's rate). This stride holds 35 frames in
1.0 s (34 Hz); the thesis recorded 35-40 Hz overall and 19-36 frames in its fast strides.
Chosen among seeds 1-10 (all listed below) as a stride near the thesis's rate that shows both
halves of the pattern: seed 7 (36.5 Hz) registered every frame, which leaves "losses in
swing" untested; seeds 1, 2, 3, 9, 10 are at 41-43 Hz, seeds 4-6 at 24-32 Hz.

Counts measured (2026-11-23): stride 0 registered 24 of 35 frames: **stance 19/19, swing
5/16**. The first 3 swing frames are right; the 4th (44 ms and 133 mm / 8.6° after the 3rd)
converged off and the 5th followed it into the corrupted map (both > 5 cm off the truth but
fitness 0.87-0.89, registered by the thesis's rule, fitness >= 0.3); the 6th (46 ms, 127 mm /
7° later) had no point within the 4 cm of the coarse level and stopped the stride
(``no_overlap``). Stance poses: within 1.8 mm of the truth (motion since the stride's first
frame). Thesis Table 4.2, fast: 5-33 registered of 19-36 recorded; 2 of 25 strides (all
speeds) registered to the end; stance always registered. Seeds 1-10 of the same scenario
(stance, swing; the stride's rate): 26/26, 3/17 (43 Hz); 10/24, 0/17 (41 Hz; a 99 ms gap in
stance); 27/27, 17/17 (42 Hz); 17/17, 5/9 (24 Hz); 20/20, 4/12 (32 Hz); 20/20, 11/11 (31 Hz);
21/21, 14/14 (36.5 Hz); 19/19, 5/16 (34 Hz, this test); 6/22, 0/22 (42 Hz; a 121 ms gap in
stance); 27/27, 17/17 (43 Hz): stance complete in 8 of 10, 4 of 10 to the end
(docs/benchmarks.md, "Baseline registered-frame counts").

Tolerance: every stance frame. In the 18 sessions measured, every stance registration after a
gap shorter than 89 ms succeeded (980 of 980); after 89-150 ms, 27 of 34; after longer gaps,
1 of 5 (docs/pipelines.md). The longest gap in this stride's stance is 66 ms, and the test
checks that first, so that a change of the simulator's draw fails with its reason, not as a
registration count.
The simulator's default drop model (bursty: bursts of ~8 frames with 10 % kept) leaves
100-290 ms gaps, in stance too, and the baseline then stops in stance: that is the thesis's
method (the last pose as the initial guess; from the true pose, the four such frames checked
register to < 1 mm), not a defect; see docs/pipelines.md.
"""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.pipelines import PipelineConfig, run_session

MAX_STANCE_GAP_S = 0.089
"""Longest gap after which every stance registration measured so far succeeded."""


@pytest.fixture(scope="module")
def stride(tmp_path_factory):
    from graph_slam.session import open_session
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("baseline") / "fast_random"
    sim = SimConfig(speed_m_s=1.4, strides=1, seed=8, fast=True, drops="random", quicklook=False)
    simulate(sim, out)
    session = open_session(out)
    return session, run_session(session, PipelineConfig(variant="icp"))


def test_thesis_table_4_2_pattern_registered_in_stance_lost_in_swing(stride):
    _, r = stride
    s = r.strides[0]
    idx = np.asarray(s.frame_indices)
    t = r.t_s[idx]
    rate_hz = (idx.size - 1) / (t[-1] - t[0])
    # measured 34 Hz (thesis: 35-40 Hz overall, 19-36 frames in its ~1 s fast strides)
    assert 30.0 <= rate_hz <= 40.0, f"drops: {rate_hz:.1f} Hz, far from the thesis's 35-40 Hz"
    loaded = np.array([r.frames[i].foot_loaded for i in idx])
    has = np.array([r.frames[i].has_pose for i in idx])
    assert loaded[0] and not loaded[-1] and loaded.sum() >= 15 and (~loaded).sum() >= 10
    stance_gaps = np.diff(t[loaded])
    assert stance_gaps.max() < MAX_STANCE_GAP_S, "the scenario changed: a long gap in stance"

    # Table 4.2: full registration through stance ...
    assert has[loaded].all(), [r.frames[i].status for i in idx[loaded & ~has]]
    # ... losses, if any, in swing, and once lost the stride stays lost (the stop rule)
    if not has.all():
        first_lost = int(np.flatnonzero(~has)[0])
        assert not loaded[first_lost]
        assert not has[first_lost:].any()
        assert s.stop_reason is not None
    n_stance, n_swing = int(loaded.sum()), int((~loaded).sum())
    counts = (int(has[loaded].sum()), n_stance, int(has[~loaded].sum()), n_swing)
    assert counts[0] == n_stance
    # the measured counts of the docstring: stance 19/19, swing 5/16 (swing may move by a
    # frame or two: Open3D's threaded sums are not bit-reproducible, borderline registrations
    # can flip)
    assert n_stance == 19 and n_swing == 16 and counts[2] <= 8, counts


def test_registered_stance_poses_follow_the_truth(stride):
    """Registered means right: motion since the stride's first frame vs the ground truth."""
    session, r = stride
    s = r.strides[0]
    idx = np.asarray(s.frame_indices)
    gt = session.ground_truth
    t_gt = np.asarray(gt.t_s)
    k = np.searchsorted(t_gt, r.t_s[idx] - 1e-9)
    assert np.allclose(t_gt[k], r.t_s[idx], atol=1e-6)
    world_T_camera = np.asarray(gt.parent_T_child)[k]
    loaded = np.array([r.frames[i].foot_loaded for i in idx])
    est = r.online_stride_T_camera[idx]
    first_T_true = np.linalg.inv(world_T_camera[0]) @ world_T_camera
    first_T_est = np.linalg.inv(est[0]) @ est
    err_m = np.linalg.norm(first_T_est[:, :3, 3] - first_T_true[:, :3, 3], axis=1)
    cos = (np.einsum("kij,kij->k", first_T_est[:, :3, :3], first_T_true[:, :3, :3]) - 1) / 2
    err_deg = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    # stance: within 1 cm and 1° of the truth (measured: max 1.8 mm); the swing frames the
    # thesis's rule accepts are not checked (two of them are wrong, see the docstring)
    assert err_m[loaded].max() < 0.01 and err_deg[loaded].max() < 1.0
