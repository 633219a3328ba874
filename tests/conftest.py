"""Shared fixtures: paths to the real C3D files (skipped cleanly when absent) and the samples."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_C3D = Path(os.environ.get("MOCAPLIB_SHARED_C3D", REPO.parent / "shared" / "data" / "c3d"))
SAMPLES = REPO / "sample_c3d"


def real_files() -> list[Path]:
    """All real C3D files, sorted; empty when the shared data is absent."""
    if not SHARED_C3D.is_dir():
        return []
    return sorted(SHARED_C3D.rglob("*.c3d"))


@pytest.fixture
def shared_c3d() -> Path:
    """The folder of real C3D files; the test is skipped when it is absent."""
    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    return SHARED_C3D


def real_file(relative: str) -> Path:
    """One real file by path relative to the shared folder; skips the test when absent."""
    path = SHARED_C3D / relative
    if not path.is_file():
        pytest.skip(f"real C3D file not found: {path}")
    return path


def plan_capture(name: str, height: float, folder: Path):
    """The sample plan's capture ``name`` for a subject ``height`` m tall (same seeds and marker
    placement, :meth:`mocaplib.synth.PlannedCapture.for_height`), written into ``folder`` as
    ``<name>_<height>.c3d``. Returns its path and the :class:`~mocaplib.synth.SynthCapture`."""
    from mocaplib.synth import write_capture
    from mocaplib.synth.plan import load_plan

    planned = next(c for c in load_plan(REPO / "protocols" / "paper_plan.toml").captures
                   if c.name == name)
    capture = planned.for_height(height).generate()
    return write_capture(capture, folder, f"{name}_{height:.2f}")[0], capture
