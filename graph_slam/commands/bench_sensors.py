"""``graph-slam bench`` commands that measure the inputs and the front end: the lazy session
reader, the simulator, frame-to-frame registration and the calibration of its information
(registered under ``bench`` by :mod:`graph_slam.commands.bench`)."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Annotated

import typer


def _check_options(**values: float) -> None:
    """Each option value (named by its keyword) is finite and > 0: a ConfigError naming it."""
    import math

    from graph_slam.errors import ConfigError

    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(
                f"--{name.replace('_', '-')}: must be a finite number > 0, got {value}"
            )


def session_io(
    minutes: Annotated[float, typer.Option(help="Session length.")] = 10.0,
    rate_hz: Annotated[float, typer.Option(help="Frame rate.")] = 90.0,
    unique_frames: Annotated[
        int, typer.Option(help="Distinct PNG pairs the index cycles through.")
    ] = 900,
) -> None:
    """Peak resident memory and throughput of the lazy reader on a long D455-sized session."""
    from graph_slam.bench.session_io import run_session_io
    from graph_slam.commands._common import progress_bar

    _check_options(minutes=minutes, rate_hz=rate_hz, unique_frames=unique_frames)
    with tempfile.TemporaryDirectory() as tmp, progress_bar("reading frames") as update:
        result = run_session_io(
            Path(tmp) / "session",
            minutes=minutes,
            rate_hz=rate_hz,
            unique_frames=unique_frames,
            progress=update,
        )
    for line in result.lines():
        typer.echo(line)


def simulate_bench(
    strides: Annotated[int, typer.Option(help="Strides to simulate.")] = 25,
    drops: Annotated[str | None, typer.Option(help="none, random, bursty (profile).")] = None,
    camera: Annotated[str, typer.Option(help="Camera profile.")] = "d455",
    fast: Annotated[bool, typer.Option("--fast", help="Quarter resolution.")] = False,
) -> None:
    """Wall time of the simulator (target: 25 strides of D455 at 90 Hz in < 3 min, 2 cores)."""
    from graph_slam.bench.simulator import run_simulate_bench
    from graph_slam.commands._common import progress_bar
    from graph_slam.config import config_from_dict
    from graph_slam.sim import SimConfig

    options = dict(strides=strides, drops=drops, camera=camera, fast=fast, quicklook=False)
    cfg = config_from_dict(SimConfig, options, source="graph-slam bench simulate options")
    with tempfile.TemporaryDirectory() as tmp, progress_bar("simulating") as update:
        result = run_simulate_bench(Path(tmp) / "session", cfg, progress=update)
    for line in result.lines():
        typer.echo(line)


def registration(
    pairs: Annotated[int, typer.Option(help="Synthetic frame pairs (848×480).")] = 10,
    rate_hz: Annotated[float, typer.Option(help="Synthetic frame rate.")] = 40.0,
    tum: Annotated[
        Path | None,
        typer.Option(help="TUM sample folder (default: ../shared/data/tum_fr1_xyz_10 if present)."),
    ] = None,
    methods: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated: thesis, default, refined, p2pl, fast, accurate, realtime, "
            "realtime-gicp (default: the first five)."
        ),
    ] = None,
    session: Annotated[
        list[Path] | None,
        typer.Option(help="Simulated session(s) instead of the synthetic frames (first pairs)."),
    ] = None,
    steps: Annotated[
        str, typer.Option(help="With --session: pixel decimations, e.g. '2,1' (424×240, 848×480).")
    ] = "2,1",
    guess: Annotated[
        str,
        typer.Option(help="Initial guess: identity or constant-velocity (previous true motion)."),
    ] = "identity",
) -> None:
    """Per-stage timings and accuracy of frame-to-frame registration (thesis and fast configs)."""
    import os

    from graph_slam.bench.registration import GUESSES, METHODS, run_registration_bench
    from graph_slam.commands._common import progress_bar

    _check_options(pairs=pairs, rate_hz=rate_hz)
    if not all(s.strip().isdigit() and int(s) >= 1 for s in steps.split(",")):
        raise typer.BadParameter(f"--steps {steps!r}: whole numbers >= 1, e.g. 2,1")
    configs = None
    if methods:
        names = [m.strip() for m in methods.split(",") if m.strip()]
        if unknown := [m for m in names if m not in METHODS]:
            raise typer.BadParameter(f"unknown {unknown}; choose from {', '.join(METHODS)}")
        configs = {METHODS[m][0]: METHODS[m][1] for m in names}
    if guess not in GUESSES:
        raise typer.BadParameter(f"--guess must be one of {', '.join(GUESSES)}")
    with progress_bar("registering") as update:
        reports = run_registration_bench(
            pairs=pairs,
            rate_hz=rate_hz,
            tum_folder=tum,
            configs=configs,
            progress=update,
            sessions=tuple(session or ()),
            steps=tuple(int(s) for s in steps.split(",")),
            guess=guess,
        )
    typer.echo(f"registration benchmark ({os.cpu_count()} CPUs visible)")
    for report in reports:
        for line in report.lines():
            typer.echo(line)


def calibration_bench(
    sessions: Annotated[
        list[Path] | None, typer.Argument(help="Simulated sessions (ground truth needed).")
    ] = None,
    pairs: Annotated[int, typer.Option(help="Consecutive pairs per session (from frame 0).")] = 59,
    tum: Annotated[
        Path | None,
        typer.Option(help="TUM sample folder (default: ../shared/data/tum_fr1_xyz_10 if present)."),
    ] = None,
) -> None:
    """Calibration: χ²/dof of the registrations' information against the truth (accurate and
    realtime presets as the pipeline uses them for the data: on recorded frames, the TUM
    sample, the accurate preset carries the real-camera covariance floor, and its line
    without the floor is printed beside it; docs/frontend.md, "Calibrated information")."""
    from graph_slam.bench.calibration import chi2_of_pairs
    from graph_slam.bench.registration_data import (
        default_tum_folder,
        read_tum_sample,
        session_dataset,
    )
    from graph_slam.determinism import apply_threads
    from graph_slam.frontend.config import realtime_registration
    from graph_slam.pipelines.config import PipelineConfig
    from graph_slam.pipelines.protocol import sensor_registration, with_camera_floor

    apply_threads(True)  # the same figures every run
    datasets = [session_dataset(p, stop=pairs + 1) for p in sessions or ()]
    folder = tum or default_tum_folder()
    if (folder / "ground_truth.json").is_file():
        datasets.append(read_tum_sample(folder))
    accurate = PipelineConfig(preset="accurate").graph.registration
    presets = {"accurate": accurate, "realtime": realtime_registration()}
    for data in datasets:
        typer.echo(data.name)
        has_color = all(f.color_rgb is not None for f in data.frames)
        for name, preset in presets.items():
            # depth only: point-to-plane with the graph's depth-only settings
            config = sensor_registration(preset, has_color, PipelineConfig().graph.depth_only)
            floored = with_camera_floor(config, not data.synthetic)  # as the pipeline does
            label = name if floored is config else f"{name} (real-camera floor)"
            typer.echo(chi2_of_pairs(data, floored, name=label).line())
            if floored is not config:
                typer.echo(chi2_of_pairs(data, config, name=f"{name}, no floor").line())
