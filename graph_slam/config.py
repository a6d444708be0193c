"""Typed configuration: pydantic models with defaults in code, partial YAML overrides.

Every configurable part of graph_slam has a sub-model here or next to its code, deriving from
:class:`ConfigModel` (frozen, unknown keys rejected). Load a YAML file of partial overrides
with :func:`load_config`; write the fully resolved config next to a run's results with
:func:`write_config`. Errors name the file and the field.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from graph_slam.errors import ConfigError

C = TypeVar("C", bound="ConfigModel")


class ConfigModel(BaseModel):
    """Base of every config: immutable, and a misspelt key is an error, not a silent default."""

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
