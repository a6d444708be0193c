"""Helpers of the adapter tests: hashing a source tree, the real TUM fr1/xyz stamps."""

from __future__ import annotations

import hashlib
from pathlib import Path

#: The first 10 rows of TUM RGB-D freiburg1_xyz rgb.txt and depth.txt (published timestamps;
#: Sturm et al., IROS 2012, CC BY 4.0). See tests/data/tum_fr1_xyz_mini/ATTRIBUTION.md for the
#: assumption that the shared copy's depth file N is row N of depth.txt.
FR1_XYZ_RGB_STAMPS = (
    "1305031102.175304", "1305031102.211214", "1305031102.243211", "1305031102.275326",
    "1305031102.311267", "1305031102.343233", "1305031102.375329", "1305031102.411258",
    "1305031102.443271", "1305031102.475318",
)  # fmt: skip
FR1_XYZ_DEPTH_STAMPS = (
    "1305031102.160407", "1305031102.194330", "1305031102.226738", "1305031102.262886",
    "1305031102.295279", "1305031102.329195", "1305031102.363013", "1305031102.394772",
    "1305031102.427815", "1305031102.462395",
)  # fmt: skip


def tree_digest(path: Path) -> str:
    """SHA-256 over every file's relative path, mode and bytes (a file or a folder)."""
    digest = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    for file in files:
        digest.update(str(file.relative_to(path.parent if path.is_file() else path)).encode())
        digest.update(oct(file.stat().st_mode).encode())
        digest.update(file.read_bytes())
    if path.is_dir():
        digest.update("\n".join(sorted(str(p.relative_to(path)) for p in path.rglob("*"))).encode())
    return digest.hexdigest()
