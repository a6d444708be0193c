"""Session I/O benchmark: resident memory and throughput of the lazy reader on a long session.

A 10-minute 90 Hz session has 54 000 frames. Writing that many distinct 848×480 PNG pairs would
take most of an hour on 2 cores, so the benchmark writes ``unique_frames`` distinct frames and
lets the frame index cycle through them (each index row still names one file; the reader decodes
every row). The index, IMU (400 Hz) and joint (500 Hz) streams have the full 10-minute length,
so what the reader keeps in memory is exactly what it keeps for a real session of that length.
"""

from __future__ import annotations

import resource
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graph_slam.session.files import FRAME_COLUMNS
from graph_slam.session.reader import open_session
from graph_slam.session.records import CameraIntrinsics, ImuSeries, JointSeries, RgbdFrame
from graph_slam.session.writer import SessionWriter


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far (MB; Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@dataclass(frozen=True)
class SessionIoResult:
    minutes: float
    frames: int
    unique_frames: int
    width_px: int
    height_px: int
    write_s: float
    open_s: float
    streams_s: float
    read_s: float
    rss_before_read_mb: float
    rss_after_10pct_mb: float
    rss_after_read_mb: float

    @property
    def read_fps(self) -> float:
        return self.frames / self.read_s

    def lines(self) -> list[str]:
        return [
            f"session: {self.minutes:g} min at {self.frames / (self.minutes * 60):g} Hz = {self.frames} "
            f"frames of {self.width_px}×{self.height_px} depth+colour ({self.unique_frames} distinct files)",
            f"write {self.write_s:.1f} s; open (manifest + index) {self.open_s:.2f} s; "
            f"IMU + joints parse {self.streams_s:.2f} s",
            f"read every frame: {self.read_s:.1f} s ({self.read_fps:.0f} frames/s)",
            f"peak RSS: before reading frames {self.rss_before_read_mb:.0f} MB, after 10 % "
            f"{self.rss_after_10pct_mb:.0f} MB, after all {self.rss_after_read_mb:.0f} MB",
        ]


def run_session_io(
    out: Path,
    *,
    minutes: float = 10.0,
    rate_hz: float = 90.0,
    width_px: int = 848,
    height_px: int = 480,
    unique_frames: int = 900,
    seed: int = 0,
    progress=None,
) -> SessionIoResult:
    rng = np.random.default_rng(seed)
    k = CameraIntrinsics(width_px, height_px, 430.0, 430.0, width_px / 2, height_px / 2)
    n_frames = int(minutes * 60 * rate_hz)
    t0 = time.perf_counter()
    with SessionWriter(out, name="bench-session-io", intrinsics=k, overwrite=True) as writer:
        base = rng.uniform(0.5, 3.0, (height_px, width_px)).astype(np.float32)
        for i in range(min(unique_frames, n_frames)):
            color = rng.integers(0, 255, (height_px, width_px, 3), dtype=np.uint8)
            writer.add_frame(RgbdFrame(i / rate_hz, base + np.float32(0.001 * i), color, i))
        t_imu = np.arange(int(minutes * 60 * 400)) / 400.0
        writer.write_imu(
            ImuSeries(t_imu, rng.normal(size=(t_imu.size, 3)), rng.normal(size=(t_imu.size, 3)))
        )
        t_j = np.arange(int(minutes * 60 * 500)) / 500.0
        writer.write_joints(JointSeries(t_j, np.sin(t_j), np.cos(t_j)))
    # Extend the index to the full length, cycling through the distinct files.
    with (out / "frames.csv").open("w", encoding="utf-8") as handle:
        handle.write(",".join(FRAME_COLUMNS) + "\n")
        for i in range(n_frames):
            name = f"{i % unique_frames:06d}.png"
            handle.write(f"{i},{i / rate_hz:.9f},depth/{name},color/{name}\n")
    write_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    session = open_session(out)
    open_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    _ = session.imu, session.joints
    streams_s = time.perf_counter() - t0
    rss_before = peak_rss_mb()
    rss_10 = rss_before
    t0 = time.perf_counter()
    for frame in session:
        if frame.index == n_frames // 10:
            rss_10 = peak_rss_mb()
        if progress is not None and frame.index % 500 == 0:
            progress(frame.index, n_frames)
    read_s = time.perf_counter() - t0
    return SessionIoResult(
        minutes=minutes,
        frames=n_frames,
        unique_frames=unique_frames,
        width_px=width_px,
        height_px=height_px,
        write_s=write_s,
        open_s=open_s,
        streams_s=streams_s,
        read_s=read_s,
        rss_before_read_mb=rss_before,
        rss_after_10pct_mb=rss_10,
        rss_after_read_mb=peak_rss_mb(),
    )
