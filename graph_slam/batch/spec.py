"""The study spec (``batch.yaml``): sessions × variants × named configurations, and what to write.

Every session × variant × configuration is one task. Paths and globs are relative to the spec
file. Every check runs here, before a cluster starts: an unknown variant, a glob that matches
nothing, a session that cannot be opened and a configuration key that :class:`CompareConfig`
does not have are :class:`~graph_slam.errors.ConfigError` naming the spec file and the field.
See docs/batch.md for the format.
"""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError

from graph_slam.config import ConfigModel, config_from_dict, format_validation_error, read_yaml
from graph_slam.errors import ConfigError, GraphSlamError
from graph_slam.report.compare import CompareConfig
from graph_slam.variants import VARIANTS, Variant

TEST_HOOKS_ENV = "GRAPH_SLAM_BATCH_TEST_HOOKS"
"""Set to ``1`` to allow the spec's test-only ``test_kill_worker`` switch (tests only)."""
DEFAULT_MEMORY_LIMIT = "4GiB"
"""Memory bound of each local worker: the nanny restarts a worker past it (its task is
retried, then recorded as failed). A 424x240 session of 9 strides peaks near 1 GiB."""


class Produce(ConfigModel):
    """What each task writes besides the scores (always computed when the session has ground
    truth), its TUM trajectories and its PLY stride maps."""

    recording: bool = Field(False, description="the rerun recording (recording.rrd) per task")
    map_plots: int = Field(0, ge=0, description="map/elevation plots for the first n strides")


class ClusterSpec(ConfigModel):
    """Local-cluster resources (the command line's options override them)."""

    workers: int | None = Field(None, ge=1, description="workers; default: cores / threads")
    threads_per_worker: int = Field(1, ge=1, description="tasks run at once in each worker")
    memory_limit: str = Field(DEFAULT_MEMORY_LIMIT, description="per worker, e.g. 4GiB")


class BatchSpec(ConfigModel):
    """The spec file as written (see :func:`load_spec` for the resolved form)."""

    sessions: list[str] = Field(min_length=1, description="session folders or globs")
    variants: list[str] = Field(default_factory=lambda: [str(v) for v in VARIANTS], min_length=1)
    config: dict[str, Any] = Field(
        default_factory=dict, description="CompareConfig overrides shared by every configuration"
    )
    configurations: dict[str, dict[str, Any]] = Field(
        default_factory=lambda: {"default": {}},
        min_length=1,
        description="named CompareConfig overrides: a grid axis",
    )
    produce: Produce = Produce()
    cluster: ClusterSpec = ClusterSpec()
    retries: int = Field(
        1, ge=0, le=10, description="re-runs of a task that raised a bug or killed its worker"
    )
    test_kill_worker: list[str] = Field(
        default_factory=list,
        description=f"TEST ONLY (needs {TEST_HOOKS_ENV}=1): sessions whose tasks kill their worker",
    )


@dataclass(frozen=True)
class SessionEntry:
    """A session of the study: a unique key (task folder names) and its folder."""

    key: str
    path: Path


@dataclass(frozen=True)
class ResolvedSpec:
    """The spec with its globs expanded, sessions opened and configurations validated."""

    path: Path
    spec: BatchSpec
    sessions: list[SessionEntry]
    variants: list[Variant]
    configurations: dict[str, CompareConfig]


