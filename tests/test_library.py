"""The library file format: schema, determinism, atomic writes, validation, loading."""

from __future__ import annotations

import copy
import gc
import json
import math
import os
import re

import numpy as np
import pandas as pd
import pytest

import mocaplib
import mocaplib.cli
from mocaplib import load_library
from mocaplib.errors import LibraryError, MocapError
from mocaplib.library.document import CHECKSUM_KEY, checksum_status, schema
from mocaplib.library.format import Library, assemble_library
from mocaplib.library.validation import control_space_warning, validate_library
from mocaplib.gait.qc import QC_NAMES
from mocaplib.skeleton import DOF_NAMES, Skeleton

from entries import plain_entry

D = len(DOF_NAMES)
# Five velocity triples that span all three axes (affine rank 3).
TRIPLES = [(1.2, 0.0, 0.0), (0.6, 0.5, 0.0), (0.3, 0.0, 0.4), (0.8, -0.4, -0.2), (0.0, 1.0, 0.0)]


def entry(i: int, *, n: int = 3, v=None, omega=None, v_l=None, **overrides) -> dict:
    rng = np.random.default_rng(i)
    a = rng.normal(scale=0.3, size=(D, n + 1))
    a[:, 0] = rng.uniform(-0.1, 0.1, D)  # mean poses within every DOF's range
    b = rng.normal(scale=0.3, size=(D, n + 1))
    b[:, 0] = 0.0
    tv, tw, tl = TRIPLES[i % len(TRIPLES)]
    fields = dict(
        id=f"capture{i:02d}_c0", source_file=f"capture{i:02d}.c3d", source_sha256=f"{i:064x}",
        cycle_index=0, start_s=0.5, end_s=1.6, T=1.1,
        pattern={"type": "arc", "parameters": {"centre": [0.0, 2.0], "radius": 2.0,
                                               "turn": 1, "length": 1.4},
                 "residual_m": 0.004, "arc_angle_rad": 0.7},
        v=tv if v is None else v, omega=tw if omega is None else omega,
        v_l=tl if v_l is None else v_l, v_f=0.9, a=a, b=b,
        root_drift={"u_f_m_s": 1.2, "u_l_m_s": 0.1, "omega_rad_s": tw if omega is None else omega},
        qc={"marker_rms_m": 0.008, "marker_max_m": 0.02, "gap_fraction": 0.01,
            "event_quality": 1.0, "fourier_rms_rad": 0.003, "cycle_closure_rad": 0.02,
            "jerk_rms_rad_s3": 40.0},
        locomotion_class="curve_left",
        segment_lengths_m=Skeleton.from_height(1.75 + 0.01 * i).lengths)
    fields.update(overrides)
    return plain_entry(**fields)


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
    lib = assemble_library([entry(0, v=0.1 + 0.2, v_l=float("nan"))], settings={})
    (e,) = lib.entries
    assert e.v == 0.3  # 0.30000000000000004 rounded to 10 significant digits
    assert e.v_l is None
    text = lib.to_json()
    assert '"v": 0.3,' in text and '"v_l": null' in text
    assert "NaN" not in text and "Infinity" not in text


def test_unbounded_dof_range_is_null():
    # the root's position has no range: written as null (unbounded), as the doc says, not as
    # the solver's internal guard [-1000, 1000]
    doc = library().document
    names, ranges = doc["skeleton"]["dof_names"], doc["skeleton"]["dof_ranges"]
    for name in ("pelvis_rotation", "pelvis_tx", "pelvis_ty", "pelvis_tz"):
        assert ranges[names.index(name)] == [None, None]
    assert ranges[names.index("knee_flexion_r")] == pytest.approx([-0.1745329252, 2.617993878])
    assert doc["skeleton"]["dof_units"][names.index("pelvis_tx")] == "m"


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
    table = lib.table
    assert isinstance(table, pd.DataFrame)
    assert list(table.index) == sorted(e.id for e in entries)
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
    np.testing.assert_allclose(a0[:, :3], entries[0].fourier.a, atol=1e-9)
    assert (a0[:, 3] == 0).all() and (b0[:, 3] == 0).all()
    assert table.loc["capture00_c0", "fourier_n"] == 2


