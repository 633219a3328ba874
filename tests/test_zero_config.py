"""Builds without a protocol written by hand (:mod:`mocaplib.build.drafting`): the shipped
protocols hidden, the build drafts one per marker set from the labels and the motion, writes it
beside the library and gives the entries the shipped protocols give."""

from __future__ import annotations

import json

import pytest
from conftest import SHARED_C3D, real_files
from test_clusters import CLUSTER_PLAN

import mocaplib.markersets.matching as matching
from mocaplib.build.drafting import DRAFTS_FOLDER, draft_missing_protocols
from mocaplib.markersets.matching import needs_draft
from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.cli import main
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.protocols import FOLDERS_VARIABLE, list_protocols, load_protocol

#: Velocities of an entry built with a drafted protocol against the same capture's entry built
#: with the shipped one (m/s, rad/s): measured at most 0.0026 on the shared files; a draft that
#: put a shoulder or pelvis marker on another landmark moves them by centimetres per second.
VELOCITY_TOLERANCE = 0.01

def _user_protocols():
    return [name for name in list_protocols() if load_protocol(name).origin != "shipped"]


@pytest.fixture
def hidden_shipped(monkeypatch):
    """The shipped protocols hidden from protocol detection (the catalogue and the label names
    stay): a build sees the user folders' protocols only. The protocol folders are restored."""
    monkeypatch.setattr(matching, "list_protocols", _user_protocols)
    monkeypatch.setenv(FOLDERS_VARIABLE, "")


def _entries(library_path) -> dict:
    return {e["source_file"]: e for e in json.loads(library_path.read_text())["entries"]}


def _limit_warnings(result) -> dict:
    return {c.file: {w for w in c.warnings if "sits at a joint limit" in w}
            for c in result.captures}


@pytest.fixture(scope="module")
def shared_builds(tmp_path_factory):
    """The shared files built with the shipped protocols and with them hidden (drafted)."""
    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    out = tmp_path_factory.mktemp("zero_config")
    shipped = build_library([SHARED_C3D], BuildSettings(), progress=False)
    shipped.write(out / "shipped.json")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(matching, "list_protocols", _user_protocols)
        patch.setenv(FOLDERS_VARIABLE, "")
        drafted = build_library([SHARED_C3D], BuildSettings(), progress=False,
                                drafts_dir=out / DRAFTS_FOLDER)
    drafted.write(out / "drafted.json")
    return out, shipped, drafted


def _shared_names():
    return [p.relative_to(SHARED_C3D).as_posix() for p in real_files()]


@pytest.mark.parametrize("name", _shared_names() or ["(no shared files)"])
def test_a_drafted_protocol_gives_the_shipped_protocols_entry(shared_builds, shared_c3d, name):
    out, shipped, drafted = shared_builds
    file = (shared_c3d / name).name
    expected, got = _entries(out / "shipped.json"), _entries(out / "drafted.json")
    assert (file in got) == (file in expected), (name, sorted(got))
    if file in expected:
        for key in ("v", "omega", "v_l"):
            assert got[file][key] == pytest.approx(expected[file][key], abs=VELOCITY_TOLERANCE), \
                (name, key)
    # no joint reaches a limit that the shipped protocol's fit keeps off it
    assert _limit_warnings(drafted)[file] <= _limit_warnings(shipped)[file], name


def test_the_drafted_protocols_are_written_beside_the_library_and_recorded(shared_builds,
                                                                          shared_c3d):
    out, _, drafted = shared_builds
    recorded = json.loads((out / "drafted.json").read_text())["settings"]["drafted_protocols"]
    written = sorted((out / DRAFTS_FOLDER).glob("*.toml"))
    assert sorted(recorded) == [p.stem for p in written]
    assert len(written) == 15            # one per label set of the 17 files
    assert {load_protocol(p).origin for p in written} == {"drafted"}
    notes = "\n".join(drafted.notes)
    assert all(str(p) in notes for p in written)           # the build says what it drafted


def test_a_kept_draft_is_matched_again_not_redrafted(tmp_path, real_c3d, hidden_shipped):
    walk = real_c3d("motonms_unipd/Walking1.c3d")
    folder = tmp_path / DRAFTS_FOLDER
    planned, notes, drafted = draft_missing_protocols([walk], [BuildSettings()], folder)
    assert planned[0].protocol == drafted[next(iter(drafted))] and len(notes) == 1
    kept = folder / f"{next(iter(drafted))}.toml"
    kept.write_text(kept.read_text().replace("drafted = true", ""))    # the technician's
    again, notes, drafted = draft_missing_protocols([walk], [BuildSettings()], folder)
    assert (again[0].protocol, notes, drafted) == ("auto", [], {})
    assert matching.match_trial(read_c3d(walk)).protocol.path == str(kept)


def test_the_build_command_drafts_writes_and_says_so(tmp_path, real_c3d, hidden_shipped,
                                                     capsys):
    walk = real_c3d("motonms_unipd/Walking1.c3d")
    out = tmp_path / "lib.json"
    # one entry: a valid library without a control space (exit 0, a warning says why)
    assert main(["build", str(walk), "-o", str(out), "--no-cache", "-q", "--qc", "waive"]) == 0
    printed = capsys.readouterr().out
    (drafted,) = (out.parent / DRAFTS_FOLDER).glob("drafted_*.toml")
    assert f"drafted protocol {drafted.stem}" in printed and str(drafted) in printed
    assert json.loads(out.read_text())["settings"]["drafted_protocols"] == {
        drafted.stem: str(drafted)}


def test_a_shipped_protocol_that_serves_is_not_redrafted(real_c3d):
    match = matching.detect_protocol(read_c3d(real_c3d("motonms_unipd/Walking1.c3d")))
    assert not needs_draft(match) and needs_draft(None)


@pytest.fixture(scope="module")
def cluster_build(tmp_path_factory):
    """The synthetic cluster-set captures built with no static and no protocol given, the
    shipped protocols hidden (cluster_fullbody among them)."""
    folder = tmp_path_factory.mktemp("cluster_zero_config")
    plan = folder / "plan.toml"
    plan.write_text(CLUSTER_PLAN)
    assert main(["synth", str(plan), "-o", str(folder / "captures"), "-q"]) == 0
    captures = [folder / "captures" / f"{name}.c3d"
                for name in ("walk", "curve_left", "curve_right", "side_left")]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(matching, "list_protocols", _user_protocols)
        patch.setenv(FOLDERS_VARIABLE, "")
        result = build_library(captures, BuildSettings(), progress=False,
                               drafts_dir=folder / DRAFTS_FOLDER)
    result.write(folder / "library.json")
    return folder, result


@pytest.mark.parametrize("name", ["walk", "curve_left", "curve_right", "side_left"])
def test_a_cluster_set_without_static_builds_with_its_drafted_protocol(cluster_build, name):
    folder, result = cluster_build
    assert len(result.settings.statics) == 0
    entry = _entries(folder / "library.json").get(f"{name}.c3d")
    assert entry is not None, [c.no_entry for c in result.captures]
    truth = json.loads((folder / "captures" / f"{name}.truth.json").read_text())["command"]
    # the synthetic walker's commanded velocities; measured within 0.002 m/s (v), 0.0025
    # rad/s (omega) and 0.011 m/s (v_l, the curves' lateral drift)
    assert entry["v"] == pytest.approx(truth["speed"], abs=0.02)
    assert entry["omega"] == pytest.approx(truth["omega"], abs=0.02)
    assert entry["v_l"] == pytest.approx(truth["v_l"], abs=0.02)
