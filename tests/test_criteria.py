"""The biomechanical criteria (C1 jerk, C2 closure, C3 internal power) and de Leva's segments."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.model.anthropometry import DE_LEVA, bodies
from mocaplib.gait.criteria import (GRAVITY, closure, internal_power, jerk_rms, segment_energies,
                               third_derivative)
from mocaplib.skeleton import DOF_NAMES, JOINT_ANGLES, SEGMENT_NAMES, Skeleton

D = len(DOF_NAMES)


def test_de_leva_masses_make_one_body_and_follow_the_subject():
    short, tall = bodies(Skeleton.from_height(1.5)), bodies(Skeleton.from_height(1.9))
    # de Leva's male fractions: head 6.94 % + trunk 43.46 % + twice a limb's 24.80 % = 100 %
    assert short.mass.sum() == pytest.approx(1.0, abs=1e-9)
    assert np.array_equal(short.mass, tall.mass)          # per kilogram of body mass
    np.testing.assert_allclose(tall.com, short.com * 1.9 / 1.5, atol=1e-12)  # lengths scale
    np.testing.assert_allclose(tall.inertia, short.inertia * (1.9 / 1.5) ** 2, atol=1e-12)
    thigh = tall.names.index("thigh_r")
    length = Skeleton.from_height(1.9).lengths["thigh"]
    mass, at, (sagittal, transverse, longitudinal) = DE_LEVA["thigh"]
    assert tall.segments[thigh] == SEGMENT_NAMES.index("femur_r")
    np.testing.assert_allclose(tall.com[thigh], [0.0, 0.0, -at * length])   # 40.95 % down
    np.testing.assert_allclose(tall.inertia[thigh], mass * (np.array(
        [sagittal, transverse, longitudinal]) * length) ** 2)


def test_third_derivative_and_jerk_of_a_sine():
    rate, w = 1000.0, 2 * np.pi * 1.5
    t = np.arange(2000) / rate
    x = np.sin(w * t)[:, None]
    third = third_derivative(x, rate)
    assert np.isnan(third[:2]).all() and np.isnan(third[-2:]).all()
    np.testing.assert_allclose(third[2:-2, 0], -w ** 3 * np.cos(w * t[2:-2]), rtol=1e-3,
                               atol=1e-3 * w ** 3)
    periodic = third_derivative(x, rate, periodic=True)     # 2 s: exactly 3 periods
    np.testing.assert_allclose(periodic[:, 0], -w ** 3 * np.cos(w * t), atol=1e-3 * w ** 3)
    assert jerk_rms(periodic) == pytest.approx(w ** 3 / np.sqrt(2), rel=1e-3)
    assert jerk_rms(third) == pytest.approx(w ** 3 / np.sqrt(2), rel=0.01)  # NaN ends left out
    assert np.isnan(jerk_rms(np.full((3, 2), np.nan)))


def test_closure_reads_the_joint_angles_only():
    start, end = np.zeros(D), np.zeros(D)
    end[DOF_NAMES.index("pelvis_tx")] = 5.0           # the walk moves on: not a joint angle
    end[DOF_NAMES.index("pelvis_rotation")] = 1.0     # neither is the heading
    end[DOF_NAMES.index("knee_flexion_r")] = 0.03
    end[DOF_NAMES.index("hip_flexion_l")] = -0.04
    assert closure(start, end) == pytest.approx(0.05)
    assert JOINT_ANGLES.sum() == D - 4


def _walk(rate: float, seconds: float = 2.0) -> np.ndarray:
    t = np.arange(int(seconds * rate)) / rate
    q = np.zeros((len(t), D))
    q[:, DOF_NAMES.index("pelvis_tz")] = 0.9
    return t, q


def test_a_rigid_body_moving_steadily_needs_no_power():
    skeleton = Skeleton.from_height(1.75)
    rate = 200.0
    t, q = _walk(rate)
    q[:, DOF_NAMES.index("pelvis_tx")] = 1.3 * t              # straight, steady
    q[:, DOF_NAMES.index("knee_flexion_l")] = 0.4             # any fixed posture
    assert internal_power(segment_energies(skeleton, q, rate), t[-1]) < 1e-9
    q[:, DOF_NAMES.index("pelvis_tx")] = 0.0
    q[:, DOF_NAMES.index("pelvis_rotation")] = 0.8 * t        # a steady spin on the spot
    energies = segment_energies(skeleton, q, rate)
    assert internal_power(energies[5:-5], t[-10] - t[0]) < 1e-6  # one-sided ends left out


def test_spin_energy_is_the_bodies_rotational_and_circular_energy():
    skeleton = Skeleton.from_height(1.75)
    parts = bodies(skeleton)
    rate, spin = 1000.0, 1.2                                      # rad/s about +Z
    t, q = _walk(rate, 0.5)
    q[:, DOF_NAMES.index("pelvis_rotation")] = spin * t
    energies = segment_energies(skeleton, q, rate, parts=parts)
    centres = skeleton.forward(q[:1])[0, parts.segments]
    centres = (centres[:, :3, :3] @ parts.com[:, :, None])[:, :, 0] + centres[:, :3, 3]
    radius2 = centres[:, 0] ** 2 + centres[:, 1] ** 2             # from the spin axis
    expected = (0.5 * spin ** 2 * (parts.inertia[:, 2] + parts.mass * radius2)
                + parts.mass * GRAVITY * centres[:, 2])
    np.testing.assert_allclose(energies[250], expected, rtol=1e-5, atol=1e-9)


def test_internal_power_of_a_bouncing_body_matches_its_energy_changes():
    # the whole body bobs 3 cm at 2 Hz: every body's energy is ½ m ż² + m g z (+ constants),
    # the sum of masses is 1, so the power is the mean |d/dt(½ ż² + g z)|
    skeleton = Skeleton.from_height(1.75)
    rate, amplitude, w = 500.0, 0.03, 2 * np.pi * 2.0
    t, q = _walk(rate, 1.0 + 1 / rate)
    q[:, DOF_NAMES.index("pelvis_tz")] += amplitude * np.sin(w * t)
    energies = segment_energies(skeleton, q, rate)
    fine = np.linspace(0, 1, 200001)
    z_dot, z_ddot = amplitude * w * np.cos(w * fine), -amplitude * w ** 2 * np.sin(w * fine)
    expected = np.mean(np.abs(z_dot * z_ddot + GRAVITY * z_dot))
    inner = slice(1, -1)                                          # centred differences only
    assert internal_power(energies[inner], (len(t) - 3) / rate) == pytest.approx(expected,
                                                                                 rel=0.01)
    # periodic differences of one cycle sampled over [0, T) give the same
    one = q[:-1]
    assert internal_power(np.vstack([e := segment_energies(skeleton, one, rate, periodic=True),
                                     e[:1]]), 1.0) == pytest.approx(expected, rel=0.01)


# --------------------------------------------------------------------------- targets
#: Pronost et al.'s internal power of natural walking, W/kg (see docs/poulaines.md).
NATURAL_WALKING = (5.1, 7.2)


def _natural(library):
    """C3 of the walks at a self-chosen or the samples' normal speed (not CMU's brisk walk)."""
    power = library.table["qc_internal_power_w_kg"]
    keep = [i for i in power.index if ("walk_" not in i or "_normal_" in i)
            and not i.startswith("07_12")]
    return power[keep]


def test_internal_power_is_computed_for_every_entry():
    from walking_library import synthetic_walks

    power = synthetic_walks()[0].table["qc_internal_power_w_kg"]
    assert len(power) == 21 and power.notna().all() and (power > 0).all()
    # faster walks take more power: slow < normal < fast on the straight walks (each capture's
    # chosen cycle, whichever it is)
    by_speed = [power[[i for i in power.index if i.startswith(f"walk_straight_{speed}_c")]]
                for speed in ("slow", "normal", "fast")]
    assert all(len(p) == 1 for p in by_speed)
    assert by_speed[0].iloc[0] < by_speed[1].iloc[0] < by_speed[2].iloc[0]


@pytest.mark.real
def test_internal_power_is_computed_for_every_real_entry():
    from walking_library import real_walks

    power = real_walks()[0].table["qc_internal_power_w_kg"]
    assert power.notna().all() and (power > 0).all()


@pytest.mark.xfail(strict=True, reason="measured 2.41-3.37 W/kg on the 7 synthetic walks at "
                                       "normal speed (1.0-1.2 m/s), below 5.1-7.2 W/kg")
def test_internal_power_of_natural_synthetic_walks_is_in_the_published_range():
    from walking_library import synthetic_walks

    power = _natural(synthetic_walks()[0])
    assert len(power) == 7
    lo, hi = NATURAL_WALKING
    assert power.between(lo, hi).all(), power.round(2).to_dict()


@pytest.mark.real
@pytest.mark.xfail(strict=True, reason="measured 0.90-3.69 W/kg on the real walks at their own "
                                       "speed (0.69-1.47 m/s), below 5.1-7.2 W/kg")
def test_internal_power_of_natural_real_walks_is_in_the_published_range():
    from walking_library import real_walks

    power = _natural(real_walks()[0])
    lo, hi = NATURAL_WALKING
    assert power.between(lo, hi).all(), power.round(2).to_dict()


def test_internal_power_of_natural_synthetic_walks_is_no_lower_than_measured():
    from walking_library import synthetic_walks

    # measured 2.41-3.37 W/kg: a power further below the published range fails
    power = _natural(synthetic_walks()[0])
    assert power.min() >= 2.41 - 0.1, power.round(2).to_dict()


@pytest.mark.real
def test_internal_power_of_natural_real_walks_is_no_lower_than_measured():
    from walking_library import real_walks

    # measured 0.90-3.69 W/kg: a power further below the published range fails
    power = _natural(real_walks()[0])
    assert power.min() >= 0.90 - 0.1, power.round(2).to_dict()