def documented_formula(a, b, ramp, T, t):
    """q_d(t) of docs/library-format.md, term by term: tau = t mod T in [0, T), the series at
    tau plus ramp_d·tau/T."""
    tau = t % T
    return np.stack([a[:, 0] + sum(a[:, k] * math.cos(2 * math.pi * k * ti / T)
                                   + b[:, k] * math.sin(2 * math.pi * k * ti / T)
                                   for k in range(1, a.shape[1])) + ramp * ti / T
                     for ti in tau])


def with_ramps() -> Library:
    ramp = np.linspace(-0.02, 0.03, D)                 # rad (m for pelvis_tz), 1.7° at most
    ramp[[0, 1, 3]] = 0.0                              # the root's horizontal pose: the drift's
    return assemble_library([entry(i, ramp=ramp) for i in range(5)], settings={})


def test_angles_follow_the_documented_fourier_formula_with_the_ramp():
    lib = with_ramps()
    a, b = lib.coefficients("capture01_c0")
    ramp = lib.entry("capture01_c0").fourier.ramp
    assert np.abs(ramp).max() > 0.02
    T = 1.1
    t = np.array([0.0, 0.3, 0.77, 1.0999, 1.1 + 0.3, -0.8, 5 * 1.1 + 0.77])
    # the same formula evaluated two ways in float64: agreement to rounding error
    np.testing.assert_allclose(lib.angles("capture01_c0", t),
                               documented_formula(a, b, ramp, T, t), atol=1e-12)
    # without the ramp the formula is another one (what the page's sketch gave)
    assert np.abs(lib.angles("capture01_c0", t)
                  - documented_formula(a, b, 0 * ramp, T, t)).max() > 0.02


def test_angles_are_periodic_on_0_to_T_and_the_ramp_restarts_each_cycle():
    lib = with_ramps()
    ramp = lib.entry("capture01_c0").fourier.ramp
    T = 1.1
    t = np.linspace(0.0, T, 50, endpoint=False)
    one = lib.angles("capture01_c0", t)
    for k in (1, 2, -1, 7):
        np.testing.assert_allclose(lib.angles("capture01_c0", t + k * T), one, atol=1e-12)
    # at T the next cycle starts: q(0); just before, q(0) + ramp (the captured end)
    q0, end, at_T = lib.angles("capture01_c0", np.array([0.0, T - 1e-9, T]))
    np.testing.assert_allclose(at_T, q0, rtol=0, atol=1e-15)   # tau = 0 both: BLAS rounding
    np.testing.assert_allclose(end, q0 + ramp, atol=1e-7)   # the series' slope × 1e-9 s
    # a t rounding to T under mod stays in [0, T): the start, not the captured end
    np.testing.assert_allclose(lib.angles("capture01_c0", np.array([-1e-300]))[0], q0,
                               rtol=0, atol=1e-15)


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


def test_an_entry_refuses_bad_shapes_and_unknown_qc():
    with pytest.raises(LibraryError, match=r"shape \(D, N\+1\)"):
        entry(0, a=np.zeros((D, 3)), b=np.zeros((D, 4)))
    with pytest.raises(LibraryError, match="unknown QC metrics"):
        entry(0, qc={"smoothness": 1.0})


# --------------------------------------------------------------------------- validation
def broken(mutate) -> dict:
    """A library document changed by ``mutate``, without its checksum (which any change
    breaks: tested on its own), so that each rule below is seen alone."""
    doc = copy.deepcopy(library().document)
    del doc[CHECKSUM_KEY]
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
    # a degenerate control space is valid (a warning), tetrahedra stored for one are not
    (lambda d: [e.update(v_l=0.0) for e in d["entries"]], "tetrahedra are stored but the "
                                                          "chosen entries span no 3-D"),
    (lambda d: d["entries"].__delitem__(slice(3, None)), "tetrahedra are stored but"),
    (lambda d: d["entries"][0]["qc"].update(marker_rms_m=0.031), "marker_rms_m 0.031 > 0.02"),
    (lambda d: d["entries"][0]["qc"].update(fourier_rms_rad=None), "fourier_rms_rad is not fin"),
    (lambda d: d["entries"][0]["qc"].update(event_quality=0.3), "event_quality 0.3 < 0.5"),
    (lambda d: d["skeleton"]["dof_names"].__setitem__(1, "pelvis_tx"), "duplicate DOF names"),
    (lambda d: d["skeleton"]["dof_units"].pop(), "31 items for 32 DOFs"),
    (lambda d: d["skeleton"]["segment_lengths_m"].update(thigh=1e30),
     r"skeleton\.segment_lengths_m\.thigh: segment length 1e\+30 m is no person's \(a "
     r"segment is 1 mm to 2 m long\)"),
    (lambda d: d["entries"][0].update(segment_lengths_m={**d["skeleton"]["segment_lengths_m"],
                                                         "shank": 1e-4}),
     r"entries\[0\]\.segment_lengths_m\.shank: entry '.*': segment length 0\.0001 m"),
    (lambda d: d["skeleton"].update(joint_shifts_m={"femur_l": [0.0, 0.0, 1e30]}),
     r"skeleton\.joint_shifts_m\.femur_l: joint shift \[0\.0, 0\.0, 1e\+30\] m is no person's"),
    (lambda d: d["entries"][0].update(source_sha256="xyz"), "schema: 'xyz' does not match"),
    (lambda d: d.pop("fourier"), "schema: 'fourier' is a required property"),
    (lambda d: d["entries"][0]["pattern"].update(type="spiral"), "schema: 'spiral' is not one"),
])
def test_validate_catches(mutate, expected):
    problems = problems_of(broken(mutate))
    assert any(re.search(expected, p) for p in problems), problems


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


