"""``compare``, ``demo`` and ``view``: the comparison report, the embedded demo, the 3D view."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Annotated

import typer

from graph_slam.commands import options
from graph_slam.commands._common import with_workers, workers_option_help

DEMO_SPEEDS: tuple[tuple[str, str, int], ...] = (
    ("slow", "Slow", 9),
    ("normal", "Normal", 9),
    ("fast", "Fast", 7),
)
"""The thesis's 25 strides (Table 4.2): 9 slow, 9 normal, 7 fast."""
DEMO_WORKERS = 4
"""``compare``'s and the demo's processes at most (default: one per core): a deterministic run
keeps Open3D on one thread, so the baseline's tasks beside the graph's use the cores."""
DEMO_RESOLUTION = "424x240"
"""The D455's real-time mode the demo simulates (848x480 and 212x120 are options)."""


def _load_compare_config(
    path: Path | None,
    variants: str | None,
    preset: str | None = None,
    baseline_pixel_step: int | None = None,
    map_files: str | None = None,
):
    """The YAML's CompareConfig with the options over it (the stride maps stay on whatever
    the preset: the report scores them)."""
    from graph_slam.report import CompareConfig

    extra: dict = {}
    if baseline_pixel_step is not None:
        extra = {"pipeline": {"baseline": {"pixel_step": baseline_pixel_step}}}
    if map_files is not None:
        extra["map_files"] = map_files
    return options.load_settings(
        CompareConfig, path, variants, preset, stride_maps=True, extra=extra
    )


def _default_workers(workers: int | None, config: Path | None) -> int | None:
    """``--workers``, else the YAML's ``workers``, else one process per core (at most
    :data:`DEMO_WORKERS`): a deterministic run keeps Open3D on one thread, so processes
    are what uses the cores."""
    from graph_slam.config import read_yaml

    if workers is not None or (config is not None and "workers" in (read_yaml(config) or {})):
        return workers
    return max(1, min(DEMO_WORKERS, len(os.sched_getaffinity(0))))


def _demo_resolution(resolution: str | None, full_resolution: bool) -> str:
    from graph_slam.errors import ConfigError

    if full_resolution and resolution not in (None, "848x480"):
        raise ConfigError(f"--full-resolution is 848x480; --resolution {resolution} contradicts it")
    size = "848x480" if full_resolution else (resolution or DEMO_RESOLUTION)
    if size not in ("848x480", "424x240", "212x120"):
        raise ConfigError(f"--resolution {size!r}: choose 848x480, 424x240 or 212x120")
    return size


def _run_compare(sessions, out: Path, cfg, overwrite: bool = False):
    from graph_slam.bench.caption import mark_start
    from graph_slam.commands._common import progress_bar

    mark_start()  # the summary's caption names the code that ran
    from graph_slam.report import compare

    with progress_bar("running variants") as update:
        return compare(sessions, out, cfg, progress=update, overwrite=overwrite)


def _print_report(report) -> None:
    from graph_slam.report import summary_table

    typer.echo("\nTable 4.2 (online poses; RMSE after SE(3) alignment, m)\n")
    typer.echo(report.table_4_2_online)
    if report.table_4_2_smoothed:
        typer.echo("Table 4.2 (smoothed poses)\n")
        typer.echo(report.table_4_2_smoothed)
    from graph_slam.bench.caption import caption, invoked_command

    typer.echo(f"Summary (medians over strides; {caption(invoked_command())})\n")
    typer.echo(summary_table(report))
    for name, table in report.tables_4_1.items():
        typer.echo(f"Table 4.1, obstacle dimensions (mm), boxes seen whole, map from {name}\n")
        typer.echo(table)
        if name in report.box_counts:
            typer.echo("Strides in which each box was measured, skipped (seen in part) or missed\n")
            typer.echo(report.box_counts[name])
    for warning in report.warnings:
        typer.echo(f"warning: {warning}", err=True)
    typer.echo(
        f"report: {report.out / 'report.md'} ({len(report.files)} files, {report.wall_s:.0f} s)"
    )
    typer.echo(f"3D view: graph-slam view {report.out}")


def _demo_strides(text: str | None, scale: float) -> list[int]:
    """Strides per speed (slow, normal, fast): from ``--strides`` or the scaled 9/9/7."""
    from graph_slam.errors import ConfigError

    if text is None:
        if not 0 < scale < 1e3:  # NaN and inf too
            raise ConfigError(f"--strides-scale: must be > 0 and < 1000, got {scale}")
        return [max(1, round(n * scale)) for _, _, n in DEMO_SPEEDS]
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != len(DEMO_SPEEDS) or not all(p.isdigit() and int(p) >= 1 for p in parts):
        raise ConfigError(
            f"--strides: {text!r} must be three whole numbers >= 1 (slow,normal,fast), e.g. 1,1,1"
        )
    return [int(p) for p in parts]


