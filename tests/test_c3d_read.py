"""read_c3d: every real file equals ezc3d's reading; quirks; bad input only ever raises C3DError."""

from __future__ import annotations

import struct
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocaplib.errors import C3DError
from mocaplib.io.c3d import (MODEL_OUTPUT_PARAMETERS, PointLayout, dec_to_ieee, decode_points,
                             detect_vertical_axis, read_c3d, y_up_to_z_up)
from mocaplib.io.c3d_write import c3d_bytes, write_c3d
from mocaplib.trial import Event, Trial

from conftest import SHARED_C3D, real_files

Y_UP = {"motonms_unipd/Static1.c3d", "motonms_unipd/Walking1.c3d", "motonms_unipd/Walking3.c3d",
        "ezc3d_testfiles/BTS.c3d", "ezc3d_testfiles/FP_Type1.c3d"}
REAL = [path.relative_to(SHARED_C3D).as_posix() for path in real_files()]


def ezc3d_reference(path: Path, units: str):
    """ezc3d's labels (LABELS + LABELS2...), markers (F, M, 3) in metres, as stored (not
    rotated)."""
    ezc3d = pytest.importorskip("ezc3d")
    c3d = ezc3d.c3d(str(path))
    point = c3d["parameters"]["POINT"]
    labels, number = list(point["LABELS"]["value"]), 2
    while f"LABELS{number}" in point:
        labels += point[f"LABELS{number}"]["value"]
        number += 1
    declared = set()
    for name in MODEL_OUTPUT_PARAMETERS:
        declared.update(point.get(name, {"value": []})["value"])
    keep = [i for i, label in enumerate(labels) if label not in declared]
    markers = c3d["data"]["points"][:3].transpose(2, 1, 0)[:, keep]
    return [labels[i] for i in keep], markers * (1.0 if units == "m" else 1e-3), c3d


@pytest.mark.parametrize("relative", REAL)
def test_real_file_equals_ezc3d(relative, real_c3d):
    path = real_c3d(relative)
    trial = read_c3d(path)
    labels, reference, c3d = ezc3d_reference(path, trial.units)

    assert trial.labels == labels
    assert trial.rate == c3d["parameters"]["POINT"]["RATE"]["value"][0]
    assert trial.units == c3d["parameters"]["POINT"]["UNITS"]["value"][0].strip("\x00 ")
    assert trial.units in ("mm", "m")
    assert trial.first_frame == c3d["header"]["points"]["first_frame"] + 1  # ezc3d counts from 0
    assert trial.vertical_axis == ("Y" if relative in Y_UP else "Z")
    if trial.vertical_axis == "Y":
        reference = y_up_to_z_up(reference)
    # ezc3d's valid mask is "residual >= 0"; mocaplib also drops samples stored as exactly
    # (0, 0, 0) (CMU files store missing markers that way; see test_all_zero_samples_are_missing).
    reference = np.where((reference == 0).all(axis=2, keepdims=True), np.nan, reference)
    np.testing.assert_array_equal(np.isnan(trial.markers), np.isnan(reference))
    # Both decode the same float32 / int16 x SCALE words to float64: 1e-6 m is the bar.
    np.testing.assert_allclose(trial.markers, reference, atol=1e-6, rtol=0, equal_nan=True)


def test_all_zero_samples_are_missing(real_c3d):
    path = real_c3d("cmu/07_12.c3d")
    trial = read_c3d(path)
    _, reference, _ = ezc3d_reference(path, trial.units)
    zero = (reference == 0).all(axis=2)
    assert zero.sum() > 0, "this CMU file stores some missing samples as (0, 0, 0)"
    assert np.isnan(trial.markers[zero]).all()
    assert not np.isnan(trial.markers[~zero & ~np.isnan(reference[..., 0])]).any()


def test_labels2_beyond_255_points(real_c3d):
    trial = read_c3d(real_c3d("biomechzoo/HC030A01.c3d"))
    ezc3d = pytest.importorskip("ezc3d")
    point = ezc3d.c3d(str(real_c3d("biomechzoo/HC030A01.c3d")))["parameters"]["POINT"]
    assert point["USED"]["value"][0] > 255
    beyond = [label for label in point["LABELS2"]["value"] if label in trial.labels]
    assert beyond, "some kept markers come from POINT:LABELS2"
    assert any("dropped" in note and "model outputs" in note for note in trial.warnings)


