"""What a live run leaves on stop: the streams as given to the pipeline (:class:`_Recorded`,
written as the live session) and :func:`write_outputs` (the session, ``graph-slam run``'s
outputs from the live results, and ``live.json``)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graph_slam.live.result import LiveResult
from graph_slam.session.records import RgbdFrame

if TYPE_CHECKING:
    from graph_slam.live.loop import LiveRunner


@dataclass
class _Recorded:
    """The streams as given to the pipeline (written as the live session on stop)."""

    frames: list[RgbdFrame] = field(default_factory=list)
    imu: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    joints: list[tuple[float, float, float]] = field(default_factory=list)
    events: list[tuple[float, str]] = field(default_factory=list)


def write_outputs(runner: LiveRunner, result: LiveResult, out: Path, *, overwrite: bool = False):
    """``out/session`` (the frames processed) and ``out/run`` (``graph-slam run``'s outputs
    from the live results)."""
    from graph_slam.report import RunConfig, run

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    session = runner.write_session(out / "session")  # (written during the run if asked)
    variant = runner.config.variant
    cfg = RunConfig(variants=[variant], pipeline=runner.config.model_copy(
        update={"mount_pitch_deg": runner.mount_pitch_deg, "event_source": None}), rrd=False)  # fmt: skip
    from graph_slam.variants import Variant

    report = run([session], out / "run", cfg, overwrite=overwrite,
                 precomputed={"live": {Variant(variant): result.results}})  # fmt: skip
    result.session, result.outputs = session, report.out
    tmp = out / ".live.json.tmp"  # written whole or not at all
    tmp.write_text(json.dumps(result.summary(), indent=2) + "\n")
    tmp.replace(out / "live.json")
    return report
