"""Pipelines: every variant through one interface on a small simulated session (quarter
resolution, 2 strides, bursty drops), baseline statuses and stop rule, the information
conversion, a NaN-laden IMU."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from graph_slam.pipelines import VARIANTS, Pipeline, PipelineConfig, make_pipeline, run_session


@pytest.fixture(scope="session")
def sim_session(tmp_path_factory):
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("pipelines") / "sim"
    simulate(SimConfig(strides=2, seed=1, fast=True, drops="bursty", quicklook=False), out)
    return out


@pytest.fixture(scope="session")
def results(sim_session):
    # the accurate preset: the stride maps and the batch smoothing these tests check
    cfg = {v: PipelineConfig(preset="accurate", variant=v, max_frames=60) for v in VARIANTS}
    return {v: run_session(sim_session, c) for v, c in cfg.items()}


def test_every_variant_through_one_interface(sim_session, results):
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import leg_model_for

    s = open_session(sim_session)
    leg = leg_model_for(s.calibration.thigh_T_camera)
    for v in VARIANTS:
        pipe = make_pipeline(
            PipelineConfig(variant=v), s.intrinsics, s.calibration.camera_T_imu, leg
        )
        assert isinstance(pipe, Pipeline)
        r = results[v]
        assert r.variant == v
        assert len(r.frames) == 60
        assert np.all(np.diff(r.t_s) > 0)
        assert len(r.strides) >= 2


@pytest.mark.parametrize("variant", ["icp+imu", "imu+kin", "icp+imu+kin"])
def test_graph_variants_pose_every_frame(results, variant):
    r = results[variant]
    assert r.has_pose.all()
    assert np.isfinite(r.smoothed_stride_T_camera).all()
    for s in r.strides:
        assert s.frame_indices == sorted(s.frame_indices)
        # every posed frame is fused into the online grid or held back by its settling gate
        assert sum(s.grid_frames) == len(s.frame_indices)
    assert r.counts["grid_frames_fused"] + r.counts["grid_frames_held"] == 60
    if variant != "imu+kin":
        assert r.counts["icp_accepted"] > 0
        # the first stride (no strike) is held; the first anchored one settles on its plane
        assert r.counts["grid_frames_fused"] > 30
    else:  # no camera, no plane: the first strike's up is the encoders' (σ 0.1 rad), held
        assert r.counts["grid_frames_held"] > 30


def test_baseline_statuses_and_stop_rule(results):
    r = results["icp"]
    statuses = r.statuses
    assert statuses.count("reset") == sum(1 for s in r.strides)
    for f in r.frames:
        if f.has_pose:
            assert f.status in ("reset", "registered")
        else:
            assert f.status.startswith("not_registered: ")
            assert f.world_T_camera is None
    for s in r.strides:
        st = [statuses[i] for i in s.frame_indices]
        if s.stop_reason is None:
            assert all(x in ("reset", "registered") for x in st)
            continue
        # after the first failure, nothing is registered for the rest of the stride
        first_fail = next(i for i, x in enumerate(st) if x.startswith("not_registered"))
        assert all(x.startswith("not_registered") for x in st[first_fail:])
        assert all(x.startswith("not_registered: stopped") for x in st[first_fail + 1 :])
        assert s.n_registered == first_fail
        if s.n_registered > 0:
            # the stride's terrain map comes out of the pipeline (online = smoothed poses)
            assert s.terrain is not None and s.terrain.online is s.terrain.smoothed
            assert len(s.terrain.online.fused) > 100


def test_baseline_threshold_is_configurable(sim_session):
    # fitness can never reach 1.01: every registration stops the stride at its first frame
    r = run_session(
        sim_session, PipelineConfig(variant="icp", max_frames=40, baseline={"stop_fitness": 1.0})
    )
    for s in r.strides:
        assert s.n_registered <= 1
        if len(s.frame_indices) > 1:
            assert "fitness" in r.frames[s.frame_indices[1]].status or "stopped" in (
                r.frames[s.frame_indices[1]].status
            )


def test_nan_imu_session_finishes_flagged(sim_session, tmp_path):
    from graph_slam.session.files import IMU_COLUMNS
    from graph_slam.session.io import read_numeric_csv, write_numeric_csv

    copy = tmp_path / "nan"
    shutil.copytree(sim_session, copy)
    cols = list(IMU_COLUMNS)
    imu = read_numeric_csv(copy / "imu.csv", cols)
    # the reader refuses NaN in a file: feed the pipeline a NaN-laden stream directly
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import leg_model_for
    from graph_slam.strides.streams import session_streams

    s = open_session(copy)
    st = session_streams(s, "load_cell")
    gyro = st.gyro_rad_s.copy()
    t = st.imu_t_s
    gyro[(t > 0.5) & (t < 0.7)] = np.nan
    cfg = PipelineConfig(variant="imu+kin")
    pipe = make_pipeline(
        cfg, s.intrinsics, s.calibration.camera_T_imu, leg_model_for(s.calibration.thigh_T_camera)
    )
    pipe.add_imu(t, gyro, st.accel_m_s2)
    pipe.add_joints(st.joints_t_s, st.knee_rad, st.ankle_rad)
    for i, frame in enumerate(s.iter_frames(0, 50)):
        if any(i > 0 and s.frame_times_s[i - 1] < x <= frame.t_s for x in st.foot_strikes_s):
            pipe.foot_strike(frame.t_s)
        pipe.add_frame(frame, st.foot_loaded(frame.t_s))
    r = pipe.finish()
    assert r.has_pose.all()
    assert r.counts["imu_nonfinite"] > 0
    assert any("imu_gap" in s.flags for s in r.strides)
    write_numeric_csv(copy / "imu.csv", cols, imu)  # unchanged file stays readable


def test_imu_kin_follows_the_truth(sim_session):
    """Regression: ``imu+kin`` diverged by metres because its stance factors held the
    foot in its orientation at foot strike (the foot then rolls ~8° flat and later lifts its
    heel by up to 19 cm before toe-off) and were rejected as inconsistent. With contact-point
    stance factors (heel, then toe) every scored stride stays within 6 cm (measured 19 and
    38 mm smoothed RMSE; before: 1.8 and 2.3 m)."""
    from graph_slam.bench.accuracy import score
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import leg_model_for

    s = open_session(sim_session)
    r = run_session(s, PipelineConfig(variant="imu+kin"))
    scores = score(s, r, leg_model_for(s.calibration.thigh_T_camera))
    assert len(scores) == 2
    for sc in scores:
        assert sc.smoothed_rmse_m < 0.06, sc
    stance = [f for f in r.backend.frames if f.stride_index > 0 and f.kinematic_factor]
    assert len(stance) > 20


@pytest.fixture(scope="session")
def scored_full(sim_session):
    """The full graph on the whole session (2 scored strides), default configuration."""
    from graph_slam.bench.accuracy import score
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import leg_model_for

    s = open_session(sim_session)
    leg = leg_model_for(s.calibration.thigh_T_camera)

    def run(**overrides):
        r = run_session(s, PipelineConfig(variant="icp+imu+kin", **overrides))
        return r, score(s, r, leg)

    return run


def test_full_graph_meets_the_stride_rmse_target(scored_full):
    """The target on a small session: smoothed stride-frame RMSE (no alignment) ≤ 5 mm per
    stride. Measured 2.0 and 2.4 mm (online 1.0, 3.0 mm); without the floor in the anchor's
    tilt 18.0 and 11.4 mm (the IMU's up vector was 1.4° and 0.8° off)."""
    r, scores = scored_full()
    assert len(scores) == 2
    for sc in scores:
        assert sc.smoothed_rmse_m < 0.005, sc
        assert sc.online_rmse_m < 0.008, sc
    assert r.has_pose.all()
    floor = [x for f in r.frames for x in f.flags if x.startswith("floor:")]
    assert floor == ["floor:ok"] * r.counts["foot_strikes"]  # one fit per stride start


def test_swing_bridged_by_imu_and_kinematics(scored_full):
    """ICP removed for every swing frame (``graph.icp_in_swing: false``): the IMU carries the
    swing; the error at the last frame before the next foot strike stays under 3 cm
    (measured 12.4 and 10.9 mm smoothed, 16.5 and 15.7 mm online)."""
    r, scores = scored_full(graph={"icp_in_swing": False})
    assert len(scores) == 2
    for sc in scores:
        assert sc.end_smoothed_m < 0.03, sc
        assert sc.end_online_m < 0.03, sc
    swing = [f for f in r.frames if not f.foot_loaded and f.stride_index > 0]
    assert swing and all(not any(x.startswith("icp:") for x in f.flags) for f in swing)
    assert r.has_pose.all()


def test_deferred_smoothing_keeps_the_accuracy_without_the_strike_spike(scored_full):
    """Real time: with ``backend.defer_smoothing`` the stride's end state carried
    into the next stride is iSAM2's and the batch smoothing runs at ``finish``; the smoothed
    poses still meet the ≤ 5 mm target and every stride ends up smoothed (no flag left)."""
    r, scores = scored_full(preset="accurate", backend={"defer_smoothing": True})
    assert len(scores) == 2
    for sc in scores:
        assert sc.smoothed_rmse_m < 0.005, sc
        assert sc.online_rmse_m < 0.008, sc
    assert all("smoothing_deferred" not in s.flags for s in r.strides)
    # the batch solution replaced the iSAM2 estimate the stride was closed with (a run without
    # smoothing closes strides the same way and keeps that estimate)
    r_isam, _ = scored_full(preset="accurate", backend={"smoothing": False})
    moved = np.nanmax(np.abs(r.smoothed_stride_T_camera - r_isam.smoothed_stride_T_camera))
    assert moved > 1e-4, moved
    assert all(s.terrain.smoothed is not None for s in r.strides if s.frame_indices)


@pytest.mark.parametrize("preset", ["realtime", "realtime-gicp"])
def test_full_graph_with_the_realtime_registration_preset(scored_full, preset):
    """``graph.registration: realtime`` (projective, organised normals, IMU guess) and
    ``realtime-gicp`` (GICP + photometric stage), each frame prepared once and kept as the
    next target: the same stride RMSE target as the default; every registered frame reports
    its cloud, preprocess and registration stages."""
    r, scores = scored_full(graph={"registration": preset})
    method = {"realtime": "projective", "realtime-gicp": "gicp"}[preset]
    assert r.config["graph"]["registration"]["method"] == method
    assert len(scores) == 2
    for sc in scores:
        assert sc.smoothed_rmse_m < 0.005, sc
    assert r.counts["icp_accepted"] > 0.8 * r.counts["frames"]
    registered = [f for f in r.frames if np.isfinite(f.fitness)]
    assert registered and all(
        {"cloud", "preprocess", "registration"} <= f.stages_s.keys() for f in registered
    )


def test_a_bounded_smoothing_queue_smooths_the_same_strides_earlier(sim_session):
    """``backend.max_deferred_strides: 0`` smooths each closed stride at the next frame (its
    graph released there, memory flat over a long run) instead of at ``finish``: the same
    graphs, so the same smoothed poses. ``imu+kin``: no ICP, so two runs are bit-identical
    (Open3D's threaded sums are not)."""

    def run(**backend):
        cfg = PipelineConfig(variant="imu+kin", backend={"defer_smoothing": True, **backend})
        return run_session(sim_session, cfg)

    r_end, r_now = run(), run(max_deferred_strides=0)
    np.testing.assert_allclose(
        r_now.smoothed_stride_T_camera, r_end.smoothed_stride_T_camera, atol=1e-9
    )
    closes = [f.stages_s.get("stride_close", 0.0) for f in r_now.frames]
    assert sum(c > 0 for c in closes) >= len(r_now.strides) - 1  # smoothed inside the run
    assert all("smoothing_deferred" not in s.flags for s in r_now.strides)
