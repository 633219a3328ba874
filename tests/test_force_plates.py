"""The force plates read_c3d reads: on the real files, each plate's vertical force, rate and
corners equal ezc3d's reading (``benchmarks/event_accuracy.vertical_forces``); on small files
written here, a known vertical force reads back in every storage, and a plate that cannot be
read is named in a warning while the markers and the other plates still read."""

from __future__ import annotations

import struct
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import mocaplib.io.c3d as c3d_reader
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_axis import to_z_up

from c3d_files import data_start, standing_person, with_parameter, without
from conftest import SHARED_C3D, real_files

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from event_accuracy import vertical_forces  # noqa: E402

REAL = [path.relative_to(SHARED_C3D).as_posix() for path in real_files()]
FRAMES, RATE, PER_FRAME, CHANNELS = 40, 100.0, 10, 8
#: The plate's channels (FORCE_PLATFORM:CHANNEL, 1-based): Fx, Fy, Fz, Mx, My, Mz.
PLATE_CHANNELS = (3, 4, 5, 6, 7, 8)
#: Corners (mm, C3D order: corner by corner) of a 400 x 600 mm plate.
CORNERS_MM = np.array([[200.0, 300.0, 0.0], [-200.0, 300.0, 0.0], [-200.0, -300.0, 0.0],
                       [200.0, -300.0, 0.0]])


def _load() -> np.ndarray:
    """A stance on the plate: (FRAMES x PER_FRAME,) whole newtons, 0 but for a 700 N bump over
    the middle 40 % of the samples."""
    samples = FRAMES * PER_FRAME
    load = np.zeros(samples)
    stance = np.arange(int(0.3 * samples), int(0.7 * samples))
    load[stance] = np.round(700.0 * np.sin(np.pi * (stance - stance[0] + 1) / (len(stance) + 1)))
    return load


LOAD = _load()


def _analogs() -> np.ndarray:
    """(CHANNELS, samples) as the plate records LOAD: its Fz reads the load downwards with a
    12 N bias; the other channels hold whole numbers."""
    rng = np.random.default_rng(3)
    analogs = rng.integers(-50, 50, (CHANNELS, LOAD.size)).astype(np.float64)
    analogs[PLATE_CHANNELS[2] - 1] = 12.0 - LOAD
    return analogs


def _ezc3d_file(path: Path, columns=(PLATE_CHANNELS,), types=(2,)) -> Path:
    """A float C3D written by ezc3d: 20 markers, :func:`_analogs` and one plate per CHANNEL
    column in ``columns`` (each of TYPE ``types``, each with the corners CORNERS_MM)."""
    ezc3d = pytest.importorskip("ezc3d")
    c3d = ezc3d.c3d()
    markers = standing_person(FRAMES)
    c3d["parameters"]["POINT"]["RATE"]["value"] = [RATE]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = [f"M{i}" for i in range(markers.shape[1])]
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    points = np.ones((4, markers.shape[1], FRAMES))
    points[:3] = markers.transpose(2, 1, 0) * 1000.0
    c3d["data"]["points"] = points
    c3d["parameters"]["ANALOG"]["RATE"]["value"] = [RATE * PER_FRAME]
    c3d["parameters"]["ANALOG"]["LABELS"]["value"] = [f"CH{i}" for i in range(CHANNELS)]
    c3d["parameters"]["ANALOG"]["SCALE"]["value"] = [2.0] * CHANNELS   # words: half the values
    c3d["data"]["analogs"] = _analogs()[None]
    plates = c3d["parameters"]["FORCE_PLATFORM"]
    plates["USED"]["value"] = [len(columns)]
    plates["TYPE"]["value"] = list(types)
    plates["CHANNEL"]["value"] = np.array(columns).T
    plates["CORNERS"]["value"] = np.repeat(CORNERS_MM.T[:, :, None], len(columns), axis=2)
    plates["ORIGIN"]["value"] = np.zeros((3, len(columns)))
    c3d.write(str(path))
    return path


