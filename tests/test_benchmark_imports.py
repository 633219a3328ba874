"""The benchmark scripts import what the package has: every ``from mocaplib... import name`` in
``benchmarks/`` (also inside functions, which only run on a benchmark's own data) resolves."""

from __future__ import annotations

import ast
import importlib
import importlib.util

import pytest

from conftest import REPO

SCRIPTS = sorted((REPO / "benchmarks").glob("*.py"))


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_every_mocaplib_name_a_benchmark_imports_exists(script):
    tree = ast.parse(script.read_text(encoding="utf-8"))
    imports = [(node.module, alias.name) for node in ast.walk(tree)
               if isinstance(node, ast.ImportFrom) and node.level == 0
               and (node.module or "").split(".")[0] == "mocaplib" for alias in node.names]
    missing = [f"{module}.{name}" for module, name in imports
               if not hasattr(importlib.import_module(module), name)
               and importlib.util.find_spec(f"{module}.{name}") is None]
    assert not missing, f"{script.name} imports what mocaplib does not have: {missing}"