def test_model_outputs_are_dropped_with_one_warning(real_c3d):
    trial = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    notes = [note for note in trial.warnings if "model outputs" in note]
    assert notes == ["dropped 80 model outputs stored as points "
                     "(POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS, REACTIONS)"]
    assert trial.n_markers == 193 - 80
    assert not any(label.endswith(("Angles", "Force", "Moment", "Power")) for label in trial.labels)
    assert {"LSHO", "RSHO", "LHEE", "RHEE"} <= set(trial.names)


def test_a_corrupt_sample_astronomically_far_is_missing(real_c3d, tmp_path):
    """One float word of LKNE corrupt (1e17 m, as garbage floats mostly are): read as missing,
    the rest as it was; kept, the low-pass filter spreads it over the whole track and the fit
    leaves LKNE, LTIB, LANK, LHEE and LTOE out in every frame."""
    original = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    markers = original.markers.copy()
    knee = original.labels.index("LKNE")
    markers[100, knee] = 1e17
    trial = read_c3d(write_c3d(tmp_path / "corrupt.c3d", markers, original.labels,
                               original.rate))
    assert np.isnan(trial.markers[100, knee]).all()
    markers[100, knee] = np.nan
    # float32 storage in mm: 1e-6 m is below its step at a few metres
    np.testing.assert_allclose(trial.markers, markers, atol=1e-6)


def test_model_outputs_are_dropped_whatever_the_subject_prefix(real_c3d, tmp_path):
    """PiG_Motion-FlatFoot-Full with its labels prefixed (``Patient_03:LHipAngles``) while
    POINT:ANGLES, FORCES... keep the bare names (a relabelling script that touched LABELS
    only): its 80 model outputs are still dropped; kept, their angles in degrees and forces in
    newtons read as 80 more markers and the vertical axis looked unclear."""
    ezc3d = pytest.importorskip("ezc3d")
    source = real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d")
    c3d = ezc3d.c3d(str(source))
    point = c3d["parameters"]["POINT"]
    point["LABELS"]["value"] = [f"Patient_03:{label}" for label in point["LABELS"]["value"]]
    path = tmp_path / "prefixed.c3d"
    c3d.write(str(path))
    original, trial = read_c3d(source), read_c3d(path)
    assert trial.labels == [f"Patient_03:{label}" for label in original.labels]
    assert trial.warnings == original.warnings          # the one note: 80 outputs dropped
    np.testing.assert_array_equal(trial.markers, original.markers)


