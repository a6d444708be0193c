"""The fault matrix (docs/reliability.md), sessions: every bad or implausible session ends in
exit code 2 and one line ``error: <file>: <rule>`` with nothing written, or in a caveat.

Each case copies the small synthetic session (tests/conftest.py), breaks one thing, runs the
command in-process and checks the exit code, the message (file, field, rule) and the output
folder. Every case fails before the long work, so the file runs in seconds. Commands, options,
converters and output folders: tests/test_faults_commands.py.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from fault_helpers import (
    cli,
    compare_refuses,
    manifest,
    one_line_error,
    read_csv,
    validate_refuses,
    write_csv,
    write_manifest,
)


def test_imu_header_only_is_refused_by_validate_and_compare(synthetic_session, tmp_path, capsys):
    imu = synthetic_session / "imu.csv"
    imu.write_text(imu.read_text().splitlines()[0] + "\n")
    validate_refuses(synthetic_session, capsys, "imu.csv", "0 sample(s)")
    compare_refuses(synthetic_session, tmp_path, capsys, "imu.csv", "0 sample(s)", "at least 2")


def test_a_variant_without_its_stream_is_refused(synthetic_session, tmp_path, capsys) -> None:
    data = manifest(synthetic_session)
    data["files"]["imu"] = None
    data["sensors"]["imu"] = None
    write_manifest(synthetic_session, data)
    line = compare_refuses(
        synthetic_session, tmp_path, capsys, "session.yaml", "'icp+imu+kin'", "files.imu",
        variants="icp+imu+kin",
    )  # fmt: skip
    assert "IMU factors" in line
    code, _, err = cli(["validate", "--quick", synthetic_session], capsys)
    assert code == 0, err  # a session without an IMU is valid ...
    code, _, err = cli(
        ["validate", "--quick", synthetic_session, "--variants", "icp,icp+imu"], capsys
    )
    assert code == 2 and "variant 'icp+imu' needs IMU factors" in err  # ... but not for icp+imu


@pytest.mark.parametrize("case", ["toe-off only", "strikes after the recording"])
def test_events_without_a_foot_strike_inside_are_refused(
    synthetic_session, tmp_path, capsys, case: str
) -> None:
    rows = {
        "toe-off only": "0.500000000,toe_off,load_cell\n",
        "strikes after the recording": "100.0,foot_strike,load_cell\n101.1,foot_strike,load_cell\n",
    }[case]
    (synthetic_session / "events.csv").write_text("t_s,kind,source\n" + rows)
    validate_refuses(synthetic_session, capsys, "events.csv", "no foot strike inside")
    compare_refuses(synthetic_session, tmp_path, capsys, "events.csv", "no foot strike inside")


def test_strides_dropped_are_counted_with_their_reason(synthetic_session) -> None:
    from types import SimpleNamespace

    from graph_slam.report.checks import run_warnings
    from graph_slam.session import open_session

    # frames at 30 Hz from t=0; strikes at frames 3, 4, 5 and 30
    t = open_session(synthetic_session).frame_times_s
    strikes = [t[3], t[4], t[5], t[30]]
    (synthetic_session / "events.csv").write_text(
        "t_s,kind,source\n" + "".join(f"{float(x)!r},foot_strike,load_cell\n" for x in strikes)
    )
    session = open_session(synthetic_session)
    stride = SimpleNamespace
    first = SimpleNamespace(
        t_s=t,
        strides=[
            stride(start="foot_strike", frame_indices=[0, 1, 2]),  # before the first strike
            stride(start="foot_strike", frame_indices=[3]),  # too short
            stride(start="foot_strike", frame_indices=[4]),  # too short
            stride(start="foot_strike", frame_indices=list(range(5, 30))),  # scored
            stride(
                start="foot_strike", frame_indices=list(range(30, t.size - 5))
            ),  # no next strike
        ],
        counts={"imu_used": 10, "imu_out_of_range": 3, "joints_used": 5},
    )
    run = SimpleNamespace(
        results={"icp": first}, references=[SimpleNamespace(frame_indices=np.arange(5, 30))]
    )
    found = {f.code: f for f in run_warnings(session, run, "load_cell")}
    assert found["strides_dropped"].message == (
        "3 strides not scored (2 fewer than 2 frames, 1 no foot strike after it); 1 scored"
    )
    assert found["samples_rejected"].message == "variant icp: imu_out_of_range 3"
    # the head before the first strike and the tail after the last one are no strides
    tail = stride(start="foot_strike", frame_indices=list(range(30, t.size)))
    first.strides = [first.strides[0], first.strides[3], tail]
    assert "strides_dropped" not in {f.code for f in run_warnings(session, run, "load_cell")}


def test_a_one_frame_tail_after_the_last_strike_is_no_stride(synthetic_session) -> None:
    """A strike at the last frame leaves a one-frame tail: no stride, no "1 strides not scored
    (1 fewer than 2 frames)" on every clean compare."""
    from types import SimpleNamespace as stride

    from graph_slam.report.checks import run_warnings
    from graph_slam.session import open_session

    t = open_session(synthetic_session).frame_times_s
    n = t.size
    (synthetic_session / "events.csv").write_text(
        "t_s,kind,source\n"
        + "".join(f"{float(x)!r},foot_strike,load_cell\n" for x in (t[3], t[n - 1]))
    )
    session = open_session(synthetic_session)
    strides = [
        stride(start="foot_strike", frame_indices=list(range(3, n - 1))),  # scored
        stride(start="foot_strike", frame_indices=[n - 1]),  # the tail: one frame
    ]
    first = stride(t_s=t, strides=strides, counts={})
    run = stride(results={"icp": first}, references=[stride(frame_indices=np.arange(3, n - 1))])
    assert run_warnings(session, run, "load_cell") == []
    strides[1] = stride(start="foot_strike", frame_indices=[n - 2])  # one frame, not the tail
    strides[0].frame_indices = list(range(3, n - 2))
    (synthetic_session / "events.csv").write_text(
        "t_s,kind,source\n"
        + "".join(f"{float(x)!r},foot_strike,load_cell\n" for x in (t[3], t[n - 2], t[n - 1]))
    )
    session = open_session(synthetic_session)
    found = run_warnings(session, run, "load_cell")
    assert [f.message for f in found] == ["1 strides not scored (1 fewer than 2 frames); 1 scored"]


