"""A causal replay of a session: every stream fed in timestamp order, as the device would.

``replay_session(session, config, pace)`` plays a recorded session into a pipeline on a clock.
Each sample, event and frame exists from its time stamp on; nothing is read ahead:

- a frame is *ready* when every sensor stream has covered its time stamp: the first IMU and
  encoder samples at or after it have arrived (at 400 / 500 Hz, 2.5 / 2 ms later). The
  estimator interpolates the IMU and the joint angles to the frame's time, so it needs that
  sample and none after it (docs/pipelines.md: extrapolating instead doubled the stride
  error). Before a ready frame is processed, the pipeline gets the samples up to and
  including those first ones, and the foot strikes stamped at or before the frame (samples
  stamped later wait for the next processed frame, even when they arrived while the
  estimator was busy: the output then depends only on which frames were processed, not on
  how long each took), then the frame with its foot-loaded state from the load-cell events
  stamped at or before it. Latency is counted from the frame's time stamp;
- the estimator is one worker: a frame that arrives while it is busy waits, and when it is
  free it takes **the newest frame that has arrived and skips the older waiting ones**
  (:func:`pick_frame`; counted, their indices kept); samples and events are never skipped.

Pacing: ``virtual`` (default) runs as fast as the machine can on a virtual clock that each
pipeline call advances by ``compute_cost``: none in a deterministic run
(``PipelineConfig.deterministic``, the default: every frame is taken at its arrival, and which
frames are processed never depends on the machine's load), the measured compute time
(``perf_counter``) with ``compute_cost="measured"`` or a non-deterministic config (a timing
study: the skipped frames then vary from run to run), or any function of it (e.g. a slower
on-board computer);
``wall`` sleeps until each frame's arrival on the real clock (a session replayed in real
time). Reading the frame from disk is not the estimator's work: both clocks stop during it.

Its parts, each importable from here too: the clocks (:mod:`graph_slam.pipelines.replay_clock`),
when a frame is ready and the feed (:mod:`graph_slam.pipelines.replay_feed`), what the replay
returns (:mod:`graph_slam.pipelines.replay_result`) and the process's memory
(:mod:`graph_slam.pipelines.memory`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence

import numpy as np

from graph_slam.errors import ConfigError, SessionError
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.memory import (
    RSS_MARKS_S,
    RssSample,
    frozen_heap,
    peak_rss_mb,
    rss_mb,
)
from graph_slam.pipelines.protocol import Pipeline
from graph_slam.pipelines.replay_clock import (  # noqa: F401 (re-exported)
    MEASURED,
    PACES,
    ComputeCost,
    Pace,
    _VirtualClock,
    _WallClock,
    clock_cost,
    no_cost,
)
from graph_slam.pipelines.replay_feed import _covering, _Feed, ready_times  # noqa: F401 (re-exported)
from graph_slam.pipelines.replay_result import ProcessedFrame, ReplayResult
from graph_slam.pipelines.runner import make_pipeline, open_pipeline, open_pipeline_mount
from graph_slam.pipelines.schedule import Schedule, pick_frame, schedule
from graph_slam.strides.streams import Streams

log = logging.getLogger(__name__)

__all__ = [
    "ProcessedFrame",
    "ReplayResult",
    "Schedule",
    "frozen_heap",
    "pick_frame",
    "ready_times",
    "replay_session",
    "schedule",
]


# --------------------------------------------------------------------------- the replay
def _play(session, stamp, arrival, clock, feed: _Feed, rss_marks_s, progress):
    """The frames on the clock: returns (processed frames, skipped indices, memory samples
    at the marks; the last at the end of the replay is the caller's)."""
    t0, n = float(stamp[0]), stamp.size
    marks = sorted(float(m) for m in rss_marks_s)
    rss = [RssSample(0.0, rss_mb(), peak_rss_mb())]
    frames: list[ProcessedFrame] = []
    skipped: list[int] = []
    i = 0
    while i < n:
        j, start = pick_frame(arrival, i, clock.now())
        clock.wait_until(start)
        skipped.extend(range(i, j))
        frames.append(_process(session, j, float(stamp[j]), clock, feed, feed.pipe))
        while marks and stamp[j] - t0 >= marks[0]:
            marks.pop(0)
            rss.append(RssSample(float(stamp[j] - t0), rss_mb(), peak_rss_mb()))
        i = j + 1
        if progress is not None:
            progress(i, n)
    return frames, np.array(skipped, dtype=int), rss


def _process(session, j: int, stamp_s: float, clock, feed: _Feed, pipe: Pipeline):
    """Read frame ``j`` (the clock stands still), deliver the streams that cover it, process
    it, advance the clock by the measured compute; its :class:`ProcessedFrame`."""
    io_t0 = time.perf_counter()
    frame = session.frame(j)
    clock.pause(time.perf_counter() - io_t0)
    start = clock.now()
    w0 = time.perf_counter()
    feed.until(frame.t_s)
    loaded = feed.known_events().foot_loaded(frame.t_s)
    w1, c1 = time.perf_counter(), time.process_time()
    out = pipe.add_frame(frame, loaded)
    w2, c2 = time.perf_counter(), time.process_time()
    clock.spent(j, w2 - w0)
    return ProcessedFrame(
        session_index=j,
        t_s=float(frame.t_s),
        arrival_s=stamp_s,
        start_s=start,
        finish_s=clock.now(),
        compute_s=w2 - w1,
        cpu_s=c2 - c1,
        feed_s=w1 - w0,
        stages_s=dict(out.stages_s),
    )


def _warm_up(pipe: Pipeline, streams: Streams, session, n: int) -> None:
    """Run a throw-away pipeline over the first ``n`` frames (nothing kept)."""
    import gc

    feed = _Feed(pipe, streams)
    for i in range(n):
        frame = session.frame(i)
        feed.until(frame.t_s)
        pipe.add_frame(frame, feed.known_events().foot_loaded(frame.t_s))
    del feed, pipe
    gc.collect()


def replay_session(
    session,
    config: PipelineConfig | None = None,
    pace: Pace = "virtual",
    *,
    compute_cost: ComputeCost | str | None = None,
    rss_marks_s: Sequence[float] = RSS_MARKS_S,
    warmup_frames: int = 3,
    freeze_gc: bool = True,
    progress: Callable[[int, int], None] | None = None,
    pipeline_factory: Callable[..., Pipeline] = make_pipeline,
) -> ReplayResult:
    """Replay a session (a :class:`graph_slam.session.Session` or its folder) causally into
    the config's pipeline (see the module docstring for the rules).

    ``compute_cost``: ``virtual`` pace only, maps each measured duration to virtual seconds
    (``"measured"``: as measured; None: none when ``config.deterministic``, else as
    measured). ``rss_marks_s``: session times (s after the first frame) at which
    the resident memory is sampled (also at the start and the end). ``warmup_frames``: before
    the clock starts, a throw-away pipeline processes the session's first frames (a device is
    started before the walk: lazy imports, thread pools and caches are not the estimator's
    per-frame cost; the first frame took 4.6 s instead of ~0.3 s without). ``freeze_gc``:
    the heap built before the walk is frozen for the replay (:func:`frozen_heap`), as a
    device process would. ``progress(frames
    arrived, frames in total)``. ``pipeline_factory``: ``make_pipeline``'s signature (tests
    pass a recording fake).
    """

    if pace not in PACES:
        raise ConfigError(f"pace {pace!r}: choose virtual or wall")
    if compute_cost is not None and pace != "virtual":
        raise ConfigError("compute_cost rescales the virtual clock: use it with pace='virtual'")
    config = config or PipelineConfig()
    if warmup_frames:  # built first: the measured pipeline is the factory's last
        session, streams, warm = open_pipeline(session, config, pipeline_factory)
        _warm_up(warm, streams, session, min(warmup_frames, session.n_frames))
    session, streams, pipe, mount = open_pipeline_mount(session, config, pipeline_factory)
    n = session.n_frames if config.max_frames is None else min(config.max_frames, session.n_frames)
    if n == 0:
        raise SessionError(f"{session.path}: the session has no frames to replay")
    stamp = np.asarray(session.frame_times_s[:n], float)
    arrival = ready_times(stamp, streams)  # a frame is taken once the sensors cover it
    t0 = float(stamp[0])
    feed = _Feed(pipe, streams)
    with frozen_heap(freeze_gc):  # before the clock starts: the collection takes ~0.1 s
        if pace == "virtual":
            clock = _VirtualClock(t0, clock_cost(compute_cost, config.deterministic))
        else:
            clock = _WallClock(t0)
        frames, skipped, rss = _play(session, stamp, arrival, clock, feed, rss_marks_s, progress)
    feed.until(float(stamp[-1]))
    w0 = time.perf_counter()
    results = pipe.finish()
    finish_call = time.perf_counter() - w0
    results.counts["foot_strikes"] = feed.i_strike
    results.config["mount_pitch"] = mount.to_dict()
    rss.append(RssSample(float(stamp[-1] - t0), rss_mb(), peak_rss_mb()))
    return ReplayResult(
        pace=pace,
        results=results,
        frames=frames,
        skipped=skipped,
        n_delivered=n,
        duration_s=float(stamp[-1] - t0),
        finish_call_s=finish_call,
        rss=rss,
    )
