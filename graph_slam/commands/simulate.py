"""``graph-slam simulate``: the gait-driven simulator (graph_slam.sim) writing a session."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def _scene_names() -> str:
    """The shipped scenes, for --help (a glob of models/scenes; no heavy import)."""
    try:
        from graph_slam_models import MODELS_DIR
    except ImportError:  # pragma: no cover - the models package ships with graph_slam
        return "see docs/simulator.md"
    return ", ".join(sorted(p.stem for p in (MODELS_DIR / "scenes").glob("*.yaml")))


_SCENES = _scene_names()


def parse_speed(text: str) -> float:
    """``slow`` / ``normal`` / ``fast`` (the thesis's speeds) or a number in m/s."""
    from graph_slam.errors import ConfigError
    from graph_slam.sim.config import SPEEDS_M_S

    if text in SPEEDS_M_S:
        return SPEEDS_M_S[text]
    try:
        return float(text)
    except ValueError:
        raise ConfigError(
            f"--speed {text!r}: use slow, normal, fast or a number in m/s (0.6-1.8)"
        ) from None


def register(app: typer.Typer) -> None:
    """Add the ``simulate`` command to ``app``."""

    @app.command("simulate")
    def simulate_cmd(
        out: Annotated[
            Path,
            typer.Option(
                "--out", help="Session folder to write (with --export: the recording's folder)."
            ),
        ],
        scene: Annotated[
            str, typer.Option(help=f"models/scenes/<name>.yaml or a path: {_SCENES}.")
        ] = "thesis-boxes",
        speed: Annotated[
            str, typer.Option(help="slow (0.8), normal (1.1), fast (1.4) or m/s.")
        ] = "normal",
        strides: Annotated[int, typer.Option(help="Complete strides to walk.")] = 9,
        seed: Annotated[int, typer.Option(help="Random seed (same seed, same bytes).")] = 1,
        camera: Annotated[str, typer.Option(help="Camera profile: d455, pico_flexx.")] = "d455",
        drops: Annotated[
            str | None, typer.Option(help="Frame drops: none, random, bursty (default: profile).")
        ] = None,
        mount_pitch: Annotated[
            float, typer.Option(help="Camera pitch below horizontal, degrees (30-45).")
        ] = 35.0,
        noise_scale: Annotated[float, typer.Option(help="Multiplies every noise σ.")] = 1.0,
        imu_rate: Annotated[float | None, typer.Option(help="IMU rate (Hz).")] = None,
        accel_range: Annotated[
            float | None, typer.Option(help="Accelerometer saturation, ±g (4 or 8).")
        ] = None,
        fast: Annotated[
            bool, typer.Option("--fast", help="Quarter resolution (D455: same as 212x120).")
        ] = False,
        resolution: Annotated[
            str | None,
            typer.Option(
                help="Image size WxH: the profile's divided by one factor (D455 real-time "
                "modes 848x480, 424x240, 212x120). Default: the profile's."
            ),
        ] = None,
        no_blur: Annotated[bool, typer.Option("--no-blur", help="No motion blur.")] = False,
        config: Annotated[
            Path | None, typer.Option("--config", help="YAML of SimConfig overrides (base).")
        ] = None,
        overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace --out.")] = False,
        export: Annotated[
            str,
            typer.Option(
                help="session: a session folder with ground truth; realsense-sdk-bag: what a "
                "real recording gives (a RealSense SDK .db3 written by librealsense, unaligned "
                "colour at 30 Hz, a prosthesis CSV log on its own clock; docs/recording.md)."
            ),
        ] = "session",
        clock_offset: Annotated[
            float | None,
            typer.Option(
                help="With --export realsense-sdk-bag: camera time = log time + this (s; "
                "default 3.217)."
            ),
        ] = None,
    ) -> None:
        """Simulate walking with a thigh-mounted camera, IMU, encoders and load cell; write a
        session with exact ground truth, sim_config.yaml and quicklook.png."""
        from graph_slam.commands._common import progress_bar
        from graph_slam.config import config_from_dict, load_config
        from graph_slam.sim import SimConfig, simulate
        from graph_slam.sim.quicklook import write_quicklook

        base = load_config(SimConfig, config).model_dump()
        base.update(
            scene=scene,
            speed_m_s=parse_speed(speed),
            strides=strides,
            seed=seed,
            camera=camera,
            drops=drops,
            mount_pitch_deg=mount_pitch,
            noise_scale=noise_scale,
            imu_rate_hz=imu_rate,
            accel_range_g=accel_range,
            fast=fast,
            motion_blur=not no_blur,
        )
        if resolution is not None:
            base["resolution"] = resolution
        cfg = config_from_dict(SimConfig, base, source="graph-slam simulate options")
        if export != "session":
            _export(cfg, out, export, 3.217 if clock_offset is None else clock_offset, overwrite)
            return
        if clock_offset is not None:
            from graph_slam.errors import ConfigError

            raise ConfigError("--clock-offset: only with --export realsense-sdk-bag (a session "
                              "has one clock)")  # fmt: skip
        with progress_bar("rendering") as update:
            result = simulate(cfg, out, overwrite=overwrite, progress=update)
        if cfg.quicklook:
            write_quicklook(result)
        for line in result.lines():
            typer.echo(line)


EXPORTS = ("session", "realsense-sdk-bag")


def _export(cfg, out: Path, export: str, clock_offset_s: float, overwrite: bool) -> None:
    """``--export realsense-sdk-bag``: the walk as an SDK recording + a prosthesis log
    (graph_slam.sim.export)."""
    from graph_slam.commands._common import progress_bar
    from graph_slam.config import config_from_dict
    from graph_slam.errors import ConfigError
    from graph_slam.sim.export import RecordingExportConfig, export_realsense_recording

    if export not in EXPORTS:
        raise ConfigError(f"--export {export!r}: choose {' or '.join(EXPORTS)}")
    options = config_from_dict(
        RecordingExportConfig, {"clock_offset_s": clock_offset_s}, source="--clock-offset"
    )
    with progress_bar("rendering") as update:
        result = export_realsense_recording(cfg, out, options, overwrite=overwrite, progress=update)
    for line in result.lines():
        typer.echo(line)
