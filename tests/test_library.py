"""The library file format: schema, determinism, atomic writes, validation, loading."""

from __future__ import annotations

import copy
import json
import math
import os

import numpy as np
import pandas as pd
import pytest

import mocaplib
from mocaplib import load_library
from mocaplib.errors import LibraryError, MocapError
from mocaplib.library import (QC_NAMES, Library, assemble_library, make_entry, schema,
                              validate_library)
from mocaplib.skeleton import DOF_NAMES, Skeleton

D = len(DOF_NAMES)
# Five velocity triples that span all three axes (affine rank 3).
TRIPLES = [(1.2, 0.0, 0.0), (0.6, 0.5, 0.0), (0.3, 0.0, 0.4), (0.8, -0.4, -0.2), (0.0, 1.0, 0.0)]


def entry(i: int, *, n: int = 3, v=None, omega=None, v_l=None, **overrides) -> dict:
    rng = np.random.default_rng(i)
    a = rng.normal(scale=0.3, size=(D, n + 1))
    b = rng.normal(scale=0.3, size=(D, n + 1))
    b[:, 0] = 0.0
    tv, tw, tl = TRIPLES[i % len(TRIPLES)]
    fields = dict(
        id=f"capture{i:02d}_c0", source_file=f"capture{i:02d}.c3d", source_sha256=f"{i:064x}",
        cycle_index=0, start_s=0.5, end_s=1.6, T=1.1,
        pattern={"type": "arc", "parameters": {"centre_m": [0.0, 2.0], "radius_m": 2.0},
                 "residual_m": 0.004, "arc_angle_rad": 0.7},
        v=tv if v is None else v, omega=tw if omega is None else omega,
        v_l=tl if v_l is None else v_l, v_f=0.9, a=a, b=b,
        root_drift={"dx_m": 1.3, "dy_m": 0.1, "dheading_rad": 0.2},
        qc={"marker_rms_m": 0.008, "marker_max_m": 0.02, "gap_fraction": 0.01,
            "event_quality": 1.0, "fourier_rms_rad": 0.003, "cycle_closure_rad": 0.02,
            "jerk_rms_rad_s3": 40.0},
        locomotion_class="curve_left",
        segment_lengths_m=Skeleton.from_height(1.75 + 0.01 * i).lengths)
    fields.update(overrides)
    return make_entry(**fields)


def library(n_entries: int = 5, **kwargs) -> Library:
    return assemble_library([entry(i) for i in range(n_entries)],
                            settings={"protocol": "auto"}, **kwargs)


def problems_of(doc: dict) -> list[str]:
    return [str(p) for p in validate_library(doc)]


def test_shipped_schema_is_a_valid_draft_2020_12_schema():
    from jsonschema import Draft202012Validator

    Draft202012Validator.check_schema(schema())
    assert schema()["$schema"].endswith("2020-12/schema")


def test_the_schema_requires_every_length_of_the_fixed_skeleton():
    # a reader rebuilds the skeleton from segment_lengths_m (`mocaplib query --bvh` does): a
    # library missing one must not validate (it did, then query failed)
    from mocaplib.skeleton import HEIGHT_PROPORTIONS

    assert set(schema()["$defs"]["segment_lengths"]["required"]) == set(HEIGHT_PROPORTIONS)
    doc = library().document
    del doc["skeleton"]["segment_lengths_m"]["ankle_height"]
    assert any("'ankle_height' is a required property" in p for p in problems_of(doc))


def test_round_trip_through_file_is_valid_and_byte_identical(tmp_path):
    lib = library()
    path = lib.write(tmp_path / "library.json")
    assert validate_library(path) == []
    loaded = load_library(path)
    assert loaded.to_json() == path.read_text(encoding="utf-8")
    assert loaded.document == lib.document


def test_same_entries_in_any_order_give_identical_bytes():
    entries = [entry(i) for i in range(5)]
    first = assemble_library(entries, settings={"b": 1, "a": 2}).to_json()
    second = assemble_library(entries[::-1], settings={"a": 2, "b": 1}).to_json()
    assert first == second


def test_floats_are_written_with_ten_significant_digits_and_nan_as_null():
    e = entry(0, v=0.1 + 0.2, v_l=float("nan"))
    assert e["v"] == 0.3  # 0.30000000000000004 rounded to 10 significant digits
    assert e["v_l"] is None
    text = assemble_library([e], settings={}).to_json()
    assert '"v": 0.3,' in text and '"v_l": null' in text
    assert "NaN" not in text and "Infinity" not in text


def test_unbounded_dof_range_is_null():
    doc = library().document
    i = doc["skeleton"]["dof_names"].index("pelvis_rotation")
    assert doc["skeleton"]["dof_ranges"][i] == [None, None]
    assert doc["skeleton"]["dof_units"][doc["skeleton"]["dof_names"].index("pelvis_tx")] == "m"