def _c3d_package_file(path: Path, *, integer: bool, unsigned: bool = False) -> Path:
    """The plate of :func:`_ezc3d_file`, written by the ``c3d`` package (ezc3d writes floats
    only) in int16 (``integer``) or float storage, with ANALOG:SCALE 0.5, OFFSET 100 and
    GEN_SCALE 2: each word is its value + 100. ``unsigned``: the words are stored 32768
    higher, as uint16 under ANALOG:FORMAT UNSIGNED, OFFSET 32868."""
    import c3d

    writer = c3d.Writer(point_rate=RATE, analog_rate=RATE * PER_FRAME,
                        point_scale=0.1 if integer else -1.0, gen_scale=2.0)
    markers = standing_person(FRAMES)
    writer.set_point_labels([f"M{i}" for i in range(markers.shape[1])])
    writer.set_analog_labels([f"CH{i}" for i in range(CHANNELS)])
    writer.set_analog_scales([0.5] * CHANNELS)
    writer.set_analog_offsets([100] * CHANNELS)
    writer.analog_group.add_str("FORMAT", "", "UNSIGNED" if unsigned else "SIGNED  ", 8)
    group = writer.add_group(3, "FORCE_PLATFORM", "force plates")
    for name, dtype, values, dimensions in (
            ("USED", "<i2", [1], []), ("TYPE", "<i2", [2], [1]),
            ("CHANNEL", "<i2", PLATE_CHANNELS, [6, 1]),
            ("CORNERS", "<f4", CORNERS_MM.ravel(), [3, 4, 1]),
            ("ORIGIN", "<f4", [0.0, 0.0, -40.0], [3, 1])):
        group.add_param(name, desc="", bytes_per_element=np.dtype(dtype).itemsize,
                        bytes=np.asarray(values, dtype).tobytes(), dimensions=dimensions)
    analogs = _analogs()
    frames = np.empty((FRAMES, 2), dtype=object)
    for index, pair in enumerate(frames):
        points = np.zeros((markers.shape[1], 5))
        points[:, :3] = markers[index] * 1000.0
        pair[0] = points
        pair[1] = analogs[:, index * PER_FRAME:(index + 1) * PER_FRAME]
    writer.add_frames(frames)
    with open(path, "wb") as handle:
        writer.write(handle)
    if unsigned:
        data = bytearray(with_parameter(path.read_bytes(), "ANALOG:OFFSET",
                                        *[32868] * CHANNELS))
        words = np.frombuffer(data, "<u2", offset=data_start(data),
                              count=FRAMES * (4 * markers.shape[1] + CHANNELS * PER_FRAME))
        block = words.reshape(FRAMES, -1)[:, 4 * markers.shape[1]:] ^ np.uint16(0x8000)
        view = np.frombuffer(data, "<u2", offset=data_start(data), count=words.size)
        view.reshape(FRAMES, -1)[:, 4 * markers.shape[1]:] = block
        path.write_bytes(bytes(data))
    return path


def _plate_notes(trial) -> list[str]:
    return [note for note in trial.warnings if "force plate" in note]


# ----------------------------------------------------------------------------- real files
@pytest.mark.parametrize("relative", REAL)
def test_real_plates_equal_ezc3d(relative, real_c3d):
    ezc3d = pytest.importorskip("ezc3d")
    path = real_c3d(relative)
    trial = read_c3d(path)
    parameters = ezc3d.c3d(str(path))["parameters"]
    used = int(parameters["FORCE_PLATFORM"]["USED"]["value"][0]) \
        if "FORCE_PLATFORM" in parameters else 0
    if not used:
        assert trial.force_plates == [] and _plate_notes(trial) == []
        return
    rate, forces = vertical_forces(path)
    assert len(trial.force_plates) == len(forces)
    factor = 1.0 if trial.units == "m" else 1e-3
    corners = np.asarray(parameters["FORCE_PLATFORM"]["CORNERS"]["value"]) * factor
    for plate, force in zip(trial.force_plates, forces):
        assert plate.rate == rate and plate.kind in (1, 2, 3, 4)
        np.testing.assert_allclose(plate.force, force, rtol=1e-9, atol=1e-9)
        expected = corners[:, :, plate.number - 1].T
        if trial.vertical_axis == "Y":
            expected = to_z_up(expected, "Y")
        np.testing.assert_allclose(plate.corners, expected, rtol=1e-12, atol=1e-12)
    read = {plate.number for plate in trial.force_plates}
    for number in range(1, used + 1):    # a plate is read, or named in one note at most
        named = [note for note in _plate_notes(trial) if f"force plate {number} " in note]
        assert len(named) <= 1 and not (named and number in read), named