def test_foot_strikes_every_50_ms_are_a_caveat(synthetic_session) -> None:
    from graph_slam.session import open_session
    from graph_slam.session.plausibility import session_findings

    t = np.arange(0.1, 2.3, 0.05)
    (synthetic_session / "events.csv").write_text(
        "t_s,kind,source\n" + "".join(f"{x:.6f},foot_strike,load_cell\n" for x in t)
    )
    found = {f.code: f for f in session_findings(open_session(synthetic_session))}
    assert not found["stride_time"].fatal
    assert f"{t.size - 1} foot strike(s) less than 0.3 s" in found["stride_time"].message


@pytest.mark.parametrize(
    ("text", "where"),
    [("schema_version: 1\nname: [unclosed\n", "line 3, column 1"), ("a: b: c\n", "line 1")],
)
def test_yaml_errors_are_one_line_with_the_position(synthetic_session, capsys, text, where):
    (synthetic_session / "session.yaml").write_text(text)
    code, _, err = cli(["info", synthetic_session], capsys)
    assert code == 2
    line = one_line_error(err, "session.yaml", "not valid YAML at", where)
    assert len(err.strip().splitlines()) == 1, line


def test_frames_csv_with_only_its_header_is_refused(synthetic_session, tmp_path, capsys) -> None:
    frames = synthetic_session / "frames.csv"
    frames.write_text(frames.read_text().splitlines()[0] + "\n")
    validate_refuses(synthetic_session, capsys, "frames.csv", "0 sample(s)")
    compare_refuses(synthetic_session, tmp_path, capsys, "frames.csv", "0 sample(s)")


@pytest.mark.parametrize("stream", ["imu.csv", "joints.csv", "frames.csv"])
def test_a_huge_timestamp_is_refused(synthetic_session, capsys, stream: str) -> None:
    path = synthetic_session / stream
    lines = path.read_text().splitlines()
    fields = lines[-1].split(",")
    fields[1 if stream == "frames.csv" else 0] = "1e308"
    lines[-1] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    validate_refuses(synthetic_session, capsys, stream, "beyond ±1e+10 s", f"line {len(lines)}")


def _edit_imu(session: Path, gyro_scale: float = 1.0, accel_scale: float = 1.0) -> None:
    header, data = read_csv(session / "imu.csv")
    data[:, 1:4] *= gyro_scale
    data[:, 4:7] *= accel_scale
    write_csv(session / "imu.csv", header, data)