def load_spec(path: str | Path, preset: str | None = None) -> ResolvedSpec:
    """Read and check the spec (``yaml.safe_load``); every error names the file and field.
    ``preset``: the pipeline preset of every configuration whose ``config`` names none (the
    command line's ``--preset``)."""
    path = Path(path)
    spec = config_from_dict(BatchSpec, read_yaml(path, "the batch spec"), source=str(path))
    if preset is not None:
        from graph_slam.pipelines.config import PIPELINE_PRESETS

        if preset not in PIPELINE_PRESETS:
            raise ConfigError(f"--preset {preset!r}: choose from {', '.join(PIPELINE_PRESETS)}")
        shared = _merge({"pipeline": {"preset": preset}}, spec.config)
        spec = spec.model_copy(update={"config": shared})
    if spec.test_kill_worker and os.environ.get(TEST_HOOKS_ENV) != "1":
        raise ConfigError(
            f"{path}: field 'test_kill_worker' is a test-only switch that kills workers; it is "
            f"refused unless {TEST_HOOKS_ENV}=1"
        )
    variants = _variants(path, spec.variants)
    configurations = {
        name: _configuration(path, spec, name, override)
        for name, override in spec.configurations.items()
    }
    sessions = _sessions(path, spec.sessions)
    unknown = set(spec.test_kill_worker) - {s.key for s in sessions}
    if unknown:
        raise ConfigError(f"{path}: field 'test_kill_worker': no session {sorted(unknown)}")
    return ResolvedSpec(path, spec, sessions, variants, configurations)


def _variants(path: Path, names: list[str]) -> list[Variant]:
    bad = [n for n in names if n not in VARIANTS]
    if bad:
        raise ConfigError(
            f"{path}: field 'variants': {', '.join(bad)} not known; choose from "
            f"{', '.join(VARIANTS)}"
        )
    if len(set(names)) != len(names):
        raise ConfigError(f"{path}: field 'variants': {names} lists a variant twice")
    return [Variant(n) for n in names]


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``override`` over ``base``, mappings merged key by key."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _configuration(path: Path, spec: BatchSpec, name: str, override: dict) -> CompareConfig:
    """``config`` then the named override over CompareConfig's defaults; ``variants`` is the
    spec's grid axis, not a setting."""
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", name):
        raise ConfigError(
            f"{path}: field 'configurations.{name}': a name of letters, digits, '_', '-', '.'"
        )
    merged = _merge(spec.config, override or {})
    if "variants" in merged:
        raise ConfigError(
            f"{path}: field 'configurations.{name}.variants': set the variants at the top "
            "level (every configuration runs every variant)"
        )
    produce = spec.produce
    merged = _merge({"rrd": produce.recording, "plot_maps_per_session": produce.map_plots}, merged)
    try:
        return CompareConfig.model_validate(merged)
    except ValidationError as err:
        raise ConfigError(
            format_validation_error(err, str(path), prefix=f"configurations.{name}.")
        ) from None
    except GraphSlamError as err:
        raise ConfigError(f"{path}: configuration {name!r}: {err}") from None


def _sessions(path: Path, patterns: list[str]) -> list[SessionEntry]:
    """Expand the globs (relative to the spec), open every session, give each a unique key."""
    from graph_slam.session import open_session

    base = path.parent
    found: list[Path] = []
    for k, pattern in enumerate(patterns):
        full = Path(pattern) if Path(pattern).is_absolute() else base / pattern
        if glob.has_magic(pattern):
            matches = sorted(Path(p) for p in glob.glob(str(full)) if Path(p).is_dir())
            if not matches:
                raise ConfigError(f"{path}: field 'sessions.{k}': {pattern!r} matches no folder")
        else:
            if not full.is_dir() or not os.access(full, os.R_OK | os.X_OK):
                raise ConfigError(
                    f"{path}: field 'sessions.{k}': {full} is not a readable session folder"
                )
            matches = [full]
        for match in matches:
            if match.resolve() in {f.resolve() for f in found}:
                raise ConfigError(f"{path}: field 'sessions.{k}': {match} is listed twice")
            try:
                open_session(match)
            except GraphSlamError as err:
                raise ConfigError(f"{path}: field 'sessions.{k}': {err}") from None
            found.append(match)
    entries, keys = [], {}
    for session in found:
        key = _session_key(base, session)
        if key in keys:
            raise ConfigError(
                f"{path}: field 'sessions': {keys[key]} and {session} get the same task name "
                f"{key!r}; list them by paths that differ"
            )
        keys[key] = session
        entries.append(SessionEntry(key, session))
    return entries


def _session_key(base: Path, session: Path) -> str:
    """The session's path below the spec's folder (or its folder name), as a file name."""
    try:
        rel = session.resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        rel = session.name
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", rel).strip("-.") or "session"