# --------------------------------------------------------------------------- semantic checks
def test_the_entry_drift_derives_its_displacement_from_its_velocities():
    from mocaplib.library.entry import EntryDrift
    from mocaplib.gait.fourier import RootDrift

    e = entry(1)  # u_f 1.2, u_l 0.1, omega 0.5 rad/s over T 1.1 s
    x, y, turned = RootDrift(0.0, 0.0, 0.0, 1.2, 0.1, 0.5).frame(1.1)
    assert e.root_drift.to_json() == pytest.approx({
        "dx_m": x, "dy_m": y, "dheading_rad": turned, "u_f_m_s": 1.2, "u_l_m_s": 0.1,
        "omega_rad_s": 0.5})
    assert e.root_drift.dheading_rad == pytest.approx(0.55)
    with pytest.raises(LibraryError, match="missing keys u_f_m_s, u_l_m_s, omega_rad_s"):
        EntryDrift.from_json({"dx_m": 1.3, "dy_m": 0.1, "dheading_rad": 0.2})


def test_entries_keep_the_capture_frame_numbering_when_given():
    e = entry(0, rate_hz=100.0, first_frame=286)
    assert (e.to_json()["rate_hz"], e.to_json()["first_frame"]) == (100.0, 286)
    assert "rate_hz" not in entry(0).to_json() and "first_frame" not in entry(0).to_json()
    lib = assemble_library([entry(i, rate_hz=100.0, first_frame=286) for i in range(5)],
                           settings={})
    assert problems_of(lib.document) == []
    assert problems_of(broken(lambda d: d["entries"][0].update(first_frame=-1)))


def arc(d) -> dict:
    return d["entries"][0]["pattern"]["parameters"]


def line_pattern(d):
    parameters = {"point": [0.0, 0.0], "direction": [0.6, 0.8], "length": 1.3}
    d["entries"][0]["pattern"] = {"type": "line", "parameters": parameters,
                                  "residual_m": 0.01, "arc_angle_rad": 0.0}


