"""Input hashes of a batch task: what it read (the session's bytes) and how (config, version).

A task's folder keeps :func:`task_hash` of its inputs; a re-run skips the task only when the
hash is the same, so a changed session file, a changed setting or a new graph_slam version
re-runs it.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from graph_slam._version import __version__
from graph_slam.session.atomic import MARKER_NAME

CHUNK_BYTES = 1 << 20


def session_fingerprint(path: str | Path) -> str:
    """BLAKE2b over every file of the session folder: its relative path, size and content.

    Content, not modification times: a session copied to a cluster's shared disk keeps its
    fingerprint. The cost is one read of the folder (~1 GB/s on a local disk).
    """
    root = Path(path)
    digest = hashlib.blake2b(digest_size=16)
    for file in sorted(p for p in root.rglob("*") if p.is_file() and p.name != MARKER_NAME):
        rel = file.relative_to(root).as_posix()
        digest.update(f"{rel}\0{file.stat().st_size}\0".encode())
        with file.open("rb") as fh:
            while chunk := fh.read(CHUNK_BYTES):
                digest.update(chunk)
    return digest.hexdigest()


def task_hash(session_fingerprint: str, resolved_config: dict[str, Any], extra: dict) -> str:
    """The hash a task's folder carries: session content, resolved config, graph_slam version
    and the task's other inputs (``extra``: the variant, what to produce)."""
    document = {
        "session": session_fingerprint,
        "config": resolved_config,
        "version": __version__,
        **extra,
    }
    text = json.dumps(document, sort_keys=True, separators=(",", ":"))
    return hashlib.blake2b(text.encode(), digest_size=16).hexdigest()
