"""evo (GPL-3) is imported only inside graph_slam/evaluation, and only lazily; rerun and
matplotlib are not imported by importing mapping, evaluation or viz."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _imports(tree: ast.AST) -> list[tuple[str, ast.AST]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.append((node.module, node))
    return out


def test_evo_only_in_evaluation_and_never_at_module_level():
    offenders = []
    for package in ("graph_slam", "kinematics"):
        for path in (ROOT / package).rglob("*.py"):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            top_level = {id(n) for n in tree.body}
            for name, node in _imports(tree):
                if name.split(".")[0] != "evo":
                    continue
                inside = path.is_relative_to(ROOT / "graph_slam" / "evaluation")
                if not inside or id(node) in top_level:
                    offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []


def test_importing_the_packages_loads_no_heavy_optional_library():
    code = (
        "import sys, graph_slam.terrain, graph_slam.evaluation, graph_slam.viz;"
        "print(sorted(m for m in ('evo', 'rerun', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