@pytest.mark.parametrize("mutate, expected", [
    # a reader truncating at fourier.n gets other angles
    (lambda d: d["entries"][0]["fourier"].update(n=1), r"harmonics beyond the fitted order n = 1"),
    (lambda d: d["entries"][0].update(cycle_index=4), "4, but the id names cycle 0"),
    (lambda d: d["entries"][1]["root_drift"].update(dheading_rad=1.0),
     r"dheading_rad 1, expected 0\.55"),
    (lambda d: d["entries"][1]["root_drift"].update(dx_m=5.0), "dx_m 5, expected"),
    (lambda d: d["entries"][1]["root_drift"].update(omega_rad_s=-0.5), "turns the other way"),
    (lambda d: d["entries"][1]["root_drift"].pop("u_f_m_s"), "'u_f_m_s' is a required"),
    (lambda d: d["entries"][1]["root_drift"].update(u_f_m_s=None), "None is not of type"),
    (lambda d: d["entries"][1]["root_drift"].update(dz_m=3.0), "'dz_m' was unexpected"),
    (lambda d: arc(d).pop("radius"), "parameters of arc patterns are centre, length, radius"),
    (lambda d: arc(d).update(radius="2 m"), "radius: .*must be a number of metres > 0"),
    (lambda d: arc(d).update(radius=-2.0), "radius: .*got -2.0"),
    (lambda d: arc(d).update(turn=0), "turn: .*must be 1"),
    (lambda d: arc(d).update(centre=[1.0]), r"centre: .*must be \[x, y\]"),
    (lambda d: d["entries"][0]["pattern"].update(type="line"), "parameters of line patterns"),
    (lambda d: (line_pattern(d), arc(d).update(direction=[1.0, 1.0])), "a unit vector"),
    (lambda d: d["entries"][0]["qc"].update(event_quality=2.0), "greater than the maximum of 1"),
    (lambda d: d["entries"][0]["qc"].update(gap_fraction=-0.3), "less than the minimum of 0"),
    (lambda d: d["qc_thresholds"].update(marker_rms_m=-1.0), "less than the minimum of 0"),
    (lambda d: d["entries"][0].update(v=-1.2), "less than the minimum of 0"),
    (lambda d: d["entries"][0].update(start_s=-99.5, end_s=-98.4), "less than the minimum"),
    (lambda d: d["skeleton"]["dof_ranges"].__setitem__(29, [2.6, -0.17]), "lower limit 2.6 > "),
    # a mean pose in degrees: knee_flexion_r 30 "rad"
    (lambda d: d["entries"][2]["fourier"]["a"][DOF_NAMES.index("knee_flexion_r")]
     .__setitem__(0, 30.0), re.escape("mean knee_flexion_r 30 rad (1718.9°, over the cycle "
                                      "after its start-to-end drift is taken out) lies outside "
                                      "its range [-0.1745, 2.618] rad ([-10.0°, 150.0°]): "
                                      "degrees stored as radians?")),
    # a mean just past the range, as a cycle that is not periodic gives: no unit slip
    (lambda d: d["entries"][2]["fourier"]["a"][DOF_NAMES.index("knee_flexion_r")]
     .__setitem__(0, 2.7), re.escape("mean knee_flexion_r 2.7 rad (154.7°, over the cycle "
                                     "after its start-to-end drift is taken out) lies outside "
                                     "its range [-0.1745, 2.618] rad ([-10.0°, 150.0°]): the "
                                     "cycle is not periodic")),
    (lambda d: d["entries"].reverse(), "entries must be sorted by id"),
    (lambda d: d["entries"][0].update(source_file="../../etc/passwd"), "without its folder"),
    # 1e-320 made normalised velocities overflow on the way to query's SVD
    (lambda d: d["control_space"]["scale"].__setitem__(0, 1e-320), "minimum of 0.001"),
    (lambda d: d["settings"].update(static_pose=42), "42 is not one of"),
    (lambda d: d["settings"].update(cutoff=-6), "cutoff"),
    (lambda d: d["settings"].update(static=["S1.c3d", 2]), "2 is not of type 'string'"),
])
def test_validate_catches_fields_that_disagree_or_leave_their_range(mutate, expected):
    problems = problems_of(broken(mutate))
    assert any(re.search(expected, p) for p in problems), problems


def test_problems_about_an_entry_name_it():
    doc = broken(lambda d: d["entries"][3]["root_drift"].pop("omega_rad_s"))
    assert problems_of(doc) == ["entries[3].root_drift: entry 'capture03_c0': schema: "
                                "'omega_rad_s' is a required property"]


def test_turn_signs_may_differ_on_a_nearly_straight_walk():
    # the shoulder line's and the pelvis' turn rates differ by up to 0.11 rad/s on real files
    doc = broken(lambda d: d["entries"][1]["root_drift"].update(omega_rad_s=-0.1))
    assert not any("turns the other way" in p for p in problems_of(doc))


def test_the_validator_is_silent_on_what_the_build_writes():
    # every check above holds on entries as assemble_library writes them, for every pattern
    # type and a waived metric
    line = {"type": "line", "parameters": {"point": [0.1, -0.2], "direction": [0.6, -0.8],
                                           "length": 1.3}, "residual_m": 0.01,
            "arc_angle_rad": 0.0}
    point = {"type": "point", "parameters": {"point": [0.0, 0.0], "length": 0.0},
             "residual_m": 0.0, "arc_angle_rad": 0.0}
    entries = [entry(0, pattern=line), entry(1, pattern=point),
               entry(2, cycle_index=3, id="capture02_c3"),
               entry(3, id="capture03_c0@0a1b2c3d"), entry(4)]
    assert problems_of(assemble_library(entries, settings={"static": None}).document) == []


