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
"""

from __future__ import annotations

import contextlib
import gc
import logging
import resource
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from graph_slam.errors import ConfigError, SessionError
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.protocol import Pipeline
from graph_slam.pipelines.results import PipelineResults
from graph_slam.pipelines.runner import make_pipeline, open_pipeline, open_pipeline_mount
from graph_slam.pipelines.schedule import Schedule, pick_frame, schedule
from graph_slam.strides.events import StrideEvents
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

Pace = Literal["virtual", "wall"]
PACES: tuple[str, ...] = ("virtual", "wall")

ComputeCost = Callable[[int, float], float]
"""``(session frame index, measured seconds) -> seconds on the virtual clock``."""

MEASURED = "measured"
"""``compute_cost`` that advances the virtual clock by the measured time (a timing study)."""


def no_cost(_frame_index: int, _measured_s: float) -> float:
    """The deterministic virtual clock's cost: none (every frame is taken when it arrives)."""
    return 0.0


def clock_cost(compute_cost: ComputeCost | str | None, deterministic: bool) -> ComputeCost | None:
    """The virtual clock's cost function (None: as measured) for ``replay_session``'s
    ``compute_cost`` and the config's ``deterministic``."""
    if compute_cost == MEASURED:
        return None
    if isinstance(compute_cost, str):
        raise ConfigError(f"compute_cost {compute_cost!r}: a function or {MEASURED!r}")
    if compute_cost is None:
        return no_cost if deterministic else None
    return compute_cost


RSS_MARKS_S: tuple[float, ...] = (60.0, 300.0, 600.0)
"""Session times (s after the first frame) at which the resident memory is sampled."""


# --------------------------------------------------------------------------- clocks
class _VirtualClock:
    """Session time that only the estimator's measured work advances."""

    def __init__(self, t0_s: float, cost: ComputeCost | None) -> None:
        self.now_s = t0_s
        self._cost = cost

    def now(self) -> float:
        return self.now_s

    def wait_until(self, t_s: float) -> None:
        self.now_s = max(self.now_s, t_s)

    def spent(self, frame_index: int, measured_s: float) -> None:
        self.now_s += measured_s if self._cost is None else self._cost(frame_index, measured_s)

    def pause(self, _measured_s: float) -> None:
        pass


class _WallClock:
    """Session time on the real clock: ``t0_s`` now, then as the wall clock runs."""

    def __init__(self, t0_s: float) -> None:
        self._origin = time.perf_counter() - t0_s

    def now(self) -> float:
        return time.perf_counter() - self._origin

    def wait_until(self, t_s: float) -> None:
        delay = t_s - self.now()
        if delay > 0:
            time.sleep(delay)

    def spent(self, _frame_index: int, _measured_s: float) -> None:
        pass

    def pause(self, measured_s: float) -> None:
        self._origin += measured_s  # the session's clock stood still meanwhile


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class ProcessedFrame:
    """One processed frame on the replay's clock (session time, s)."""

    session_index: int
    t_s: float
    arrival_s: float
    start_s: float
    """When the estimator took it (before the buffered samples were delivered)."""
    finish_s: float
    compute_s: float
    """Wall time of ``add_frame``."""
    cpu_s: float
    """Process CPU time of ``add_frame`` (every thread)."""
    feed_s: float
    """Wall time delivering the buffered samples and foot strikes before it."""
    stages_s: dict[str, float] = field(default_factory=dict)
    """The pipeline's per-stage times (:attr:`FrameOutput.stages_s`)."""

    @property
    def latency_s(self) -> float:
        return self.finish_s - self.arrival_s


@dataclass(frozen=True)
class RssSample:
    """Resident memory at a moment of the replay."""

    session_s: float
    """Session time since the first frame."""
    rss_mb: float
    peak_mb: float


@dataclass(eq=False)
class ReplayResult:
    """What :func:`replay_session` produced: the pipeline's results over the processed frames
    (``results.frames[k]`` is ``frames[k]``) and the timing of each."""

    pace: str
    results: PipelineResults
    frames: list[ProcessedFrame]
    skipped: np.ndarray
    """Session indices of the frames skipped by the policy."""
    n_delivered: int
    duration_s: float
    """Session time from the first to the last delivered frame."""
    finish_call_s: float
    """Wall time of the pipeline's ``finish`` (closing the last stride)."""
    rss: list[RssSample]

    @property
    def n_processed(self) -> int:
        return len(self.frames)

    @property
    def n_skipped(self) -> int:
        return int(self.skipped.size)

    @property
    def session_indices(self) -> np.ndarray:
        return np.array([f.session_index for f in self.frames], dtype=int)

    @property
    def latency_s(self) -> np.ndarray:
        return np.array([f.latency_s for f in self.frames])

    @property
    def compute_s(self) -> np.ndarray:
        return np.array([f.compute_s for f in self.frames])

    @property
    def cpu_s(self) -> np.ndarray:
        return np.array([f.cpu_s for f in self.frames])

    @property
    def delivered_rate_hz(self) -> float:
        return (self.n_delivered - 1) / self.duration_s if self.duration_s > 0 else float("nan")

    @property
    def achieved_rate_hz(self) -> float:
        """Processed frames per second of session time (the delivered rate when none is
        skipped)."""
        if self.duration_s <= 0:
            return float("nan")
        return self.delivered_rate_hz * self.n_processed / self.n_delivered

    @property
    def peak_rss_mb(self) -> float:
        return max((s.peak_mb for s in self.rss), default=float("nan"))

    def stage_s(self, name: str) -> np.ndarray:
        """The stage's time on every processed frame where it ran."""
        return np.array([f.stages_s[name] for f in self.frames if name in f.stages_s])


