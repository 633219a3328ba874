"""The package's layout holds: imports run down the layers of pyproject.toml's import-linter
contract (``lint-imports``), and no module grows past what one reader takes in."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "mocaplib"
#: The most lines a module may hold: past it, it mixes concerns and is split by them.
MAX_MODULE_LINES = 600


def test_imports_run_down_the_layers_of_the_contract(monkeypatch, capsys):
    from importlinter.cli import lint_imports

    monkeypatch.chdir(REPO)
    code = lint_imports(config_filename=str(REPO / "pyproject.toml"), no_cache=True)
    out = capsys.readouterr().out
    assert code == 0, out
    assert "1 kept, 0 broken" in out


@pytest.mark.parametrize("module", sorted(PACKAGE.rglob("*.py")),
                         ids=lambda p: os.fspath(p.relative_to(PACKAGE)))
def test_no_module_is_longer_than_the_limit(module):
    lines = len(module.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_MODULE_LINES, f"{module.relative_to(REPO)}: {lines} lines: split it"