def test_units_spelled_out_are_refused_saying_what_to_do(real_c3d, tmp_path):
    ezc3d = pytest.importorskip("ezc3d")
    c3d = ezc3d.c3d(str(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d")))
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["millimeters"]
    path = tmp_path / "spelled.c3d"
    c3d.write(str(path))
    with pytest.raises(C3DError, match=r"spelled.c3d: unknown POINT:UNITS 'millimeters' "
                                       r"\(mocaplib knows mm, cm, dm, m: set POINT:UNITS to the "
                                       r"one the coordinates are in, or re-export the file\)"):
        read_c3d(path)


def test_dec_file_with_nul_padded_units(real_c3d):
    trial = read_c3d(real_c3d("btkdata/Gait.c3d"))
    assert trial.units == "mm"  # stored as 'mm\x00\x00'
    assert trial.n_frames == 487 and trial.rate == 100.0
    heel = np.nanmedian(trial.marker("RHEE")[:, 2])
    shoulder = np.nanmedian(trial.marker("RSHO")[:, 2])
    assert 0.0 < heel < 0.15 and 1.2 < shoulder < 1.7


def test_duplicate_labels_are_kept_and_flagged(real_c3d):
    trial = read_c3d(real_c3d("btkdata/Gait.c3d"))
    assert trial.n_markers == 33
    assert trial.labels.count("RKNE") == 2
    assert {n for n in trial.names if trial.names.count(n) > 1} == {
        "RKNE", "RANK", "LKNE", "LANK", "RFOO", "LFOO"}
    assert ("duplicate labels kept as separate markers: LANK, LFOO, LKNE, RANK, RFOO, RKNE"
            in trial.warnings)
    first, second = [i for i, label in enumerate(trial.labels) if label == "RKNE"]
    assert not np.allclose(trial.markers[:, first], trial.markers[:, second], equal_nan=True)


def test_units_in_metres(real_c3d):
    trial = read_c3d(real_c3d("ezc3d_testfiles/FP_Type1.c3d"))
    assert trial.units == "m"
    assert 1.3 < np.nanmedian(trial.marker("c7")[:, 2]) < 1.7  # not scaled by 1e-3


@pytest.mark.parametrize("relative, head, heel", [
    ("motonms_unipd/Walking1.c3d", "C7", "RCA"),
    ("motonms_unipd/Static1.c3d", "C7", "LCA"),
    ("ezc3d_testfiles/BTS.c3d", "c7", "r heel"),
    ("ezc3d_testfiles/FP_Type1.c3d", "c7", "l heel"),
])
def test_y_up_files_end_up_z_up(relative, head, heel, real_c3d):
    trial = read_c3d(real_c3d(relative))
    assert trial.vertical_axis == "Y"
    assert "Y-up file rotated to Z up: (x, y, z) -> (x, -z, y)" in trial.warnings
    assert np.nanmedian(trial.marker(heel)[:, 2]) < 0.12     # heel on the floor
    assert np.nanmedian(trial.marker(head)[:, 2]) > 1.2      # C7 above


@pytest.mark.parametrize("relative, right, left, root", [
    ("motonms_unipd/Walking1.c3d", "RASIS", "LASIS", "L5"),
    ("ezc3d_testfiles/BTS.c3d", "r asis", "l asis", "sacrum"),
    ("cmu/07_01.c3d", "RFWT", "LFWT", "RBWT"),
])
def test_world_frame_is_right_handed(relative, right, left, root, real_c3d):
    """The left pelvis marker lies on the walker's left: +Z x walking direction."""
    trial = read_c3d(real_c3d(relative))
    path = trial.marker(root)
    seen = np.flatnonzero(np.isfinite(path[:, 0]))
    forward = path[seen[-1], :2] - path[seen[0], :2]
    assert np.linalg.norm(forward) > 1.0, "the subject walks"
    leftward = np.array([-forward[1], forward[0]])
    across = np.nanmedian(trial.marker(left)[:, :2] - trial.marker(right)[:, :2], axis=0)
    assert across @ leftward > 0


@pytest.mark.parametrize("relative", REAL)
def test_events_match_the_event_group(relative, real_c3d):
    path = real_c3d(relative)
    trial = read_c3d(path)
    ezc3d = pytest.importorskip("ezc3d")
    event = ezc3d.c3d(str(path))["parameters"].get("EVENT")
    if event is None or event["USED"]["value"][0] == 0:
        assert trial.events == []
        return
    value = np.asarray(event["TIMES"]["value"], dtype=float)  # 2 x N, or flat pairs (BTK)
    minutes, seconds = value if value.ndim == 2 else value.reshape(-1, 2).T
    contexts = event.get("CONTEXTS", {"value": []})["value"] or ["General"] * len(minutes)
    expected = sorted(zip(minutes * 60 + seconds, contexts, event["LABELS"]["value"]))
    assert [(e.context, e.label) for e in trial.events] == [(c, l) for _, c, l in expected]
    # float32 seconds: 1e-6 s is far below a frame.
    np.testing.assert_allclose([e.time_s for e in trial.events], [t for t, _, _ in expected],
                               atol=1e-6)


@pytest.mark.parametrize("relative, count", [
    ("biomechzoo/HC030A05.c3d", 8), ("biomechzoo/HC030A22.c3d", 19),
    ("ezc3d_testfiles/Qualisys.c3d", 7), ("btkdata/PiG_Motion-FlatFoot-Full.c3d", 12),
    ("motonms_unipd/Walking1.c3d", 2),
])
def test_files_with_events_have_them(relative, count, real_c3d):
    events = read_c3d(real_c3d(relative)).events
    assert len(events) == count
    assert all(e.time_s > 0 for e in events)


def test_files_the_c3d_package_refuses_are_read(real_c3d):
    c3d = pytest.importorskip("c3d")
    for relative, refusal in [("btkdata/PiG_Calibration-FlatFoot-One.c3d", KeyError),
                              ("cmu/16_07.c3d", AssertionError)]:
        path = real_c3d(relative)
        with open(path, "rb") as handle, pytest.raises(refusal):
            c3d.Reader(handle)
        trial = read_c3d(path)
        assert trial.n_frames > 0 and trial.n_markers > 0


# ----------------------------------------------------------------------------- data decoding
def ieee_to_dec_words(values: np.ndarray) -> np.ndarray:
    """Test-side encoder: IEEE float32 -> DEC F-float words (value x 4, 16-bit halves swapped)."""
    bits = (np.asarray(values, dtype=np.float32) * np.float32(4.0)).view(np.uint32)
    return (bits >> np.uint32(16)) | (bits << np.uint32(16))


def test_dec_to_ieee_known_values_and_c3d_package():
    # VAX F-float 1.0 is stored as bytes 80 40 00 00, -2.5 as 20 C1 00 00, 0 as 00 00 00 00.
    words = np.frombuffer(bytes.fromhex("80400000" "20c10000" "00000000"), dtype="<u4")
    np.testing.assert_array_equal(dec_to_ieee(words), [1.0, -2.5, 0.0])
    c3d = pytest.importorskip("c3d")
    rng = np.random.default_rng(3)
    values = rng.normal(scale=1e3, size=200).astype(np.float32)
    words = ieee_to_dec_words(values)
    expected = [c3d.c3d.DEC_to_IEEE(int(word)) for word in words]
    np.testing.assert_array_equal(dec_to_ieee(words), expected)
    np.testing.assert_array_equal(dec_to_ieee(words), values)


def layout(processor, scale, frames=3, count=2, analog=2):
    return PointLayout(processor, 512, frames, count, 4 * count + analog, scale, 100.0, 1)


def point_words(frames=3, count=2, analog=2):
    """Coordinates (F, M, 3), residual words (F, M) with one invalid sample, analog padding."""
    rng = np.random.default_rng(4)
    xyz = rng.integers(-3000, 3000, size=(frames, count, 3)).astype(np.float32)
    residual = np.zeros((frames, count), dtype=np.float32)
    residual[1, 0] = -1.0
    words = np.concatenate([np.dstack([xyz, residual]).reshape(frames, -1),
                            np.full((frames, analog), 7.0, np.float32)], axis=1)
    expected = xyz.astype(np.float64)
    expected[1, 0] = np.nan
    return words, expected


@pytest.mark.parametrize("processor, encode", [
    ("INTEL", lambda w: w.astype("<f4").tobytes()),
    ("MIPS", lambda w: w.astype(">f4").tobytes()),
    ("DEC", lambda w: ieee_to_dec_words(w).astype("<u4").tobytes()),
])
def test_decode_float_storage_for_each_processor(processor, encode):
    words, expected = point_words()
    data = bytes(512) + encode(words)
    got = decode_points(data, layout(processor, -0.1), factor=1e-3)
    np.testing.assert_array_equal(got, expected * 1e-3)


@pytest.mark.parametrize("processor, dtype", [("INTEL", "<i2"), ("DEC", "<i2"), ("MIPS", ">i2")])
def test_decode_integer_storage_for_each_processor(processor, dtype):
    words, expected = point_words()
    data = bytes(512) + words.astype(dtype).tobytes()
    got = decode_points(data, layout(processor, 0.5))
    np.testing.assert_array_equal(got, expected * 0.5)  # exact: int16 x power of two


def convert_processor(data: bytes, processor: str) -> bytes:
    """Test-side converter of an Intel float C3D (as written by write_c3d) to DEC or MIPS.

    MIPS swaps the bytes of every 16-bit integer and 32-bit float; DEC keeps integers and
    re-encodes floats as VAX F-floats. Header, parameter records and the data block are walked.
    """
    out = bytearray(data)

    def floats(at: int, count: int) -> None:
        values = np.frombuffer(data, "<f4", count, at)
        encoded = values.astype(">f4") if processor == "MIPS" else ieee_to_dec_words(values)
        out[at:at + 4 * count] = encoded.astype(">f4" if processor == "MIPS" else "<u4").tobytes()

    def ints(at: int, count: int) -> None:
        if processor == "MIPS":
            out[at:at + 2 * count] = np.frombuffer(data, "<i2", count, at).astype(">i2").tobytes()

    ints(2, 5), floats(12, 1), ints(16, 2), floats(20, 1), ints(298, 3)
    start = (data[0] - 1) * 512
    out[start + 3] = {"MIPS": 86, "DEC": 85}[processor]
    position = start + 4
    while data[position] != 0:
        length, group = struct.unpack_from("bb", data, position)
        offset_at = position + 2 + abs(length)
        offset, = struct.unpack_from("<h", data, offset_at)
        ints(offset_at, 1)
        if group > 0:
            element, dims = struct.unpack_from("bB", data, offset_at + 2)
            count = int(np.prod(list(data[offset_at + 4:offset_at + 4 + dims])))
            body = offset_at + 4 + dims
            if element == 2:
                ints(body, count)
            elif element == 4:
                floats(body, count)
        if offset <= 0:
            break
        position = offset_at + offset
    data_start = (struct.unpack_from("<H", data, 16)[0] - 1) * 512
    floats(data_start, (len(data) - data_start) // 4)
    return bytes(out)


@pytest.mark.parametrize("processor", ["DEC", "MIPS"])
def test_whole_file_in_other_processor_formats(tmp_path, processor):
    intel, other = tmp_path / "intel.c3d", tmp_path / f"{processor}.c3d"
    intel.write_bytes(SMALL)
    other.write_bytes(convert_processor(SMALL, processor))
    expected, got = read_c3d(intel), read_c3d(other)
    assert (got.labels, got.rate, got.first_frame, got.units) == \
        (expected.labels, expected.rate, expected.first_frame, expected.units)
    assert got.events == expected.events
    np.testing.assert_array_equal(got.markers, expected.markers)  # same float32 values
    if processor == "DEC":  # ezc3d reads DEC (not MIPS): an independent check of the converter
        ezc3d = pytest.importorskip("ezc3d")
        points = ezc3d.c3d(str(other))["data"]["points"][:3].transpose(2, 1, 0) * 1e-3
        np.testing.assert_allclose(got.markers, points, atol=1e-12, equal_nan=True)


# ----------------------------------------------------------------------------- vertical axis
def standing_person(frames=50, seed=5):
    """A crude 1.7 m person walking along +X, Z up: (F, 20, 3) metres."""
    rng = np.random.default_rng(seed)
    heights = np.linspace(0.05, 1.7, 20)
    body = np.column_stack([rng.normal(0, 0.08, 20), rng.normal(0, 0.15, 20), heights])
    travel = np.linspace(0, 2.0, frames)[:, None, None] * np.array([1.0, 0, 0])
    return body[None] + travel


def test_detect_vertical_axis_both_ways():
    person = standing_person()
    assert detect_vertical_axis(person) == ("Z", [])
    as_y_up = np.stack([person[..., 0], person[..., 2], -person[..., 1]], axis=-1)
    assert detect_vertical_axis(as_y_up) == ("Y", [])
    np.testing.assert_allclose(y_up_to_z_up(as_y_up), person, atol=0)  # exact permutation


def test_vertical_axis_unclear_falls_back_to_screen_axis():
    ball = np.random.default_rng(6).normal(size=(30, 20, 3))
    axis, notes = detect_vertical_axis(ball, screen_axis="Y")
    assert axis == "Y" and "unclear" in notes[0]
    assert detect_vertical_axis(ball)[0] == "Z"


def test_two_subjects_side_by_side_do_not_make_the_floor_look_vertical():
    """Two people 3 m apart across the floor: relative to the mean of all markers the floor's
    axis spreads widest (3 m against a body's 1.7 m); each subject's markers relative to their
    own mean show Z."""
    person = standing_person()
    pair = np.concatenate([person, person + [0.0, 3.0, 0.0]], axis=1)
    assert detect_vertical_axis(pair)[0] == "Y"          # one cloud: the floor looks vertical
    assert detect_vertical_axis(pair, subjects=["A"] * 20 + ["B"] * 20) == ("Z", [])


def test_a_file_of_two_subjects_is_read_z_up_and_says_so(real_c3d, tmp_path):
    """Qualisys.c3d with a copy of its subject 3 m to the side, labels prefixed A: and B: (how
    Vicon Nexus stores a capture of two people): the file stays Z up, subject A's markers are
    the original's, and a note names both subjects."""
    original = read_c3d(real_c3d("ezc3d_testfiles/Qualisys.c3d"))
    markers = np.concatenate([original.markers, original.markers + [0.0, 3.0, 0.0]], axis=1)
    labels = [f"{subject}:{label}" for subject in "AB" for label in original.labels]
    trial = read_c3d(write_c3d(tmp_path / "pair.c3d", markers, labels, original.rate))
    assert trial.vertical_axis == "Z"
    # float32 storage in mm: 1e-6 m is far below its precision step at a few metres
    np.testing.assert_allclose(trial.markers[:, :len(original.labels)], original.markers,
                               atol=1e-6)
    assert any("labels of 2 subjects (A, B)" in note for note in trial.warnings)


def test_screen_axis_disagreeing_with_data_is_noted():
    axis, notes = detect_vertical_axis(standing_person(), screen_axis="Y")
    assert axis == "Z" and "Y_SCREEN shows Y up" in notes[0]


# ----------------------------------------------------------------------------- bad input
def small_file_bytes() -> bytes:
    markers = standing_person(frames=12)
    markers[4:6, 3] = np.nan
    return c3d_bytes(markers, [f"M{i}" for i in range(20)], 100.0,
                     events=[Event("Left", "Foot Strike", 0.05)])


SMALL = small_file_bytes()


def test_small_file_reads(tmp_path):
    path = tmp_path / "small.c3d"
    path.write_bytes(SMALL)
    trial = read_c3d(path)
    assert isinstance(trial, Trial) and trial.n_frames == 12 and trial.vertical_axis == "Z"
    assert np.isnan(trial.markers[4:6, 3]).all()


@pytest.mark.parametrize("content, match", [
    (b"", "the file is empty"),
    (b"hello", "only 5 bytes"),
    (b"PK\x03\x04" + bytes(600), "not a C3D file"),
    (bytes([200, 0x50]) + bytes(1000), "parameter section at block 200, beyond the end"),
    (bytes([1, 0x50]) + bytes(1000), "parameter section at block 1, inside the header"),
])
def test_not_a_c3d(tmp_path, content, match):
    path = tmp_path / "bad.c3d"
    path.write_bytes(content)
    with pytest.raises(C3DError, match=match) as info:
        read_c3d(path)
    assert str(path) in str(info.value)


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(C3DError, match="no such file"):
        read_c3d(tmp_path / "absent.c3d")
    with pytest.raises(C3DError, match="is a folder"):
        read_c3d(tmp_path)


SMALL_DATA_END = (struct.unpack_from("<H", SMALL, 16)[0] - 1) * 512 + 12 * 20 * 4 * 4


@pytest.mark.parametrize("cut", [513, 1024, SMALL_DATA_END - 700, SMALL_DATA_END - 1])
def test_truncated_file(tmp_path, cut):
    path = tmp_path / "cut.c3d"
    path.write_bytes(SMALL[:cut])
    with pytest.raises(C3DError, match="truncated"):
        read_c3d(path)


def test_cut_in_the_final_padding_still_reads(tmp_path):
    """Every frame is there: only zero padding after the last frame is missing."""
    assert SMALL_DATA_END < len(SMALL)
    path = tmp_path / "padding.c3d"
    path.write_bytes(SMALL[:SMALL_DATA_END])
    assert read_c3d(path).n_frames == 12


def test_sizes_that_would_need_gigabytes(tmp_path):
    """Header frame numbers claiming 65535 frames: refused from the file size, nothing allocated."""
    data = bytearray(SMALL)
    struct.pack_into("<H", data, 8, 65535)    # header word 5: last frame
    path = tmp_path / "huge.c3d"
    path.write_bytes(bytes(data))
    with pytest.raises(C3DError, match="truncated: 65535 frames"):
        read_c3d(path)


def test_wrong_processor_byte(tmp_path):
    data = bytearray(SMALL)
    data[(data[0] - 1) * 512 + 3] = 99
    path = tmp_path / "proc.c3d"
    path.write_bytes(bytes(data))
    with pytest.raises(C3DError, match="unknown processor type 99"):
        read_c3d(path)


# ----------------------------------------------------------------------------- fuzzing
def read_or_c3derror(data: bytes) -> None:
    """The only outcomes allowed: a Trial or a C3DError."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.c3d"
        path.write_bytes(data)
        try:
            assert isinstance(read_c3d(path), Trial)
        except C3DError as error:
            assert str(path) in str(error)


def mutate(data: bytes, draw, header_bias: int) -> bytes:
    """Truncate ``data`` or overwrite a few bytes, mostly in the header and parameter section."""
    if draw(st.booleans()):
        return data[:draw(st.integers(0, len(data) - 1))]
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 8))):
        limit = header_bias if draw(st.booleans()) else len(out) - 1
        out[draw(st.integers(0, min(limit, len(out) - 1)))] = draw(st.integers(0, 255))
    return bytes(out)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_fuzz_small_written_file(data):
    read_or_c3derror(mutate(SMALL, data.draw, header_bias=(SMALL[0] + 1) * 512))


FUZZ_REAL = ["btkdata/PiG_Calibration-FlatFoot-One.c3d", "btkdata/Gait.c3d", "cmu/07_12.c3d"]


@pytest.mark.skipif(not all((SHARED_C3D / name).is_file() for name in FUZZ_REAL),
                    reason="real C3D files not available")
@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_fuzz_real_files(real_c3d, data):
    original = real_c3d(data.draw(st.sampled_from(FUZZ_REAL))).read_bytes()
    read_or_c3derror(mutate(original, data.draw, header_bias=(original[0] + 12) * 512))


@pytest.mark.parametrize("dims", [[0, 255], [0, 255, 255, 255, 255]], ids=["255", "255**4"])
def test_zero_width_labels_are_made_up(tmp_path, dims):
    """POINT:LABELS declared as strings of width 0 (255 of them, or 255**4: 4e9 iterations if
    looped over): nothing to decode, labels are made up at once, with a warning."""
    data = bytearray(SMALL)
    at = SMALL.index(b"LABELS") + len("LABELS") + 2 + 1   # after the offset word and element size
    assert data[at] == 2                                      # two dimensions: width, count
    # the new dimensions, no data, an empty description; the offset word still points at the
    # next parameter, so the rest of the old record is skipped
    data[at:at + len(dims) + 2] = bytes([len(dims), *dims, 0])
    path = tmp_path / "zero.c3d"
    path.write_bytes(bytes(data))
    trial = read_c3d(path)
    assert trial.labels[:2] == ["POINT1", "POINT2"]
    assert any("have no label" in note for note in trial.warnings)


# ----------------------------------------------------------------------------- damaged files
def parameter_record(data: bytes, group: str, name: str):
    """The record of parameter GROUP:NAME in a file's parameter section."""
    from mocaplib.io.c3d import _parameter_records

    records, _ = _parameter_records(data)
    groups = {-r.group: r.name.decode() for r in records if r.group < 0}
    return next(r for r in records if r.group > 0 and groups[r.group] == group
                and r.name.decode() == name)


def with_scale(data: bytes, factor: float) -> bytes:
    """``data`` with POINT:SCALE (parameter and header) multiplied by ``factor``."""
    out = bytearray(data)
    record = parameter_record(data, "POINT", "SCALE")
    at = record.link_at + 2 + 2 + data[record.link_at + 3]  # after type, dimensions
    for offset in (at, 12):  # the parameter, and the header's copy (words 7-8)
        struct.pack_into("<f", out, offset, struct.unpack_from("<f", data, offset)[0] * factor)
    return bytes(out)


def test_float_data_whose_scale_says_integers_is_read_as_floats_with_a_note(tmp_path):
    # the sign of POINT:SCALE says how points are stored; flipped, 32-bit floats would be read
    # as 16-bit integers: garbage, and a build then blames POINT:UNITS ("233 m tall")
    path = tmp_path / "flipped.c3d"
    path.write_bytes(with_scale(SMALL, -1.0))
    trial, original = read_c3d(path), read_c3d_bytes(SMALL, tmp_path)
    np.testing.assert_array_equal(trial.markers, original.markers)
    assert any("POINT:SCALE 1 says 16-bit integer storage" in w and "read as floats" in w
               for w in trial.warnings)


def test_integer_data_whose_scale_says_floats_is_refused_saying_why(tmp_path):
    integer = c3d_bytes(standing_person(frames=12), [f"M{i}" for i in range(20)], 100.0,
                        integer=True)
    path = tmp_path / "flipped.c3d"
    path.write_bytes(with_scale(integer, -1.0))
    with pytest.raises(C3DError, match="POINT:SCALE's sign is wrong"):
        read_c3d(path)


def read_c3d_bytes(data: bytes, folder: Path) -> Trial:
    path = folder / "original.c3d"
    path.write_bytes(data)
    return read_c3d(path)


@pytest.mark.parametrize("link", [-4, -200, 0])
def test_a_parameter_link_pointing_backwards_loses_no_group(tmp_path, link):
    # a record whose link to the next points backwards (or ends the chain early): the c3d
    # package would take the rest of the file for its value and silently drop every group
    # after it (EVENT, POINT:SCALE, POINT:RATE)
    from mocaplib.io.c3d import _parameter_records

    records, _ = _parameter_records(SMALL)
    damaged = bytearray(SMALL)
    struct.pack_into("<h", damaged, records[1].link_at, link)
    path = tmp_path / "backwards.c3d"
    path.write_bytes(bytes(damaged))
    trial, original = read_c3d(path), read_c3d_bytes(SMALL, tmp_path)
    assert trial.events == original.events and len(trial.events) == 1
    assert trial.rate == original.rate and trial.labels == original.labels
    np.testing.assert_array_equal(trial.markers, original.markers)
    assert any(f"the link after {records[1].name.decode()}" in w and "re-export" in w
               for w in trial.warnings)


def test_control_characters_in_labels_are_escaped(tmp_path):
    # a label may hold anything: printed as it is, ESC [ 2 J would clear the terminal
    path = tmp_path / "escape.c3d"
    labels = [f"M{i}" for i in range(19)] + ["LASI\x1b[2J\x07"]
    path.write_bytes(c3d_bytes(standing_person(frames=12), labels, 100.0))
    trial = read_c3d(path)
    assert trial.labels[-1] == "LASI\\x1b[2J\\x07"


def _long_capture(frames: int) -> np.ndarray:
    """(F, 3, 3) metres: three markers wandering about 1 m up, one sample missing."""
    rng = np.random.default_rng(11)
    markers = np.cumsum(rng.normal(0, 1e-3, (frames, 3, 3)), axis=0) + [0.0, 0.0, 1.0]
    markers[frames - 2, 1] = np.nan
    return markers


def _ezc3d_write(path: Path, markers: np.ndarray, labels: list[str], rate: float) -> Path:
    ezc3d = pytest.importorskip("ezc3d")
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = labels
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    points = np.ones((4,) + markers.shape[1::-1])
    points[:3] = np.nan_to_num(markers.transpose(2, 1, 0) * 1000.0, nan=0.0)
    c3d["data"]["points"] = points
    c3d.write(str(path))
    return path


@pytest.mark.parametrize("writer", ["mocaplib", "ezc3d"])
def test_a_file_of_more_than_65535_frames_is_read_whole(tmp_path, writer):
    # C3D's header counts frames in 16 bits. mocaplib's writer (the c3d package's) also stores
    # the count in TRIAL:ACTUAL_END_FIELD (32 bits) and POINT:LONG_FRAMES; ezc3d 1.7 stores it
    # in 16 bits only, at 65535, and writes every frame after it
    markers = _long_capture(70_000)
    labels = ["A", "B", "C"]
    path = (write_c3d(tmp_path / "long.c3d", markers, labels, 100.0) if writer == "mocaplib"
            else _ezc3d_write(tmp_path / "long.c3d", markers, labels, 100.0))
    trial = read_c3d(path)
    assert trial.n_frames == 70_000
    # float32 millimetres: 1e-7 m at 1 m
    np.testing.assert_allclose(trial.markers, markers, atol=1e-7, rtol=0)
    np.testing.assert_array_equal(np.isnan(trial.markers), np.isnan(markers))
    counted = [w for w in trial.warnings if "16 bits" in w]
    assert counted == ([] if writer == "mocaplib" else
                       ["the file counts 65535 frames, the most 16 bits hold, and its data "
                        "section holds 70000: all read"])


def test_reading_holds_little_more_than_the_marker_array(tmp_path, monkeypatch):
    """Frames are read a chunk at a time and the analog samples between them skipped: the
    peak of the allocations (tracemalloc, which numpy reports to) stays near the marker array
    even for a file several times larger."""
    import tracemalloc

    import c3d
    import mocaplib.io.c3d as reader

    monkeypatch.setattr(reader, "CHUNK_BYTES", 1 << 20)
    frames, analog = 20_000, (16, 10)         # 16 channels x 10 samples a frame: 640 bytes
    markers = _long_capture(frames)
    writer = c3d.Writer(point_rate=100.0, analog_rate=1000.0, point_scale=-1.0)
    writer.set_point_labels(["A", "B", "C"])
    writer.set_analog_labels([f"CH{i}" for i in range(analog[0])])
    points = np.zeros((3, 5))
    samples = np.ones(analog, dtype=np.float32)
    for frame in markers:
        points[:, :3] = np.nan_to_num(frame * 1000.0)
        points[:, 3] = np.where(np.isfinite(frame[:, 0]), 0.0, -1.0)
        writer.add_frames([(points.copy(), samples)])
    path = tmp_path / "analog.c3d"
    with open(path, "wb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        writer.write(handle)
    tracemalloc.start()
    try:
        trial = read_c3d(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    np.testing.assert_allclose(trial.markers, markers, atol=1e-7, rtol=0)
    size = path.stat().st_size
    assert size > 5 * trial.markers.nbytes           # 13.8 MB of file, 1.4 MB of markers
    # measured: 2.7 MB (the markers, a 1 MiB chunk and its decoding); reading the whole file
    # at once would hold its 13.8 MB
    assert peak < 2 * trial.markers.nbytes + 2 * reader.CHUNK_BYTES, (peak, size)
