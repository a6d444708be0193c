"""Fuzzed parsers: every input either parses or raises a library error, never another exception.

Hypothesis drives each reader with random text, random bytes, and mutations (truncation,
flipped bytes) of a valid file. The runs are derandomized (the same examples every run) and
small, so CI stays fast; ``GRAPH_SLAM_FUZZ_EXAMPLES=2000`` runs a longer search. Inputs that
once crashed a reader are kept in ``tests/data/fuzz_corpus/<reader>/`` and replayed first.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from graph_slam.errors import library_errors

CORPUS = Path(__file__).resolve().parent / "data" / "fuzz_corpus"
EXAMPLES = int(os.environ.get("GRAPH_SLAM_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

IMU_HEADER = "t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2"
CSV_ALPHABET = st.sampled_from([*list("0123456789.,-+eE \n\tnaifNAIF#\r\"'x:"), "1e308", "nan"])
csv_text = st.lists(CSV_ALPHABET, max_size=200).map("".join)
yaml_alphabet = st.sampled_from([*list("abc: -[]{}!&*|>'\"#\n\t 0123.,"), "!!python/object", "~"])
yaml_text = st.lists(yaml_alphabet, max_size=120).map("".join)


def _mutations(valid: bytes):
    """Random bytes, truncations and single-byte flips of ``valid``."""
    n = len(valid)
    return st.one_of(
        st.binary(max_size=300),
        st.integers(0, n).map(lambda k: valid[:k]),
        st.tuples(st.integers(0, max(n - 1, 0)), st.integers(0, 255)).map(
            lambda p: valid[: p[0]] + bytes([p[1]]) + valid[p[0] + 1 :]
        ),
    )


def _parses_or_library_error(fn, data: bytes, name: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_bytes(data)
        try:
            fn(path)
        except library_errors():
            pass


def _corpus(reader: str) -> list[Path]:
    folder = CORPUS / reader
    return sorted(folder.iterdir()) if folder.is_dir() else []


# ----------------------------------------------------------------------------- readers


def _read_manifest(path: Path) -> None:
    from graph_slam.session.manifest import load_manifest

    target = path.parent / "session.yaml"
    path.rename(target)
    load_manifest(path.parent)


def _read_imu_csv(path: Path) -> None:
    from graph_slam.session import io
    from graph_slam.session.files import IMU_COLUMNS

    io.check_times(path, io.read_numeric_csv(path, IMU_COLUMNS)[:, 0])


def _read_events(path: Path) -> None:
    from graph_slam.session.files import read_events

    read_events(path)


def _read_tum(path: Path) -> None:
    from graph_slam.session.io import read_tum

    read_tum(path)


def _read_ply(path: Path) -> None:
    from graph_slam.session.adapters.ply import read_ply

    read_ply(path)


def _read_config(path: Path) -> None:
    from graph_slam.config import load_config
    from graph_slam.report import CompareConfig

    load_config(CompareConfig, path)


def _read_gait_imu(path: Path) -> None:
    from kinematics.gait_events import read_imu_csv

    read_imu_csv(path)


def _convert_bag(path: Path) -> None:
    pytest.importorskip("rosbags")
    from graph_slam.session.adapters import ConvertConfig, convert

    convert(path, path.parent / "out", ConvertConfig(format="rosbag"))


LOG_MAPPING = {
    "time": {"column": "time_ms", "unit": "ms"},
    "knee": {"column": "knee", "unit": "deg"},
    "ankle": {"column": "ankle", "unit": "deg"},
}
LOG_HEADER = "time_ms,knee,ankle,load,event"
VALID_LOG = (
    LOG_HEADER
    + "\n"
    + "".join(
        f"{10 * i},{30 + (i % 7) * 5},{(i % 5) - 2},{(i % 10) * 90},{'HS' if i % 10 == 0 else ''}\n"
        for i in range(24)
    )
).encode()


def _read_prosthesis_log(path: Path) -> None:
    from graph_slam.config import config_from_dict
    from graph_slam.session.adapters.config import ProsthesisLogConfig
    from graph_slam.session.adapters.prosthesis_log import read_prosthesis_log

    events = {"column": "event", "values": {"HS": "foot_strike"}, "ignore": ["MS"]}
    load = {"column": "load", "foot_strike_above_n": 50, "toe_off_below_n": 20}
    for extra in ({"events": events}, {"load": load}):
        spec = config_from_dict(ProsthesisLogConfig, {**LOG_MAPPING, **extra})
        read_prosthesis_log(path, spec)


def _read_batch_spec(path: Path) -> None:
    from graph_slam.batch.spec import load_spec

    load_spec(path)


READERS = {
    "manifest": (_read_manifest, "session.yaml"),
    "imu_csv": (_read_imu_csv, "imu.csv"),
    "events_csv": (_read_events, "events.csv"),
    "tum": (_read_tum, "groundtruth.txt"),
    "ply": (_read_ply, "map.ply"),
    "config": (_read_config, "compare.yaml"),
    "gait_imu_csv": (_read_gait_imu, "imu.csv"),
    "bag": (_convert_bag, "walk.bag"),
    "prosthesis_log": (_read_prosthesis_log, "controller.csv"),
    "batch_spec": (_read_batch_spec, "batch.yaml"),
}


@pytest.mark.parametrize(
    ("reader", "sample"),
    [(r, p) for r in READERS for p in _corpus(r)],
    ids=lambda v: v.name if isinstance(v, Path) else str(v),
)
def test_corpus_inputs_stay_fixed(reader: str, sample: Path) -> None:
    fn, name = READERS[reader]
    _parses_or_library_error(fn, sample.read_bytes(), name)


def test_the_corpus_is_not_empty() -> None:
    assert len(_corpus("bag")) >= 2 and len(_corpus("config")) >= 1


@FUZZ
@given(text=yaml_text)
def test_manifest_yaml(text: str) -> None:
    _parses_or_library_error(_read_manifest, text.encode(), "session.yaml")


@FUZZ
@given(data=_mutations(b"schema_version: 1\nname: x\nsensors: {camera: null}\nfiles: {}\n"))
def test_manifest_bytes(data: bytes) -> None:
    _parses_or_library_error(_read_manifest, data, "session.yaml")


@FUZZ
@given(body=csv_text)
def test_imu_csv_text(body: str) -> None:
    _parses_or_library_error(_read_imu_csv, (IMU_HEADER + "\n" + body).encode(), "imu.csv")


@FUZZ
@given(data=_mutations((IMU_HEADER + "\n0,0,0,0,0,0,9.8\n0.005,0,0,0,0,0,9.8\n").encode()))
def test_imu_csv_bytes(data: bytes) -> None:
    _parses_or_library_error(_read_imu_csv, data, "imu.csv")


@FUZZ
@given(data=_mutations(b"t_s,kind,source\n0.5,foot_strike,load_cell\n0.9,toe_off,load_cell\n"))
def test_events_csv(data: bytes) -> None:
    _parses_or_library_error(_read_events, data, "events.csv")


@FUZZ
@given(
    data=st.one_of(csv_text.map(str.encode), _mutations(b"0.1 1 2 3 0 0 0 1\n0.2 1 2 3 0 0 0 1\n"))
)
def test_tum(data: bytes) -> None:
    _parses_or_library_error(_read_tum, data, "groundtruth.txt")


def _valid_ply(binary: bool) -> bytes:
    import io as _io

    import numpy as np

    from graph_slam.session.adapters.ply import write_ply
    from graph_slam.session.records import Cloud

    buf = _io.BytesIO()
    cloud = Cloud(
        np.array([[0.0, 1.0, 2.0], [1.0, 2.0, 3.0]]), np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    )
    write_ply(cloud, buf, binary=binary)
    return buf.getvalue()


@FUZZ
@given(data=st.data(), binary=st.booleans())
def test_ply(data, binary: bool) -> None:
    _parses_or_library_error(_read_ply, data.draw(_mutations(_valid_ply(binary))), "map.ply")


@FUZZ
@given(text=yaml_text)
def test_config_yaml(text: str) -> None:
    _parses_or_library_error(_read_config, text.encode(), "compare.yaml")


@FUZZ
@given(data=_mutations((IMU_HEADER + "\n0,0,0,0,0,0,9.8\n").encode()))
def test_gait_events_imu_csv(data: bytes) -> None:
    _parses_or_library_error(_read_gait_imu, data, "imu.csv")


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory) -> bytes:
    pytest.importorskip("rosbags")
    from bagfactory import BagSpec, write_bag

    path = tmp_path_factory.mktemp("fuzzbag") / "sdk.bag"
    write_bag(path, BagSpec(n_frames=2))
    return path.read_bytes()


@settings(FUZZ, max_examples=max(10, EXAMPLES // 2), suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_bag_bytes(small_bag: bytes, data) -> None:
    _parses_or_library_error(_convert_bag, data.draw(_mutations(small_bag)), "walk.bag")


@FUZZ
@given(body=csv_text)
def test_prosthesis_log_text(body: str) -> None:
    data = (LOG_HEADER + "\n" + body).encode()
    _parses_or_library_error(_read_prosthesis_log, data, "controller.csv")


@FUZZ
@given(data=_mutations(VALID_LOG))
def test_prosthesis_log_bytes(data: bytes) -> None:
    _parses_or_library_error(_read_prosthesis_log, data, "controller.csv")


def _valid_spec(session: Path) -> bytes:
    return (
        f"sessions: [{session}]\nvariants: [icp, icp+imu]\nconfig: {{match_margin_m: 0.05}}\n"
        "configurations: {a: {}, b: {pipeline: {cloud: {max_depth_m: 2.5}}}}\n"
        "produce: {map_plots: 1}\ncluster: {workers: 1, memory_limit: 2GiB}\nretries: 1\n"
    ).encode()


@FUZZ
@given(text=yaml_text)
def test_batch_spec_yaml(text: str) -> None:
    _parses_or_library_error(_read_batch_spec, text.encode(), "batch.yaml")


@settings(FUZZ, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_batch_spec_bytes(_synthetic_master: Path, data) -> None:
    valid = _valid_spec(_synthetic_master)
    _parses_or_library_error(_read_batch_spec, data.draw(_mutations(valid)), "batch.yaml")
