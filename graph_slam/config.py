"""Typed configuration: pydantic models with defaults in code, partial YAML overrides.

Every configurable part of graph_slam has a sub-model here or next to its code, deriving from
:class:`ConfigModel` (frozen, unknown keys rejected). Load a YAML file of partial overrides
with :func:`load_config`; write the fully resolved config next to a run's results with
:func:`write_config`. Errors name the file and the field.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from graph_slam.errors import ConfigError

C = TypeVar("C", bound="ConfigModel")


MAX_CONFIG_MAGNITUDE = 1e12
"""The largest magnitude a float setting may have: beyond it (1e400 reads as inf) a value is a
typo or a unit mistake, never a setting (metres, seconds, Hz, N all stay far below)."""


def non_finite_in(value: Any, where: str = "") -> tuple[str, float] | None:
    """The first float in ``value`` (a number, list, tuple, dict or dataclass of them) that is
    NaN, infinite or beyond :data:`MAX_CONFIG_MAGNITUDE`: ``(where inside, value)``; else None.
    Nested pydantic models are skipped (they check their own fields)."""
    if isinstance(value, bool | BaseModel):
        return None
    if isinstance(value, float | np.floating):
        bad = not math.isfinite(value) or abs(value) > MAX_CONFIG_MAGNITUDE
        return (where, float(value)) if bad else None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        items = [(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)]
    elif isinstance(value, dict):
        items = [(str(k), v) for k, v in value.items()]
    elif isinstance(value, list | tuple | set | frozenset):
        items = [(str(i), v) for i, v in enumerate(value)]
    else:
        return None
    for key, item in items:
        found = non_finite_in(item, f"{where}.{key}" if where else key)
        if found is not None:
            return found
    return None


class FiniteFloats(BaseModel):
    """Mixin: every float of every field (also inside lists, dicts and dataclasses) is finite
    and within ±:data:`MAX_CONFIG_MAGNITUDE`, else a validation error naming the field."""

    @field_validator("*", mode="after")
    @classmethod
    def _floats_are_finite(cls, value: Any) -> Any:
        found = non_finite_in(value)
        if found is not None:
            where, number = found
            at = f" (at {where})" if where else ""
            raise ValueError(
                f"{number!r}{at} is not a finite number within ±{MAX_CONFIG_MAGNITUDE:g} "
                "(1e400 reads as inf; write the value in the field's unit)"
            )
        return value


class ConfigModel(FiniteFloats):
    """Base of every config: immutable, a misspelt key is an error, not a silent default, and
    every float is finite (:class:`FiniteFloats`)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


def format_validation_error(err: ValidationError, source: str, prefix: str = "") -> str:
    """pydantic's errors as one line: ``source: field 'prefix.a.b': message; ...``."""
    parts = []
    for item in err.errors():
        field = prefix + ".".join(str(p) for p in item["loc"]) or "<root>"
        parts.append(f"field '{field}': {item['msg']}")
    return f"{source}: " + "; ".join(parts)


def config_from_dict(cls: type[C], data: dict[str, Any] | None, source: str = "<dict>") -> C:
    """Build ``cls`` from a (partial) mapping; missing fields take their defaults."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: the top level must be a mapping, got {type(data).__name__}")
    try:
        return cls.model_validate(data)
    except ValidationError as err:
        raise ConfigError(format_validation_error(err, source)) from None


def load_config(cls: type[C], path: str | Path | None) -> C:
    """Read a YAML file of partial overrides (``yaml.safe_load``) into ``cls``.

    ``path=None`` gives the defaults.
    """
    if path is None:
        return cls()
    return config_from_dict(cls, read_yaml(path), source=str(path))


def merge_dicts(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``over`` merged into ``base``, mapping by mapping (``over`` wins; neither is changed)."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_dicts(out[key], value)
        else:
            out[key] = value
    return out


def overlay_config(
    cls: type[C], path: str | Path | None, patch: dict[str, Any] | None = None, source: str = ""
) -> C:
    """The YAML file's config (``path``; None: the defaults), dumped, with ``patch`` merged
    over it, validated again: how a command puts its options over ``--config``. Errors name
    ``source`` (the options) or the file."""
    data = merge_dicts(load_config(cls, path).model_dump(mode="json"), patch or {})
    where = source or (str(path) if path is not None else "the command line")
    return config_from_dict(cls, data, source=where)


def read_yaml(path: str | Path, what: str = "config file") -> Any:
    """The document in the YAML file ``path`` (``yaml.safe_load``); a :class:`ConfigError`
    naming the file when it cannot be read (``cannot read <what>``), is not UTF-8 or not YAML."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"{path}: cannot read {what} ({err.strerror})") from None
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: not UTF-8 text (byte {err.start})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: {yaml_error_text(err)}") from None


def yaml_error_text(err: Exception) -> str:
    """PyYAML's multi-line error as one line: ``not valid YAML at line L, column C: problem``."""
    mark = getattr(err, "problem_mark", None)
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    context = getattr(err, "context", None)
    where = "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"
    text = f"not valid YAML{where}: {problem}" + (f" ({context})" if context else "")
    return " ".join(text.split())


def write_config(config: ConfigModel, path: str | Path) -> Path:
    """Write the fully resolved config as YAML (every field, defaults included)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = config.model_dump(mode="json")
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path