@pytest.mark.parametrize(
    ("edit", "needles"),
    [
        ({"accel_scale": 1 / 9.80665}, ("imu.csv", "accel_*_m_s2", "looks like g")),
        ({"gyro_scale": 180 / np.pi * 10}, ("imu.csv", "gyro_*_rad_s", "°/s")),
    ],
    ids=["accel-in-g", "gyro-in-deg-s"],
)
def test_imu_in_the_wrong_units_stops_compare(synthetic_session, tmp_path, capsys, edit, needles):
    _edit_imu(synthetic_session, **edit)
    validate_refuses(synthetic_session, capsys, *needles)
    compare_refuses(synthetic_session, tmp_path, capsys, *needles)


def test_joints_in_degrees_name_the_file(synthetic_session, tmp_path, capsys) -> None:
    header, data = read_csv(synthetic_session / "joints.csv")
    data[:, 1:] = np.degrees(data[:, 1:]) * 10  # the synthetic knee bends little
    write_csv(synthetic_session / "joints.csv", header, data)
    compare_refuses(synthetic_session, tmp_path, capsys, "joints.csv", "knee_rad", "degrees")


def test_principal_point_outside_the_image_stops_compare(synthetic_session, tmp_path, capsys):
    data = manifest(synthetic_session)
    data["sensors"]["camera"]["intrinsics"]["cx_px"] = 5000.0
    write_manifest(synthetic_session, data)
    compare_refuses(
        synthetic_session, tmp_path, capsys, "session.yaml", "intrinsics.cx_px", "outside the image"
    )


def test_ground_truth_off_the_frame_times_fails_validate(synthetic_session, tmp_path, capsys):
    lines = (synthetic_session / "groundtruth.txt").read_text().splitlines()
    shifted = []
    for line in lines:
        if line.startswith("#") or not line.strip():
            shifted.append(line)
            continue
        t, *rest = line.split()
        shifted.append(" ".join([repr(float(t) + 0.003), *rest]))
    (synthetic_session / "groundtruth.txt").write_text("\n".join(shifted) + "\n")
    validate_refuses(synthetic_session, capsys, "groundtruth.txt", "not at the frame times")
    compare_refuses(synthetic_session, tmp_path, capsys, "groundtruth.txt", "3.000 ms")


def test_caveats_gap_clipping_depth_are_warnings_not_errors(synthetic_session, capsys) -> None:
    from graph_slam.session import open_session
    from graph_slam.session.plausibility import session_findings

    header, data = read_csv(synthetic_session / "imu.csv")
    keep = (data[:, 0] < 0.5) | (data[:, 0] > 1.5)  # a 1 s gap
    data = data[keep]
    data[:5, 4] = 30.0  # five samples clipped at the accelerometer's range
    write_csv(synthetic_session / "imu.csv", header, data)
    m = manifest(synthetic_session)
    m["sensors"]["camera"]["depth_unit_m"] *= 10.0  # depth 10x off
    write_manifest(synthetic_session, m)
    found = {f.code: f for f in session_findings(open_session(synthetic_session))}
    assert {"imu_gap", "accel_clipped", "depth_range"} <= set(found), found
    assert not any(f.fatal for f in found.values())
    assert "longest 1.0" in found["imu_gap"].message
    assert "column accel_x: 5 samples at ±30" in found["accel_clipped"].message
    code, _, err = cli(["validate", "--quick", synthetic_session], capsys)
    assert code == 0 and "warning: " in err and "imu_gap" not in err and "gap(s)" in err


def test_path_escape_in_the_manifest_is_refused(synthetic_session, capsys) -> None:
    data = manifest(synthetic_session)
    data["files"]["imu"] = "../../etc/passwd"
    write_manifest(synthetic_session, data)
    code, _, err = cli(["info", synthetic_session], capsys)
    assert code == 2
    one_line_error(err, "files.imu", "escapes the session folder")


def test_hostile_yaml_tag_is_not_executed(synthetic_session, tmp_path, capsys) -> None:
    marker = tmp_path / "pwned"
    (synthetic_session / "session.yaml").write_text(
        f"!!python/object/apply:os.system ['touch {marker}']\n"
    )
    code, _, err = cli(["info", synthetic_session], capsys)
    assert code == 2 and not marker.exists()
    one_line_error(err, "session.yaml")


def test_truncated_png_is_refused(synthetic_session, capsys) -> None:
    png = synthetic_session / "depth" / "000003.png"
    png.write_bytes(png.read_bytes()[:40])
    code, _, err = cli(["validate", synthetic_session], capsys)
    assert code == 2 and "000003.png" in err and "Traceback" not in err