def rss_mb() -> float:
    """The process's resident memory now (MB; Linux ``/proc``, else the peak)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return peak_rss_mb()
    return pages * resource.getpagesize() / 1e6


def peak_rss_mb() -> float:
    """The process's peak resident memory so far (MB; ``ru_maxrss``)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 1e6 if sys.platform == "darwin" else peak / 1e3  # bytes on macOS, else KiB


# --------------------------------------------------------------------------- the feed
def _covering(t_s: np.ndarray, t: float) -> int:
    """How many samples a device has once its stream covers ``t``: up to and including the
    first one at or after ``t``."""
    return min(int(np.searchsorted(t_s, t, side="left")) + 1, t_s.size)


def ready_times(frame_t_s: np.ndarray, streams: Streams) -> np.ndarray:
    """When each frame can be processed: its time stamp, or later, when the IMU or encoder
    sample that covers it arrives (never before the stamp; a stream that ends does not
    hold frames back)."""
    stamp = np.asarray(frame_t_s, float)
    ready = stamp.copy()
    for t_s in (streams.imu_t_s, streams.joints_t_s):
        if t_s is None or t_s.size == 0:
            continue
        k = np.searchsorted(t_s, stamp, side="left")
        inside = k < t_s.size
        ready[inside] = np.maximum(ready[inside], t_s[k[inside]])
    return np.maximum.accumulate(ready)


class _Feed:
    """The session's streams, delivered up to a time in timestamp order (never twice)."""

    def __init__(self, pipe: Pipeline, streams: Streams) -> None:
        self.pipe = pipe
        self.s = streams
        self.i_imu = self.i_joint = self.i_strike = 0
        self.t_known = -np.inf
        self.strikes = streams.events.foot_strikes_s
        self.strikes_known = streams.events.strikes_known_s
        self.toe_offs = streams.events.toe_offs_s

    def _samples_until(self, t_s: float) -> None:
        """Every sample up to and including the first at or after ``t_s`` (per stream)."""
        s = self.s
        if s.imu_t_s is not None:
            j = _covering(s.imu_t_s, t_s)
            if j > self.i_imu:
                sl = slice(self.i_imu, j)
                self.pipe.add_imu(s.imu_t_s[sl], s.gyro_rad_s[sl], s.accel_m_s2[sl])
                self.i_imu = j
        if s.joints_t_s is not None:
            j = _covering(s.joints_t_s, t_s)
            if j > self.i_joint:
                sl = slice(self.i_joint, j)
                self.pipe.add_joints(s.joints_t_s[sl], s.knee_rad[sl], s.ankle_rad[sl])
                self.i_joint = j

    def until(self, t_s: float) -> None:
        """Samples and foot strikes stamped at or before ``t_s``; each strike after the
        samples up to it."""
        while self.i_strike < self.strikes.size and self.strikes_known[self.i_strike] <= t_s:
            t_strike = float(self.strikes[self.i_strike])
            self._samples_until(float(self.strikes_known[self.i_strike]))
            self.pipe.foot_strike(t_strike)
            self.i_strike += 1
        self._samples_until(t_s)
        self.t_known = t_s

    def known_events(self) -> StrideEvents:
        """The events delivered (known) so far."""
        return self.s.events.known_at(self.t_known)


@contextlib.contextmanager
def frozen_heap(enabled: bool = True) -> Iterator[None]:
    """CPython's garbage collector with the heap built so far frozen (``gc.freeze``), for a
    real-time loop; unfrozen on exit.

    With GTSAM, Open3D, numba and scipy loaded the process holds ~170k tracked objects, and
    every full (generation 2) collection walks all of them: 60–100 ms, measured on the
    424×240 replays, during which 5–9 frames arrive (the normal session skipped 9 with
    one). Frozen, a full
    collection walks only the objects made since. A controller running a pipeline does the
    same once it is built: ``gc.collect(); gc.freeze()`` before the walk.
    """
    if not enabled:
        yield
        return
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


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
