"""``graph-slam planar``: the thesis's 2D study beside the per-stride factor graph."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add the ``planar`` command to ``app``."""

    @app.command("planar")
    def planar(
        out: Annotated[Path, typer.Option("--out", help="Folder for figures, tables, config.")],
        config: Annotated[
            Path | None, typer.Option("--config", help="YAML file of partial config overrides.")
        ] = None,
        seed: Annotated[
            int | None, typer.Option("--seed", help="Override the config's random seed.")
        ] = None,
    ) -> None:
        """Simulate the thesis's 2D study (ch. 3.1-3.2) at 0.83 and 1.33 m/s; write Figures
        3.3-3.5 as PNG and the per-stride error table of both methods."""
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        from graph_slam.config import config_from_dict, load_config
        from graph_slam.planar.config import PlanarConfig
        from graph_slam.planar.evaluation import table_markdown
        from graph_slam.planar.study import n_steps, run_planar

        cfg = load_config(PlanarConfig, config)
        if seed is not None:
            cfg = config_from_dict(PlanarConfig, {**cfg.model_dump(), "seed": seed}, "--seed")
        console = Console()
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total}"),
            TimeElapsedColumn(),
        )
        with Progress(*columns, console=console, transient=True) as bar:
            task = bar.add_task("planar study", total=n_steps(cfg))

            def advance(description: str) -> None:
                bar.update(task, advance=1, description=description)

            result = run_planar(cfg, out, progress=advance)
        typer.echo(table_markdown(result.table))
        typer.echo(f"wrote {len(result.files)} files to {out}")