@pytest.mark.parametrize("bad", ["nan", "inf"])
def test_non_finite_imu_sample_is_refused(synthetic_session, capsys, bad: str) -> None:
    lines = (synthetic_session / "imu.csv").read_text().splitlines()
    fields = lines[5].split(",")
    fields[2] = bad
    lines[5] = ",".join(fields)
    (synthetic_session / "imu.csv").write_text("\n".join(lines) + "\n")
    validate_refuses(synthetic_session, capsys, "imu.csv", "NaN or inf", "line 6")


def test_duplicate_timestamp_is_refused(synthetic_session, capsys) -> None:
    lines = (synthetic_session / "joints.csv").read_text().splitlines()
    lines.insert(4, lines[3])
    (synthetic_session / "joints.csv").write_text("\n".join(lines) + "\n")
    validate_refuses(synthetic_session, capsys, "joints.csv", "strictly increasing", "duplicate")


def test_valid_session_stays_valid(synthetic_session, capsys) -> None:
    code, out, err = cli(["validate", synthetic_session], capsys)
    assert code == 0 and out.startswith("valid:"), err
    assert "warning" not in err
    shutil.rmtree(synthetic_session / "color")  # colour is optional per frame set: now invalid
    code, _, err = cli(["validate", "--quick", synthetic_session], capsys)
    assert code == 2 and "color" in err


def test_events_csv_with_only_its_header_is_refused(synthetic_session, tmp_path, capsys):
    (synthetic_session / "events.csv").write_text("t_s,kind,source\n")
    compare_refuses(synthetic_session, tmp_path, capsys, "events.csv", "no foot strike inside")


def test_session_without_camera_is_refused_by_compare(synthetic_session, tmp_path, capsys):
    data = manifest(synthetic_session)
    data["sensors"]["camera"] = None
    write_manifest(synthetic_session, data)
    (synthetic_session / "frames.csv").write_text("index,t_s,depth,color\n")
    compare_refuses(synthetic_session, tmp_path, capsys, "sensors.camera", "without a camera")


@pytest.mark.parametrize(
    ("text", "rule"),
    [("", "top level must be a mapping"), ("\xff\xfe", "cannot read")],
    ids=["empty", "binary"],
)
def test_manifest_empty_or_binary(synthetic_session, capsys, text: str, rule: str) -> None:
    (synthetic_session / "session.yaml").write_bytes(text.encode("latin-1"))
    code, _, err = cli(["info", synthetic_session], capsys)
    assert code == 2
    one_line_error(err, "session.yaml", rule)


def test_missing_stream_file_is_named(synthetic_session, capsys) -> None:
    (synthetic_session / "imu.csv").unlink()
    validate_refuses(synthetic_session, capsys, "imu.csv", "file is missing")


@pytest.mark.parametrize(
    ("row", "rule"),
    [("0.0 1 2 3 0 0 0 2", "quaternion norm"), ("0.0 1 2 3", "8 entries")],
    ids=["non-unit-quaternion", "short-row"],
)
def test_bad_ground_truth_row(synthetic_session, capsys, row: str, rule: str) -> None:
    path = synthetic_session / "groundtruth.txt"
    lines = [x for x in path.read_text().splitlines() if x and not x.startswith("#")]
    lines[0] = row
    path.write_text("\n".join(lines) + "\n")
    validate_refuses(synthetic_session, capsys, "groundtruth.txt", rule)


def test_event_source_missing_is_refused_before_the_run(synthetic_session, tmp_path, capsys):
    # the synthetic session's events come from source 'synthetic'; compare cuts at 'load_cell'
    compare_refuses(synthetic_session, tmp_path, capsys, "events.csv", "source 'load_cell'")


def test_imu_online_strides_need_the_imu_not_events(synthetic_session) -> None:
    from graph_slam.session import open_session
    from graph_slam.session.plausibility import session_findings, variant_findings

    (synthetic_session / "events.csv").write_text("t_s,kind,source\n")  # no strike at all
    session = open_session(synthetic_session)
    assert not [f for f in session_findings(session, events_cut_strides=False) if f.fatal]
    assert not variant_findings(session, ["icp"], events_cut_strides=False)
    data = manifest(synthetic_session)
    data["files"]["imu"] = None
    data["sensors"]["imu"] = None
    write_manifest(synthetic_session, data)
    (found,) = variant_findings(open_session(synthetic_session), ["icp"], events_cut_strides=False)
    assert found.fatal and "IMU gait events" in found.message and "files.imu" in found.message


