"""LibraryEntry, the one definition of a library entry: its fields are the JSON Schema's entry
properties, and entries written by the build read back equal, from format versions 2 and 1."""

from __future__ import annotations

import copy
import json
import math
from dataclasses import MISSING, fields, replace

import numpy as np
import pytest

from mocaplib.library.entry import (EntryAnkle, EntryDrift, EntryFourier, EntryPattern, EntryPoulaine,
                            LibraryEntry)
from mocaplib.errors import LibraryError
from mocaplib.library.document import CHECKSUM_KEY, schema
from mocaplib.library.format import assemble_library, load_library
from mocaplib.library.validation import validate_library

#: What each record stores, in the schema (a path of keys from its root).
RECORDS = [
    (LibraryEntry, ("$defs", "entry")),
    (EntryPattern, ("$defs", "entry", "properties", "pattern")),
    (EntryFourier, ("$defs", "entry", "properties", "fourier")),
    (EntryDrift, ("$defs", "entry", "properties", "root_drift")),
    (EntryPoulaine, ("$defs", "poulaine")),
    (EntryAnkle, ("$defs", "ankle_path")),
]
#: Keys of the file that are no field: derived from one (``mirrored``: ``mirror_of`` is set).
DERIVED = {LibraryEntry: {"mirrored"}}
#: Versions-2 keys of an entry (docs/library-format.md, *Versions*): a version-1 file has none.
VERSION_2_KEYS = ("joint_shifts_m", "held_dofs", "dofs_at_limit", "poulaine", "right_toe_off_s",
                  "mirrored", "mirror_of", "mirror_method")


def _node(path: tuple[str, ...]) -> dict:
    node = schema()
    for key in path:
        node = node[key]
    return node


@pytest.mark.parametrize("record, path", RECORDS, ids=[r.__name__ for r, _ in RECORDS])
def test_the_fields_are_the_schema_properties_required_ones_without_a_default(record, path):
    node = _node(path)
    names = {f.name for f in fields(record)}
    assert names | DERIVED.get(record, set()) == set(node["properties"])
    assert all(isinstance(getattr(record, name, None), property)
               for name in DERIVED.get(record, ()))
    required = {f.name for f in fields(record)
                if f.default is MISSING and f.default_factory is MISSING}
    assert required == set(node["required"]) & names
    for f in fields(record):
        if f.name not in required:  # optional: absent reads as None, empty, or chosen's True
            default = f.default if f.default is not MISSING else f.default_factory()
            assert default in (None, {}, True), f.name


@pytest.fixture(scope="module")
def sample_library(sample_dir, tmp_path_factory):
    """A library of sample captures as `mocaplib build` writes it — a walk on a curve, a
    side-step and a turn on the spot, their every cycle and their mirror images cut from the
    captures (QC waived), and the session's static as a rest entry — with the series mirror image (`mocaplib mirror`) of its chosen
    walk cycle and a copy of that cycle given what a lab subject has and the synthetic walker
    has not (joint shifts, held DOFs, DOFs at a limit): every optional key of an entry occurs
    in it. The marker RMS limit is 0.1 mm, so that every entry waives it."""
    from mocaplib.gait.qc import DEFAULT_QC_THRESHOLDS
    from mocaplib.library.mirror import mirror_entry
    from mocaplib.library.phase import start_later
    from mocaplib.build.pipeline import build_library
    from mocaplib.build.settings import BuildSettings

    strict = {**DEFAULT_QC_THRESHOLDS, "marker_rms_m": 1e-4}
    settings = BuildSettings(static=str(sample_dir / "rest.c3d"), static_pose="neutral",
                             toe_off="lift", all_cycles=True, mirror=True, qc_policy="waive",
                             qc_thresholds=strict)
    captures = ("walk_curve_r2_left_normal", "side_left_normal", "turn_spot_left_normal", "rest")
    result = build_library([sample_dir / f"{name}.c3d" for name in captures], settings, jobs=2,
                   progress=False)
    assert result.ok, result.summary_text()
    library = result.library
    source = next(e for e in library.entries if e.chosen and not e.mirrored
                  and e.source_file.startswith("walk_curve"))
    series = mirror_entry(replace(source, id=source.id.replace("_c", "_s", 1)))
    lab = replace(source, id=source.id.replace("_c", "_lab_c", 1),
                  joint_shifts_m={"tibia_r": (0.012, -0.004, 0.0), "foot_l": (0.0, 0.01, 0.0)},
                  held_dofs={"ankle_inversion_r": 0.05}, dofs_at_limit={"knee_flexion_l": 0.02})
    # the same cycle cut from its right toe-off, as a build cuts one when fewer than two left
    # toe-offs are in view (the protocol's fallback_starts)
    fallback = start_later(replace(source, id=source.id.replace("_c", "_rto_c", 1)),
                           source.right_toe_off_s, cycle_start="right_toe_off",
                           left_toe_off_s=source.T - source.right_toe_off_s)
    library = assemble_library([*library.entries, series, lab, fallback],
                               settings=library.settings,
                               qc_thresholds=library.document["qc_thresholds"])
    path = library.write(tmp_path_factory.mktemp("entry") / "library.json")
    return library, path


