"""The layout of a C3D file's data (points and analog words per frame, frames) chosen from the
header and the parameters and checked against the file size: the combination that fits the
data is read, with a note naming the values that disagree; when none fits, a C3DError names
them. Files written here by the ``c3d`` package, then edited as other systems write them."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocaplib.errors import C3DError
from mocaplib.io.c3d import read_c3d

from c3d_files import (capture_bytes, cut_after, data_start, standing_person, with_header_word,
                       with_parameter, without)

#: Float32 millimetres read back in metres: the float32 step at 4 m is 2.4e-7 m.
ATOL_M = 1e-6


def walker(frames: int, markers: int) -> np.ndarray:
    """(F, M, 3) metres: ``markers`` points of :func:`standing_person`, some missing."""
    cloud = standing_person(frames)[:, np.arange(markers) % 20]
    cloud = cloud + np.arange(markers)[None, :, None] * 1e-3      # distinct points
    cloud[frames // 3, 0] = np.nan
    return cloud


def read(data: bytes, tmp_path, name: str = "capture.c3d"):
    path = tmp_path / name
    path.write_bytes(data)
    return read_c3d(path)


def assert_markers(trial, markers):
    np.testing.assert_array_equal(np.isnan(trial.markers), np.isnan(markers))
    np.testing.assert_allclose(trial.markers, markers, atol=ATOL_M, rtol=0)


def layout_notes(trial) -> list[str]:
    return [w for w in trial.warnings if "disagrees with itself" in w]


# ----------------------------------------------------------------------------- analog words
@pytest.mark.parametrize("header_frames", [280, 840], ids=["frames-agree", "header-840-frames"])
def test_analog_words_the_header_miscounts_are_taken_from_what_fits(tmp_path, header_frames):
    """8 points and 16 channels sampled 7 times a frame: 112 analog words a frame
    (ANALOG:USED x ANALOG:RATE / POINT:RATE), 576 bytes, which the file size agrees with.
    The header says 16 words (192 bytes a frame): stepping by it reads analog samples as
    markers. With the header's last frame at 840 as well, 840 frames of 192 bytes fill the
    data section exactly too; the parameters (analog words, POINT:FRAMES, TRIAL) outvote it."""
    markers = walker(280, 8)
    data = capture_bytes(markers, [f"M{i}" for i in range(8)], analog=(16, 7))
    data = with_header_word(with_header_word(data, 3, 16), 5, header_frames)
    trial = read(data, tmp_path)
    assert trial.n_frames == 280
    assert_markers(trial, markers)
    notes = layout_notes(trial)
    assert any("analog words per frame" in n and "112 (ANALOG:USED x ANALOG:RATE / POINT:RATE"
               in n and "16 (the header)" in n for n in notes), trial.warnings
    assert ("840 (the header)" in " ".join(notes)) == (header_frames == 840)


# ----------------------------------------------------------------------------- frames
def test_point_frames_is_a_count_that_may_fill_the_file_exactly(tmp_path):
    """A writer counting frames from 0: header frames 0-669, POINT:FRAMES 670 (a count), no
    TRIAL group, the 670 frames fill the data section to its last byte. Taken as the last
    frame's number, 670 would mean 671 frames, one more than the file holds."""
    markers = walker(670, 40)                                   # 640 bytes a frame
    data = capture_bytes(markers, [f"M{i}" for i in range(40)])
    data = without(without(data, "TRIAL:ACTUAL_START_FIELD"), "TRIAL:ACTUAL_END_FIELD")
    data = cut_after(with_header_word(with_header_word(data, 4, 0), 5, 669), 670, 640)
    trial = read(data, tmp_path)
    assert (trial.n_frames, trial.first_frame) == (670, 0)
    assert_markers(trial, markers)
    assert layout_notes(trial) == []


def test_point_frames_one_more_than_the_data_holds_gives_way_to_the_header(tmp_path):
    """POINT:FRAMES 500, the header and the data section 499 frames (no TRIAL group): 499
    frames are read, and a note names both counts."""
    markers = walker(499, 40)
    data = capture_bytes(markers, [f"M{i}" for i in range(40)])
    data = without(without(data, "TRIAL:ACTUAL_START_FIELD"), "TRIAL:ACTUAL_END_FIELD")
    trial = read(with_parameter(data, "POINT:FRAMES", 500), tmp_path)
    assert trial.n_frames == 499
    assert_markers(trial, markers)
    [note] = layout_notes(trial)
    assert "frames" in note and "499 (the header" in note and "500 (POINT:FRAMES)" in note


