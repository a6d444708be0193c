"""Atomic output folders (graph_slam.session.atomic): written whole or not at all; --overwrite
replaces only what graph-slam wrote; an interrupted simulate leaves nothing behind."""

from __future__ import annotations

import shutil

import pytest

from graph_slam.errors import OutputError
from graph_slam.session.atomic import (
    LEGACY_SIGNS,
    MARKER_NAME,
    atomic_folder,
    check_output,
    marker_text,
    written_by,
    written_by_us,
)


def test_success_renames_and_marks(tmp_path) -> None:
    out = tmp_path / "run"
    with atomic_folder(out, command="run") as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".run.partial-")
        (tmp / "a.txt").write_text("a")
        assert not out.exists()  # nothing at the target while writing
    assert (out / "a.txt").read_text() == "a" and (out / MARKER_NAME).is_file()
    assert written_by_us(out) and written_by(out) == "run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, RuntimeError])
def test_interrupted_write_leaves_the_old_folder_and_no_partial(tmp_path, interrupt) -> None:
    out = tmp_path / "run"
    with atomic_folder(out, command="run") as tmp:
        (tmp / "old.txt").write_text("old")
    with pytest.raises(interrupt), atomic_folder(out, overwrite=True, command="run") as tmp:
        (tmp / "new.txt").write_text("half")
        raise interrupt()
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER_NAME, "old.txt"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_overwrite_replaces_only_our_folders(tmp_path) -> None:
    ours = tmp_path / "ours"
    with atomic_folder(ours, command="run") as tmp:
        (tmp / "stale.txt").write_text("stale")
    with pytest.raises(OutputError, match=r"already exists \(pass --overwrite"):
        check_output(ours, overwrite=False, command="run")
    with atomic_folder(ours, overwrite=True, command="run") as tmp:
        (tmp / "fresh.txt").write_text("fresh")
    assert not (ours / "stale.txt").exists() and (ours / "fresh.txt").is_file()  # no merge
    user = tmp_path / "user"
    user.mkdir()
    (user / "thesis.tex").write_text("precious")
    with pytest.raises(OutputError, match="was not written by graph-slam"):
        check_output(user, overwrite=True, command="run")
    assert (user / "thesis.tex").read_text() == "precious"
    empty = tmp_path / "empty"
    empty.mkdir()
    check_output(empty, overwrite=False, command="run")  # an empty folder is fine


def test_stale_partial_of_a_killed_run_is_removed(tmp_path) -> None:
    stale = tmp_path / ".run.partial-999999"
    stale.mkdir()
    (stale / "x").write_text("x")
    with atomic_folder(tmp_path / "run", command="run") as tmp:
        (tmp / "y").write_text("y")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_file_shaped_targets(tmp_path) -> None:
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output(f, overwrite=True, command="run")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output(f / "deeper" / "out", overwrite=True, command="run")
    link = tmp_path / "link"
    link.symlink_to(tmp_path)
    with pytest.raises(
        OutputError, match=r"link: is a symbolic link \(to .*\); give a real folder"
    ):
        check_output(link, overwrite=True, command="run")


def test_simulate_interrupted_leaves_nothing_and_keeps_the_old_session(tmp_path, monkeypatch):
    from graph_slam.sim import SimConfig, recording, simulate

    out = tmp_path / "s"
    with atomic_folder(out, command="simulate") as tmp:
        (tmp / "session.yaml").write_text("schema_version: 1\n")
    calls = {"n": 0}
    real = recording.Renderer.render

    def render_then_ctrl_c(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)

    monkeypatch.setattr(recording.Renderer, "render", render_then_ctrl_c)
    cfg = SimConfig(strides=1, fast=True, drops="none", seed=3, quicklook=False)
    with pytest.raises(KeyboardInterrupt):
        simulate(cfg, out, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]
    assert (out / "session.yaml").read_text() == "schema_version: 1\n"


# --- --overwrite never replaces an input or another command's folder (the CLI) -------------


def _refused(argv, capsys, *needles: str) -> str:
    from fault_helpers import cli, one_line_error

    code, _, err = cli(argv, capsys)
    assert code == 2, err
    return one_line_error(err, *needles)


@pytest.mark.parametrize("command", ["run", "compare"])
def test_out_that_is_the_input_session_is_refused(synthetic_session, capsys, command) -> None:
    from fault_helpers import snapshot

    before = snapshot(synthetic_session)
    s = synthetic_session
    for out in (s, s / "out"):
        line = _refused(
            [command, s, "--out", out, "--overwrite", "--variants", "icp"], capsys, str(out)
        )
        assert "is an input of this run" in line or "lies inside the input" in line, line
        assert snapshot(synthetic_session) == before  # byte for byte
    parent = s.parent
    _refused([command, s, "--out", parent, "--overwrite"], capsys, "contains the input")
    assert snapshot(synthetic_session) == before
    assert sorted(p.name for p in parent.iterdir()) == ["session"]


