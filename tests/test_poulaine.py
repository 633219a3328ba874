"""Poulaines: the four-point Hermite model of an ankle's path, its parameters and blending."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.errors import MocapError
from mocaplib.gait.fourier import RootDrift
from mocaplib.gait.poulaine import (KINDS, MIN_TRAVEL_SPEED, AnklePath, Poulaine, blend,
                               characteristic_indices, cycle_poulaine, fit_ankle, travel_angle,
                               travel_coordinates)
from mocaplib.skeleton import DOF_NAMES, Skeleton


def loop(phase, *, x0=0.05, half_step=0.32, y=0.06, z=-0.85, lift=0.12):
    """A smooth closed ankle-like path (n, 3): from the front backwards in 'support' (z low,
    phases 0 to ½), up and forwards in 'swing'."""
    w = 2 * np.pi * phase
    return np.column_stack([x0 + half_step * np.cos(w), y + 0.01 * np.sin(w),
                            z + lift * np.maximum(0.0, -np.sin(w)) ** 2])


def test_characteristic_points_are_the_documented_samples():
    phase = np.arange(120) / 120
    path = loop(phase)
    found = characteristic_indices(path)
    assert found["foremost"] == 0 and found["rearmost"] == 60          # cos 2πφ: 1 and −1
    assert found["highest"] == 90                                        # sin² peaks at φ = ¾
    # support runs from foremost (φ = 0) to rearmost (φ = ½): x crosses 0 on the way
    under = found["under_pelvis"]
    assert 0 < under < 60 and abs(path[under, 0]) <= 0.32 * 2 * np.pi / 120 / 2


def test_the_model_follows_a_smooth_path_and_passes_its_points_at_their_phases():
    phase = np.arange(110) / 110
    path = loop(phase)
    model = fit_ankle(path, phase)
    assert sorted(model.kinds) == sorted(KINDS) and np.all(np.diff(model.phases) > 0)
    # a cubic per quarter of a smooth loop: well under a millimetre
    assert model.fit_rms < 5e-4 and model.fit_max < 2e-3 and model.timed_rms < 1e-3
    np.testing.assert_allclose(model(model.phases), model.points, atol=1e-12)
    for kind, index in characteristic_indices(path).items():
        np.testing.assert_array_equal(model.point(kind), path[index])
    again = AnklePath.from_dict(model.to_dict())
    np.testing.assert_allclose(again(phase), model(phase), atol=1e-12)
    assert again.fit_rms == model.fit_rms


def test_fit_error_measures_the_distance_to_the_path():
    # a wiggle the four cubics cannot follow: 4 mm at 9 cycles per cycle, across the path
    phase = np.arange(200) / 200
    path = loop(phase)
    path[:, 1] += 0.004 * np.sin(2 * np.pi * 9 * phase)
    model = fit_ankle(path, phase)
    assert 0.002 < model.fit_rms < 0.0035 and model.fit_max < 0.006   # 4 mm / √2 = 2.8 mm
    with pytest.raises(MocapError, match="at least 8 samples"):
        fit_ankle(path[:5], phase[:5])


def test_travel_frame():
    assert travel_angle(1.2, 0.0) == 0.0
    assert travel_angle(0.0, -0.5) == pytest.approx(-np.pi / 2)          # side-step right
    assert travel_angle(0.6 * MIN_TRAVEL_SPEED, 0.5 * MIN_TRAVEL_SPEED) == 0.0   # on the spot
    q = np.zeros((3, len(DOF_NAMES)))
    q[:, :3] = [1.0, 2.0, 0.9]
    q[:, DOF_NAMES.index("pelvis_rotation")] = 0.3
    local = travel_coordinates(q, 0.2)
    assert np.all(local[:, :3] == 0.0)
    np.testing.assert_allclose(local[:, DOF_NAMES.index("pelvis_rotation")], 0.1)


def _poulaine(step, spacing, stance, travel=0.0) -> Poulaine:
    phase = np.arange(100) / 100
    left = loop(phase, half_step=step / 2, y=spacing / 2, z=-stance)
    right = loop(phase + 0.5, half_step=step / 2, y=-spacing / 2, z=-stance)
    return Poulaine(travel, fit_ankle(left, phase), fit_ankle(right, phase))


def test_parameters_are_read_on_the_characteristic_points():
    p = _poulaine(0.64, 0.12, 0.85)
    step, spacing, stance = p.parameters
    assert step == pytest.approx(0.64, abs=1e-3)        # x from +0.37 to −0.27
    assert spacing == pytest.approx(0.12, abs=0.02)     # y under the pelvis ± the 1 cm sway
    assert stance == pytest.approx(0.85, abs=1e-3)
    stored = p.to_dict()
    assert (stored["step_length_m"], stored["foot_spacing_m"], stored["stance_m"]) == \
        p.parameters and Poulaine.from_dict(stored).parameters == p.parameters
    assert p(np.array([0.0, 0.5])).shape == (2, 2, 3)
    # each loop moves back from its foremost (φ = 0) to its rearmost point (φ = ½)
    assert p.duty_factor == pytest.approx(0.5, abs=0.011)


def test_blend_takes_each_axis_from_the_closest_and_corrects_it_exactly():
    library = {"short": _poulaine(0.45, 0.10, 0.80), "long": _poulaine(0.80, 0.16, 0.88),
               "mid": _poulaine(0.62, 0.20, 0.84)}
    made = blend(library, step_length=0.75, foot_spacing=0.11, stance=0.83)
    assert made.names == ("long", "short", "mid")
    np.testing.assert_allclose(made.parameters, (0.75, 0.11, 0.83), rtol=1e-12)
    phase = np.linspace(0, 1, 7)
    ankles = made(phase)
    long_x = library["long"](phase)[..., 0] * 0.75 / library["long"].parameters[0]
    np.testing.assert_allclose(ankles[..., 0], long_x)
    np.testing.assert_allclose(ankles[:, 0, 1] - ankles[:, 1, 1],
                               library["short"](phase)[:, 0, 1] - library["short"](phase)[:, 1, 1]
                               + 0.11 - library["short"].parameters[1])
    # a tie goes to the preferred entry; its own parameters give it back unchanged
    same = blend(library, step_length=0.62, foot_spacing=0.20, stance=0.84, prefer="mid")
    assert same.names == ("mid", "mid", "mid")
    np.testing.assert_allclose(same(phase), library["mid"](phase), atol=1e-12)
    with pytest.raises(MocapError, match="must be > 0"):
        blend(library, step_length=-0.1, foot_spacing=0.1, stance=0.8)
    with pytest.raises(MocapError, match="no poulaine"):
        blend({}, step_length=0.5, foot_spacing=0.1, stance=0.8)


def test_cycle_poulaine_of_a_skeleton_standing_still_in_the_travel_frame():
    # joint angles only: the pelvis translation and the path frame's heading play no part
    skeleton = Skeleton.from_height(1.75)
    phase = np.arange(100) / 100
    q = np.zeros((100, len(DOF_NAMES)))
    q[:, :3] = [3.0, -1.0, 0.9]
    hip = DOF_NAMES.index("hip_flexion_l")
    q[:, hip] = 0.4 * np.cos(2 * np.pi * phase)
    drift = RootDrift(0.0, 0.0, 0.0, 1.0, 1.0, 0.0)          # travelling 45° to the left
    model, measured = cycle_poulaine(skeleton, q, phase, drift)
    assert model.travel == pytest.approx(np.pi / 4)
    leg = skeleton.lengths["thigh"] + skeleton.lengths["shank"]
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    hip_y = skeleton.lengths["hip_width"] / 2
    forward = leg * np.sin(q[:, hip])                          # in the pelvis frame
    expected = np.column_stack([c * forward + s * hip_y, -s * forward + c * hip_y,
                                -leg * np.cos(q[:, hip])])
    np.testing.assert_allclose(measured[:, 0], expected, atol=1e-12)


# --------------------------------------------------------------------------- targets
def test_fit_error_target_on_the_synthetic_walks():
    from walking_library import synthetic_walks

    errors = synthetic_walks()[0].table["poulaine_fit_rms_m"]
    assert len(errors) == 21 and errors.notna().all()
    assert errors.max() <= 0.005, f"worst {errors.max() * 1000:.2f} mm ({errors.idxmax()})"


@pytest.mark.real
def test_fit_error_target_on_the_real_walks():
    from walking_library import real_walks

    errors = real_walks()[0].table["poulaine_fit_rms_m"]
    assert len(errors) >= 10 and errors.notna().all()     # every cycle passing QC
    assert errors.max() <= 0.005, f"worst {errors.max() * 1000:.2f} mm ({errors.idxmax()})"


def test_aligned_phases_put_a_source_s_points_where_the_timing_has_its_own():
    from mocaplib.gait.poulaine import aligned_phases

    phase = np.arange(120) / 120
    timing = fit_ankle(loop(phase), phase)
    late = fit_ankle(loop(phase - 0.1), phase)     # the same loop, 0.1 of a cycle later
    aligned = aligned_phases(phase, timing, late)
    np.testing.assert_allclose(np.mod(aligned - phase, 1.0), 0.1, atol=1 / 120)
    np.testing.assert_allclose(late(aligned), timing(phase), atol=2e-3)
    np.testing.assert_allclose(aligned_phases(timing.phases, timing, late),
                               np.mod(timing.phases + 0.1, 1.0), atol=1 / 120)