def test_plates_nobody_stood_on_are_left_out_without_a_note(real_c3d):
    trial = read_c3d(real_c3d("ezc3d_testfiles/BTS.c3d"))     # plates 2, 3 and 6 read 0 N
    assert [plate.number for plate in trial.force_plates] == [1, 4, 5]
    assert _plate_notes(trial) == []
    for plate in trial.force_plates:    # a walker's stance: 0 N empty, up to a body weight
        assert 300.0 < plate.force.max() < 1500.0
        assert np.median(np.abs(plate.force[plate.force < 20.0])) < 5.0


def test_plates_loaded_throughout_are_left_out_without_a_note(real_c3d):
    # a static: the subject stands on both plates from the first sample to the last
    trial = read_c3d(real_c3d("btkdata/PiG_Calibration2-NoOption.c3d"))
    assert trial.force_plates == []
    assert _plate_notes(trial) == []


def test_the_type_4_plates_calibration_matrix_gives_newtons(real_c3d):
    # CAL_MATRIX's third row (Fz) applied to the six channels: a stance of 1.0-1.3 body
    # weights; its transpose (the third column) would not give a plausible stance
    trial = read_c3d(real_c3d("btkdata/Gait.c3d"))
    assert [plate.kind for plate in trial.force_plates] == [4, 4]
    for plate in trial.force_plates:
        assert 600.0 < plate.force.max() < 1000.0


def test_plates_read_in_small_chunks_are_those_read_whole(real_c3d, monkeypatch):
    import mocaplib.io.c3d_points as chunks

    path = real_c3d("motonms_unipd/Walking1.c3d")
    whole = read_c3d(path)
    monkeypatch.setattr(chunks, "CHUNK_BYTES", 12000)   # 5 frames of 2316 bytes, then 3
    chunked = read_c3d(path)
    assert len(chunked.force_plates) == len(whole.force_plates) == 2
    for a, b in zip(chunked.force_plates, whole.force_plates):
        np.testing.assert_array_equal(a.force, b.force)


def test_read_time_with_and_without_plates(real_c3d, monkeypatch, capsys):
    path = real_c3d("biomechzoo/HC030A22.c3d")         # the largest shared file with plates

    def best_of_five() -> float:
        times = []
        for _ in range(5):
            start = time.perf_counter()
            read_c3d(path)
            times.append(time.perf_counter() - start)
        return min(times)

    with_plates = best_of_five()
    monkeypatch.setattr(c3d_reader, "read_force_plates", lambda *args: [])
    without_plates = best_of_five()
    with capsys.disabled():
        print(f"\nread_c3d {path.name} ({path.stat().st_size / 1e6:.1f} MB): "
              f"{1000 * with_plates:.1f} ms with plates, {1000 * without_plates:.1f} ms without")