@pytest.mark.parametrize(
    ("command", "other"),
    [("run", "simulate"), ("run", "batch"), ("compare", "run"), ("run", "compare")],
)
def test_overwrite_replaces_only_what_the_same_command_wrote(
    synthetic_session, tmp_path, capsys, command, other
) -> None:
    from fault_helpers import snapshot

    theirs = tmp_path / "theirs"  # e.g. another session, a whole batch study, a report
    shutil.copytree(synthetic_session, theirs / "data")
    (theirs / MARKER_NAME).write_text(marker_text(other))
    before = snapshot(theirs)
    line = _refused(
        [command, synthetic_session, "--out", theirs, "--overwrite", "--variants", "icp"],
        capsys,
        str(theirs),
        f"was written by `graph-slam {other}`, not `graph-slam {command}`",
    )
    assert "--overwrite replaces only a folder the same command wrote" in line
    assert snapshot(theirs) == before


def test_simulate_and_convert_never_replace_another_session(
    synthetic_session, tmp_path, capsys
) -> None:
    from fault_helpers import snapshot

    recorded = synthetic_session  # a user's recording: a session.yaml, no marker
    before = snapshot(recorded)
    _refused(["simulate", "--out", recorded, "--overwrite"], capsys, "not written by graph-slam")
    simulated = tmp_path / "sim"
    shutil.copytree(recorded, simulated)
    (simulated / MARKER_NAME).write_text(marker_text("simulate"))
    _refused(
        ["convert", recorded, simulated, "--overwrite"], capsys, "`graph-slam simulate`"
    )  # a converted session is not a simulated one, and the other way round
    older = tmp_path / "older"  # a marker of an older graph-slam names no command
    shutil.copytree(recorded, older)
    (older / MARKER_NAME).write_text("written by graph-slam; --overwrite may replace this folder\n")
    _refused(["simulate", "--out", older, "--overwrite"], capsys, "an older graph-slam")
    assert snapshot(recorded) == before and (older / "session.yaml").is_file()


def test_demo_does_not_replace_a_run(tmp_path, capsys) -> None:
    ran = tmp_path / "ran"
    ran.mkdir()
    (ran / "report.md").write_text("# run\n")
    (ran / MARKER_NAME).write_text(marker_text("run"))
    _refused(
        ["demo", "--out", ran, "--overwrite", "--strides", "1,1,1"], capsys, "`graph-slam run`"
    )
    assert sorted(p.name for p in ran.iterdir()) == sorted([MARKER_NAME, "report.md"])


def test_a_symlinked_out_is_named_a_link(synthetic_session, tmp_path, capsys) -> None:
    target = tmp_path / "real"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    for argv in (
        ["run", synthetic_session, "--out", link, "--overwrite"],
        ["compare", synthetic_session, "--out", link, "--overwrite"],
        ["simulate", "--out", link, "--overwrite"],
    ):
        line = _refused(argv, capsys, str(link), "is a symbolic link")
        assert "is a file" not in line
    assert link.is_symlink() and not any(target.iterdir())


def test_a_batch_study_inside_or_around_a_session_is_refused(synthetic_session, tmp_path, capsys):
    pytest.importorskip("dask.distributed")
    import yaml
    from fault_helpers import snapshot

    spec = tmp_path / "batch.yaml"
    spec.write_text(yaml.safe_dump({"sessions": [str(synthetic_session)], "variants": ["icp"]}))
    before = snapshot(synthetic_session)
    _refused(["batch", spec, "--out", synthetic_session / "study"], capsys, "lies inside the input")
    _refused(["batch", spec, "--out", synthetic_session], capsys, "is an input of this run")
    assert snapshot(synthetic_session) == before


# --- Ctrl-C of the parallel commands: one line, no worker traceback ------------------------


