"""The session manifest (``session.yaml``): schema, loading and path safety.

See docs/session_format.md for the layout of a session folder.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ConfigDict, Field, ValidationError, field_validator

from graph_slam.config import FiniteFloats, yaml_error_text
from graph_slam.errors import ManifestError, PathEscapeError, SchemaVersionError

MANIFEST_NAME = "session.yaml"
SCHEMA_VERSION = 1
SUPPORTED_SCHEMA_VERSIONS = (1,)


class _Strict(FiniteFloats):
    model_config = ConfigDict(extra="forbid", frozen=True)


class IntrinsicsSpec(_Strict):
    width_px: int = Field(gt=0)
    height_px: int = Field(gt=0)
    fx_px: float = Field(gt=0)
    fy_px: float = Field(gt=0)
    cx_px: float
    cy_px: float


class CameraSpec(_Strict):
    profile: str = "unknown"
    intrinsics: IntrinsicsSpec
    depth_unit_m: float = Field(gt=0, le=0.01, description="metres per 16-bit depth PNG unit")
    has_color: bool = False
    nominal_rate_hz: float | None = Field(default=None, gt=0)


class ImuSpec(_Strict):
    profile: str = "unknown"
    nominal_rate_hz: float | None = Field(default=None, gt=0)


class JointsSpec(_Strict):
    names: tuple[str, ...] = ("knee", "ankle")
    nominal_rate_hz: float | None = Field(default=None, gt=0)


class SensorsSpec(_Strict):
    #: Required key; ``null`` for a session without a camera (IMU-only, joints-only), which then
    #: has zero frames.
    camera: CameraSpec | None
    imu: ImuSpec | None = None
    joints: JointsSpec | None = None


Matrix4 = tuple[
    tuple[float, float, float, float],
    tuple[float, float, float, float],
    tuple[float, float, float, float],
    tuple[float, float, float, float],
]
_IDENTITY: Matrix4 = tuple(tuple(float(v) for v in row) for row in np.eye(4))  # type: ignore[assignment]


class CalibrationSpec(_Strict):
    thigh_T_camera: Matrix4 = _IDENTITY
    camera_T_imu: Matrix4 = _IDENTITY
    imu_time_offset_s: float = 0.0
    joints_time_offset_s: float = 0.0


class FilesSpec(_Strict):
    """Paths relative to the session folder; ``None`` = stream absent."""

    frames: str = "frames.csv"
    imu: str | None = None
    joints: str | None = None
    events: str | None = None
    ground_truth: str | None = None
    ground_truth_hf: str | None = None
    scene: str | None = None


#: Writers of sessions rendered from a model: no systematic sensor error (calibration, depth
#: bias, timing), which is what the pipelines' real-camera covariance floor models.
SYNTHETIC_GENERATORS = ("graph_slam.sim", "graph_slam.session.synthetic")


class Provenance(_Strict):
    generator: str = "unknown"
    source: str | None = None
    seed: int | None = None
    created_utc: str | None = None
    notes: str | None = None

    @property
    def synthetic(self) -> bool:
        """Written by the simulator or the synthetic generator (:data:`SYNTHETIC_GENERATORS`),
        not recorded by a camera."""
        return self.generator in SYNTHETIC_GENERATORS


class Manifest(_Strict):
    schema_version: int
    name: str
    sensors: SensorsSpec
    calibration: CalibrationSpec = CalibrationSpec()
    files: FilesSpec = FilesSpec()
    provenance: Provenance = Provenance()

    @field_validator("schema_version")
    @classmethod
    def _known_version(cls, value: int) -> int:
        if value not in SUPPORTED_SCHEMA_VERSIONS:
            raise ValueError(
                f"unknown schema version {value}; this reader supports {SUPPORTED_SCHEMA_VERSIONS}"
            )
        return value

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)


def load_manifest(session_dir: Path) -> Manifest:
    """Read and check ``session.yaml``: missing file, bad YAML, unknown field or version."""
    path = session_dir / MANIFEST_NAME
    if not session_dir.is_dir():
        raise ManifestError(f"{session_dir}: not a session folder (no such directory)")
    if not path.is_file():
        raise ManifestError(
            f"{path}: manifest is missing; a session folder must hold {MANIFEST_NAME}"
        )
    try:
        data: Any = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as err:
        raise ManifestError(f"{path}: {yaml_error_text(err)}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ManifestError(f"{path}: cannot read ({err})") from None
    if not isinstance(data, dict):
        raise ManifestError(f"{path}: the top level must be a mapping")
    version = data.get("schema_version")
    if version not in SUPPORTED_SCHEMA_VERSIONS:
        raise SchemaVersionError(
            f"{path}: field 'schema_version' is {version!r}; this reader supports "
            f"{list(SUPPORTED_SCHEMA_VERSIONS)}"
        )
    try:
        manifest = Manifest.model_validate(data)
    except ValidationError as err:
        problems = "; ".join(
            f"field '{'.'.join(str(p) for p in e['loc'])}': {e['msg']}" for e in err.errors()
        )
        raise ManifestError(f"{path}: {problems}") from None
    for field, rel in manifest.files.model_dump().items():
        if rel is not None:
            resolve_inside(session_dir, rel, what=f"{MANIFEST_NAME} field 'files.{field}'")
    return manifest


def check_relative(session_dir: Path, relative: str, *, what: str) -> None:
    """Lexical check (no file-system access): ``relative`` must stay inside the session folder."""
    if Path(relative).is_absolute() or relative.startswith(("/", "\\")):
        raise PathEscapeError(
            f"{session_dir}: {what} = {relative!r} is absolute; "
            "paths must be relative to the session folder"
        )
    normal = os.path.normpath(relative)
    if normal == ".." or normal.startswith(("../", "..\\")):
        raise PathEscapeError(f"{session_dir}: {what} = {relative!r} escapes the session folder")


def resolve_inside(session_dir: Path, relative: str, *, what: str) -> Path:
    """Resolve ``relative`` against the session folder; refuse absolute paths and escapes
    (also through symbolic links)."""
    check_relative(session_dir, relative, what=what)
    root = session_dir.resolve()
    full = (root / relative).resolve()
    if not full.is_relative_to(root):
        raise PathEscapeError(f"{session_dir}: {what} = {relative!r} escapes the session folder")
    return full
