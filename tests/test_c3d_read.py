"""read_c3d on the real files (each equals ezc3d's reading; their quirks) and the decoding of
POINT words in every storage and processor format."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from mocaplib.errors import C3DError
from mocaplib.io.c3d import MODEL_OUTPUT_PARAMETERS, read_c3d, unit_of
from mocaplib.io.c3d_axis import to_z_up
from mocaplib.io.c3d_layout import PointLayout
from mocaplib.io.c3d_params import dec_to_ieee
from mocaplib.io.c3d_points import decode_points
from mocaplib.io.c3d_write import write_c3d

from c3d_files import SMALL, capture_bytes, standing_person, with_text
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
        reference = to_z_up(reference, "Y")
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


def test_units_spelled_out_are_read_and_unknown_ones_refused_saying_what_to_do(real_c3d,
                                                                               tmp_path):
    ezc3d = pytest.importorskip("ezc3d")
    source = real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d")
    c3d = ezc3d.c3d(str(source))
    for units in ("millimeters", "inches"):
        c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
        c3d.write(str(tmp_path / f"{units}.c3d"))
    trial = read_c3d(tmp_path / "millimeters.c3d")
    np.testing.assert_array_equal(trial.markers, read_c3d(source).markers)
    assert "POINT:UNITS 'millimeters' read as mm" in trial.warnings
    with pytest.raises(C3DError, match=r"inches.c3d: unknown POINT:UNITS 'inches' \(mocaplib "
                                       r"knows mm, cm, dm, m in any case, and their names "
                                       r"spelled out or cut short"):
        read_c3d(tmp_path / "inches.c3d")


@pytest.mark.parametrize("text, per_metre, unit", [
    ("mete", 1.0, "m"), ("Mete", 1.0, "m"), ("m", 1.0, "m"), ("MM", 1e3, "mm"),
    ("mill", 1e3, "mm"), ("cm", 1e2, "cm"), ("cent", 1e2, "cm")])
def test_units_cut_short_or_in_another_case_are_read(tmp_path, text, per_metre, unit):
    """POINT:UNITS of 4 characters holding 'mete' (metres cut to the width a writer kept),
    'mill', 'cent', or a symbol in upper case: coordinates stored in that unit read back in
    metres, with a note naming the text read."""
    markers = standing_person(frames=10)
    data = capture_bytes(markers * per_metre / 1000.0, [f"M{i}" for i in range(20)])
    path = tmp_path / "units.c3d"
    path.write_bytes(with_text(data, "POINT:UNITS", text))
    trial = read_c3d(path)
    assert trial.units == text
    # float32 of the stored unit: 1e-6 m
    np.testing.assert_allclose(trial.markers, markers, atol=1e-6, rtol=0)
    assert trial.warnings == ([] if text == unit else [f"POINT:UNITS {text!r} read as {unit}"])


@pytest.mark.parametrize("text, unit", [
    ("metres", "m"), ("meter", "m"), ("me", "m"), ("MILLIMETRES", "mm"), ("milli", "mm"),
    ("centimeter", "cm"), ("centi", "cm"), ("deci", "dm"), ("dm", "dm"), ("mi", None),
    ("inch", None), ("mile", None), ("", None)])
def test_unit_of_reads_symbols_and_names_cut_short(text, unit):
    assert unit_of(text) == unit


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
