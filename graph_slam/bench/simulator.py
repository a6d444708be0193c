"""Simulator benchmark: wall time of ``simulate`` against its target (25 strides of D455 at
90 Hz nominal under 3 minutes on 2 cores)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

from graph_slam.sim import SimConfig, SimResult, simulate


@dataclass(frozen=True)
class SimBenchResult:
    config: SimConfig
    result: SimResult
    wall_s: float
    cpus: int

    def lines(self) -> list[str]:
        c, r = self.config, self.result
        return [
            f"simulate: {c.strides} strides, {c.camera}, drops {c.drops or 'profile default'}, "
            f"scene {c.scene}, speed {c.speed_m_s} m/s, fast={c.fast} ({self.cpus} CPUs visible)",
            f"frames rendered {r.frames} of {r.nominal_frames} nominal "
            f"({r.effective_rate_hz:.1f} Hz effective, {r.frames_per_stride.mean():.1f}/stride)",
            f"wall time {self.wall_s:.1f} s ({1000 * self.wall_s / max(r.frames, 1):.0f} ms/frame); "
            + ", ".join(f"{k} {v:.1f} s" for k, v in r.timings_s.items()),
        ]


def run_simulate_bench(out: Path, cfg: SimConfig, progress=None) -> SimBenchResult:
    start = time.perf_counter()
    result = simulate(cfg, out, overwrite=True, progress=progress)
    return SimBenchResult(cfg, result, time.perf_counter() - start, len(os.sched_getaffinity(0)))