# --------------------------------------------------------------------------- NaN, Infinity
def write_text(tmp_path, doc) -> os.PathLike:
    path = tmp_path / "lib.json"
    path.write_text(json.dumps(doc, allow_nan=True))  # NaN / Infinity tokens, as Python writes
    return path


@pytest.mark.parametrize("mutate, where, token", [
    (lambda d: d["entries"][0].update(start_s=float("nan")), "entries[0].start_s", "NaN"),
    (lambda d: d["entries"][0]["segment_lengths_m"].update(thigh=float("nan")),
     "entries[0].segment_lengths_m.thigh", "NaN"),
    (lambda d: d["qc_thresholds"].update(marker_rms_m=float("nan")), "qc_thresholds.marker_rms_m",
     "NaN"),
    (lambda d: d["control_space"]["scale"].__setitem__(0, float("nan")), "control_space.scale[0]",
     "NaN"),
    (lambda d: d["control_space"]["scale"].__setitem__(1, float("inf")), "control_space.scale[1]",
     "Infinity"),
    (lambda d: arc(d).update(radius=-float("inf")), "entries[0].pattern.parameters.radius",
     "-Infinity"),
])
def test_nan_and_infinity_are_refused_where_they_are(mutate, where, token, tmp_path):
    # json.loads took them; C++ and C# JSON readers refuse the file; a NaN scale crashed
    # validate (SVD did not converge)
    path = write_text(tmp_path, broken(mutate))
    assert token in path.read_text()
    problems = [str(p) for p in validate_library(path)]
    assert any(p.startswith(f"{where}: ") and f"{token} is not a JSON number" in p
               for p in problems), problems
    with pytest.raises(LibraryError, match=re.escape(where)):
        load_library(path)
    assert problems_of(broken(mutate))  # the same document in memory


# --------------------------------------------------------------------------- control space
def test_validation_and_the_control_space_use_the_chosen_entries():
    from mocaplib.library.controlspace import ControlSpace

    # --all-cycles: 3 chosen entries (one per capture) and 3 more cycles that span 3-D
    entries = [entry(i, chosen=i < 3) for i in range(6)]
    lib = assemble_library(entries, settings={})
    # valid without a control space: no tetrahedra stored, a warning saying why
    assert problems_of(lib.document) == [] and "tetrahedra" not in lib.document["control_space"]
    assert control_space_warning(lib) == (
        "no control space: the control space of the 3 chosen entries with finite velocities "
        "is degenerate: it needs at least 4 entries with distinct velocities, got 3; "
        "`mocaplib query` cannot blend commands and the report has no control-space figures; "
        "add captures with other speeds, turns and side-steps so the entries span all three "
        "axes")
    with pytest.raises(LibraryError, match="no control space: .*needs at least 4 entries with "
                                           "distinct velocities, got 3"):
        ControlSpace.from_library(lib)
    none_chosen = assemble_library([entry(i, chosen=False) for i in range(6)], settings={})
    assert problems_of(none_chosen.document) == []
    assert "got 0" in control_space_warning(none_chosen)
    assert control_space_warning(library()) is None


@pytest.mark.parametrize("thickness", [0.0, 1e-12, 1e-9, 1e-7, 1e-5, 1e-3])
def test_validation_warns_of_exactly_the_control_spaces_query_refuses(thickness):
    # the validator counted rank with 1e-6 of all entries, the control space with 1e-9 of the
    # chosen ones: a library 1e-7 thick passed one and not the other
    from mocaplib.library.controlspace import ControlSpace

    rng = np.random.default_rng(7)
    points = rng.uniform([0.0, -1.0, -0.3], [1.8, 1.0, 0.3], (8, 3))
    points[:, 2] = 0.25 * points[:, 0] + thickness * rng.choice([-1.0, 1.0], 8)
    doc = library(8).document
    for e, (v, w, vl) in zip(doc["entries"], points.tolist()):
        e.update(v=v, omega=w, v_l=vl)  # full precision: 10 digits would hide the thinnest
    doc["control_space"].pop("tetrahedra", None)  # those of the velocities replaced above
    lib = Library(doc)
    invalid = control_space_warning(lib) is not None
    assert not any(p.startswith("control_space") for p in problems_of(lib.document))
    try:
        ControlSpace.from_library(lib)
        refused = False
    except LibraryError:
        refused = True
    assert invalid == refused
    assert refused == (thickness < 1e-5)