@pytest.mark.parametrize("x_m", [float("nan"), float("inf"), -float("inf"), 1e300])
def test_height_at_an_impossible_coordinate_is_nan(x_m) -> None:
    """``FrameOutput.terrain.height_at`` (and the stride map's) answers NaN for a coordinate
    off the grid, as its docstring promises, NaN and inf included (no ValueError)."""
    from graph_slam.terrain.grid.online import CellSums, OnlineElevationMap, OnlineTerrainConfig
    from graph_slam.terrain.maps.elevation import ElevationConfig, elevation_grid

    cfg = OnlineTerrainConfig()
    view = OnlineElevationMap(cfg, prior=CellSums.empty(int(np.prod(cfg.shape)))).view()
    grid = elevation_grid(np.tile([0.5, 0.0, 0.1], (4, 1)), ElevationConfig())
    for terrain in (view, grid):
        assert np.isnan(terrain.height_at(x_m, 0.0)) and np.isnan(terrain.height_at(0.0, x_m))
    assert np.isnan(view.sigma_at(x_m, 0.0))
    assert grid.height_at(0.5, 0.0) == pytest.approx(0.1)


@pytest.mark.parametrize("fault", ["all-zero", "the-same-image"])
def test_depth_that_cannot_be_registered_is_refused(synthetic_session, tmp_path, capsys, fault):
    """No valid depth pixel in any frame, or one depth image repeated in every frame (a frozen
    stream): validate and compare stop (before: "valid", then 0 registered / 10 frames
    "registered" with zero motion)."""
    from graph_slam.session.io import write_png

    pngs = sorted((synthetic_session / "depth").glob("*.png"))
    first = pngs[0].read_bytes()
    for png in pngs:
        if fault == "all-zero":
            write_png(png, np.zeros((48, 64), dtype=np.uint16))  # the small session's size
        else:
            png.write_bytes(first)
    rule = "no valid depth pixel" if fault == "all-zero" else "hold the same depth image"
    validate_refuses(synthetic_session, capsys, "frames.csv", rule)
    compare_refuses(synthetic_session, tmp_path, capsys, "frames.csv", rule)


@pytest.mark.parametrize("variant", ["icp", "imu+kin"])
def test_the_streaming_strike_and_frame_contract(synthetic_session, variant) -> None:
    """``foot_strike(t)`` with t NaN / inf / not after the previous strike / after the next
    frame, and frames out of order, are typed errors; a strike too close to the previous one
    is used and counted (docs/pipelines.md)."""
    from graph_slam.errors import EstimationError
    from graph_slam.pipelines import PipelineConfig
    from graph_slam.pipelines.runner import open_pipeline
    from graph_slam.session import RgbdFrame

    cfg = PipelineConfig(variant=variant, mount_pitch_deg=35.0, event_source=None)
    s, st, pipe = open_pipeline(synthetic_session, cfg)
    pipe.add_imu(st.imu_t_s, st.gyro_rad_s, st.accel_m_s2)
    pipe.add_joints(st.joints_t_s, st.knee_rad, st.ankle_rad)
    f = list(s.iter_frames(0, 4))
    for bad in (float("nan"), float("inf"), "soon"):
        with pytest.raises(EstimationError, match=r"foot_strike: t_s = .* not a"):
            pipe.foot_strike(bad)
    pipe.add_frame(f[0], True)
    pipe.foot_strike(f[0].t_s + 0.002)
    with pytest.raises(EstimationError, match="not after the previous strike"):
        pipe.foot_strike(f[0].t_s)  # in the past
    pipe.add_frame(f[1], True)
    pipe.foot_strike(f[0].t_s + 0.003)  # 1 ms after the last strike: used and counted
    pipe.add_frame(f[2], True)
    with pytest.raises(EstimationError, match="not after the previous frame"):
        pipe.add_frame(f[1], True)
    with pytest.raises(EstimationError, match="frame is a NoneType, not a"):
        pipe.add_frame(None, True)
    small = RgbdFrame(f[3].t_s, f[3].depth_m[:-2], index=3)
    with pytest.raises(EstimationError, match=r"frame 3 is 64×46 px but the camera's"):
        pipe.add_frame(small, True)
    pipe.foot_strike(f[3].t_s + 1.0)  # announced before it happened
    with pytest.raises(EstimationError, match="lies after the next frame"):
        pipe.add_frame(f[3], True)
    assert pipe.finish().counts["foot_strikes_too_close"] == 1
