"""The session folder's own files: column schemas and the codecs of ``frames.csv``,
``events.csv`` and ``scene.yaml``, and the depth unit's plausibility rule.

The generic parts (strict PNG, numeric CSV streams, TUM poses) are in
:mod:`graph_slam.session.io`; the manifest ``session.yaml`` is in
:mod:`graph_slam.session.manifest`. The reader (:mod:`graph_slam.session.reader`), the writer
(:mod:`graph_slam.session.writer`) and validation (:mod:`graph_slam.session.validation`)
share what is here, so both directions use one schema.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from graph_slam.config import yaml_error_text
from graph_slam.errors import DepthScaleError, RecordError, SessionError, StreamError
from graph_slam.session import io
from graph_slam.session.manifest import MANIFEST_NAME, check_relative, resolve_inside
from graph_slam.session.records import GaitEvents, SceneObject, SceneTruth
from kinematics.imu import IMU_COLUMNS  # the one IMU CSV schema (also graph-slam gait-events)

__all__ = [
    "EVENT_COLUMNS",
    "FRAME_COLUMNS",
    "IMU_COLUMNS",
    "JOINT_COLUMNS",
    "PLAUSIBLE_MEDIAN_DEPTH_M",
    "FrameIndex",
    "check_depth_scale",
    "read_events",
    "read_frame_index",
    "scene_from_yaml",
    "scene_to_yaml",
    "wrap_record_error",
]

JOINT_COLUMNS = ("t_s", "knee_rad", "ankle_rad")
FRAME_COLUMNS = ("index", "t_s", "depth", "color")
EVENT_COLUMNS = ("t_s", "kind", "source")

#: A depth scale is implausible when it puts the median valid depth outside this range (m).
PLAUSIBLE_MEDIAN_DEPTH_M = (0.1, 20.0)


def wrap_record_error(path: Path, err: RecordError) -> SessionError:
    """A record's rule broken in the file at ``path``, as a :class:`SessionError` naming it."""
    return SessionError(f"{path}: {err}")


def check_depth_scale(path: Path, depth_m: np.ndarray, depth_unit_m: float) -> None:
    """The median valid depth must be plausible for a body-worn camera (0.1–20 m)."""
    valid = depth_m[depth_m > 0]
    if valid.size == 0:
        return
    median = float(np.median(valid))
    lo, hi = PLAUSIBLE_MEDIAN_DEPTH_M
    if not lo <= median <= hi:
        raise DepthScaleError(
            f"{path}: with depth_unit_m={depth_unit_m} the median valid depth is {median:.4g} m, "
            f"outside the plausible {lo}–{hi} m; the manifest's depth scale is probably wrong"
        )


# --------------------------------------------------------------------------- frames.csv


@dataclass(frozen=True)
class FrameIndex:
    """The parsed ``frames.csv``: per-frame time and image paths (relative)."""

    t_s: np.ndarray
    depth: tuple[str, ...]
    color: tuple[str | None, ...]


def read_frame_index(session_dir: Path, rel: str) -> FrameIndex:
    """Parse ``frames.csv`` (``rel``, inside ``session_dir``): rows numbered in order, times
    finite and increasing, image paths relative and inside the folder."""
    path = resolve_inside(session_dir, rel, what=f"{MANIFEST_NAME} field 'files.frames'")
    with io.text_errors(path):
        return _read_frame_rows(session_dir, rel, path)


