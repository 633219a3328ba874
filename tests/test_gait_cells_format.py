"""The gait cells and their frontal tetrahedra as the library file stores them (format_version
5), how version-3 and -4 files are read, and who uses the cells: coverage, and the answer to a command no motion does.

On the JavaScript reader's fixture (js/test/fixtures/library.json, made by
make_fixtures.py): sixteen sample captures, walks, side-steps on the cone and four runs."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from mocaplib.cli import main
from mocaplib.gait.gaits import class_gait
from mocaplib.library.cells import onto_cone, to_frontal
from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.coverage import Envelope, coverage
from mocaplib.library.document import CHECKSUM_KEY, content_sha256, version_note
from mocaplib.library.format import load_library
from mocaplib.library.triangulation import delaunay_tetrahedra
from mocaplib.library.validation import validate_library

FIXTURE = Path(__file__).resolve().parents[1] / "js" / "test" / "fixtures" / "library.json"


@pytest.fixture(scope="module")
def document():
    return json.loads(FIXTURE.read_text(encoding="utf-8"))


def sealed(document: dict) -> dict:
    """The document with its checksum recomputed (a file mocaplib could have written)."""
    return {**document, CHECKSUM_KEY: content_sha256(document)}


def written(document: dict, tmp_path, name="library.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(sealed(document)), encoding="utf-8")
    return path


def as_version_3(document: dict) -> dict:
    """The document as a version-3 mocaplib wrote it: the tetrahedra of all the entries."""
    old = copy.deepcopy(document)
    old["format_version"] = 3
    stored = old["control_space"]["tetrahedra"]
    cs = ControlSpace.from_library(load_library(FIXTURE))
    old["control_space"]["tetrahedra"] = {"ids": stored["ids"],
                                          "simplices": cs.tri.simplices.tolist()}
    return old


def test_each_stored_tetrahedron_is_of_one_gait_and_the_hull_of_all_entries(document):
    stored = document["control_space"]["tetrahedra"]
    gait_of = {e["id"]: class_gait(e["locomotion_class"]) for e in document["entries"]}
    vertex_gaits = [{gait_of[stored["ids"][k]] for k in s} for s in stored["simplices"]]
    assert [g.pop() if len(g) == 1 else "mixed" for g in vertex_gaits] == stored["gaits"]
    assert stored["gaits"] == sorted(stored["gaits"], key=("walk", "run").index)  # walks first
    assert set(stored["gaits"]) == {"walk", "run"}
    scale = np.array(document["control_space"]["scale"])
    entries = {e["id"]: e for e in document["entries"]}
    x = np.array([[entries[i][k] for k in ("v", "omega", "v_l")] for i in stored["ids"]])
    hull = delaunay_tetrahedra(x / scale).convex_hull
    assert sorted(map(sorted, stored["hull"])) == sorted(map(sorted, hull.tolist()))


def test_the_stored_frontal_tetrahedra_are_each_cells_on_the_frontal_axes(document):
    stored = document["control_space"]["tetrahedra"]
    gait_of = {e["id"]: class_gait(e["locomotion_class"]) for e in document["entries"]}
    assert [{gait_of[stored["ids"][k]] for k in s} for s in stored["frontal_simplices"]] == [
        {g} for g in stored["frontal_gaits"]]
    assert set(stored["frontal_gaits"]) == {"walk", "run"}
    # the walk cell's frontal points: (sqrt(v² − v_l²), omega, v_l), side-steps on the cone
    entries = {e["id"]: e for e in document["entries"]}
    walks = [i for i, e in enumerate(stored["ids"]) if gait_of[e] == "walk"]
    x = np.array([[entries[stored["ids"][i]][k] for k in ("v", "omega", "v_l")] for i in walks])
    x = to_frontal(onto_cone(x)) / document["control_space"]["scale"]
    expected = np.array(walks)[delaunay_tetrahedra(x).simplices]
    got = [s for s, g in zip(stored["frontal_simplices"], stored["frontal_gaits"]) if g == "walk"]
    assert sorted(map(sorted, got)) == sorted(map(sorted, expected.tolist()))
    assert sorted(map(sorted, got)) != sorted(map(sorted, [   # not the cell's own tetrahedra
        s for s, g in zip(stored["simplices"], stored["gaits"]) if g == "walk"]))


@pytest.mark.parametrize("edit, message", [
    (lambda t: t["gaits"].__setitem__(0, "run"), "gaits are not"),
    (lambda t: t["hull"].pop(), "hull is not"),
    (lambda t: t.__setitem__("gaits", t["gaits"][1:]), "gaits are not"),
    (lambda t: t["frontal_simplices"].__setitem__(0, t["simplices"][0]),
     "frontal_simplices and frontal_gaits are not"),
])
def test_validation_finds_stored_cells_that_are_not_the_entries(document, edit, message):
    edited = copy.deepcopy(document)
    edit(edited["control_space"]["tetrahedra"])
    problems = [str(p) for p in validate_library(sealed(edited))]
    assert len(problems) == 1 and message in problems[0], problems


def test_a_version_3_file_validates_with_a_note_and_queries_as_version_4(document, tmp_path,
                                                                           capsys):
    old = as_version_3(document)
    path = written(old, tmp_path)
    assert validate_library(path) == []
    assert main(["validate", str(path)]) == 0
    said = capsys.readouterr().out
    assert "note: format_version 3" in said and "build the library again" in said
    assert version_note(document) is None
    # mocaplib query blends in the cells computed from the entries, whatever the file stores
    commands = np.array([[1.2, 0.0, 0.0], [1.75, 0.19, 0.0], [0.4, 0.0, 0.4], [3.0, 0.0, 0.0]])
    new, then = (ControlSpace.from_library(load_library(p)).query(commands)
                 for p in (FIXTURE, path))
    np.testing.assert_array_equal(new.entries, then.entries)
    assert list(new.gait) == list(then.gait) and then.clamped.tolist() == new.clamped.tolist()
    # a version-3 file holding the gait cells is not what version 3 means: rebuild
    mixed = copy.deepcopy(document)
    mixed["format_version"] = 3
    problems = [str(p) for p in validate_library(sealed(mixed))]
    assert len(problems) == 1 and "format_version 3: of all of them" in problems[0], problems


def test_a_command_faster_sideways_than_its_speed_is_told_why(tmp_path, capsys):
    assert main(["query", str(FIXTURE), "0.4", "0", "0.45"]) == 0
    said = capsys.readouterr().out
    assert "OUTSIDE" in said and "no motion moves faster sideways than its speed" in said
    assert "v̂ is the speed along the path and v̂_l its lateral part" in said
    assert "--axes frontal" in said
    cs = ControlSpace.from_library(load_library(FIXTURE))
    res = cs.query([0.4, 0.0, 0.45])
    assert "faster sideways" in cs.outside_text(res)
    assert cs.impossible_text([0.4, 0.0, 0.4]) is None     # a pure side-step is asked alright
    assert cs.impossible_text([0.4, 0.0, -0.41]) is not None


def test_coverage_counts_the_cells_not_the_gap_between_walks_and_runs():
    cs = ControlSpace.from_library(load_library(FIXTURE))
    gap = [1.75, 0.19, 0.0]
    res = cs.query(gap)
    assert res.inside[0] and res.clamped[0]           # served, clamped onto the walk cell
    assert not cs.contains(gap)[0]
    assert cs.contains([1.2, 0.0, 0.0])[0] and cs.contains([0.4, 0.0, 0.4])[0]
    # a box from the walks to the runs: the gap is not covered, the hull of all would say so
    box = Envelope.box({"v": (1.0, 3.0), "omega": (-0.1, 0.1), "v_l": (-0.05, 0.05)})
    cov = coverage(cs, box, n_grid=9)
    res = cs.query(cov.samples)
    np.testing.assert_array_equal(cov.samples_inside, res.inside & ~res.clamped)
    assert (res.clamped & ~cov.samples_inside).any()


def test_a_version_4_file_validates_with_a_note_and_queries_as_version_5(document, tmp_path,
                                                                           capsys):
    old = copy.deepcopy(document)
    old["format_version"] = 4
    for key in ("frontal_simplices", "frontal_gaits"):
        del old["control_space"]["tetrahedra"][key]
    path = written(old, tmp_path)
    assert validate_library(path) == []
    assert main(["validate", str(path)]) == 0
    said = capsys.readouterr().out
    assert "note: format_version 4" in said and "frontal tetrahedra" in said, said
    # mocaplib weighs in the frontal tetrahedra it computes from the entries
    commands = np.array([[1.2, 0.0, 0.0], [0.4, 0.0, 0.39], [0.4, 0.0, 0.4]])
    new, then = (ControlSpace.from_library(load_library(p)).query(commands)
                 for p in (FIXTURE, path))
    np.testing.assert_array_equal(new.entries, then.entries)
    np.testing.assert_allclose(new.weights, then.weights, atol=1e-15)
