"""Atomic output folders (graph_slam.session.atomic): written whole or not at all; --overwrite
replaces only what graph-slam wrote; an interrupted simulate leaves nothing behind."""

from __future__ import annotations

import pytest

from graph_slam.errors import OutputError
from graph_slam.session.atomic import MARKER_NAME, atomic_folder, check_output, written_by_us


def test_success_renames_and_marks(tmp_path) -> None:
    out = tmp_path / "run"
    with atomic_folder(out) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".run.partial-")
        (tmp / "a.txt").write_text("a")
        assert not out.exists()  # nothing at the target while writing
    assert (out / "a.txt").read_text() == "a" and (out / MARKER_NAME).is_file()
    assert written_by_us(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, RuntimeError])
def test_interrupted_write_leaves_the_old_folder_and_no_partial(tmp_path, interrupt) -> None:
    out = tmp_path / "run"
    with atomic_folder(out) as tmp:
        (tmp / "old.txt").write_text("old")
    with pytest.raises(interrupt), atomic_folder(out, overwrite=True) as tmp:
        (tmp / "new.txt").write_text("half")
        raise interrupt()
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER_NAME, "old.txt"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_overwrite_replaces_only_our_folders(tmp_path) -> None:
    ours = tmp_path / "ours"
    with atomic_folder(ours) as tmp:
        (tmp / "stale.txt").write_text("stale")
    with pytest.raises(OutputError, match=r"already exists \(pass --overwrite"):
        check_output(ours, overwrite=False)
    with atomic_folder(ours, overwrite=True) as tmp:
        (tmp / "fresh.txt").write_text("fresh")
    assert not (ours / "stale.txt").exists() and (ours / "fresh.txt").is_file()  # no merge
    user = tmp_path / "user"
    user.mkdir()
    (user / "thesis.tex").write_text("precious")
    with pytest.raises(OutputError, match="was not written by graph-slam"):
        check_output(user, overwrite=True)
    assert (user / "thesis.tex").read_text() == "precious"
    empty = tmp_path / "empty"
    empty.mkdir()
    check_output(empty, overwrite=False)  # an empty folder is fine


def test_stale_partial_of_a_killed_run_is_removed(tmp_path) -> None:
    stale = tmp_path / ".run.partial-999999"
    stale.mkdir()
    (stale / "x").write_text("x")
    with atomic_folder(tmp_path / "run") as tmp:
        (tmp / "y").write_text("y")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_file_shaped_targets(tmp_path) -> None:
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output(f, overwrite=True)
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output(f / "deeper" / "out", overwrite=True)
    link = tmp_path / "link"
    link.symlink_to(tmp_path)
    with pytest.raises(OutputError, match="is a file"):
        check_output(link, overwrite=True)


def test_simulate_interrupted_leaves_nothing_and_keeps_the_old_session(tmp_path, monkeypatch):
    from graph_slam.sim import SimConfig, recording, simulate

    out = tmp_path / "s"
    with atomic_folder(out, session=True) as tmp:
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