def _read_frame_rows(session_dir: Path, rel: str, path: Path) -> FrameIndex:
    io.read_header(path, FRAME_COLUMNS)
    times: list[float] = []
    depth: list[str] = []
    color: list[str | None] = []
    with path.open("r", encoding="utf-8", newline="") as handle:
        reader = csv.reader(handle)
        next(reader)
        for row, fields in enumerate(reader):
            line = row + 2
            if len(fields) != len(FRAME_COLUMNS):
                raise StreamError(
                    f"{path}: data row {row} (line {line}) has {len(fields)} fields, "
                    f"the header has {len(FRAME_COLUMNS)}"
                )
            index_txt, t_txt, depth_rel, color_rel = (f.strip() for f in fields)
            if index_txt != str(row):
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 'index': expected {row}, "
                    f"found {index_txt!r}; frames must be numbered 0, 1, 2, ... in order"
                )
            try:
                t = float(t_txt)
            except ValueError:
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 't_s': {t_txt!r} is not a number"
                ) from None
            if not np.isfinite(t):
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 't_s': {t_txt!r} is not finite"
                )
            for name, value in (("depth", depth_rel), ("color", color_rel)):
                if value:
                    check_relative(session_dir, value, what=f"{rel} row {row} column {name!r}")
            if not depth_rel:
                raise StreamError(f"{path}: data row {row} (line {line}), column 'depth' is empty")
            times.append(t)
            depth.append(depth_rel)
            color.append(color_rel or None)
    t_s = np.asarray(times, dtype=np.float64)
    io.check_times(path, t_s)
    return FrameIndex(t_s, tuple(depth), tuple(color))


# --------------------------------------------------------------------------- events.csv


def read_events(path: Path) -> GaitEvents:
    """Parse ``events.csv`` (``t_s,kind,source``; times increasing, kinds known)."""
    with io.text_errors(path):
        return _read_event_rows(path)


def _read_event_rows(path: Path) -> GaitEvents:
    io.read_header(path, EVENT_COLUMNS)
    times: list[float] = []
    kinds: list[str] = []
    sources: list[str] = []
    with path.open("r", encoding="utf-8", newline="") as handle:
        reader = csv.reader(handle)
        next(reader)
        for row, fields in enumerate(reader):
            if len(fields) != 3:
                raise StreamError(
                    f"{path}: data row {row} (line {row + 2}) has {len(fields)} fields, expected 3"
                )
            try:
                times.append(float(fields[0]))
            except ValueError:
                raise StreamError(
                    f"{path}: data row {row} (line {row + 2}), column 't_s': "
                    f"{fields[0]!r} is not a number"
                ) from None
            kinds.append(fields[1].strip())
            sources.append(fields[2].strip())
    t_s = np.asarray(times, dtype=np.float64)
    io.check_times(path, t_s)
    try:
        return GaitEvents(t_s, tuple(kinds), tuple(sources))
    except RecordError as err:
        raise wrap_record_error(path, err) from None


# --------------------------------------------------------------------------- scene.yaml


def scene_from_yaml(path: Path) -> SceneTruth:
    """Read ``scene.yaml``: a name and a list of objects (pose, size, kind)."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SessionError(f"{path}: scene file is missing") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SessionError(f"{path}: cannot read ({err})") from None
    except yaml.YAMLError as err:
        raise SessionError(f"{path}: {yaml_error_text(err)}") from None
    if not isinstance(data, dict) or not isinstance(data.get("objects", []), list):
        raise SessionError(f"{path}: must be a mapping with a list 'objects'")
    objects = []
    for i, obj in enumerate(data.get("objects", [])):
        try:
            objects.append(
                SceneObject(
                    name=str(obj["name"]),
                    world_T_object=np.asarray(obj["world_T_object"], dtype=float),
                    size_m=np.asarray(obj["size_m"], dtype=float),
                    kind=str(obj.get("kind", "box")),
                )
            )
        except KeyError as err:
            raise SessionError(f"{path}: objects[{i}] lacks field {err.args[0]!r}") from None
        except (RecordError, TypeError, ValueError) as err:
            raise SessionError(f"{path}: objects[{i}]: {err}") from None
    return SceneTruth(name=str(data.get("name", path.stem)), objects=tuple(objects))


def scene_to_yaml(scene: SceneTruth) -> str:
    """The text of ``scene.yaml`` for ``scene`` (what :func:`scene_from_yaml` reads)."""
    return yaml.safe_dump(
        {
            "name": scene.name,
            "objects": [
                {
                    "name": o.name,
                    "kind": o.kind,
                    "size_m": o.size_m.tolist(),
                    "world_T_object": o.world_T_object.tolist(),
                }
                for o in scene.objects
            ],
        },
        sort_keys=False,
    )
