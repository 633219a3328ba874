"""Bad, damaged and unusual C3D files: only ever a Trial or a C3DError naming the file."""

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
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_params import parameter_records
from mocaplib.io.c3d_write import c3d_bytes, write_c3d
from mocaplib.trial import Trial

from c3d_files import (SMALL, SMALL_DATA_END, read_c3d_bytes, standing_person, with_header_word,
                       with_parameter, with_scale)
from conftest import SHARED_C3D


# ----------------------------------------------------------------------------- bad input
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
    """Every frame count claiming 65535 frames (header, POINT:FRAMES, TRIAL): refused from the
    file size, nothing allocated."""
    data = with_header_word(SMALL, 5, 65535)
    data = with_parameter(with_parameter(data, "POINT:FRAMES", 65535),
                          "TRIAL:ACTUAL_END_FIELD", 65535, 0)
    path = tmp_path / "huge.c3d"
    path.write_bytes(data)
    with pytest.raises(C3DError, match="truncated: 65535 frames"):
        read_c3d(path)


def test_a_header_alone_claiming_65535_frames_is_outvoted(tmp_path):
    """The header's last frame at 65535 while POINT:FRAMES, TRIAL and the data section say 12:
    12 frames are read, with a note naming both counts."""
    path = tmp_path / "header.c3d"
    path.write_bytes(with_header_word(SMALL, 5, 65535))
    trial = read_c3d(path)
    np.testing.assert_array_equal(trial.markers, read_c3d_bytes(SMALL, tmp_path).markers)
    assert any("frames: 12 (" in w and "65535 (the header)" in w for w in trial.warnings)


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


@pytest.mark.parametrize("record, link, where", [
    (1, -4, "ANALOG:GEN_SCALE points backwards (-4 bytes)"),
    (1, -200, "ANALOG:GEN_SCALE points backwards (-200 bytes)"),
    (1, 0, "ANALOG:GEN_SCALE ends the chain early (+0 bytes)"),
    (1, 0x7FFF, "ANALOG:GEN_SCALE points past the end of the section (+32767 bytes)"),
    (0, 0x7FFF, "ANALOG points past the end of the section (+32767 bytes)"),
    (7, 4000, "POINT points past the end of the section (+4000 bytes)")])
def test_a_broken_parameter_link_loses_no_group_and_is_named(tmp_path, record, link, where):
    # a record whose link to the next points backwards, ends the chain early or past the end
    # of the section: the c3d package would take the rest of the file for its value, or stop,
    # and silently drop every group after it (EVENT, POINT:SCALE, POINT:RATE)
    records, _ = parameter_records(SMALL)
    damaged = bytearray(SMALL)
    struct.pack_into("<h", damaged, records[record].link_at, link)
    path = tmp_path / "backwards.c3d"
    path.write_bytes(bytes(damaged))
    trial, original = read_c3d(path), read_c3d_bytes(SMALL, tmp_path)
    assert trial.events == original.events and len(trial.events) == 1
    assert trial.rate == original.rate and trial.labels == original.labels
    np.testing.assert_array_equal(trial.markers, original.markers)
    assert any(f"parameter section: the link after {where}" in w and "re-export" in w
               for w in trial.warnings), trial.warnings


def test_control_characters_in_labels_are_escaped(tmp_path):
    # a label may hold anything: printed as it is, ESC [ 2 J would clear the terminal
    path = tmp_path / "escape.c3d"
    labels = [f"M{i}" for i in range(19)] + ["LASI\x1b[2J\x07"]
    path.write_bytes(c3d_bytes(standing_person(frames=12), labels, 100.0))
    trial = read_c3d(path)
    assert trial.labels[-1] == "LASI\\x1b[2J\\x07"


def _long_capture(frames: int) -> np.ndarray:
    """(F, 3, 3) metres: three markers one above the other, 0.5 to 1.5 m up (a body is taller
    than wide: the reader keeps Z up), wandering by a random walk; one sample missing."""
    rng = np.random.default_rng(11)
    markers = (np.cumsum(rng.normal(0, 1e-3, (frames, 3, 3)), axis=0)
               + [[0.0, 0.0, 0.5], [0.0, 0.0, 1.0], [0.0, 0.0, 1.5]])
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

    import mocaplib.io.c3d_points as decoder

    monkeypatch.setattr(decoder, "CHUNK_BYTES", 1 << 20)
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
    assert peak < 2 * trial.markers.nbytes + 2 * decoder.CHUNK_BYTES, (peak, size)