@pytest.mark.slow
def test_the_sample_library_holds_every_kind_of_entry(sample_library):
    library, _ = sample_library
    entries = library.entries
    assert {e.mirror_method for e in entries} == {None, "capture", "series"}
    assert any(e.locomotion_class == "rest" and e.poulaine is None for e in entries)
    assert all(e.qc_waived for e in entries) and any(not e.chosen for e in entries)
    assert all(e.fourier.ramp is not None for e in entries)
    every_key = set().union(*(e.to_json() for e in entries))
    assert every_key == set(_node(("$defs", "entry", "properties")))
    assert validate_library(library) == []  # the waived QC failures keep it valid


@pytest.mark.slow
def test_each_entry_is_the_file_s_json_and_reads_back_equal(sample_library):
    library, path = sample_library
    document = json.loads(path.read_text(encoding="utf-8"))
    assert len(library.entries) == len(document["entries"]) >= 7
    for entry, data in zip(library.entries, document["entries"]):
        assert entry.to_json() == data, entry.id        # the file's entry, key for key
        assert LibraryEntry.from_json(entry.to_json()) == entry
    assert load_library(path).entries == library.entries


@pytest.mark.slow
def test_equal_means_every_value_equal(sample_library):
    library, _ = sample_library
    entry = library.entries[0]
    assert LibraryEntry.from_json(copy.deepcopy(entry.to_json())) == entry
    data = entry.to_json()
    data["fourier"]["a"][3][1] += 1e-9
    assert LibraryEntry.from_json(data) != entry
    ankle = next(e for e in library.entries if e.poulaine is not None).to_json()
    changed = copy.deepcopy(ankle)
    changed["poulaine"]["left"]["points_m"][2][0] += 1e-9
    assert LibraryEntry.from_json(changed) != LibraryEntry.from_json(ankle)
    assert replace(entry, qc={**entry.qc, "marker_rms_m": 0.5}) != entry


@pytest.mark.slow
def test_a_version_1_library_still_reads(sample_library, tmp_path):
    library, path = sample_library
    document = json.loads(path.read_text(encoding="utf-8"))
    document["format_version"] = 1
    del document[CHECKSUM_KEY]
    del document["skeleton"]["joint_shifts_m"]
    del document["control_space"]["tetrahedra"]
    document["entries"] = [e for e in document["entries"] if not e.get("mirrored")]
    for e in document["entries"]:       # no waivers: the thresholds are version 1's defaults
        e["qc_waived"] = {}
    document["qc_thresholds"] = document["settings"]["qc_thresholds"] = {
        name: limit for name, limit in document["qc_thresholds"].items()
        if name != "internal_power_w_kg"} | {"marker_rms_m": 0.02}
    for e in document["entries"]:
        for key in VERSION_2_KEYS:
            e.pop(key, None)
        e["fourier"].pop("ramp")
        e["qc"].pop("internal_power_w_kg")
    old = tmp_path / "old.json"
    old.write_text(json.dumps(document), encoding="utf-8")
    assert validate_library(old) == []
    entries = load_library(old).entries
    assert [e.to_json() for e in entries] == document["entries"]
    for e in entries:
        assert (e.poulaine, e.right_toe_off_s, e.mirror_of, e.fourier.ramp) == (None,) * 4
        assert (e.joint_shifts_m, e.held_dofs, e.dofs_at_limit) == ({}, {}, {})
        assert not e.mirrored and "internal_power_w_kg" not in e.qc
    no_chosen = {k: v for k, v in document["entries"][0].items() if k != "chosen"}
    assert LibraryEntry.from_json(no_chosen).chosen is True


@pytest.mark.slow
def test_an_entry_that_is_not_one_is_refused_naming_it(sample_library):
    library, _ = sample_library
    data = library.entries[0].to_json()
    name = f"entry {data['id']}"
    # an entry is an open object (a later version's key is left out), but a key it needs is not
    with pytest.raises(LibraryError, match=f"{name}: missing keys T"):
        LibraryEntry.from_json({**{k: v for k, v in data.items() if k != "T"}, "speed": 1.0})
    with pytest.raises(LibraryError, match=f"{name}.root_drift: missing keys dx_m"):
        LibraryEntry.from_json({**data, "root_drift": {k: v for k, v in data["root_drift"]
                                                        .items() if k != "dx_m"}})
    with pytest.raises(LibraryError, match="mirrored is True but mirror_of is None"):
        LibraryEntry.from_json({**data, "mirrored": True})
    with pytest.raises(LibraryError, match="needs both mirror_of and mirror_method"):
        LibraryEntry.from_json({**data, "mirrored": True, "mirror_of": "x_c0"})
    with pytest.raises(LibraryError, match="unknown QC metrics"):
        replace(library.entries[0], qc={"smoothness": 1.0})
    with pytest.raises(LibraryError, match=r"shape \(D, N\+1\)"):
        EntryFourier.of(np.zeros((3, 4)), np.zeros((3, 5)))


@pytest.mark.slow
def test_the_writer_rounds_to_ten_digits_what_the_entry_holds_in_full(sample_library):
    library, _ = sample_library
    entry = library.entries[0]
    precise = replace(entry, v=math.pi)
    assert precise.to_json()["v"] == math.pi                    # the entry: full precision
    written = assemble_library([precise], settings={}).entries[0]
    assert written.v == 3.141592654                             # the file: 10 digits