# ----------------------------------------------------------------------------- written here
def test_a_type_2_plate_written_by_ezc3d_reads_back(tmp_path):
    path = _ezc3d_file(tmp_path / "plate.c3d")
    trial = read_c3d(path)
    assert trial.warnings == [] and trial.analog_channels == CHANNELS
    np.testing.assert_allclose(trial.markers, standing_person(FRAMES), atol=1e-6)
    (plate,) = trial.force_plates
    assert (plate.number, plate.kind, plate.rate) == (1, 2, RATE * PER_FRAME)
    np.testing.assert_allclose(plate.force, LOAD, rtol=0, atol=1e-4)   # float32 words
    np.testing.assert_allclose(plate.corners, CORNERS_MM * 1e-3, rtol=1e-7)
    _, (force,) = vertical_forces(path)
    np.testing.assert_allclose(plate.force, force, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("integer, unsigned", [(True, False), (False, False), (True, True)],
                         ids=["int16", "float", "uint16"])
def test_a_known_load_reads_back_in_every_storage(tmp_path, integer, unsigned):
    path = _c3d_package_file(tmp_path / "plate.c3d", integer=integer, unsigned=unsigned)
    trial = read_c3d(path)
    assert _plate_notes(trial) == []
    np.testing.assert_allclose(trial.markers, standing_person(FRAMES), atol=0.1e-3)
    (plate,) = trial.force_plates
    assert plate.rate == RATE * PER_FRAME
    np.testing.assert_array_equal(plate.force, LOAD)                  # whole words: exact
    np.testing.assert_allclose(plate.corners, CORNERS_MM * 1e-3, rtol=1e-7)
    if not unsigned:               # ezc3d reads every integer word as signed
        _, (force,) = vertical_forces(path)
        np.testing.assert_allclose(plate.force, force, rtol=1e-9, atol=1e-9)


def test_a_channel_beyond_analog_used_skips_its_plate_and_keeps_the_rest(tmp_path):
    good = read_c3d(_ezc3d_file(tmp_path / "good.c3d"))
    trial = read_c3d(_ezc3d_file(tmp_path / "bad.c3d", columns=(PLATE_CHANNELS, (9, 10, 11, 12,
                                                                              13, 14)),
                                 types=(2, 2)))
    assert trial.warnings == ["force plate 2 not read: FORCE_PLATFORM:CHANNEL names channel "
                              "11 of 8; gait events come from the markers there"]
    assert [plate.number for plate in trial.force_plates] == [1]
    np.testing.assert_array_equal(trial.force_plates[0].force, good.force_plates[0].force)
    np.testing.assert_array_equal(trial.markers, good.markers)


def _with_float_word(data: bytes, frame: int, word: int, value: float) -> bytes:
    """``data`` (float storage, 20 markers) with word ``word`` of frame ``frame`` set."""
    out = bytearray(data)
    frame_bytes = 4 * (4 * 20 + CHANNELS * PER_FRAME)
    struct.pack_into("<f", out, data_start(data) + frame * frame_bytes + 4 * word, value)
    return bytes(out)


FZ_WORD = 4 * 20 + 3 * CHANNELS + PLATE_CHANNELS[2] - 1    # frame's 4th sample, plate's Fz
DAMAGES = {
    "unknown type": (lambda d: with_parameter(d, "FORCE_PLATFORM:TYPE", 7),
                     "force plate 1 not read: FORCE_PLATFORM:TYPE 7 is none of the types 1 to 4"),
    "no corners": (lambda d: without(d, "FORCE_PLATFORM:CORNERS"),
                   "force plate 1 not read: FORCE_PLATFORM:CORNERS gives no corners for it"),
    "no channels": (lambda d: without(d, "FORCE_PLATFORM:CHANNEL"),
                    "force plate 1 not read: FORCE_PLATFORM:CHANNEL gives it no channel 3"),
    "type 3 of 6 channels": (lambda d: with_parameter(d, "FORCE_PLATFORM:TYPE", 3),
                             "force plate 1 not read: FORCE_PLATFORM:CHANNEL gives it no "
                             "channel 8 (type 3 needs channels 5 to 8)"),
    "no type 4 matrix": (lambda d: with_parameter(d, "FORCE_PLATFORM:TYPE", 4),
                         "force plate 1 not read: FORCE_PLATFORM:CAL_MATRIX gives no 6 x 6"),
    "a NaN sample": (lambda d: _with_float_word(d, 7, FZ_WORD, float("nan")),
                     "force plate 1 not read: its channels hold values that are not finite"),
    "an infinite sample": (lambda d: _with_float_word(d, 7, FZ_WORD, float("inf")),
                           "force plate 1 not read: its channels hold values that are not"),
    "samples not a whole number": (lambda d: with_parameter(d, "ANALOG:USED", 7),
                                   "force plates not read: the 80 analog words of a frame are "
                                   "no whole number of samples of the 7 channels"),
}


@pytest.mark.parametrize("damage", DAMAGES)
def test_a_plate_that_cannot_be_read_is_named_and_the_markers_still_read(tmp_path, damage):
    edit, note = DAMAGES[damage]
    original = _ezc3d_file(tmp_path / "plate.c3d")
    damaged = tmp_path / "damaged.c3d"
    damaged.write_bytes(edit(original.read_bytes()))
    trial = read_c3d(damaged)
    np.testing.assert_array_equal(trial.markers, read_c3d(original).markers)
    assert trial.force_plates == []
    (found,) = _plate_notes(trial)
    assert found.startswith(note) and "; gait events come from the markers" in found, found


def test_no_plates_used_gives_none_and_no_note(tmp_path):
    path = tmp_path / "none.c3d"
    path.write_bytes(with_parameter(_ezc3d_file(tmp_path / "plate.c3d").read_bytes(),
                                    "FORCE_PLATFORM:USED", 0))
    trial = read_c3d(path)
    assert trial.force_plates == [] and trial.warnings == []
