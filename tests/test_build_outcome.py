"""What `mocaplib build` leaves behind and its exit code when captures fail or the library it
writes has no control space; the frame numbering the entries keep."""

from __future__ import annotations

import json

import pytest

from mocaplib.build import pipeline
from mocaplib.cli import main
from mocaplib.errors import LibraryError
from mocaplib.library.format import load_library
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import process_capture
from conftest import SAMPLES
from test_pipeline import TRIPLES, fake_process, write_captures


@pytest.fixture
def fake_build(monkeypatch):
    monkeypatch.setattr(pipeline, "process_capture", fake_process)


def test_a_build_where_every_capture_fails_replaces_nothing(tmp_path, fake_build, capsys):
    good, bad = tmp_path / "good", tmp_path / "bad"
    write_captures(good)
    out = tmp_path / "lib.json"
    assert main(["build", str(good), "-o", str(out), "--no-cache", "-q"]) == 0
    before = out.read_bytes(), out.with_name("lib.diagnostics.json").read_bytes()
    bad.mkdir()
    (bad / "broken.c3d").write_text(json.dumps({"fail": "truncated"}))
    capsys.readouterr()
    assert main(["build", str(bad), "-o", str(out), "--no-cache", "-q"]) == 1
    printed = capsys.readouterr()
    assert "broken.c3d [import]" in printed.out  # the summary still says why
    assert f"{out}: nothing written: every capture failed" in printed.err
    assert "left as it was" in printed.err
    assert (out.read_bytes(), out.with_name("lib.diagnostics.json").read_bytes()) == before
    fresh = tmp_path / "new" / "lib.json"
    fresh.parent.mkdir()
    assert main(["build", str(bad), "-o", str(fresh), "--no-cache", "-q"]) == 1
    assert not any(fresh.parent.iterdir())


def test_an_empty_library_is_never_written_from_python_either(tmp_path):
    (tmp_path / "dropped.c3d").write_text(json.dumps({"fail": "truncated"}))
    result = build_library([tmp_path / "dropped.c3d"], progress=False, process=fake_process)
    with pytest.raises(LibraryError, match="nothing written: every capture failed"):
        result.write(tmp_path / "lib.json")
    result.captures[0].ok = True  # the capture worked but no cycle was kept
    with pytest.raises(LibraryError, match="no capture gave a library entry"):
        result.write(tmp_path / "lib.json")
    assert not list(tmp_path.glob("lib*"))


def test_a_library_without_a_control_space_is_valid_and_the_build_says_why(tmp_path,
                                                                           fake_build, capsys):
    write_captures(tmp_path / "caps", TRIPLES[:3])  # 3 entries: no 3-D control space
    out = tmp_path / "lib.json"
    assert main(["build", str(tmp_path / "caps"), "-o", str(out), "--no-cache", "-q"]) == 0
    printed = capsys.readouterr()
    assert "failed 0" in printed.out and len(load_library(out)) == 3
    assert (f"warning: {out}: no control space: the control space of the 3 chosen entries"
            in printed.err) and "add captures" in printed.err
    assert "not valid" not in printed.err
    assert main(["validate", str(out)]) == 0


@pytest.mark.usefixtures("sample_dir")
def test_entries_keep_the_capture_frame_rate_and_first_frame(tmp_path):
    # start_s counts from the capture's first frame: with rate_hz and first_frame a reader
    # finds the C3D frame (HC030A05.c3d starts at frame 286, 2.85 s on the lab clock)
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    source = SAMPLES / "walk_straight_normal.c3d"
    trial = read_c3d(source)
    path = write_c3d(tmp_path / "late.c3d", trial.markers, trial.labels, trial.rate,
                     first_frame=286)
    entries = process_capture(path, BuildSettings(all_cycles=True)).entries
    assert entries and all(e.first_frame == 286 and e.rate_hz == trial.rate
                           for e in entries)