def test_a_library_without_drift_is_an_error_not_a_walk_on_the_spot():
    # one entry without u_f_m_s made the whole library's root motion vanish at query time
    from mocaplib.library.controlspace import ControlSpace

    doc = copy.deepcopy(library().document)
    assert ControlSpace.from_library(Library(doc)).drift.shape == (5, 3)
    doc["entries"][2]["root_drift"]["u_f_m_s"] = None
    with pytest.raises(LibraryError, match="without a finite root_drift .*: capture02_c0"):
        ControlSpace.from_library(Library(doc))
    del doc["entries"][2]["root_drift"]["u_f_m_s"]
    with pytest.raises(LibraryError, match="entry capture02_c0.root_drift: missing keys "
                                           "u_f_m_s"):
        ControlSpace.from_library(Library(doc))


# --------------------------------------------------------------------------- integrity
def one_coefficient_changed(path) -> None:
    """Change one Fourier coefficient in the file's text, keeping it valid for the schema
    and every rule (an edit nobody can see)."""
    text = path.read_text()
    found = re.search(r'"a": \[\n\s*\[(-?[0-9.e-]+)', text)
    value = float(found.group(1))
    path.write_text(text[:found.start(1)] + repr(value + 1e-3) + text[found.end(1):])


def test_a_written_library_carries_a_checksum_that_validate_verifies(tmp_path):
    path = library().write(tmp_path / "lib.json")
    document = json.loads(path.read_text())
    assert re.fullmatch("[0-9a-f]{64}", document[CHECKSUM_KEY])
    assert checksum_status(path) == "verified" and validate_library(path) == []
    # reformatting keeps the content, and the checksum with it
    path.write_text(json.dumps(document, indent=7))
    assert checksum_status(path) == "verified" and validate_library(path) == []


