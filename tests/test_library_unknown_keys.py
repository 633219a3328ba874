"""The rule for keys a reader does not know (docs/library-format.md, *Unknown keys*): open
objects take a later version's additions and readers ignore them; closed ones, whose keys a
reader computes with, refuse them; an unknown format_version is refused."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from mocaplib.errors import LibraryError
from mocaplib.library.document import FORMAT_VERSION, schema
from mocaplib.library.format import load_library, Library
from mocaplib.library.validation import validate_library

from test_library import with_poulaines

#: Where a later version may add a key (open objects), as functions of the document.
OPEN = {
    "the document": lambda d: d,
    "settings": lambda d: d["settings"],
    "fourier": lambda d: d["fourier"],
    "entries[1]": lambda d: d["entries"][1],
    "entries[1].pattern": lambda d: d["entries"][1]["pattern"],
    "entries[1].poulaine": lambda d: d["entries"][1]["poulaine"],
}
#: Objects whose keys enter what a reader computes: an unknown key there is refused.
CLOSED = {
    "skeleton": lambda d: d["skeleton"],
    "control_space": lambda d: d["control_space"],
    "entries[1].fourier": lambda d: d["entries"][1]["fourier"],
    "entries[1].root_drift": lambda d: d["entries"][1]["root_drift"],
    "entries[1].poulaine.left": lambda d: d["entries"][1]["poulaine"]["left"],
    "entries[1].qc": lambda d: d["entries"][1]["qc"],
    "entries[1].qc_waived": lambda d: d["entries"][1]["qc_waived"],
    "qc_thresholds": lambda d: d["qc_thresholds"],
}


def written(document: dict, tmp_path) -> str:
    """The document written with its checksum recomputed (a later mocaplib's file)."""
    path = tmp_path / "lib.json"
    Library(document).write(path)
    return path


@pytest.mark.parametrize("where", OPEN)
def test_a_later_versions_key_in_an_open_object_is_ignored(tmp_path, where):
    lib = with_poulaines()
    document = copy.deepcopy(lib.document)
    OPEN[where](document)["added_by_a_later_version"] = {"any": [1, "value"]}
    path = written(document, tmp_path)
    assert validate_library(path) == []
    read = load_library(path)
    assert [e.id for e in read.entries] == [e.id for e in lib.entries]
    t = np.linspace(0.0, 1.0, 7)
    np.testing.assert_array_equal(read.angles("capture01_c0", t), lib.angles("capture01_c0", t))
    assert read.poulaine("capture01_c0") is not None


@pytest.mark.parametrize("where", CLOSED)
def test_an_unknown_key_in_a_closed_object_is_refused(tmp_path, where):
    document = copy.deepcopy(with_poulaines().document)
    CLOSED[where](document)["added_by_a_later_version"] = 1.0
    path = written(document, tmp_path)
    problems = validate_library(path)
    assert problems and all(p.where.startswith(where) for p in problems), problems
    assert any("added_by_a_later_version" in p.message for p in problems), problems
    with pytest.raises(LibraryError, match="added_by_a_later_version"):
        load_library(path)


def test_pattern_parameters_stay_those_of_the_type(tmp_path):
    document = copy.deepcopy(with_poulaines().document)
    document["entries"][1]["pattern"]["parameters"]["added_by_a_later_version"] = 1.0
    path = written(document, tmp_path)
    assert [p.where for p in validate_library(path)] == ["entries[1].pattern.parameters"]


def test_an_unknown_format_version_is_refused(tmp_path):
    document = copy.deepcopy(with_poulaines().document)
    document["format_version"] = FORMAT_VERSION + 1
    path = written(document, tmp_path)
    assert [p.where for p in validate_library(path)] == ["format_version"]
    with pytest.raises(LibraryError, match="format_version"):
        load_library(path)


def test_the_schema_has_no_union_types():
    # Ajv's strict mode refuses "type": [...]; anyOf of single types says the same
    def types(node):
        if isinstance(node, dict):
            yield node.get("type")
            for value in node.values():
                yield from types(value)
        elif isinstance(node, list):
            for value in node:
                yield from types(value)

    assert not [t for t in types(schema()) if isinstance(t, list)]