def _check_demo_out(out: Path, overwrite: bool) -> None:
    """The demo folder (marked as graph-slam's) and its parts, checked before any work."""
    from graph_slam.session.atomic import check_output, mark_folder

    check_output(out, overwrite=overwrite, command="demo")
    for speed, _, _ in DEMO_SPEEDS:
        check_output(out / "sessions" / speed, overwrite=overwrite, command="simulate")
    check_output(out / "report", overwrite=overwrite, command="compare")
    mark_folder(out, command="demo")
    mark_folder(out / "sessions", command="demo")


def _simulate_demo(sim_cfgs, out: Path, overwrite: bool) -> list[Path]:
    """The demo's sessions, one after the other (each simulation already keeps the cores
    busy: two at once in worker processes took 41-50 s against 42 s)."""
    from graph_slam.commands._common import progress_bar
    from graph_slam.sim import simulate

    paths = []
    for (speed, label, _), sim_cfg in zip(DEMO_SPEEDS, sim_cfgs, strict=True):
        with progress_bar(f"simulating {label.lower()} ({sim_cfg.strides} strides)") as update:
            folder = out / "sessions" / speed
            paths.append(simulate(sim_cfg, folder, overwrite=overwrite, progress=update).path)
    return paths


def _folder_bytes(folder: Path) -> int:
    """The bytes of every file under ``folder``."""
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def _drop_sessions(out: Path, sim_cfgs, seed: int) -> tuple[int, str]:
    """Remove the demo's simulated sessions (its inputs, most of its size) once the report is
    written; ``sessions/README.md`` keeps the commands that simulate the same frames and
    streams again (the simulator is seeded; only session.yaml's creation time differs). Returns the bytes freed and that file's path."""
    freed = 0
    lines = [
        "# The demo's sessions",
        "",
        "Removed after the report to keep the demo's output small (`graph-slam demo",
        "--keep-sessions` keeps them). The simulator is deterministic: these commands write the",
        "same frames, streams and ground truth again.",
        "",
        "```bash",
    ]
    for (speed, _, _), cfg in zip(DEMO_SPEEDS, sim_cfgs, strict=True):
        folder = out / "sessions" / speed
        if folder.is_dir():
            freed += _folder_bytes(folder)
            shutil.rmtree(folder)
        lines.append(
            f"graph-slam simulate --scene {cfg.scene} --speed {speed} --strides "
            f"{cfg.strides} --seed {seed} --drops {cfg.drops} --resolution {cfg.resolution} "
            f"--out {folder}"
        )
    readme = out / "sessions" / "README.md"
    readme.write_text("\n".join([*lines, "```", ""]))
    return freed, str(readme)


def has_display(env: dict[str, str] | None = None) -> bool:
    env = os.environ if env is None else env
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