def test_a_library_edited_by_hand_fails_validation_on_its_checksum(tmp_path, capsys):
    path = library().write(tmp_path / "lib.json")
    one_coefficient_changed(path)
    problems = validate_library(path)
    assert [p.where for p in problems] == [CHECKSUM_KEY]
    assert "changed after `mocaplib build` wrote it" in problems[0].message
    assert checksum_status(path) == "mismatch"
    assert load_library(path) is not None  # still readable: the values are usable, flagged
    assert mocaplib.cli.main(["validate", str(path)]) == 1
    assert "content_sha256: the content does not match" in capsys.readouterr().out
    assert mocaplib.cli.main(["validate", str(path), "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["checksum"] == "mismatch"


def test_a_skeleton_no_person_has_is_refused_even_with_a_matching_checksum(tmp_path, capsys):
    from mocaplib.library.document import content_sha256

    path = library().write(tmp_path / "lib.json")
    document = json.loads(path.read_text())
    document["skeleton"]["segment_lengths_m"] = {
        name: 1e30 for name in document["skeleton"]["segment_lengths_m"]}
    document[CHECKSUM_KEY] = content_sha256(document)
    path.write_text(json.dumps(document))
    assert mocaplib.cli.main(["validate", str(path)]) == 1
    printed = capsys.readouterr().out
    assert "14 problem(s)" in printed and "segment length 1e+30 m is no person's" in printed
    with pytest.raises(LibraryError, match="segment length 1e\\+30 m is no person's"):
        load_library(path)


def test_a_library_without_a_checksum_is_read_with_a_note(tmp_path, capsys):
    # libraries written before the checksum existed stay valid; validate says it cannot check
    path = library().write(tmp_path / "lib.json")
    document = json.loads(path.read_text())
    del document[CHECKSUM_KEY]
    path.write_text(json.dumps(document))
    assert validate_library(path) == [] and checksum_status(path) == "absent"
    assert len(load_library(path)) == 5
    assert mocaplib.cli.main(["validate", str(path)]) == 0
    printed = capsys.readouterr().out
    assert f"{path}: valid\n" in printed and "note: no content checksum" in printed
    assert mocaplib.cli.main(["validate", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["checksum"] == "absent"


@pytest.mark.parametrize("number", ["1" + "0" * 400, "9" * 5001, "-1e400"])
def test_numbers_beyond_a_double_are_problems_not_crashes(tmp_path, capsys, number):
    path = library().write(tmp_path / "lib.json")
    text = path.read_text()
    path.write_text(re.sub(r'"T": [0-9.e-]+', f'"T": {number}', text, count=1))
    problems = validate_library(path)
    assert any(p.where == "entries[0].T" and "beyond the range of a double" in p.message
               for p in problems)
    with pytest.raises(LibraryError, match="beyond the range of a double"):
        load_library(path)
    for command in (["validate", str(path)], ["query", str(path), "1", "0", "0"],
                    ["report", str(path), "-o", str(tmp_path / "reports")]):
        assert mocaplib.cli.main(command) == 1
        printed = capsys.readouterr()
        assert "beyond the range of a double" in printed.out + printed.err
        assert "Traceback" not in printed.err


# --------------------------------------------------------------------------- poulaines
def poulaine() -> dict:
    """A poulaine as the build stores it, of two analytic ankle loops half a cycle apart."""
    from mocaplib.gait.poulaine import Poulaine, fit_ankle

    phase = np.arange(80) / 80

    def ankle(shift, y):
        w = 2 * np.pi * (phase + shift)
        return np.column_stack([0.3 * np.cos(w), np.full_like(w, y),
                                -0.85 + 0.1 * np.maximum(0.0, -np.sin(w)) ** 2])

    return Poulaine(-0.05, fit_ankle(ankle(0.0, 0.05), phase),
                    fit_ankle(ankle(0.5, -0.05), phase)).to_dict()


def with_poulaines() -> Library:
    return assemble_library([entry(i, poulaine=poulaine()) for i in range(5)], settings={})


def test_a_stored_poulaine_validates_and_reads_back():
    lib = with_poulaines()
    assert problems_of(lib.document) == []
    model = lib.poulaine("capture00_c0")
    assert model.travel == -0.05
    step, spacing, stance = model.parameters
    row = lib.table.loc["capture00_c0"]
    assert (row["step_length_m"], row["foot_spacing_m"], row["stance_m"]) == pytest.approx(
        (step, spacing, stance)) and step == pytest.approx(0.6, abs=1e-3)
    assert row["poulaine_fit_rms_m"] == max(model.left.fit_rms, model.right.fit_rms)
    reread = load_library(_written(lib))
    np.testing.assert_allclose(reread.poulaine("capture00_c0")(np.linspace(0, 1, 9)),
                               model(np.linspace(0, 1, 9)), atol=1e-9)


def _written(lib: Library) -> str:
    import tempfile

    path = os.path.join(tempfile.mkdtemp(), "lib.json")
    lib.write(path)
    return path


def test_a_library_without_poulaines_or_internal_power_still_reads_and_validates():
    # files written before the poulaine and C3 were stored: same format version, still valid
    lib = library()
    assert "poulaine" not in lib.document["entries"][0]
    assert "internal_power_w_kg" not in lib.document["entries"][0]["qc"]
    assert problems_of(lib.document) == []
    assert lib.poulaine("capture00_c0") is None
    assert lib.table[["step_length_m", "poulaine_fit_rms_m",
                        "qc_internal_power_w_kg"]].isna().all().all()


def poulaine_of(d, side="left") -> dict:
    return d["entries"][1]["poulaine"][side]


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: poulaine_of(d)["phases"].reverse(), r"poulaine\.left\.phases: .*must increase"),
    (lambda d: poulaine_of(d, "right")["timing"][2].reverse(), r"right\.timing: .*every segment"),
    (lambda d: poulaine_of(d)["timing"][0].pop(), r"left\.timing: .*every segment"),
    (lambda d: d["entries"][1]["poulaine"].update(stance_m=0.95),
     r"poulaine: .*stance_m 0\.95, the points give 0\.85"),
    (lambda d: poulaine_of(d)["points_m"][0].pop(), "should be non-empty|is too short"),
    (lambda d: poulaine_of(d)["kinds"].__setitem__(0, "lowest"), "'lowest' is not one of"),
    (lambda d: poulaine_of(d).update(fit_rms_m=-0.001), "less than the minimum of 0"),
    (lambda d: poulaine_of(d)["phases"].__setitem__(3, 1.0), "greater than or equal to the max"),
    (lambda d: d["entries"][1]["poulaine"].pop("right"), "'right' is a required property"),
    (lambda d: d["entries"][1]["qc"].update(internal_power_w_kg=-2.0),
     "less than the minimum of 0"),
])
def test_validate_catches_a_broken_poulaine(mutate, expected):
    doc = copy.deepcopy(with_poulaines().document)
    doc.pop(CHECKSUM_KEY, None)          # an edit the checksum would catch anyway
    mutate(doc)
    problems = problems_of(doc)
    assert any(re.search(expected, p) for p in problems), problems
    assert all("capture01_c0" in p for p in problems)


def test_version_5_is_written_and_version_1_files_still_read(tmp_path):
    from mocaplib.library.document import FORMAT_VERSION

    path = library().write(tmp_path / "lib.json")
    document = json.loads(path.read_text())
    assert document["format_version"] == FORMAT_VERSION == 5
    # a version-1 file: no joint shifts (nor any field version 2 added), its own checksum gone
    document["format_version"] = 1
    del document[CHECKSUM_KEY]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(document))
    assert validate_library(old) == [] and len(load_library(old)) == 5
    document["format_version"] = 6
    old.write_text(json.dumps(document))
    assert any("format_version" in p.where for p in validate_library(old))


