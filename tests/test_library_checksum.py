"""The library's content checksum: SHA-256 of the RFC 8785 (JCS) form of the document, which
any language recomputes; version-1 and -2 files keep the Python-printed checksum they carry."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import rfc8785

from mocaplib.library.document import CHECKSUM_KEY, checksum_status
from mocaplib.library.format import load_library
from mocaplib.library.validation import validate_library

from test_library import library


def independent_jcs_sha256(document: dict) -> str:
    """The documented procedure, with the RFC 8785 library alone."""
    content = {k: v for k, v in document.items() if k != CHECKSUM_KEY}
    return hashlib.sha256(rfc8785.dumps(content)).hexdigest()


def old_checksum(document: dict) -> str:
    """The checksum versions 1 and 2 carry, as their format page gave it: Python's json.dumps
    with sorted keys and no whitespace."""
    content = {k: v for k, v in document.items() if k != CHECKSUM_KEY}
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def numbers(value):
    """Every number of a JSON value, depth first."""
    if isinstance(value, dict):
        for item in value.values():
            yield from numbers(item)
    elif isinstance(value, list):
        for item in value:
            yield from numbers(item)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield value


def test_a_written_library_carries_the_jcs_checksum(tmp_path):
    path = library().write(tmp_path / "lib.json")
    document = json.loads(path.read_text())
    assert document[CHECKSUM_KEY] == independent_jcs_sha256(document)
    # the Python-printed form differs (the file holds 0.0, which JCS prints 0): the two
    # checksums are told apart, so the version must say which one a file carries
    assert old_checksum(document) != document[CHECKSUM_KEY]
    assert checksum_status(path) == "verified"


def test_every_number_written_survives_the_jcs_round_trip(tmp_path):
    # JCS prints numbers as ECMAScript does (shortest text that reads back as the double);
    # a number that came back different would make the checksum depend on the reader
    document = json.loads(library().write(tmp_path / "lib.json").read_text())
    values = list(numbers(document))
    assert len(values) > 1000
    for value in values:
        assert float(rfc8785.dumps(value)) == value, value
    assert json.loads(rfc8785.dumps(document)) == document


@pytest.mark.parametrize("version", [1, 2])
def test_a_version_1_or_2_library_keeps_its_python_printed_checksum(tmp_path, version):
    document = json.loads(library().write(tmp_path / "lib.json").read_text())
    document["format_version"] = version
    document[CHECKSUM_KEY] = old_checksum(document)
    old = tmp_path / "old.json"
    old.write_text(json.dumps(document, indent=1))
    assert validate_library(old) == [] and checksum_status(old) == "verified"
    assert len(load_library(old)) == 5
    # the version says which checksum: the JCS one in an old file is a mismatch
    document[CHECKSUM_KEY] = independent_jcs_sha256(document)
    old.write_text(json.dumps(document))
    assert [p.where for p in validate_library(old)] == [CHECKSUM_KEY]


def test_a_current_library_carrying_the_old_checksum_is_a_mismatch(tmp_path):
    document = json.loads(library().write(tmp_path / "lib.json").read_text())
    document[CHECKSUM_KEY] = old_checksum(document)
    assert checksum_status(document) == "mismatch"
    assert [p.where for p in validate_library(document)] == [CHECKSUM_KEY]


def test_content_jcs_cannot_hold_is_a_mismatch_not_a_crash():
    document = library().document
    document["settings"] = {"cutoff": float("nan")}
    assert checksum_status(document) == "mismatch"


#: A library written by the code before format version 3 (mocaplib at commit 940f32f: format
#: version 2, its checksum over Python's json.dumps), from ``[entry(i, n=1) for i in range(5)]``
#: of tests/test_library.py: a file as users hold them, not one rebuilt by this version.
VERSION_2_FILE = Path(__file__).parent / "data" / "library_v2.json"


def test_a_library_written_before_version_3_loads_validates_and_verifies(tmp_path):
    document = json.loads(VERSION_2_FILE.read_text(encoding="utf-8"))
    assert document["format_version"] == 2
    assert document[CHECKSUM_KEY] == old_checksum(document) != independent_jcs_sha256(document)
    assert checksum_status(VERSION_2_FILE) == "verified"
    assert validate_library(VERSION_2_FILE) == []
    lib = load_library(VERSION_2_FILE)
    assert len(lib) == 5 and lib.angles(lib.entries[0].id, [0.0, 0.5]).shape == (2, 32)
    # a value changed in it is found by the checksum its version carries
    edited = tmp_path / "edited.json"
    text = VERSION_2_FILE.read_text(encoding="utf-8")
    edited.write_text(text.replace('"T": 1.1', '"T": 1.1000001', 1), encoding="utf-8")
    assert checksum_status(edited) == "mismatch"
