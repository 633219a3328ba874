"""The vertical axis of a capture: detected from the markers (each subject apart), the file's
screen axes as the tie-breaker; Y-up files rotated to Z up."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_axis import detect_vertical_axis, far_from_body, to_z_up
from mocaplib.io.c3d_write import write_c3d

from c3d_files import capture_bytes, standing_person


def test_detect_vertical_axis_every_way():
    person = standing_person()
    assert detect_vertical_axis(person) == ("Z", [])
    as_y_up = np.stack([person[..., 0], person[..., 2], -person[..., 1]], axis=-1)
    assert detect_vertical_axis(as_y_up) == ("Y", [])
    np.testing.assert_allclose(to_z_up(as_y_up, "Y"), person, atol=0)  # exact permutation
    as_x_up = person[..., [2, 0, 1]]                        # (z, x, y): a proper rotation
    assert detect_vertical_axis(as_x_up) == ("X", [])
    np.testing.assert_allclose(to_z_up(as_x_up, "X"), person, atol=0)
    for axis in ("X", "Y"):                                  # proper rotations: det +1
        turn = to_z_up(np.eye(3), axis)
        assert np.linalg.det(turn) == pytest.approx(1.0)


def test_an_x_up_file_is_read_z_up_the_same_body(real_c3d, tmp_path):
    # some systems write X up: the file is turned as a Y-up one is, left staying left
    from mocaplib.markersets.matching import detect_protocol

    original = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    trial = read_c3d(write_c3d(tmp_path / "x_up.c3d", original.markers[..., [2, 0, 1]],
                               original.labels, original.rate))
    assert trial.vertical_axis == "X"
    assert any(note.startswith("X-up file rotated to Z up") for note in trial.warnings)
    np.testing.assert_allclose(trial.markers, original.markers, atol=1e-6, equal_nan=True)
    assert detect_protocol(trial).swaps == ()


def test_vertical_axis_unclear_falls_back_to_screen_axis():
    ball = np.random.default_rng(6).normal(size=(30, 20, 3))
    axis, notes = detect_vertical_axis(ball, screen_axis="Y")
    assert axis == "Y" and "unclear" in notes[0]
    assert detect_vertical_axis(ball)[0] == "Z"


def test_two_subjects_side_by_side_do_not_make_the_floor_look_vertical():
    """Two people 3 m apart across the floor: relative to the mean of all markers the floor's
    axis would spread widest (3 m against a body's 1.7 m). Each subject's markers relative to
    their own mean show Z; without subject prefixes, the body's main cluster is one of them."""
    person = standing_person()
    pair = np.concatenate([person, person + [0.0, 3.0, 0.0]], axis=1)
    assert detect_vertical_axis(pair, subjects=["A"] * 20 + ["B"] * 20) == ("Z", [])
    assert detect_vertical_axis(pair) == ("Z", [])
    assert far_from_body(pair[0]).sum() == 20


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
    assert axis == "Z" and "screen axes (POINT:X_SCREEN, Y_SCREEN) show Y up" in notes[0]


# ----------------------------------------------------------------------------- strays
#: A lower-body Plug-in Gait static (left side; the right mirrors it), metres, Z up.
LEFT_LEG = {"ASI": (0.12, 0.12, 0.95), "PSI": (-0.08, 0.05, 1.0), "THI": (0.05, 0.16, 0.70),
            "KNE": (0.02, 0.14, 0.50), "TIB": (0.03, 0.13, 0.30), "ANK": (0.0, 0.12, 0.08),
            "HEE": (-0.08, 0.10, 0.05), "TOE": (0.14, 0.11, 0.04)}
#: Two unlabelled points 1.5 and 2.4 m from the nearest body marker, on the floor's Y axis.
STRAYS = {"*17": (0.4, 1.7, 0.02), "*18": (-0.3, 2.5, 0.3)}


def lower_body_static(frames: int = 100) -> tuple[np.ndarray, list[str]]:
    """(F, 18, 3) metres: the 16 markers of :data:`LEFT_LEG` and its mirror standing still
    (1 mm noise), then the two :data:`STRAYS`; and their labels."""
    body = {f"{side}{name}": (x, y if side == "L" else -y, z)
            for side in "LR" for name, (x, y, z) in LEFT_LEG.items()} | STRAYS
    rng = np.random.default_rng(1)
    markers = np.array(list(body.values()))[None] + rng.normal(0, 1e-3, (frames, len(body), 3))
    return markers, list(body)


def test_stray_markers_far_from_the_body_never_decide_the_vertical_axis(tmp_path):
    """A Z-up static of 16 markers and 2 stray unlabelled points 1.5-2.4 m away along Y,
    POINT:Y_SCREEN '+Z': the strays are 11 % of the markers, enough to stretch the spread
    along Y past the body's height when they count. Left out as far from the body's main
    cluster, the file stays Z up, as its screen axes say, and is not rotated."""
    markers, labels = lower_body_static()
    assert far_from_body(markers[0]).tolist() == [False] * 16 + [True] * 2
    path = tmp_path / "static.c3d"
    path.write_bytes(capture_bytes(markers, labels, screen=("+X", "+Z")))
    trial = read_c3d(path)
    assert trial.vertical_axis == "Z" and trial.warnings == []
    # float32 mm: 1e-6 m
    np.testing.assert_allclose(trial.markers, markers, atol=1e-6, rtol=0)


def test_no_point_is_far_when_the_units_spread_the_body_kilometres_wide():
    """Millimetres stored as metres: every marker is more than the link from every other, so
    the main cluster would be one marker; then no point is called far."""
    markers, _ = lower_body_static(frames=1)
    assert not far_from_body(markers[0, :16] * 1000.0).any()


@pytest.mark.parametrize("x_screen, z_screen, up", [("+X", "+Z", "Y"), ("+X", "+Y", "Z")])
def test_x_and_z_screen_axes_decide_where_the_markers_do_not(tmp_path, x_screen, z_screen, up):
    """Without POINT:Y_SCREEN, the screen's up is the axis X_SCREEN (its right) and Z_SCREEN
    (towards the viewer) leave; it decides a cloud as wide as it is tall."""
    ball = np.random.default_rng(6).normal([0.0, 0.0, 1.0], 0.3, size=(30, 20, 3))
    path = tmp_path / "ball.c3d"
    path.write_bytes(capture_bytes(ball, [f"M{i}" for i in range(20)],
                                   point_params={"X_SCREEN": [x_screen],
                                                 "Z_SCREEN": [z_screen]}))
    trial = read_c3d(path)
    assert trial.vertical_axis == up
    assert any(f"unclear from the markers; {up} assumed (the file's screen axes)" in w
               for w in trial.warnings)
