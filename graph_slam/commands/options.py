"""The options every command that runs pipelines shares, declared once, and how they are put
over ``--config``: load the YAML, dump it, patch it with the options, validate it again
(:func:`graph_slam.config.overlay_config`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

PRESET_HELP = (
    "Pipeline preset over --config: realtime (the default: the real-time front end, the "
    "thesis baseline on the 212x120 cloud), realtime-gicp, accurate (colored ICP, batch "
    "smoothing, the baseline on every pixel) or thesis. Default: the config's preset "
    "(realtime when it names none)."
)

Out = Annotated[Path, typer.Option("--out", help="Output folder.")]
Config = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="YAML of the command's config overrides (variants:, pipeline: {preset:, graph:, "
        "terrain:, ...}, ...).",
    ),
]
Preset = Annotated[str | None, typer.Option("--preset", help=PRESET_HELP)]
Variants = Annotated[
    str | None,
    typer.Option(
        "--variants", help="Comma-separated: icp,icp+imu,imu+kin,icp+imu+kin (default all)."
    ),
]
MapFiles = Annotated[
    str | None,
    typer.Option(
        "--map-files",
        help="Stride maps written as PLY: main (the main variant's and the ground truth's; "
        "the default), all, none. Every map is scored either way.",
    ),
]
Markdown = Annotated[
    bool,
    typer.Option(
        "--markdown",
        help="Also print the markdown table (its caption: date, commit, cores, command).",
    ),
]
Overwrite = Annotated[
    bool, typer.Option("--overwrite", help="Replace an output folder graph-slam wrote.")
]


def settings_patch(
    variants: str | None = None, preset: str | None = None, stride_maps: bool = False
) -> dict[str, Any]:
    """The options as a patch of a RunConfig / CompareConfig dump. ``preset``: the
    pipeline preset's settings (:data:`~graph_slam.pipelines.config.PIPELINE_PRESETS`) and
    its name; ``stride_maps``: the stride maps stay on whatever the preset says (``compare``
    scores them)."""
    from graph_slam.errors import ConfigError
    from graph_slam.pipelines.config import PIPELINE_PRESETS
    from graph_slam.variants import parse_variants

    patch: dict[str, Any] = {}
    if variants is not None:
        patch["variants"] = [str(v) for v in parse_variants(variants)]
    if preset is not None:
        if preset not in PIPELINE_PRESETS:
            raise ConfigError(f"--preset {preset!r}: choose from {', '.join(PIPELINE_PRESETS)}")
        pipeline = {**PIPELINE_PRESETS[preset], "preset": preset}
        if stride_maps:
            pipeline["terrain"] = {**pipeline["terrain"], "enabled": True}
        patch["pipeline"] = pipeline
    return patch


def load_settings(
    cls,
    config: Path | None,
    variants: str | None = None,
    preset: str | None = None,
    stride_maps: bool = False,
    extra: dict[str, Any] | None = None,
):
    """``cls`` (RunConfig, CompareConfig) from ``--config`` with the options over it."""
    from graph_slam.config import merge_dicts, overlay_config

    patch = merge_dicts(settings_patch(variants, preset, stride_maps), extra or {})
    return overlay_config(cls, config, patch, source=f"{config or 'defaults'} with the options")