def test_atomic_write_failure_leaves_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = library().write(tmp_path / "library.json")
    before = path.read_bytes()

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(MocapError, match="No space left"):
        library(n_entries=4).write(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["library.json"]


def test_load_library_gives_a_dataframe_and_coefficient_arrays(tmp_path):
    entries = [entry(i, n=2 + i % 2) for i in range(5)]  # orders 2 and 3: padded to 3
    path = assemble_library(entries, settings={}).write(tmp_path / "lib.json")
    lib = load_library(path)
    table = lib.entries
    assert isinstance(table, pd.DataFrame)
    assert list(table.index) == sorted(e["id"] for e in entries)
    assert table.loc["capture02_c0", "v_l"] == 0.4
    assert table.loc["capture01_c0", "pattern_type"] == "arc"
    assert set(f"qc_{name}" for name in QC_NAMES) <= set(table.columns)
    assert lib.n_harmonics == 3
    assert repr(lib) == f"<Library 5 entries, {D} DOFs, N=3, mocaplib {mocaplib.__version__}>"
    a, b = lib.coefficient_arrays()
    assert a.shape == b.shape == (5, D, 4)
    a0, b0 = lib.coefficients("capture00_c0")
    # capture00 was fitted with N = 2: its third harmonic is zero padding; rounding to 10
    # significant digits changes a coefficient of size ~0.3 by at most ~1e-10.
    np.testing.assert_allclose(a0[:, :3], entries[0]["fourier"]["a"], atol=1e-9)
    assert (a0[:, 3] == 0).all() and (b0[:, 3] == 0).all()
    assert table.loc["capture00_c0", "fourier_n"] == 2


def test_angles_follow_the_documented_fourier_formula():
    lib = library()
    a, b = lib.coefficients("capture01_c0")
    T = 1.1
    t = np.array([0.0, 0.3, 0.77])
    expected = np.stack([a[:, 0] + sum(a[:, k] * math.cos(2 * math.pi * k * ti / T)
                                       + b[:, k] * math.sin(2 * math.pi * k * ti / T)
                                       for k in range(1, a.shape[1])) for ti in t])
    # Same formula evaluated two ways in float64: agreement to rounding error.
    np.testing.assert_allclose(lib.angles("capture01_c0", t), expected, atol=1e-12)
    np.testing.assert_allclose(lib.angles("capture01_c0", t + T), expected, atol=1e-12)


def test_load_library_rejects_non_libraries(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(LibraryError, match="not valid JSON"):
        load_library(bad)
    bad.write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(LibraryError, match="not a valid mocaplib library"):
        load_library(bad)
    with pytest.raises(LibraryError, match="cannot read"):
        load_library(tmp_path / "absent.json")


def test_unknown_entry_raises_with_the_ids():
    with pytest.raises(LibraryError, match="no entry 'nope'"):
        library().coefficients("nope")


def test_make_entry_rejects_bad_shapes_and_unknown_qc():
    with pytest.raises(LibraryError, match=r"shape \(D, N\+1\)"):
        entry(0, a=np.zeros((D, 3)), b=np.zeros((D, 4)))
    with pytest.raises(LibraryError, match="unknown QC metrics"):
        entry(0, qc={"smoothness": 1.0})


# --------------------------------------------------------------------------- validation
def broken(mutate) -> dict:
    doc = copy.deepcopy(library().document)
    mutate(doc)
    return doc


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: d["entries"][1].update(id=d["entries"][0]["id"]), "duplicate id"),
    (lambda d: d["entries"][0]["fourier"]["a"][3].__setitem__(1, None), "non-finite"),
    (lambda d: d["entries"][0]["fourier"]["b"].pop(), "must be 32 rows of 4"),
    (lambda d: d["entries"][0]["fourier"]["a"][0].append(0.0), "must be 32 rows of 4"),
    (lambda d: d["entries"][2]["fourier"]["b"][5].__setitem__(0, 0.1), r"b\[:, 0\] must be 0"),
    (lambda d: d["entries"][0]["fourier"].update(n=7), "fitted order 7 exceeds"),
    (lambda d: d["entries"][0].update(T=0.0), "period must be finite and > 0"),
    (lambda d: d["entries"][0].update(T=None), "period must be finite and > 0"),
    (lambda d: d["entries"][0].update(end_s=1.7), "end_s - start_s"),
    (lambda d: d["entries"][3].update(omega=None), "velocity is missing"),
    (lambda d: [e.update(v_l=0.0) for e in d["entries"]], "span only 2 dimension"),
    (lambda d: d["entries"].__delitem__(slice(3, None)), "needs at least 4"),
    (lambda d: d["entries"][0]["qc"].update(marker_rms_m=0.031), "marker_rms_m 0.031 > 0.02"),
    (lambda d: d["entries"][0]["qc"].update(fourier_rms_rad=None), "fourier_rms_rad is not fin"),
    (lambda d: d["entries"][0]["qc"].update(event_quality=0.3), "event_quality 0.3 < 0.5"),
    (lambda d: d["skeleton"]["dof_names"].__setitem__(1, "pelvis_tx"), "duplicate DOF names"),
    (lambda d: d["skeleton"]["dof_units"].pop(), "31 items for 32 DOFs"),
    (lambda d: d["entries"][0].update(source_sha256="xyz"), "schema: 'xyz' does not match"),
    (lambda d: d.pop("fourier"), "schema: 'fourier' is a required property"),
    (lambda d: d["entries"][0]["pattern"].update(type="spiral"), "schema: 'spiral' is not one"),
])
def test_validate_catches(mutate, expected):
    problems = problems_of(broken(mutate))
    assert any(__import__("re").search(expected, p) for p in problems), problems


def test_valid_library_has_no_problems_and_waiver_accepts_a_qc_failure():
    assert problems_of(library().document) == []
    doc = broken(lambda d: d["entries"][0]["qc"].update(marker_max_m=0.05))
    assert len(problems_of(doc)) == 1
    doc["entries"][0]["qc_waived"] = {"marker_max_m": "known occlusion of RTOE, checked by eye"}
    assert problems_of(doc) == []


def test_threshold_null_means_reported_only():
    doc = broken(lambda d: d["entries"][0]["qc"].update(jerk_rms_rad_s3=1e9))
    assert doc["qc_thresholds"]["jerk_rms_rad_s3"] is None
    assert problems_of(doc) == []


def test_validate_reports_unreadable_file(tmp_path):
    path = tmp_path / "x.json"
    path.write_bytes(b"\xff\xfe garbage")
    assert "not UTF-8" in str(validate_library(path)[0])
