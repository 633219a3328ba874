"""The vertical axis of a capture: detected from the markers (each subject apart), the file's
screen axes as the tie-breaker; Y-up files rotated to Z up."""

from __future__ import annotations

import numpy as np

from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_axis import detect_vertical_axis, y_up_to_z_up
from mocaplib.io.c3d_write import write_c3d

from c3d_files import standing_person


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
