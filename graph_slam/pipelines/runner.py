"""``make_pipeline(config, ...)`` and ``run_session(session, config) -> PipelineResults``."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from graph_slam.errors import SessionError
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.protocol import Pipeline
from graph_slam.pipelines.results import FrameOutput, PipelineResults
from graph_slam.strides.kinematics import session_leg_model
from graph_slam.strides.streams import session_streams

log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int], None]
"""Called after every frame with (frames done, frames in total)."""


def make_pipeline(
    config: PipelineConfig,
    intrinsics,
    camera_T_imu: np.ndarray,
    leg_model,
    has_color: bool = True,
) -> Pipeline:
    """The variant's pipeline: ``icp`` = the thesis baseline, else the factor graph; Open3D's
    threads set for the run (``config.deterministic``: :mod:`graph_slam.determinism`)."""
    from graph_slam.determinism import apply_threads

    apply_threads(config.deterministic)
    if config.variant == "icp":
        from graph_slam.pipelines.baseline import ThesisBaseline

        return ThesisBaseline(config, intrinsics, camera_T_imu, leg_model, has_color)
    from graph_slam.pipelines.graph import GraphPipeline

    return GraphPipeline(config, intrinsics, camera_T_imu, leg_model, has_color)


def open_pipeline(
    session, config: PipelineConfig, factory: Callable[..., Pipeline] = make_pipeline
):
    """The session (opened when a folder is given), its streams on the camera clock and the
    config's pipeline for it: what every way of running a session starts from. ``factory``:
    ``make_pipeline``'s signature. The leg model's camera mount: :func:`open_pipeline_mount`."""
    session, streams, pipe, _ = open_pipeline_mount(session, config, factory)
    return session, streams, pipe


def open_pipeline_mount(
    session, config: PipelineConfig, factory: Callable[..., Pipeline] = make_pipeline
):
    """:func:`open_pipeline` and the :class:`~graph_slam.strides.mount.MountPitch` its leg
    model was built with (``pipeline.mount_pitch_deg``, else the calibration's
    ``thigh_T_camera``, else estimated from the session: :func:`session_leg_model`)."""
    from graph_slam.session import open_session

    if isinstance(session, str | Path):
        session = open_session(session)
    if session.intrinsics is None:
        raise SessionError(f"{session.path}: the session has no camera; pipelines need frames")
    config = for_session(config, session)
    streams = session_streams(session, config.event_source)
    calib = session.calibration
    leg_model, mount = session_leg_model(
        session, config.mount_pitch_deg, config.mount_estimate, streams=streams
    )
    has_color = bool(session.manifest.sensors.camera.has_color)
    if config.variant == "icp" and session.n_color_frames < session.n_frames:
        has_color = False  # the thesis baseline's coloured map needs colour in every frame
    pipe = factory(config, session.intrinsics, calib.camera_T_imu, leg_model, has_color)
    return session, streams, pipe, mount


def for_session(config: PipelineConfig, session) -> PipelineConfig:
    """``config`` with what it leaves to the session decided: ``graph.real_camera_floor``
    None becomes on for a recorded session, off for one the simulator or the synthetic
    generator wrote (no systematic sensor error to model)."""
    if config.graph.real_camera_floor is not None:
        return config
    real = not session.manifest.provenance.synthetic
    graph = config.graph.model_copy(update={"real_camera_floor": real})
    return config.model_copy(update={"graph": graph})


def run_session(
    session,
    config: PipelineConfig | None = None,
    progress: ProgressCallback | None = None,
    on_frame: Callable[[FrameOutput], None] | None = None,
) -> PipelineResults:
    """Run one variant over a session (a :class:`graph_slam.session.Session` or its folder).

    Steps: read the streams and shift them onto the camera clock (calibration offsets); build
    the leg model (its camera mount from the config, the calibration, or estimated from the
    session: :func:`~graph_slam.strides.mount.session_leg_model`); make the pipeline; give it the IMU and encoders;
    for every frame, announce the foot strikes (``events.csv``, source ``event_source``) that
    happened since the previous frame, then the frame with its foot-loaded state (between a
    foot strike and the next toe-off); finish.

    ``on_frame``: called with every frame's :class:`FrameOutput` as ``add_frame`` returned it
    (with its ``terrain`` view, which ``PipelineResults.frames`` do not keep): a report's way to
    record what the online map knew at each frame.
    """
    config = config or PipelineConfig()
    session, streams, pipe, mount = open_pipeline_mount(session, config)
    if streams.imu_t_s is not None:
        pipe.add_imu(streams.imu_t_s, streams.gyro_rad_s, streams.accel_m_s2)
    if streams.joints_t_s is not None:
        pipe.add_joints(streams.joints_t_s, streams.knee_rad, streams.ankle_rad)
    n = session.n_frames if config.max_frames is None else min(config.max_frames, session.n_frames)
    # a strike is announced once known (an online source knows it after it happened)
    strikes = list(zip(streams.events.strikes_known_s, streams.foot_strikes_s, strict=True))
    t_prev = -np.inf
    for i, frame in enumerate(session.iter_frames(0, n)):
        for t_strike in (t for known, t in strikes if t_prev < known <= frame.t_s):
            pipe.foot_strike(t_strike)
        out = pipe.add_frame(frame, streams.foot_loaded(frame.t_s))
        if on_frame is not None:
            on_frame(out)
        t_prev = frame.t_s
        if progress is not None:
            progress(i + 1, n)
    results = pipe.finish()
    results.counts["foot_strikes"] = int(np.sum(streams.events.strikes_known_s <= t_prev))
    results.config["mount_pitch"] = mount.to_dict()
    results.config.setdefault("strides_cut_by", streams.events.source or "all events.csv sources")
    return results
