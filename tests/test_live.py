"""Live: the online IMU merge, the prosthesis's UDP stream on loopback (bad datagrams counted,
never fatal, bounded in count and time), load-cell events online, and a recording played back
through librealsense's pipeline into the real-time pipeline with run's outputs on stop."""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from graph_slam.live.camera import ImuMerger
from graph_slam.live.prosthesis import LoadEvents, UdpStream
from graph_slam.session.adapters.config import LoadColumn


def test_imu_merger_interpolates_accel_at_gyro_stamps_causally() -> None:
    m = ImuMerger(max_gap_s=0.05)
    out = []
    out += m.gyro(0.000, np.array([1.0, 0, 0]))  # before any accel: waits, then dropped
    out += m.accel(0.001, np.array([0.0, 0, 10]))
    assert out == []
    out += m.gyro(0.0035, np.array([2.0, 0, 0]))  # waits for the accel after it
    assert out == []
    out += m.accel(0.005, np.array([4.0, 0, 10]))
    (t, gyro, accel), = out  # fmt: skip
    assert t == 0.0035 and gyro[0] == 2.0
    np.testing.assert_allclose(accel, [2.5, 0, 10])  # (3.5 - 1) / 4 of the way
    out = m.gyro(0.0036, np.array([3.0, 0, 0]))  # out of order? no: later than 0.0035
    assert len(out) == 1
    assert m.gyro(0.0030, np.array([0.0, 0, 0])) == []  # earlier than the last: counted
    m.accel(0.2, np.array([0.0, 0, 10]))
    assert m.gyro(0.1, np.array([0.0, 0, 0])) == []  # across a 195 ms accel gap: dropped
    c = m.counts
    assert (c["used"], c["before accel"], c["out of order"], c["accel gap"]) == (2, 1, 1, 1)
    assert c["gyro"] == c["used"] + c["before accel"] + c["out of order"] + c["accel gap"]


def test_imu_merger_counts_the_samples_that_never_arrived() -> None:
    """400 Hz gyro with 3 samples lost in one gap and 1 in another, 250 Hz accel with 2
    lost: counted, not guessed from a nominal rate."""
    m = ImuMerger()
    gyro = np.delete(np.arange(40) * 0.0025, [10, 11, 12, 30])
    accel = np.delete(np.arange(26) * 0.004, [7, 8])
    for t in sorted([(t, "g") for t in gyro] + [(t, "a") for t in accel]):
        m.gyro(t[0], np.zeros(3)) if t[1] == "g" else m.accel(t[0], np.zeros(3))
    assert (m.counts["gyro missing"], m.counts["accel missing"]) == (4, 2)


def test_load_events_online_with_hysteresis() -> None:
    events = LoadEvents(LoadColumn(column="load_n", foot_strike_above_n=50, toe_off_below_n=20))
    t = np.arange(0, 1.0, 0.01)
    load = np.where((t > 0.2) & (t < 0.6), 700.0, 0.0)
    found = [e for e in (events.add(float(a), float(b)) for a, b in zip(t, load, strict=True)) if e]
    assert [k for _, k in found] == ["foot_strike", "toe_off"]
    assert found[0][0] == pytest.approx(0.2 + 0.01 * 50 / 700, abs=1e-9)


def test_log_replay_knows_an_event_at_its_stamp(tmp_path: Path) -> None:
    """A load crossing is known from the sample after it: by a frame stamped after the
    crossing's (interpolated) time the event is known, as run's replay has it."""
    from graph_slam.live.prosthesis import LogReplay
    from graph_slam.session.adapters.config import ProsthesisLogConfig

    t = np.arange(12) * 0.01
    load = np.where(t >= 0.06, 700.0, 0.0)
    rows = "\n".join(f"{a:.3f},0.1,0.0,{b}" for a, b in zip(t, load, strict=True))
    (tmp_path / "log.csv").write_text("t_s,knee_rad,ankle_rad,load_n\n" + rows + "\n")
    spec = ProsthesisLogConfig(load=LoadColumn(column="load_n", foot_strike_above_n=50,
                                               toe_off_below_n=20))  # fmt: skip
    log = LogReplay(tmp_path / "log.csv", spec, 100.0)
    assert log.until(100.05).events == []  # the crossing sample (0.06) not yet known
    (t_event, kind), = log.until(100.0508).events  # fmt: skip
    assert kind == "foot_strike" and t_event == pytest.approx(100.05 + 0.01 * 50 / 700)