def register(app: typer.Typer) -> None:
    @app.command("compare")
    def compare_cmd(
        session: Annotated[Path, typer.Argument(help="Session folder (with ground truth).")],
        out: options.Out,
        variants: options.Variants = None,
        config: options.Config = None,
        preset: options.Preset = None,
        map_files: options.MapFiles = None,
        overwrite: options.Overwrite = False,
        workers: Annotated[
            int | None,
            typer.Option(
                min=1,
                max=64,
                help=workers_option_help(f"the cores this process may use, at most {DEMO_WORKERS}"),
            ),
        ] = None,
    ) -> None:
        """Run the baseline and the graph variants on one session; write the report folder."""
        from graph_slam.commands._common import exit_on_interrupt

        cfg = _load_compare_config(config, variants, preset, map_files=map_files)
        cfg = with_workers(cfg, _default_workers(workers, config))
        with exit_on_interrupt(out):
            report = _run_compare([session], out, cfg, overwrite)
        _print_report(report)

    @app.command()
    def demo(
        out: Annotated[Path, typer.Option(help="Output folder.")] = Path("runs/demo"),
        strides_scale: Annotated[
            float, typer.Option(help="Multiply the 9/9/7 strides (e.g. 0.34 → 3/3/2).")
        ] = 1.0,
        strides: Annotated[
            str | None,
            typer.Option(
                help="Strides per speed as SLOW,NORMAL,FAST (e.g. 1,1,1); overrides "
                "--strides-scale."
            ),
        ] = None,
        resolution: Annotated[
            str | None,
            typer.Option(
                help=f"Image size: 848x480, 424x240 or 212x120 (default {DEMO_RESOLUTION})."
            ),
        ] = None,
        full_resolution: Annotated[
            bool, typer.Option(help="Same as --resolution 848x480.")
        ] = False,
        variants: options.Variants = None,
        preset: options.Preset = None,
        map_files: options.MapFiles = None,
        baseline_pixel_step: Annotated[
            int | None,
            typer.Option(
                min=1,
                max=8,
                help="The thesis baseline's cloud from every n-th pixel, over --config and "
                "--preset (default: the preset's; realtime: the 212x120 cloud at any "
                "resolution; 1 = every pixel).",
            ),
        ] = None,
        seed: Annotated[int, typer.Option(help="Simulator seed.")] = 1,
        course: Annotated[
            str,
            typer.Option(
                help="boxes (the thesis box course, walked beside) or terrain (level, an 8° "
                "ramp up, a platform, 4 steps up and a landing: the terrain-course scene)."
            ),
        ] = "boxes",
        config: options.Config = None,
        overwrite: options.Overwrite = False,
        workers: Annotated[
            int | None,
            typer.Option(
                min=1,
                max=64,
                help=workers_option_help(f"the cores this process may use, at most {DEMO_WORKERS}"),
            ),
        ] = None,
        keep_sessions: Annotated[
            bool,
            typer.Option(
                help="Keep the simulated sessions (about 260 MB at 424x240) after the report; "
                "by default they are removed and sessions/README.md holds the commands that "
                "simulate the same frames and streams again."
            ),
        ] = False,
    ) -> None:
        """Simulate the thesis box course (9 slow, 9 normal, 7 fast strides, bursty frame drops),
        compare the variants on it and print the tables.

        424×240, the thesis baseline and the three graph variants on the default preset
        (realtime: the real-time front end, the baseline on the 212×120 cloud;
        docs/benchmarks.md, "Demo").
        """
        from graph_slam.bench.caption import mark_start
        from graph_slam.config import config_from_dict
        from graph_slam.report import SessionSpec
        from graph_slam.sim import SPEEDS_M_S, SimConfig

        mark_start()
        t0 = time.perf_counter()
        courses = {"boxes": "thesis-boxes", "terrain": "terrain-course"}
        if course not in courses:
            raise typer.BadParameter(f"--course {course!r}: choose boxes or terrain")
        counts = _demo_strides(strides, strides_scale)
        size = _demo_resolution(resolution, full_resolution)
        cfg = _load_compare_config(config, variants, preset, baseline_pixel_step, map_files)
        cfg = with_workers(cfg, _default_workers(workers, config))
        sim_cfgs = [
            config_from_dict(
                SimConfig,
                dict(
                    scene=courses[course],
                    speed_m_s=SPEEDS_M_S[speed],
                    strides=n_strides,
                    seed=seed,
                    drops="bursty",
                    resolution=size,
                    quicklook=False,
                ),
                source="graph-slam demo options",
            )  # every option checked before the folder is made
            for (speed, _, _), n_strides in zip(DEMO_SPEEDS, counts, strict=True)
        ]
        _check_demo_out(out, overwrite)
        paths = _simulate_demo(sim_cfgs, out, overwrite)
        specs = [SessionSpec(p, label) for p, (_, label, _) in zip(paths, DEMO_SPEEDS, strict=True)]
        t_sim = time.perf_counter() - t0
        typer.echo(
            f"simulated {len(specs)} sessions in {t_sim:.0f} s ({size}; variants "
            f"{', '.join(cfg.variants)}; preset {cfg.pipeline.preset})"
        )
        report = _run_compare(specs, out / "report", cfg, overwrite)
        _print_report(report)
        if not keep_sessions:
            freed, readme = _drop_sessions(out, sim_cfgs, seed)
            typer.echo(
                f"sessions removed ({freed / 1e6:.0f} MB; --keep-sessions keeps them): "
                f"{readme} simulates them again"
            )
        size_mb = _folder_bytes(out) / 1e6
        typer.echo(f"demo done in {time.perf_counter() - t0:.0f} s; {out}: {size_mb:.0f} MB")

    @app.command()
    def view(
        run_dir: Annotated[
            Path, typer.Argument(help="A compare/demo report folder or a .rrd file.")
        ],
    ) -> None:
        """Open the run's rerun recording (spawns the viewer when a display exists)."""
        from graph_slam.errors import EvaluationError

        rrd = run_dir if run_dir.suffix == ".rrd" else run_dir / "recording.rrd"
        if not rrd.is_file() and run_dir.is_dir():
            found = sorted(run_dir.rglob("*.rrd"))
            rrd = found[0] if found else rrd
        if not rrd.is_file():
            raise EvaluationError(
                f"{rrd}: no such recording (run graph-slam compare or demo to write it)"
            )
        exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
        if not has_display() or not Path(exe).exists():
            why = (
                "no display ($DISPLAY/$WAYLAND_DISPLAY unset)"
                if not has_display()
                else "no rerun executable"
            )
            typer.echo(f"{why}; open the recording on a machine with a display:\n  rerun {rrd}")
            return
        try:
            subprocess.Popen([exe, str(rrd)], start_new_session=True)
        except OSError as err:
            raise EvaluationError(
                f"{exe}: cannot start the rerun viewer ({err}); open the recording by hand: "
                f"rerun {rrd}"
            ) from None
        typer.echo(f"opened {rrd} in the rerun viewer")