def test_validation_runs_with_the_garbage_collector_paused(tmp_path, monkeypatch):
    # a collection would visit every value of the document: 0.15 to 0.3 s on 5,000 entries
    import mocaplib.library.validation as validation

    path = library().write(tmp_path / "library.json")
    enabled, checksum_problems = [], validation._checksum_problems
    monkeypatch.setattr(validation, "_checksum_problems",
                        lambda doc: enabled.append(gc.isenabled()) or checksum_problems(doc))
    assert validate_library(path) == []
    assert enabled == [False] and gc.isenabled()


def test_read_document_hashes_the_files_bytes_only_when_asked(tmp_path):
    import hashlib

    from mocaplib.library.document import read_document

    path = library().write(tmp_path / "library.json")
    from mocaplib.io.fastjson import strict_loads

    document, sha256, finite = read_document(path)
    assert sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    # known finite where orjson read it (this file has a run of 19 digits: the reference did)
    assert finite == (strict_loads(path.read_bytes()) is not None)
    assert read_document(path, file_sha256=False) == (document, None, finite)


def test_a_file_with_nan_is_not_known_finite_and_its_nan_is_named(tmp_path):
    # orjson reads no NaN: the reference parser reads the file, and validation looks for them
    from mocaplib.library.document import read_document
    from mocaplib.library.validation import validate_library

    path = library().write(tmp_path / "library.json")
    text = path.read_text()
    start = text.index('"T":') + len('"T":')
    path.write_text(text[:start] + "NaN" + text[text.index(",", start):])
    assert read_document(path, file_sha256=False)[2] is False
    problems = validate_library(path)
    assert problems and "NaN" in problems[0].message and problems[0].where.endswith(".T")


def test_mocaplib_validate_reads_and_checks_with_the_garbage_collector_paused(tmp_path,
                                                                             monkeypatch,
                                                                             capsys):
    # from reading the file to the warnings: 0.5 s of collections on a 5,000-entry library
    import mocaplib.library.document as document
    import mocaplib.library.validation as validation

    path = library().write(tmp_path / "library.json")
    enabled, read, warning = [], document.read_document, validation.control_space_warning
    monkeypatch.setattr(document, "read_document", lambda *a, **k: enabled.append(
        gc.isenabled()) or read(*a, **k))
    monkeypatch.setattr(validation, "control_space_warning", lambda doc: enabled.append(
        gc.isenabled()) or warning(doc))
    assert mocaplib.cli.main(["validate", str(path)]) == 0
    assert "valid (content checksum verified)" in capsys.readouterr().out
    assert enabled == [False, False] and gc.isenabled()


def test_a_file_orjson_reads_is_not_searched_for_nan(tmp_path, monkeypatch):
    # its numbers are finite for certain: loading and validating skip the search (the
    # fixture's made-up hashes, runs of 64 digits, written with letters for orjson to read it)
    import re

    from mocaplib.io.fastjson import strict_loads
    from mocaplib.library import validation
    from mocaplib.library.validation import validate_library

    path = library().write(tmp_path / "library.json")
    path.write_text(re.sub(r'"\d{64}"', '"' + "a" * 64 + '"', path.read_text()))
    assert strict_loads(path.read_bytes()) is not None

    def searched(document):
        raise AssertionError("searched for NaN")
    monkeypatch.setattr(validation, "all_finite", searched)
    # the hashes changed the content: the checksum is the one problem
    assert [p.where for p in validate_library(path)] == ["content_sha256"]
    load_library(path)