def _send(sock, port: int, payload) -> None:
    data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
    sock.sendto(data, ("127.0.0.1", port))


def test_udp_stream_counts_bad_datagrams_and_never_stalls() -> None:
    load = LoadColumn(column="load_n", foot_strike_above_n=50, toe_off_below_n=20)
    stream = UdpStream(0, offset_s=10.0, load=load, max_datagrams=500)
    port = stream.address[1]
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        good = [{"seq": i, "t_s": 0.01 * i, "knee_rad": 0.1 * i, "ankle_rad": -0.01 * i,
                 "load_n": 700.0 if 5 <= i < 15 else 0.0} for i in range(20)]  # fmt: skip
        order = list(range(20))
        order[3], order[4] = order[4], order[3]  # out of order (not late)
        for i in order[:10]:
            _send(tx, port, good[i])
        _send(tx, port, good[2])  # duplicate
        for bad in (b"not json", b"\xff\xfe", {"seq": 99}, {"seq": 98, "t_s": "x"},
                    {"seq": 97, "t_s": 0.5, "knee_rad": float("nan")},
                    {"seq": 96, "t_s": 0.5, "event": "jump"}, [1, 2]):  # fmt: skip
            _send(tx, port, bad)
        time.sleep(0.05)
        t0 = time.perf_counter()
        known = stream.until(10.0 + 0.05)  # camera time of seq 5
        assert time.perf_counter() - t0 < 0.5  # bounded: never waits for data
        assert known.joints_t_s == pytest.approx([10.0 + 0.01 * i for i in range(7)])
        _send(tx, port, {"seq": 50, "t_s": 0.02, "knee_rad": 0.0, "ankle_rad": 0.0})  # late
        for i in order[10:]:
            _send(tx, port, good[i])
        time.sleep(0.05)
        rest = stream.until(100.0)
        assert rest.joints_t_s == pytest.approx([10.0 + 0.01 * i for i in range(7, 20)])
        kinds = [k for _, k in known.events + rest.events]
        assert kinds == ["foot_strike", "toe_off"]
        c = stream.counts
        assert (c["duplicate"], c["malformed"], c["late"]) == (1, 7, 1)
        assert c["out of order"] >= 1
        assert c["received"] == 20 + 1 + 7 + 1
        assert c["used"] == 20
        # a flood is read at most max_datagrams per poll: the estimator is never held up
        for i in range(1200):
            _send(tx, port, {"seq": 1000 + i, "t_s": 1.0 + i * 1e-4, "knee_rad": 0.0,
                             "ankle_rad": 0.0})  # fmt: skip
        time.sleep(0.1)
        t0 = time.perf_counter()
        stream.until(11.0)
        assert time.perf_counter() - t0 < 1.0
        assert stream.counts["received"] <= 29 + 500 + 1
    finally:
        tx.close()
        stream.close()


@pytest.fixture(scope="module")
def realtime_recording(tmp_path_factory) -> Path:
    pytest.importorskip("pyrealsense2")
    from graph_slam.sim import SimConfig
    from graph_slam.sim.export import RecordingExportConfig, export_realsense_recording

    out = tmp_path_factory.mktemp("rt") / "rec"
    cfg = SimConfig(strides=1, resolution="106x60", motion_blur=False, seed=2, quicklook=False,
                    drops="none")  # fmt: skip
    export_realsense_recording(cfg, out, RecordingExportConfig(record_speed=1.0))
    return out


def _run_counts(run_dir: Path) -> dict:
    """The counts in ``run_dir/run.json`` of the live session's icp+imu+kin run."""
    import yaml

    summary = yaml.safe_load((run_dir / "run.json").read_text())
    return summary["sessions"]["live"]["variants"]["icp+imu+kin"]["counts"]


