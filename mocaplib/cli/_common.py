"""Small helpers shared by the sub-commands (output formatting, input expansion)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import MocapError


def print_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NaN written as null)."""
    print(json.dumps(_clean(obj), indent=2, ensure_ascii=False))


def _clean(obj):
    if isinstance(obj, float):
        return None if obj != obj or obj in (float("inf"), float("-inf")) else obj
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return _clean(obj.item())
    return obj


def expand_inputs(inputs: list[str], *, suffix: str = ".c3d") -> list[Path]:
    """Files named directly plus files with ``suffix`` found (recursively, sorted) in folders."""
    files: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            files.extend(sorted(p for p in path.rglob("*") if p.suffix.lower() == suffix))
        elif path.exists():
            files.append(path)
        else:
            raise MocapError("no such file or folder", path=path,
                             hint="check the path; folders are searched for *.c3d")
    return files


def warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)
