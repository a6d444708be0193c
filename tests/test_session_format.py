"""Session format: round trip, info, lazy memory, and every bad input."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import SMALL_SYNTHETIC

from graph_slam.errors import (
    DepthScaleError,
    ImageError,
    ManifestError,
    NonFiniteError,
    PathEscapeError,
    SchemaVersionError,
    SessionError,
    StreamError,
    TimestampError,
)
from graph_slam.session import open_session, session_info, validate_session
from graph_slam.session.synthetic import intrinsics_for, iter_synthetic_frames, synthetic_streams


# --------------------------------------------------------------------------- round trip
def test_round_trip_equal_within_png_quantisation(synthetic_session: Path) -> None:
    session = open_session(synthetic_session)
    truth = synthetic_streams(SMALL_SYNTHETIC)
    unit = SMALL_SYNTHETIC.depth_unit_m
    assert session.intrinsics == intrinsics_for(SMALL_SYNTHETIC)
    originals = list(iter_synthetic_frames(SMALL_SYNTHETIC))
    assert session.n_frames == len(originals) == truth.frame_times_s.size
    for original, read in zip(originals, session, strict=True):
        assert read.t_s == pytest.approx(original.t_s, abs=1e-9)
        # Quantisation to the 16-bit unit: error at most half a unit (+ float32 rounding).
        assert np.abs(read.depth_m - original.depth_m).max() <= 0.5 * unit + 1e-6
        assert np.array_equal(read.depth_m > 0, original.depth_m > 0)
        assert np.array_equal(read.color_rgb, original.color_rgb)
    np.testing.assert_array_equal(session.imu.t_s, truth.imu.t_s)
    np.testing.assert_array_equal(session.imu.gyro_rad_s, truth.imu.gyro_rad_s)
    np.testing.assert_array_equal(session.imu.accel_m_s2, truth.imu.accel_m_s2)
    np.testing.assert_array_equal(session.joints.knee_rad, truth.joints.knee_rad)
    np.testing.assert_array_equal(session.joints.ankle_rad, truth.joints.ankle_rad)
    np.testing.assert_allclose(session.events.t_s, truth.events.t_s, atol=1e-9)
    assert session.events.kind == truth.events.kind
    np.testing.assert_allclose(
        session.ground_truth.parent_T_child, truth.ground_truth.parent_T_child, atol=1e-8
    )
    np.testing.assert_allclose(session.calibration.camera_T_imu, truth.calibration.camera_T_imu)
    assert validate_session(synthetic_session).ok


def test_info_reports_true_rates_and_strides(synthetic_session: Path) -> None:
    info = session_info(open_session(synthetic_session))
    streams = {s.name: s for s in info.streams}
    assert streams["frames"].mean_rate_hz == pytest.approx(SMALL_SYNTHETIC.camera_rate_hz, rel=1e-6)
    assert streams["imu"].median_rate_hz == pytest.approx(SMALL_SYNTHETIC.imu_rate_hz, rel=1e-6)
    assert streams["joints"].mean_rate_hz == pytest.approx(SMALL_SYNTHETIC.joints_rate_hz, rel=1e-6)
    assert streams["frames"].duration_s == pytest.approx(SMALL_SYNTHETIC.duration_s)
    assert streams["frames"].gaps == 0
    # Foot strikes at 0, 1.1, 2.2 s → 2 complete strides of 1.1 s, 33 frames each at 30 Hz.
    assert info.strides.strides == 2
    assert info.strides.mean_stride_s == pytest.approx(1.1)
    assert info.strides.frames_per_stride == (33, 33)


def test_info_counts_gaps(synthetic_session: Path) -> None:
    frames_csv = synthetic_session / "frames.csv"
    lines = frames_csv.read_text().splitlines()
    kept = [lines[0]] + [row for i, row in enumerate(lines[1:]) if not 10 <= i < 15]
    renumbered = [kept[0]] + [f"{i}," + row.split(",", 1)[1] for i, row in enumerate(kept[1:])]
    frames_csv.write_text("\n".join(renumbered) + "\n")
    frames = next(
        s for s in session_info(open_session(synthetic_session)).streams if s.name == "frames"
    )
    assert frames.gaps == 1
    assert frames.longest_gap_s == pytest.approx(6 / 30.0, abs=1e-6)


def test_reader_memory_does_not_grow_with_frames_read(synthetic_session: Path) -> None:
    session = open_session(synthetic_session)
    tracemalloc.start()
    try:
        for _frame in session.iter_frames(0, 10):
            pass
        after_10 = tracemalloc.get_traced_memory()[0]
        for frame in session.iter_frames(10, session.n_frames):
            assert frame.depth_m.shape == (48, 64)
        after_all = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert frame.index == session.n_frames - 1
    frame_bytes = frame.depth_m.nbytes + frame.color_rgb.nbytes
    assert after_all - after_10 < 2 * frame_bytes


# --------------------------------------------------------------------------- bad input
def _manifest(path: Path) -> dict:
    return yaml.safe_load((path / "session.yaml").read_text())


def _write_manifest(path: Path, data: dict) -> None:
    (path / "session.yaml").write_text(yaml.safe_dump(data))


def test_missing_manifest(synthetic_session: Path) -> None:
    (synthetic_session / "session.yaml").unlink()
    with pytest.raises(ManifestError, match=r"session\.yaml: manifest is missing"):
        open_session(synthetic_session)


def test_unknown_schema_version(synthetic_session: Path) -> None:
    data = _manifest(synthetic_session)
    data["schema_version"] = 99
    _write_manifest(synthetic_session, data)
    with pytest.raises(SchemaVersionError, match=r"'schema_version' is 99.*supports \[1\]"):
        open_session(synthetic_session)


def test_manifest_unknown_field_is_named(synthetic_session: Path) -> None:
    data = _manifest(synthetic_session)
    data["sensors"]["camera"]["depth_scale"] = 1000
    _write_manifest(synthetic_session, data)
    with pytest.raises(ManifestError, match=r"field 'sensors\.camera\.depth_scale'"):
        open_session(synthetic_session)


@pytest.mark.parametrize("bad", ["../outside.csv", "/etc/passwd", "sub/../../x.csv"])
def test_manifest_path_escaping_session(synthetic_session: Path, bad: str) -> None:
    data = _manifest(synthetic_session)
    data["files"]["imu"] = bad
    _write_manifest(synthetic_session, data)
    with pytest.raises(PathEscapeError, match=r"files\.imu"):
        open_session(synthetic_session)


def test_frame_index_path_escaping_session(synthetic_session: Path) -> None:
    frames_csv = synthetic_session / "frames.csv"
    text = frames_csv.read_text().replace("depth/000003.png", "../../000003.png")
    frames_csv.write_text(text)
    with pytest.raises(PathEscapeError, match=r"row 3 column 'depth'"):
        open_session(synthetic_session)


def test_missing_png(synthetic_session: Path) -> None:
    (synthetic_session / "depth" / "000004.png").unlink()
    session = open_session(synthetic_session)
    with pytest.raises(ImageError, match=r"000004\.png: image file is missing"):
        session.frame(4)
    report = validate_session(synthetic_session)
    assert not report.ok and len(report.problems) == 1
    assert report.frames_checked == session.n_frames - 1


@pytest.mark.parametrize("cut", [0.5, 0.99])
def test_truncated_png_is_never_zero_filled(synthetic_session: Path, cut: float) -> None:
    png = synthetic_session / "depth" / "000002.png"
    data = png.read_bytes()
    png.write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(ImageError, match=r"000002\.png: corrupt or truncated PNG"):
        open_session(synthetic_session).frame(2)


def test_corrupt_png(synthetic_session: Path) -> None:
    png = synthetic_session / "color" / "000001.png"
    data = bytearray(png.read_bytes())
    data[60:80] = b"\x00" * 20  # inside the first data chunk: its CRC no longer matches
    png.write_bytes(bytes(data))
    with pytest.raises(ImageError, match=r"color/000001\.png: corrupt or truncated PNG"):
        open_session(synthetic_session).frame(1)


def test_image_size_disagreeing_with_intrinsics(synthetic_session: Path) -> None:
    data = _manifest(synthetic_session)
    data["sensors"]["camera"]["intrinsics"]["width_px"] = 65
    _write_manifest(synthetic_session, data)
    with pytest.raises(ImageError, match=r"is 64×48 px \(W×H\) but the intrinsics say 65×48"):
        open_session(synthetic_session).frame(0)


def test_depth_png_of_wrong_type(synthetic_session: Path) -> None:
    from PIL import Image

    Image.fromarray(np.zeros((48, 64), np.uint8)).save(synthetic_session / "depth" / "000000.png")
    with pytest.raises(ImageError, match=r"must be 16-bit grayscale, found mode 'L'"):
        open_session(synthetic_session).frame(0)


@pytest.mark.parametrize("unit", [1e-6, 0.01])
def test_implausible_depth_scale(synthetic_session: Path, unit: float) -> None:
    data = _manifest(synthetic_session)
    data["sensors"]["camera"]["depth_unit_m"] = unit
    _write_manifest(synthetic_session, data)
    with pytest.raises(DepthScaleError, match=r"median valid depth is .* outside the plausible"):
        open_session(synthetic_session).frame(0)
    report = validate_session(synthetic_session)
    assert sum(isinstance(p, DepthScaleError) for p in report.problems) == 1


def _rewrite_column(path: Path, row: int, column: int, value: str) -> None:
    lines = path.read_text().splitlines()
    fields = lines[row + 1].split(",")
    fields[column] = value
    lines[row + 1] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")


def test_duplicate_imu_timestamps_report_count_and_first_row(synthetic_session: Path) -> None:
    imu = synthetic_session / "imu.csv"
    lines = imu.read_text().splitlines()
    t = [line.split(",")[0] for line in lines[1:]]
    _rewrite_column(imu, 5, 0, t[4])
    _rewrite_column(imu, 9, 0, t[8])
    with pytest.raises(
        TimestampError,
        match=r"2 offending row\(s\) \(2 duplicate, 0 going back\), first at data row 5 \(line 7\)",
    ):
        open_session(synthetic_session).imu  # noqa: B018


def test_non_monotonic_joint_timestamps(synthetic_session: Path) -> None:
    joints = synthetic_session / "joints.csv"
    _rewrite_column(joints, 20, 0, "0.0")
    with pytest.raises(TimestampError, match=r"joints\.csv: .*first at data row 20 \(line 22\)"):
        open_session(synthetic_session).joints  # noqa: B018


def test_non_monotonic_frame_timestamps(synthetic_session: Path) -> None:
    _rewrite_column(synthetic_session / "frames.csv", 7, 1, "0.1")
    with pytest.raises(
        TimestampError, match=r"frames\.csv: .*first at data row 7 \(line 9\): 0\.2 then 0\.1"
    ):
        open_session(synthetic_session)


@pytest.mark.parametrize(
    ("stream", "column", "value"),
    [("imu.csv", 3, "nan"), ("imu.csv", 6, "inf"), ("joints.csv", 2, "NaN")],
)
def test_non_finite_samples(synthetic_session: Path, stream: str, column: int, value: str) -> None:
    _rewrite_column(synthetic_session / stream, 12, column, value)
    _rewrite_column(synthetic_session / stream, 40, column, value)
    session = open_session(synthetic_session)
    with pytest.raises(
        NonFiniteError,
        match=rf"{stream}: 2 row\(s\) hold NaN or inf; first at data row 12 \(line 14\)",
    ):
        session.imu if stream == "imu.csv" else session.joints  # noqa: B018


def test_non_numeric_sample_names_row_and_column(synthetic_session: Path) -> None:
    _rewrite_column(synthetic_session / "imu.csv", 3, 2, "abc")
    with pytest.raises(
        StreamError, match=r"data row 3 \(line 5\), column 'gyro_y_rad_s': 'abc' is not a number"
    ):
        open_session(synthetic_session).imu  # noqa: B018


def test_wrong_header(synthetic_session: Path) -> None:
    joints = synthetic_session / "joints.csv"
    lines = joints.read_text().splitlines()
    lines[0] = "t_s,knee_deg,ankle_rad"
    joints.write_text("\n".join(lines) + "\n")
    with pytest.raises(StreamError, match=r"header must be 't_s,knee_rad,ankle_rad'"):
        open_session(synthetic_session).joints  # noqa: B018


def test_unknown_event_kind(synthetic_session: Path) -> None:
    _rewrite_column(synthetic_session / "events.csv", 1, 1, "heel_off")
    with pytest.raises(SessionError, match=r"events\.csv: GaitEvents\.kind\[1\]: 'heel_off'"):
        open_session(synthetic_session).events  # noqa: B018


def test_source_files_are_not_modified_by_reading(synthetic_session: Path) -> None:
    before = {p: p.read_bytes() for p in synthetic_session.rglob("*") if p.is_file()}
    session = open_session(synthetic_session)
    validate_session(synthetic_session)
    list(session)
    after = {p: p.read_bytes() for p in synthetic_session.rglob("*") if p.is_file()}
    assert before == after


def test_writer_refuses_existing_non_session_folder(tmp_path: Path) -> None:
    from graph_slam.session import SessionWriter

    (tmp_path / "keep.txt").write_text("precious")
    with pytest.raises(SessionError, match="already exists"):
        SessionWriter(tmp_path, name="x", intrinsics=intrinsics_for(SMALL_SYNTHETIC))
    with pytest.raises(SessionError, match="not a session; refusing"):
        SessionWriter(
            tmp_path, name="x", intrinsics=intrinsics_for(SMALL_SYNTHETIC), overwrite=True
        )
    assert (tmp_path / "keep.txt").read_text() == "precious"


def test_interrupted_write_leaves_no_manifest(tmp_path: Path) -> None:
    from graph_slam.session import SessionWriter

    frames = iter_synthetic_frames(SMALL_SYNTHETIC)
    with (
        pytest.raises(RuntimeError),
        SessionWriter(
            tmp_path / "s", name="x", intrinsics=intrinsics_for(SMALL_SYNTHETIC)
        ) as writer,
    ):
        writer.add_frame(next(frames))
        raise RuntimeError("crash")
    with pytest.raises(ManifestError, match="manifest is missing"):
        open_session(tmp_path / "s")
