"""``graph-slam bench ...``: benchmarks that print the figures recorded in docs/benchmarks.md.

The commands live by the stage they measure: :mod:`~graph_slam.commands.bench_sensors` (the
session reader, the simulator, registration and its calibration),
:mod:`~graph_slam.commands.bench_pipelines` (accuracy, real time, scenarios) and
:mod:`~graph_slam.commands.bench_terrain` (the elevation grid, the terrain walker). This module
makes the ``bench`` group and adds them in the order ``graph-slam bench --help`` lists them.
"""

from __future__ import annotations

import typer

from graph_slam.commands import bench_pipelines, bench_sensors, bench_terrain

bench_app = typer.Typer(
    help="Benchmarks (figures recorded in docs/benchmarks.md).", no_args_is_help=True
)


@bench_app.callback()
def _started() -> None:
    """The commit a printed table names is the one that started (bench.caption.commit)."""
    from graph_slam.bench.caption import mark_start

    mark_start()


def run_all() -> None:
    """Every benchmark with its default settings."""
    bench_sensors.session_io()
    bench_sensors.simulate_bench()
    bench_sensors.registration()


for _name, _command in (
    ("session-io", bench_sensors.session_io),
    ("simulate", bench_sensors.simulate_bench),
    ("registration", bench_sensors.registration),
    ("all", run_all),
    ("pipelines", bench_pipelines.pipelines_bench),
    ("realtime", bench_pipelines.realtime_bench),
    ("scenarios", bench_pipelines.scenarios_bench),
    ("calibration", bench_sensors.calibration_bench),
    ("terrain", bench_terrain.terrain_bench),
    ("terrain-walk", bench_terrain.terrain_walk_bench),
):
    bench_app.command(_name)(_command)


def register(app: typer.Typer) -> None:
    app.add_typer(bench_app, name="bench")
