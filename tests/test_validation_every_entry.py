"""Validation's rules checked over all the entries (or stored rows) at once find a problem
wherever it is: at the first, a middle and the last entry or row, with the message that names
it; rows and vertices stored in another order stay valid.

On the JavaScript reader's fixture (js/test/fixtures/library.json, made by make_fixtures.py):
sixteen sample captures, walks, side-steps and four runs, format_version 5."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from mocaplib.library.document import CHECKSUM_KEY, content_sha256
from mocaplib.library.entry import drift_displacement
from mocaplib.library.validation import TURN_SIGN_RATE, validate_library

FIXTURE = Path(__file__).resolve().parents[1] / "js" / "test" / "fixtures" / "library.json"
#: Where a problem is put: the first, a middle and the last entry (or row).
PLACES = {"first": 0, "middle": 0.5, "last": -1}


@pytest.fixture(scope="module")
def document():
    return json.loads(FIXTURE.read_text(encoding="utf-8"))


def problems_of(document: dict) -> list[str]:
    """The problems of ``document`` with its checksum recomputed (as a file mocaplib wrote)."""
    return [str(p) for p in validate_library({**document, CHECKSUM_KEY:
                                              content_sha256(document)})]


def index(rows: list, place: str) -> int:
    """The row of ``rows`` at ``place`` (:data:`PLACES`)."""
    at = PLACES[place]
    return int(at * len(rows)) if isinstance(at, float) else at % len(rows)


def test_the_fixture_is_valid(document):
    assert problems_of(document) == []


def test_stored_tetrahedra_in_another_order_are_the_same(document):
    edited = copy.deepcopy(document)
    stored = edited["control_space"]["tetrahedra"]
    # rows reversed (each with its gait), the vertices of each row turned
    stored["simplices"] = [s[1:] + s[:1] for s in reversed(stored["simplices"])]
    stored["gaits"] = stored["gaits"][::-1]
    stored["hull"] = [h[::-1] for h in reversed(stored["hull"])]
    assert problems_of(edited) == []


@pytest.mark.parametrize("place", PLACES)
@pytest.mark.parametrize("key, message", [
    ("simplices", "simplices and gaits are not the tetrahedra of these entries' gait cells"),
    ("hull", "hull is not the boundary of these entries' points"),
])
def test_a_stored_row_with_another_vertex_is_found(document, key, message, place):
    edited = copy.deepcopy(document)
    stored = edited["control_space"]["tetrahedra"]
    row = stored[key][index(stored[key], place)]
    row[0] = next(v for v in range(len(stored["ids"])) if v not in row)
    problems = problems_of(edited)
    assert len(problems) == 1 and message in problems[0], problems


@pytest.mark.parametrize("place", PLACES)
def test_a_stored_gait_changed_is_found(document, place):
    edited = copy.deepcopy(document)
    gaits = edited["control_space"]["tetrahedra"]["gaits"]
    k = index(gaits, place)
    gaits[k] = "walk" if gaits[k] == "run" else "run"
    problems = problems_of(edited)
    assert len(problems) == 1 and "simplices and gaits are not" in problems[0], problems


@pytest.mark.parametrize("place", PLACES)
def test_a_root_drift_displacement_edited_is_found(document, place):
    edited = copy.deepcopy(document)
    k = index(edited["entries"], place)
    edited["entries"][k]["root_drift"]["dy_m"] += 0.01
    problems = problems_of(edited)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"entries[{k}].root_drift: entry ")
    assert "the displacement does not follow from" in problems[0] and "dy_m" in problems[0]
    assert "dx_m" not in problems[0] and "dheading_rad" not in problems[0]


@pytest.mark.parametrize("place", PLACES)
def test_a_root_drift_turning_the_other_way_is_found(document, place):
    # among the entries that turn faster than the rate from which signs must agree
    turning = [i for i, e in enumerate(document["entries"]) if abs(e["omega"]) > TURN_SIGN_RATE]
    k = turning[index(turning, place)]
    edited = copy.deepcopy(document)
    entry = edited["entries"][k]
    entry["root_drift"]["omega_rad_s"] = -entry["omega"]
    entry["root_drift"].update(drift_displacement(entry["root_drift"], entry["T"]))
    problems = problems_of(edited)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"entries[{k}].root_drift.omega_rad_s: entry ")
    assert "turns the other way from the entry's omega" in problems[0]


@pytest.mark.parametrize("place", PLACES)
def test_a_mean_angle_outside_its_range_is_found(document, place):
    edited = copy.deepcopy(document)
    k = index(edited["entries"], place)
    d = edited["skeleton"]["dof_names"].index("trunk_flexion")   # range -40° to 90°
    edited["entries"][k]["fourier"]["a"][d][0] = 57.3       # 1 rad written in degrees
    problems = problems_of(edited)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"entries[{k}].fourier.a[{d}][0]: entry ")
    assert "lies outside its range" in problems[0] and "degrees stored as radians?" in problems[0]