def _ctrl_c(argv: list, when: str, cwd, timeout_s: float = 120.0) -> tuple[int, str]:
    """Run ``graph-slam argv`` in its own process group (as a terminal runs it), send SIGINT
    to the whole group (as Ctrl-C does) once a stderr line starts with ``when``; return the
    exit code and the whole stderr. Bounded: killed after ``timeout_s``."""
    import os
    import signal
    import subprocess
    import sys
    import threading

    proc = subprocess.Popen(
        [sys.executable, "-m", "graph_slam", *map(str, argv)],
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # a shell's background job ignores SIGINT, and a child would inherit that: restore it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # noqa: PLW1509
    )
    timer = threading.Timer(timeout_s, lambda: os.killpg(proc.pid, signal.SIGKILL))
    timer.start()
    lines = []
    try:
        for line in proc.stderr:
            lines.append(line)
            if line.startswith(when):
                os.killpg(proc.pid, signal.SIGINT)
                when = "\0never"
        code = proc.wait()
    finally:
        timer.cancel()
    return code, "".join(lines)


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """A simulated one-stride walk (the issue's `simulate --fast --strides 1 --seed 3`)."""
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("walk") / "walk"
    simulate(SimConfig(strides=1, fast=True, seed=3, quicklook=False), out)
    return out


def test_ctrl_c_of_run_with_workers_is_one_line(walk, tmp_path) -> None:
    out = tmp_path / "o"
    argv = ["run", walk, "--out", out, "--workers", "2", "--variants", "icp,icp+imu"]
    code, err = _ctrl_c(
        argv,
        "running variants:",  # the first progress line: the workers are running
        tmp_path,
    )
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.strip().splitlines()[-1] == f"interrupted: nothing written to {out}", err
    assert not out.exists() and not list(tmp_path.glob(".o.partial-*"))


def test_ctrl_c_of_batch_is_one_line(walk, tmp_path) -> None:
    pytest.importorskip("dask.distributed")
    import yaml

    spec = tmp_path / "batch.yaml"
    spec.write_text(
        yaml.safe_dump(
            {
                "sessions": [str(walk)],
                "variants": ["icp"],
            }
        )
    )
    code, err = _ctrl_c(
        ["batch", spec, "--out", tmp_path / "b", "--workers", "1"], "local cluster:", tmp_path
    )
    assert code == 130, err
    assert "Traceback" not in err and "CancelledError" not in err, err
    assert "WARNING" not in err, err
    assert err.strip().splitlines()[-1].startswith("interrupted: finished tasks are kept"), err


def test_a_folder_an_older_version_marked_is_known_by_its_files(tmp_path) -> None:
    """Markers written before they named the command: the folder's files tell which command
    wrote it, so `--overwrite` keeps working on one's own older outputs and still never
    replaces another command's."""
    older = "written by graph-slam; --overwrite may replace this folder\n"
    for k, (command, names) in enumerate(LEGACY_SIGNS):
        folder = tmp_path / f"out{k}"
        folder.mkdir()
        (folder / MARKER_NAME).write_text(older)
        for name in names:
            (folder / name).write_text("x")
        assert written_by(folder) == command
        check_output(folder, overwrite=True, command=command)
        other = "run" if command != "run" else "compare"
        with pytest.raises(OutputError, match=f"was written by `graph-slam {command}`"):
            check_output(folder, overwrite=True, command=other)


def test_the_worker_plugin_makes_a_worker_ignore_ctrl_c() -> None:
    pytest.importorskip("dask.distributed")
    import signal

    from graph_slam.batch.cluster import ignore_sigint_plugin

    before = signal.getsignal(signal.SIGINT)
    try:
        ignore_sigint_plugin().setup(worker=None)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_dasks_sync_cancel_race_is_dropped_from_the_log_and_nothing_else() -> None:
    """The NameError Dask's own ``sync()`` cancel callback raises when a Ctrl-C lands before
    its future exists is kept out of stderr; any other callback error is still logged."""
    import logging

    from graph_slam.batch.cluster import drop_sync_cancel_race

    source = (
        "def make():\n"
        "    future = None\n"
        "    del future\n"
        "    def cancel():\n"
        "        if future is not None:\n"
        "            pass\n"
        "    return cancel\n"
    )
    space: dict = {}
    exec(compile(source, "/x/site-packages/distributed/utils.py", "exec"), space)
    seen: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record):
            seen.append(record.getMessage())

    log = logging.getLogger("tornado.application")
    handler = Keep()
    log.addHandler(handler)
    try:
        drop_sync_cancel_race()
        drop_sync_cancel_race()  # idempotent: one filter
        for fn, label in ((space["make"](), "race"), (lambda: 1 / 0, "other")):
            try:
                fn()
            except Exception:
                log.error("Exception in callback %s", label, exc_info=True)
    finally:
        log.removeHandler(handler)
    assert seen == ["Exception in callback other"]
    assert sum(getattr(f, "_graph_slam_sync_cancel", False) for f in log.filters) == 1
