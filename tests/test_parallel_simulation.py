"""The demo's sessions simulated in worker processes (report.parallel.simulate_sessions) are
byte for byte (the creation time aside) the sessions simulated one after the other in this process, and the progress
adds up over them."""

from __future__ import annotations

import hashlib
from pathlib import Path

from graph_slam.report.parallel import simulate_sessions
from graph_slam.sim import SimConfig, simulate


def _digest(folder: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(folder.rglob("*")):
        if f.is_file() and not f.name.startswith(".") and f.name != "sim_config.yaml":
            h.update(f.relative_to(folder).as_posix().encode())
            data = f.read_bytes()
            if f.name == "session.yaml":  # its creation time is the one line that differs
                data = b"".join(x for x in data.splitlines(True) if b"created_utc" not in x)
            h.update(data)
    return h.hexdigest()


def test_sessions_simulated_in_workers_are_the_same_bytes(tmp_path: Path) -> None:
    common = dict(strides=1, seed=1, resolution="212x120", drops="bursty", quicklook=False)
    cfgs = [SimConfig(speed_m_s=speed, **common) for speed in (0.8, 1.4)]
    alone = [simulate(c, tmp_path / f"alone{i}").path for i, c in enumerate(cfgs)]
    seen: list[tuple[int, int]] = []
    pooled = simulate_sessions(
        cfgs, [tmp_path / "pool0", tmp_path / "pool1"], False, 2, lambda d, t: seen.append((d, t))
    )
    assert [Path(p).name for p in pooled] == ["pool0", "pool1"]
    assert [_digest(Path(p)) for p in pooled] == [_digest(Path(p)) for p in alone]
    done, total = seen[-1]
    assert done == total > 0 and all(d <= t for d, t in seen)