def test_live_playback_writes_runs_outputs_up_to_the_last_frame(
    realtime_recording: Path, tmp_path: Path
) -> None:
    """A recording played back in real time: frames processed in order, the run's outputs
    for exactly those frames (timing depends on the machine: only counts are asserted)."""
    import yaml

    from graph_slam.config import load_config
    from graph_slam.live import LiveRunner, LogReplay, RealsenseSource, write_outputs
    from graph_slam.pipelines.config import PipelineConfig, with_preset
    from graph_slam.session import open_session
    from graph_slam.session.adapters.config import ConvertConfig

    conv = load_config(ConvertConfig, realtime_recording / "convert.yaml")
    source = RealsenseSource(playback=realtime_recording / "recording.db3",
                             camera_T_imu=np.asarray(conv.calibration.camera_T_imu))  # fmt: skip
    log = LogReplay(conv.prosthesis_log.path, conv.prosthesis_log, 3.217)
    lines: list[str] = []
    cfg = PipelineConfig.model_validate(with_preset({"variant": "icp+imu+kin"}, "realtime"))
    from graph_slam.live.viewer import LiveViewer, ViewerConfig

    viewer = LiveViewer(tmp_path / "live.rrd", ViewerConfig(pose_hz=0, grid_hz=30))  # to a file
    runner = LiveRunner(source, log, cfg, mount_pitch_deg=35.0, status=lines.append,
                        session_path=tmp_path / "out" / "session", viewer=viewer)  # fmt: skip
    result = runner.run(max_s=30.0)
    viewer.close()
    assert (tmp_path / "live.rrd").stat().st_size > 1000
    assert result.stop_reason == "end of playback"
    assert result.n_processed >= 3 and result.n_processed + result.skipped == result.n_arrived
    assert lines and "frames/s" in lines[0] and "latency p95" in lines[0]
    assert result.counts["imu"]["used"] > 100 and log.counts["events"] >= 2
    write_outputs(runner, result, tmp_path / "out")
    session = open_session(tmp_path / "out" / "session")
    assert session.n_frames == result.n_processed
    assert np.all(np.diff(session.frame_times_s) > 0)
    summary = yaml.safe_load((tmp_path / "out" / "run" / "run.json").read_text())
    assert list(summary["sessions"]) == ["live"]
    online = np.loadtxt(tmp_path / "out" / "run" / "live" / "icp_imu_kin" / "online.tum", ndmin=2)
    np.testing.assert_allclose(online[:, 0], session.frame_times_s[: online.shape[0]])
    assert online.shape[0] >= 0.5 * result.n_processed
    live = json.loads((tmp_path / "out" / "live.json").read_text())
    assert live["frames"]["processed"] == result.n_processed
    assert sum(live["frames"]["skipped_by_reason"].values()) == result.skipped
    # graph-slam run on the frames processed gives the live outputs, exactly
    from graph_slam.report import RunConfig, run

    cfg_run = RunConfig.model_validate(
        yaml.safe_load((tmp_path / "out" / "run" / "config.yaml").read_text())
    )
    again = run([tmp_path / "out" / "session"], tmp_path / "again", cfg_run)
    for name in ("online.tum", "smoothed.tum", "frames.csv"):
        ours = (tmp_path / "out" / "run" / "live" / "icp_imu_kin" / name).read_text()
        assert (again.out / "live" / "icp_imu_kin" / name).read_text() == ours, name
    # and run.json counts the same things: the strikes the live estimator took in among them
    counts, counts_again = _run_counts(tmp_path / "out" / "run"), _run_counts(again.out)
    assert sorted(counts) == sorted(counts_again)
    assert counts["foot_strikes"] == counts_again["foot_strikes"] >= 1
    assert counts == counts_again


def test_missing_extra_is_named_before_any_work(monkeypatch, tmp_path: Path, capsys) -> None:
    import sys

    from graph_slam.cli import main
    from graph_slam.errors import MissingExtraError
    from graph_slam.live.sdk import rs_module

    monkeypatch.setitem(sys.modules, "pyrealsense2", None)  # import fails as when missing
    with pytest.raises(MissingExtraError, match=r"optional extra 'realsense'.*\[realsense\]"):
        rs_module()
    with pytest.raises(SystemExit) as done:
        main(["live", "--playback", str(tmp_path / "x.db3"), "--out", str(tmp_path / "o")])
    assert done.value.code == 2
    assert "optional extra 'realsense'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
