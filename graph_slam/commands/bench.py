"""``graph-slam bench ...``: benchmarks that print the figures recorded in docs/benchmarks.md."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Annotated

import typer

from graph_slam.commands import options

bench_app = typer.Typer(
    help="Benchmarks (figures recorded in docs/benchmarks.md).", no_args_is_help=True
)


@bench_app.callback()
def _started() -> None:
    """The commit a printed table names is the one that started (bench.caption.commit)."""
    from graph_slam.bench.caption import mark_start

    mark_start()


def _check_options(**values: float) -> None:
    """Each option value (named by its keyword) is finite and > 0: a ConfigError naming it."""
    import math

    from graph_slam.errors import ConfigError

    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(
                f"--{name.replace('_', '-')}: must be a finite number > 0, got {value}"
            )


@bench_app.command("session-io")
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


@bench_app.command("simulate")
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


@bench_app.command("registration")
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


@bench_app.command("all")
def run_all() -> None:
    """Every benchmark with its default settings."""
    session_io()
    simulate_bench()
    registration()


def register(app: typer.Typer) -> None:
    app.add_typer(bench_app, name="bench")


@bench_app.command("pipelines")
def pipelines_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Simulated sessions (graph-slam simulate), one per speed.")
    ],
    variants: Annotated[
        str,
        typer.Option(
            help="Comma-separated: icp, icp+imu, imu+kin, icp+imu+kin, bridge "
            "(icp+imu+kin without ICP in swing); a graph row may name a pipeline preset: "
            "icp+imu+kin:realtime (accurate, thesis, realtime, realtime-gicp; docs/pipelines.md)."
        ),
    ] = "icp,icp+imu,imu+kin,icp+imu+kin,bridge",
    markdown: options.Markdown = False,
) -> None:
    """Accuracy figures: every variant on simulated sessions (RMSE, swing, counts, timing),
    and the bridging experiment (no ICP in swing). Prints each variant as it finishes."""
    from graph_slam.bench import accuracy as bp

    names = tuple(v.strip() for v in variants.split(",") if v.strip())
    from graph_slam.pipelines.config import PIPELINE_PRESETS

    known = (*bp.VARIANTS, bp.BRIDGE)
    graph_rows = (*(v for v in bp.VARIANTS if v != "icp"), bp.BRIDGE)
    if unknown := [
        v
        for v in names
        if v.partition(":")[0] not in known
        or (v.partition(":")[2] and (v.partition(":")[2] not in PIPELINE_PRESETS
                                     or v.partition(":")[0] not in graph_rows))
    ]:  # fmt: skip
        raise typer.BadParameter(
            f"unknown {unknown}; choose from {', '.join(known)}, a graph row optionally with "
            f":{'/'.join(PIPELINE_PRESETS)}"
        )
    typer.echo(bp.header_line())

    def show(sc, v: str) -> None:
        if len(sc.variants) == 1:
            typer.echo(f"== {sc.name} ({sc.speed})")
        for line in bp.variant_lines(v, sc.variants[v]):
            typer.echo(line)
        if len(sc.variants) == len(names):
            for line in bp.swing_lines(sc):
                typer.echo(line)

    scores = bp.run_pipelines_bench({p.name: p for p in sessions}, names, on_variant=show)
    for line in bp.summary_lines(scores):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + bp.markdown_table(scores, invoked_command()))


@bench_app.command("realtime")
def realtime_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Sessions (e.g. graph-slam simulate --drops none).")
    ],
    variants: Annotated[
        str,
        typer.Option(
            help="Comma-separated rows: a variant (icp = the thesis baseline) or "
            "VARIANT:PRESET (a pipeline preset, e.g. icp+imu+kin:realtime: the real-time "
            "registration, IMU guess, deferred smoothing; docs/pipelines.md)."
        ),
    ] = "icp:accurate,icp+imu+kin:accurate,icp+imu+kin:realtime",
    pace: Annotated[
        str, typer.Option(help="virtual (as fast as it runs, deterministic skips) or wall.")
    ] = "virtual",
    config: Annotated[
        Path | None, typer.Option("--config", help="YAML of PipelineConfig overrides (base).")
    ] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Write the figures as JSON.")] = None,
    markdown: options.Markdown = False,
    minutes: Annotated[
        float | None,
        typer.Option(
            help="Loop each session's strides to this many minutes (memory over a long run; "
            "resident memory printed at 1, 5 and 10 min)."
        ),
    ] = None,
) -> None:
    """Real time: every row replayed causally (streams in timestamp order, newest frame taken
    when the estimator is free): per-stage latency, frames processed / skipped, rate, CPU,
    memory, accuracy of what was processed, speed-ups vs the thesis baseline."""
    from graph_slam.bench import realtime as rt
    from graph_slam.config import load_config
    from graph_slam.pipelines import PipelineConfig

    base = load_config(PipelineConfig, config)
    rows = tuple(v.strip() for v in variants.split(",") if v.strip())
    for row in rows:  # an unknown variant or preset fails before any work
        rt.row_config(row, base)
    typer.echo(rt.header_line(pace))
    current: list[str] = []

    def start(session: str, row: str) -> None:
        if session not in current:
            current.append(session)
            typer.echo(f"== {session}")
        typer.echo(f"  ... {row}")

    def show(r) -> None:
        for line in rt.row_lines(r):
            typer.echo(line)

    results = rt.run_realtime_bench(
        sessions, rows, base, pace, minutes=minutes, on_start=start, on_row=show
    )
    for line in rt.headline_lines(results):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + rt.markdown_table(results, invoked_command()))
    if out is not None:
        typer.echo(f"wrote {rt.write_json(results, out)}")


@bench_app.command("scenarios")
def scenarios_bench(
    only: Annotated[
        str | None, typer.Option(help="Comma-separated scenario names (default: all).")
    ] = None,
    strides: Annotated[int, typer.Option(help="Strides simulated per scenario.")] = 2,
    seed: Annotated[int, typer.Option(help="Simulator seed.")] = 3,
    speeds: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated walking speeds (slow,normal,fast): every scenario at each "
            "(default: each scenario's own)."
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="YAML of PipelineConfig overrides for both pipelines."),
    ] = None,
    markdown: options.Markdown = False,
) -> None:
    """Scenarios: a fixed list of scenes and conditions (flat floor and box course with and
    without texture, Pico Flexx, fast walk, double noise, stairs): coverage, frames registered
    / partial / bridged, smoothed and online per-stride RMSE, the baseline beside them."""
    from graph_slam.bench import scenarios as sc
    from graph_slam.config import load_config
    from graph_slam.pipelines import PipelineConfig

    base = load_config(PipelineConfig, config)  # a bad file fails before any simulation
    if seed < 0 or strides < 1:
        raise typer.BadParameter(f"--seed {seed} must be >= 0 and --strides {strides} >= 1")
    names = None if only is None else tuple(n.strip() for n in only.split(",") if n.strip())
    known = {s.name for s in sc.SCENARIOS}
    if names and (unknown := [n for n in names if n not in known]):
        raise typer.BadParameter(f"unknown {unknown}; choose from {', '.join(sorted(known))}")
    chosen = None if speeds is None else tuple(v.strip() for v in speeds.split(",") if v.strip())
    typer.echo(sc.HEADER)
    scores = sc.run_scenarios(
        names, strides, seed, on_score=lambda s: typer.echo(s.line()), speeds=chosen, base=base
    )
    pooled = sc.pooled(scores)  # the targets are over the speeds
    for score in pooled:
        typer.echo(score.line())
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + sc.markdown_table(scores + pooled, invoked_command()))


@bench_app.command("calibration")
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
    from graph_slam.bench.registration import default_tum_folder, read_tum_sample, session_dataset
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


@bench_app.command("terrain")
def terrain_bench(
    sessions: Annotated[
        list[Path], typer.Argument(help="Simulated sessions with a scene (graph-slam simulate).")
    ],
    rows: Annotated[
        str,
        typer.Option(
            help="Comma-separated rows: VARIANT, VARIANT:PRESET, and a /nocarry suffix (the "
            "grid starts empty at every stride, the thesis behaviour)."
        ),
    ] = "icp,icp+imu+kin,icp+imu+kin/nocarry,icp+imu+kin:realtime",
    covariances: Annotated[
        bool,
        typer.Option(help="Graph rows: per-frame marginal covariances in the grid's variance."),
    ] = True,
    out: Annotated[Path | None, typer.Option("--out", help="Write the figures as JSON.")] = None,
    markdown: options.Markdown = False,
) -> None:
    """Terrain: the per-frame elevation grid against the scene's truth (docs/terrain.md):
    box sightings at toe-off, the carried map, σ-consistency, update time, deadlines."""
    import json

    from graph_slam.bench import terrain as bt

    names = tuple(r.strip() for r in rows.split(",") if r.strip())
    for name in names:  # an unknown variant, preset or suffix fails before any work
        bt.row_config(name, None, covariances)
    results = []
    for session in sessions:
        typer.echo(f"== {session}")
        typer.echo(bt.HEADER)
        for name in names:
            results.append(bt.run_terrain_row(session, name, covariances=covariances))
            typer.echo(bt.row_line(results[-1].figures()))
        med, p95 = bt.update_cost_ms(session)
        typer.echo(
            f"grid update alone (least of 5 per frame): median {med:.2f} ms, p95 {p95:.2f} ms"
        )
    pooled = bt.pooled(results)
    typer.echo("== all sessions")
    typer.echo(bt.HEADER)
    for r in pooled:
        typer.echo(bt.row_line(r.figures()))
    if markdown:
        from graph_slam.bench.caption import invoked_command

        figures = [r.figures() for r in results + pooled]
        typer.echo("\n" + bt.markdown_table(figures, invoked_command()))
    if out is not None:
        figures = [r.figures() for r in results + pooled]
        out.write_text(json.dumps(figures, indent=1, default=float))
        typer.echo(f"wrote {out}")


@bench_app.command("terrain-walk")
def terrain_walk_bench(
    scenes: Annotated[
        str,
        typer.Option(help="Comma-separated scenes of the terrain-following walker."),
    ] = "stairs-ascent,ramp-up-8,ramp-down-8,curb-up,step-over,terrain-course",
    speeds: Annotated[str, typer.Option(help="Comma-separated: slow,normal,fast.")] = "normal",
    strides: Annotated[int, typer.Option(help="Strides simulated per session.")] = 2,
    resolution: Annotated[str, typer.Option(help="Image size WxH.")] = "424x240",
    preset: Annotated[str, typer.Option(help="Pipeline preset ('' for the defaults).")] = (
        "realtime"
    ),
    seed: Annotated[int, typer.Option(help="Simulator seed.")] = 3,
    angles: Annotated[
        bool,
        typer.Option(
            "--angles", help="Only the walker's joint-angle peaks per terrain (no rendering)."
        ),
    ] = False,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="YAML of PipelineConfig overrides for every run."),
    ] = None,
    compare_level: Annotated[
        bool,
        typer.Option(
            "--compare-level/--no-compare-level",
            help="Also run the level-ground anchor on every scene (its ramp tilt beside the "
            "new anchor's); off: half the time.",
        ),
    ] = True,
    markdown: options.Markdown = False,
) -> None:
    """The full graph on the terrain walker's scenes (stairs, ramps, curbs, boxes): per-stride
    RMSE beside level walking, the anchor's tilt error with the level-ground anchor beside it,
    the anchor's case and slope, every frame posed (docs/benchmarks.md)."""
    from graph_slam.bench import terrain_walk as tw
    from graph_slam.config import load_config, read_yaml
    from graph_slam.pipelines import PipelineConfig
    from graph_slam.sim import SPEEDS_M_S

    load_config(PipelineConfig, config)  # a bad file fails before any simulation
    overrides = None if config is None else read_yaml(config)
    names = [s.strip() for s in scenes.split(",") if s.strip()]
    chosen = [v.strip() for v in speeds.split(",") if v.strip()]
    if unknown := [v for v in chosen if v not in SPEEDS_M_S]:
        raise typer.BadParameter(f"unknown speeds {unknown}; choose from slow, normal, fast")
    if angles:
        for line in tw.angle_lines(names, chosen, max(strides, 4), seed):
            typer.echo(line)
        return
    runs = tw.run_terrain_bench(
        names, chosen, strides, resolution, preset or None, seed, progress=typer.echo,
        overrides=overrides, compare_level=compare_level,
    )  # fmt: skip
    typer.echo(
        "== summary (median per stride, each session's first stride left out; × level: over "
        "flat-floor at the same speed)"
    )
    for line in tw.summary_lines(runs):
        typer.echo(line)
    if markdown:
        from graph_slam.bench.caption import invoked_command

        typer.echo("\n" + tw.markdown_table(runs, invoked_command()))
