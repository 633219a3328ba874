"""A library of fewer than 4 entries is valid without a control space: built from the shipped
samples with 1, 2 and 3 captures, ``validate`` exits 0 with a warning, ``query`` says there is
no control space and what to do, ``report`` renders without the control-space figures and
says why; no command shows a traceback."""

from __future__ import annotations

import pytest

from mocaplib.cli import main

#: Captures of the small libraries: a slow, a normal and a fast straight walk.
WALKS = ("walk_straight_slow", "walk_straight_normal", "walk_straight_fast")


@pytest.fixture(scope="module")
def small_libraries(sample_dir, tmp_path_factory):
    """Paths of the libraries of the first 1, 2 and 3 :data:`WALKS`, keyed by their size."""
    from mocaplib.build.settings import BuildSettings
    from mocaplib.build.workflow import process_capture
    from mocaplib.library.format import assemble_library

    settings = BuildSettings(static=str(sample_dir / "rest.c3d"), static_pose="neutral")
    entries = [e for name in WALKS
               for e in process_capture(sample_dir / f"{name}.c3d", settings).entries
               if e.chosen]
    assert len(entries) == len(WALKS)
    folder = tmp_path_factory.mktemp("small")
    return {n: assemble_library(entries[:n], settings=settings.to_dict()).write(
        folder / f"library{n}.json") for n in (1, 2, 3)}


@pytest.mark.parametrize("n", [1, 2, 3])
def test_validate_accepts_a_small_library_with_a_warning(small_libraries, n, capsys):
    path = small_libraries[n]
    assert main(["validate", str(path)]) == 0
    printed = capsys.readouterr()
    assert printed.out.strip() == f"{path}: valid (content checksum verified)"
    assert f"needs at least 4 entries with distinct velocities, got {n}" in printed.err
    assert "add captures" in printed.err and "Traceback" not in printed.err


@pytest.mark.parametrize("n", [1, 3])
def test_query_says_there_is_no_control_space(small_libraries, n, capsys):
    path = small_libraries[n]
    assert main(["query", str(path), "1.2", "0", "0"]) == 1
    error = capsys.readouterr().err
    assert f"{path}: no control space" in error and f"got {n}" in error
    assert "add captures" in error and "Traceback" not in error


def test_report_renders_without_the_control_space_and_says_why(small_libraries, tmp_path,
                                                               capsys):
    path = small_libraries[2]
    assert main(["report", str(path), "-o", str(tmp_path), "--no-opengl"]) == 0
    html = (tmp_path / f"{path.stem}-report.html").read_text()
    assert "no control space" in html and "needs at least 4 entries" in html
    assert "No 3-D view" in html
    assert "Traceback" not in capsys.readouterr().err
