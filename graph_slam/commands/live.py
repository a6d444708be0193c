"""``graph-slam live``: the causal real-time pipeline on a RealSense camera (or a recording
played back in real time), with the prosthesis's streams from a log replayed on its clock or
from UDP datagrams; on stop, the outputs of ``graph-slam run`` (docs/recording.md, "Live")."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def live(
        out: Annotated[Path, typer.Option("--out", help="Folder for the session and outputs.")],
        serial: Annotated[
            str | None, typer.Option(help="Camera serial number (default: the first camera).")
        ] = None,
        playback: Annotated[
            Path | None, typer.Option(help="Play this SDK recording (.db3) in real time.")
        ] = None,
        config: Annotated[
            Path | None,
            typer.Option(
                help="Conversion YAML giving prosthesis_log (columns) and "
                "calibration.camera_T_imu (e.g. an export's convert.yaml)."
            ),
        ] = None,
        log: Annotated[
            Path | None, typer.Option(help="Prosthesis log replayed on its clock.")
        ] = None,
        clock_offset: Annotated[
            float, typer.Option(help="Camera time = prosthesis time + this (s).")
        ] = 0.0,
        udp: Annotated[
            int | None,
            typer.Option(help="Receive the prosthesis's JSON datagrams on 127.0.0.1:PORT."),
        ] = None,
        mount_pitch: Annotated[
            float, typer.Option(help="Camera pitch below horizontal (deg).")
        ] = 35.0,
        preset: Annotated[str, typer.Option(help="Pipeline preset.")] = "realtime",
        variant: Annotated[str, typer.Option(help="Pipeline variant.")] = "icp+imu+kin",
        rerun: Annotated[
            str | None,
            typer.Option(
                help="spawn: open a rerun viewer; file: only OUT/live.rrd; or a "
                "viewer address to connect to."
            ),
        ] = None,
        rerun_pose_hz: Annotated[
            float,
            typer.Option(
                help="Poses sent to rerun per second, on the frames' clock (0: every frame)."
            ),
        ] = 30.0,
        rerun_grid_hz: Annotated[
            float,
            typer.Option(
                help="Elevation grids sent to rerun per second (0: every frame; each "
                "is a box search in the viewer's process)."
            ),
        ] = 5.0,
        imu_wait: Annotated[
            float,
            typer.Option(
                help="Skip a frame whose IMU sample after it has not come this long "
                "after the frame (ms)."
            ),
        ] = 20.0,
        max_seconds: Annotated[
            float | None, typer.Option(help="Stop after this long (default: until Ctrl-C).")
        ] = None,
        overwrite: Annotated[bool, typer.Option(help="Replace --out.")] = False,
    ) -> None:
        """Run the pipeline live; a status line every second; Ctrl-C stops and writes."""
        import numpy as np

        from graph_slam.config import config_from_dict, load_config
        from graph_slam.errors import ConfigError
        from graph_slam.live.camera import RealsenseSource
        from graph_slam.live.loop import LiveRunner, write_outputs
        from graph_slam.live.prosthesis import LogReplay, NoProsthesis, UdpStream
        from graph_slam.live.sdk import rs_module
        from graph_slam.pipelines.config import PipelineConfig, with_preset
        from graph_slam.session.adapters.config import ConvertConfig

        rs_module()  # a missing extra is said before anything else
        if not imu_wait > 0:
            raise ConfigError(f"--imu-wait {imu_wait}: must be positive (ms)")
        if log is not None and udp is not None:
            raise ConfigError("--log and --udp: give one prosthesis source")
        from graph_slam.live.viewer import ViewerConfig

        view_cfg = config_from_dict(ViewerConfig, {"pose_hz": rerun_pose_hz,
                                                   "grid_hz": rerun_grid_hz},
                                    source="--rerun-pose-hz / --rerun-grid-hz")  # fmt: skip
        from graph_slam.session.atomic import check_output, mark_folder

        inputs = [p for p in (playback, log, config) if p is not None]
        out = check_output(out, overwrite=overwrite, command="live", inputs=inputs)
        conv = load_config(ConvertConfig, config)
        pcfg = config_from_dict(
            PipelineConfig, with_preset({"variant": variant}, preset), source="--preset"
        )
        camera_T_imu = conv.calibration.camera_T_imu
        source = RealsenseSource(
            serial=serial,
            playback=playback,
            camera_T_imu=None if camera_T_imu is None else np.asarray(camera_T_imu),
        )
        log_path = log or (Path(conv.prosthesis_log.path) if conv.prosthesis_log.path else None)
        if log_path is not None:
            prosthesis = LogReplay(log_path, conv.prosthesis_log, clock_offset)
        elif udp is not None:
            prosthesis = UdpStream(udp, offset_s=clock_offset, load=conv.prosthesis_log.load)
            typer.echo(f"prosthesis datagrams on udp://{prosthesis.address[0]}:"
                       f"{prosthesis.address[1]}")  # fmt: skip
        else:
            prosthesis = NoProsthesis()
        check_output(
            out, overwrite=overwrite, command="live", inputs=[*inputs, *filter(None, [log_path])]
        )
        if out.is_dir() and any(out.iterdir()):  # a live run's folder, --overwrite (checked)
            import shutil

            shutil.rmtree(out)
        mark_folder(out, command="live")
        viewer = None
        if rerun is not None:
            from graph_slam.live.viewer import LiveViewer

            out.mkdir(parents=True, exist_ok=True)
            viewer = LiveViewer(out / "live.rrd", view_cfg, spawn=rerun == "spawn",
                                connect=None if rerun in ("spawn", "file") else rerun)  # fmt: skip
            viewer.wait_ready()
        session_path = out / "session"
        runner = LiveRunner(source, prosthesis, pcfg, mount_pitch_deg=mount_pitch,
                            status=typer.echo, viewer=viewer, session_path=session_path,
                            imu_wait_s=imu_wait * 1e-3)  # fmt: skip
        result = runner.run(max_s=max_seconds)
        if viewer is not None:
            viewer.close()
            typer.echo(f"viewer: {viewer.counts}")
        lat = result.latency_s * 1e3
        skipped_pct = 100.0 * result.skipped / max(result.n_arrived, 1)
        typer.echo(
            f"stopped: {result.stop_reason}; {result.n_processed} of {result.n_arrived} frames "
            f"processed, {result.skipped} skipped ({skipped_pct:.1f} %), latency median "
            f"{np.median(lat) if lat.size else float('nan'):.1f} ms, p95 "
            f"{np.percentile(lat, 95) if lat.size else float('nan'):.1f} ms"
        )
        why = ", ".join(f"{k} {v}" for k, v in result.counts["skipped"].items())
        typer.echo(f"skipped by reason: {why}; warm-up before the start {result.warm_up_s:.1f} s")
        typer.echo(f"timing: {result.timing.summary()}")
        typer.echo(f"counts: {result.counts}")
        if result.n_processed == 0:
            raise ConfigError("no frame was processed: nothing to write")
        report = write_outputs(runner, result, out, overwrite=overwrite)
        typer.echo(f"wrote {result.session} and {report.out}")