def test_frame_counts_that_all_agree_but_exceed_the_file_are_truncation(tmp_path):
    markers = walker(30, 40)
    data = capture_bytes(markers, [f"M{i}" for i in range(40)])
    with pytest.raises(C3DError, match=r"truncated: 30 frames of 40 points need \d+ bytes"):
        read(cut_after(data, 29, 640), tmp_path)


# ----------------------------------------------------------------------------- points
@pytest.mark.parametrize("count", [40, 20], ids=["frames-of-640-bytes", "frames-of-320-bytes"])
def test_point_used_one_more_than_labels_and_header_reads_the_header_count(tmp_path, count):
    """POINT:USED one more than the labels and the header's point count. With 40 points a
    frame only the header's count fits the file; with 20, 12 frames of 21 points also fit in
    the final block's padding, and the labels side with the header."""
    frames = 12 if count == 20 else 30
    markers = walker(frames, count)
    data = capture_bytes(markers, [f"M{i}" for i in range(count)])
    trial = read(with_parameter(data, "POINT:USED", count + 1), tmp_path)
    assert trial.labels == [f"M{i}" for i in range(count)]
    assert_markers(trial, markers)
    [note] = layout_notes(trial)
    assert f"points per frame: {count} (the header" in note
    assert f"{count + 1} (POINT:USED)" in note


def test_point_counts_that_disagree_and_fit_nowhere_are_named_not_called_truncation(tmp_path):
    markers = walker(30, 40)
    data = capture_bytes(markers, [f"M{i}" for i in range(40)])
    data = cut_after(with_parameter(data, "POINT:USED", 41), 29, 640)
    with pytest.raises(C3DError) as info:
        read(data, tmp_path)
    message = str(info.value)
    assert "truncated:" not in message
    assert re.search(r"points per frame: 41 \(POINT:USED\), 40 \(the header", message), message
    assert f"data section ({29 * 640} bytes" in message


# ----------------------------------------------------------------------------- property
@st.composite
def layouts(draw):
    """A consistent file: points, analog channels x samples a frame, frames, storage."""
    return dict(count=draw(st.integers(1, 6)), channels=draw(st.integers(0, 3)),
                per_frame=draw(st.integers(1, 4)), frames=draw(st.integers(1, 25)),
                scale=draw(st.sampled_from([-1.0, 0.25])), seed=draw(st.integers(0, 2**16)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(layouts())
def test_any_consistent_layout_reads_back_what_was_written(tmp_path, layout):
    rng = np.random.default_rng(layout["seed"])
    frames, count = layout["frames"], layout["count"]
    # a body-shaped cloud (taller than wide: read Z up) somewhere within 4 m of the origin,
    # above the floor: no sample rounds to (0, 0, 0), which is read as missing
    place = rng.uniform(-3.5, 3.5, size=3) * [1.0, 1.0, 0.0]
    markers = place + rng.uniform([-0.3, -0.3, 0.05], [0.3, 0.3, 1.8], size=(frames, count, 3))
    markers[rng.random((frames, count)) < 0.1] = np.nan
    data = capture_bytes(markers, [f"P{i}" for i in range(count)], scale=layout["scale"],
                         analog=(layout["channels"], layout["per_frame"]))
    trial = read(data, tmp_path)
    assert trial.n_frames == frames and trial.labels == [f"P{i}" for i in range(count)]
    assert trial.vertical_axis == "Z"
    assert not layout_notes(trial), trial.warnings
    assert data_start(data) + frames * (4 * count + layout["channels"] * layout["per_frame"]) \
        * (4 if layout["scale"] < 0 else 2) <= len(data)
    # float32 mm: 1e-6 m; int16 x 0.25 mm: the writer truncates to the step, 2.5e-4 m
    atol = ATOL_M if layout["scale"] < 0 else 0.25e-3 + ATOL_M
    np.testing.assert_array_equal(np.isnan(trial.markers), np.isnan(markers))
    np.testing.assert_allclose(trial.markers, markers, atol=atol, rtol=0)
