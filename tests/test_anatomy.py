"""Anatomical joint centres and frames (mocaplib.model.anatomy) against Plug-in Gait's own points in
the shared captures, and their geometry."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.model.anatomy import chord_centre, davis_hip, frame, pelvis_axes
from mocaplib.io.c3d import read_c3d


@pytest.fixture(scope="module")
def static(real_c3d):
    """biomechzoo's static with Plug-in Gait's points (read with ezc3d) and its measurements."""
    ezc3d = pytest.importorskip("ezc3d")
    path = real_c3d("biomechzoo/HC030A01.c3d")
    c3d = ezc3d.c3d(str(path))
    point = c3d["parameters"]["POINT"]
    labels = [label for key in ("LABELS", "LABELS2") for label in point[key]["value"]]
    data = c3d["data"]["points"][:3].transpose(2, 1, 0) / 1000.0
    return {label: data[:, i] for i, label in enumerate(labels)}, read_c3d(path).measurements


def test_processing_measurements_are_read_in_si_units(static):
    _, measured = static
    # the file's PROCESSING group: LKneeWidth 102 mm, RShoulderOffset 35 mm, RAnkleWidth 59 mm,
    # Bodymass 45.8 kg...
    assert measured["knee_width_l"] == pytest.approx(0.102)
    assert measured["shoulder_offset_r"] == pytest.approx(0.035)
    assert measured["ankle_width_r"] == pytest.approx(0.059)
    assert measured["leg_length_l"] == pytest.approx(0.830)
    assert measured["marker_diameter"] == pytest.approx(0.010)
    assert measured["body_mass"] == pytest.approx(45.8, rel=1e-6)


def test_chord_knee_and_ankle_centres_are_plug_in_gaits(static):
    points, measured = static
    for side, other in ("LR", "RL"):
        s = side.lower()
        medial = points[f"{other}HJC"] - points[f"{side}HJC"]     # towards the midline
        delta = 0.5 * (measured[f"knee_width_{s}"] + measured["marker_diameter"])
        knee = chord_centre(points[f"{side}HJC"], points[f"{side}THI"], points[f"{side}KNE"],
                            delta, medial_hint=medial)
        # Plug-in Gait's femur origin is its knee centre; the same definition to round-off of
        # the file's single-precision coordinates
        np.testing.assert_allclose(knee, points[f"{side}FEO"], atol=5e-4)
        delta = 0.5 * (measured[f"ankle_width_{s}"] + measured["marker_diameter"])
        ankle = chord_centre(points[f"{side}FEO"], points[f"{side}TIB"], points[f"{side}ANK"],
                             delta, medial_hint=medial)
        np.testing.assert_allclose(ankle, points[f"{side}TIO"], atol=5e-4)


def test_davis_hips_are_plug_in_gaits(static):
    points, measured = static
    for side in "LR":
        s = side.lower()
        hip = davis_hip(points["LASI"], points["RASI"], points["SACR"], side=s,
                        leg_length=measured[f"leg_length_{s}"],
                        marker_radius=0.5 * measured["marker_diameter"],
                        asis_trochanter=measured.get(f"asis_trochanter_{s}"),
                        asis_distance=measured["inter_asis_distance"])
        np.testing.assert_allclose(hip, points[f"{side}HJC"], atol=5e-4)


def test_frames_are_right_handed_with_the_asked_axes():
    rng = np.random.default_rng(0)
    primary, secondary = rng.normal(size=(2, 50, 3))
    for order in ("zy", "yz", "yx", "xy", "zx", "xz"):
        R = frame(primary, secondary, order=order)
        np.testing.assert_allclose(R.transpose(0, 2, 1) @ R, np.broadcast_to(np.eye(3), R.shape),
                                   atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
        first = R[..., "xyz".index(order[0])]
        np.testing.assert_allclose(first, primary / np.linalg.norm(primary, axis=1)[:, None],
                                   atol=1e-12)
        # the second axis lies in the plane of the two vectors, on the secondary's side
        second = R[..., "xyz".index(order[1])]
        assert ((second * secondary).sum(axis=1) > 0).all()


def test_the_pelvis_frame_is_level_when_the_asis_and_psis_are():
    lasi, rasi, back = np.array([[0.05, 0.12, 0.9]]), np.array([[0.05, -0.12, 0.9]]), \
        np.array([[-0.12, 0.0, 0.9]])
    np.testing.assert_allclose(pelvis_axes(lasi, rasi, back)[0], np.eye(3), atol=1e-12)
    # the back 3 cm higher: the pelvis tilts forward (its X axis points down)
    tilted = pelvis_axes(lasi, rasi, back + [0.0, 0.0, 0.03])[0]
    assert tilted[2, 0] < 0 and np.degrees(np.arcsin(-tilted[2, 0])) == pytest.approx(
        np.degrees(np.arctan(0.03 / 0.17)), abs=1e-9)


def test_functional_centre_of_a_hinge_is_found_nearest_the_proximal_centre():
    from mocaplib.model.functional import functional_joint, marker_frames

    rng = np.random.default_rng(0)
    n = 200
    angle = np.deg2rad(60.0) * (0.5 - 0.5 * np.cos(np.linspace(0, 4 * np.pi, n)))   # 0-60°
    knee = np.array([0.02, 0.01, 0.5])                      # the true centre, world, fixed thigh
    hip = knee + (0.0, 0.0, 0.42)
    thigh = knee + np.array([[0.08, 0.09, 0.2], [0.0, 0.1, 0.25], [0.05, 0.11, 0.12]])
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((n, 3, 3))
    R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, -s, 1.0, s, c   # about Y
    shank_local = np.array([[0.05, 0.07, -0.15], [-0.03, 0.08, -0.2], [0.02, 0.06, -0.3]])
    shank = knee + np.einsum("fij,mj->fmi", R, shank_local)
    noise = 0.0005
    frames = [marker_frames(np.broadcast_to(thigh, (n, 3, 3)) + rng.normal(0, noise, (n, 3, 3))),
              marker_frames(shank + rng.normal(0, noise, shank.shape))]
    # a hinge: the centre slides along its axis (Y) unless the hip says where
    found = functional_joint(*frames, hint=np.broadcast_to(hip, (n, 3))).centre
    # 0.5 mm of marker noise leaves the centre within a few millimetres
    np.testing.assert_allclose(np.median(found, axis=0), knee, atol=0.004)
    still = [marker_frames(np.broadcast_to(x, (n, 3, 3)).copy()) for x in (thigh, shank_local)]
    assert functional_joint(*still).range_deg == 0.0         # no turn: nothing to find


def test_leg_frames_are_the_legs_of_segment_frames_to_the_bit():
    # calibration builds the legs again for each trial knee axis (leg_frames) and keeps the
    # other frames: the legs must be those segment_frames builds with the same turns
    from mocaplib.model.anatomy import leg_frames, segment_frames

    rng = np.random.default_rng(1)
    n = 20

    def wobble():
        return rng.normal(scale=0.01, size=(n, 3))

    centres, where = {}, {}
    for side, y in (("l", 0.09), ("r", -0.09)):
        centres[(f"femur_{side}", 0.0)] = np.array([0.0, y, 0.9]) + wobble()
        centres[(f"tibia_{side}", 0.0)] = np.array([0.03, y, 0.5]) + wobble()
        centres[(f"foot_{side}", 0.0)] = np.array([0.0, y, 0.08]) + wobble()
        where[f"{side.upper()}_KNEE_LAT"] = np.array([0.03, y * 1.6, 0.5]) + wobble()
        where[f"{side.upper()}_HEEL"] = np.array([-0.05, y, 0.04]) + wobble()
        where[f"{side.upper()}_TOE"] = np.array([0.15, y, 0.03]) + wobble()
    turns = {"l": 0.2, "r": -0.1}
    flat = rng.random(n) < 0.5
    for flat_feet in (None, {"l": flat, "r": ~flat}):
        whole = segment_frames(where, centres, flat_feet=flat_feet, knee_turns=turns)
        for side, turn in turns.items():
            legs = leg_frames(where, centres, side, flat=(flat_feet or {}).get(side),
                              knee_turn=turn)
            assert sorted(legs) == [f"femur_{side}", f"foot_{side}", f"tibia_{side}"]
            for name, (R, origin) in legs.items():
                assert R.tobytes() == whole[name][0].tobytes()
                assert origin.tobytes() == whole[name][1].tobytes()
            # the turn turns the femur's frame about its long axis (Z)
            plain = leg_frames(where, centres, side)[f"femur_{side}"][0]
            assert np.allclose(plain[..., 2], legs[f"femur_{side}"][0][..., 2])
            assert not np.allclose(plain[..., 1], legs[f"femur_{side}"][0][..., 1])


def test_the_foot_lies_along_the_sole_it_stands_flat_on():
    # a heel marker 25 mm above the sole and a toe marker 10 mm above it: their line rises
    # -4.3° over the sole; in the frames the foot stands flat the foot frame must be level,
    # and pitched by the ankle's own turn elsewhere, whatever the markers' heights
    from mocaplib.model.anatomy import leg_frames

    n = 40
    pitch = np.where(np.arange(n) < 20, 0.0, np.radians(np.linspace(-20, 25, n)))   # sole's
    ankle = np.array([0.0, 0.1, 0.08])
    forward = np.stack([np.cos(pitch), np.zeros(n), np.sin(pitch)], axis=1)
    up = np.stack([-np.sin(pitch), np.zeros(n), np.cos(pitch)], axis=1)
    sole_at_ankle = ankle - 0.08 * up                           # the sole under the ankle
    where = {"L_HEEL": sole_at_ankle - 0.06 * forward + 0.025 * up,
             "L_TOE": sole_at_ankle + 0.14 * forward + 0.010 * up,
             "L_KNEE_LAT": np.tile([0.0, 0.15, 0.5], (n, 1))}
    centres = {("femur_l", 0.0): np.tile([0.0, 0.1, 0.9], (n, 1)),
               ("tibia_l", 0.0): np.tile([0.0, 0.1, 0.5], (n, 1)),
               ("foot_l", 0.0): np.tile(ankle, (n, 1))}
    flat = np.arange(n) < 20
    along_sole = leg_frames(where, centres, "l", flat=flat)["foot_l"][0]
    along_line = leg_frames(where, centres, "l")["foot_l"][0]
    rise = np.degrees(np.arcsin(along_sole[:, 2, 0]))
    line_rise = np.degrees(np.arcsin(along_line[:, 2, 0]))
    np.testing.assert_allclose(rise, np.degrees(pitch), atol=1e-9)   # exact geometry
    line = np.degrees(np.arctan2(0.010 - 0.025, 0.20))
    np.testing.assert_allclose(line_rise, np.degrees(pitch) + line, atol=1e-9)
    # no flat frame: the marker line, as before a foot-flat phase is seen
    same = leg_frames(where, centres, "l", flat=np.zeros(n, dtype=bool))["foot_l"][0]
    assert same.tobytes() == along_line.tobytes()
