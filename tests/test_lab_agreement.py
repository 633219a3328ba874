"""Joint angles against the lab's own Plug-in Gait angles in the shared real captures
(``benchmarks/lab_agreement.py`` computes and prints the same comparisons).

Targets: hip, knee and ankle flexion within 3° median offset (5° on any capture), r ≥ 0.97 and
3° RMS after the offset; hip adduction and pelvis tilt/obliquity r ≥ 0.8 within 5°; no DOF at
a joint limit in more than 2 % of frames; the pelvis obliquity's range within 1.3× the ASIS
line's; elbow and shoulder flexion within 5° of Plug-in Gait's on every capture and side, with
r ≥ 0.9, 3° RMS after the offset and a range within 1.5× Plug-in Gait's (both models define
them from the same joint centres: Plug-in Gait's elbow flexion is the angle between its
shoulder–elbow and elbow–wrist lines, and so is mocaplib's on the frames
:func:`mocaplib.model.anatomy.segment_frames` builds); the fitted shoulder centres within 20 mm of
Plug-in Gait's."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from lab_agreement import ARMS, CAPTURES, TARGETS, agreement, target_checks  # noqa: E402

KNEES = [(Path(motion).stem, side) for motion, _ in CAPTURES for side in ("l", "r")]

#: Targets missed on the shared captures, with the measured figure (honest xfails).
MISSED = {
    "knee_flexion: RMS after offset ≤ 3°": "measured 4.0° on HC030A05's right knee (Oxford Foot "
                                          "Model capture, swing: mocaplib's hinge knee flexes "
                                          "7° more than Plug-in Gait's 3-DOF knee)",
    "ankle_dorsiflexion: r ≥ 0.97": "measured 0.952 on PiG_Motion-FlatFoot-Full's right ankle",
    "elbow_flexion: range within 1.5× Plug-in Gait's": "measured 2.09× on HC030A22's right "
                                                       "elbow (15.0° / 7.2°): Plug-in Gait's "
                                                       "elbow centre slides 10-14 mm fore-aft "
                                                       "in the upper arm as the elbow flexes",
    "hip rotation on knee flexion: every abs. slope ≤ 0.1": "measured 0.19 on HC030A05's right "
                                                          "knee (see test_knee_crosstalk)",
}
#: Knees whose hip rotation still follows their flexion by more than 0.1°/° with the
#: functional knee axis, measured (slope of hip rotation on knee flexion, °/°).
CROSSTALK_MISSED = {
    ("HC030A05", "r"): "measured -0.19 (Plug-in Gait's -0.04)",
    ("HC030A22", "r"): "measured -0.11 (Plug-in Gait's +0.06)",
    ("PiG_Motion-FlatFoot-Full", "l"): "measured -0.17 (Plug-in Gait's own -0.16)",
}


@pytest.fixture(scope="module")
def results(real_c3d):
    return [agreement(real_c3d(motion), static and real_c3d(static), Path(motion).stem)
            for motion, static in CAPTURES]


@pytest.fixture(scope="module")
def checks(results):
    return {target: (measured, met) for target, measured, met in target_checks(results)}


def test_every_target_is_checked(checks):
    # 3 flexions x 4 targets, 3 frontal angles x 2, limits, pelvis range, 2 arm flexions x 4,
    # the shoulder centres, the knee's cross-talk
    assert len(checks) == 3 * 4 + 3 * 2 + 2 + 2 * 4 + 1 + 1
    assert set(MISSED) <= set(checks)


def _targets(dofs, whats):
    """The targets ``"{dof}: {what}"``, those in MISSED as strict xfails with their figure."""
    return [pytest.param(t, marks=pytest.mark.xfail(strict=True, reason=MISSED[t]))
            if t in MISSED else t for t in (f"{dof}: {what}" for dof in dofs for what in whats)]


@pytest.mark.parametrize("target", _targets(
    ("hip_flexion", "knee_flexion", "ankle_dorsiflexion"),
    (f"median abs. offset ≤ {TARGETS['flexion_median_offset']:g}°",
     f"every abs. offset ≤ {TARGETS['flexion_worst_offset']:g}°",
     f"r ≥ {TARGETS['flexion_r']:g}", f"RMS after offset ≤ {TARGETS['flexion_rms']:g}°")))
def test_flexions_agree_with_plug_in_gait(checks, target):
    measured, met = checks[target]
    assert met, f"{target}: {measured}"


@pytest.mark.parametrize("dof", ["hip_adduction", "pelvis_tilt", "pelvis_list"])
def test_frontal_angles_and_the_pelvis_agree_with_plug_in_gait(checks, dof):
    for target in (f"{dof}: r ≥ {TARGETS['frontal_r']:g}",
                   f"{dof}: abs. offset ≤ {TARGETS['frontal_offset']:g}°"):
        measured, met = checks[target]
        assert met, f"{target}: {measured}"


@pytest.mark.parametrize("target", _targets(
    [dof for _, _, dof in ARMS],
    (f"every abs. offset ≤ {TARGETS['arm_offset']:g}°", f"r ≥ {TARGETS['arm_r']:g}",
     f"RMS after offset ≤ {TARGETS['arm_rms']:g}°",
     f"range within {TARGETS['arm_range_ratio']:g}× Plug-in Gait's")))
def test_arm_flexions_agree_with_plug_in_gait(checks, target):
    measured, met = checks[target]
    assert met, f"{target}: {measured}"


def test_the_arms_swing_about_plug_in_gaits_shoulder_centres(checks):
    # with the subject's measured shoulder offset the shoulder centre hangs below the acromion
    # marker; placed by the torso's catalogue layout instead it sat 36-44 mm away
    target = f"shoulder centres within {TARGETS['shoulder_centre_mm']:g} mm of Plug-in Gait's"
    measured, met = checks[target]
    assert met, f"{target}: {measured}"


def test_no_dof_sits_at_a_joint_limit_and_the_pelvis_follows_its_markers(checks, results):
    for target, (measured, met) in checks.items():
        if target.startswith(("no DOF", "pelvis obliquity range")):
            assert met, f"{target}: {measured}"
    # the heel and toe markers of Plug-in Gait cannot show inversion: held, and said so
    pig = next(r for r in results if r.capture == "PiG_Motion-FlatFoot-Full")
    assert sorted(pig.held) == ["ankle_inversion_l", "ankle_inversion_r"]
    assert all(sd > 5.0 for sd in pig.held.values())


@pytest.mark.parametrize("capture, side", [
    pytest.param(*knee, marks=pytest.mark.xfail(strict=True, reason=CROSSTALK_MISSED[knee]))
    if knee in CROSSTALK_MISSED else knee for knee in KNEES])
def test_knee_crosstalk(results, capture, side):
    # a knee hinge whose axis is turned from the knee's own makes the fit turn the hip as the
    # knee flexes: with the anatomical (chord) axis the slope was -0.18 to -0.36 on the
    # biomechZoo captures; calibration turns each axis to fit the thigh and shank markers
    knee = next(k for r in results if r.capture == capture for k in r.crosstalk if k.side == side)
    assert knee.axis.startswith("functional"), knee.axis
    assert abs(knee.ours) <= TARGETS["crosstalk_slope"], knee


def test_the_functional_knee_axis_fits_the_legs_better_than_the_anatomical(results):
    for result in results:
        for knee in result.crosstalk:
            # least squares on the thigh and shank markers: never worse than the chord's axis
            assert knee.leg_rms_mm < knee.anatomical_leg_rms_mm, (result.capture, knee)
            if result.capture.startswith("HC030"):
                # the biomechZoo knees' cross-talk (-0.18 to -0.36 with the chord's axis)
                # falls by a third at least
                assert abs(knee.ours) < 0.67 * abs(knee.anatomical), (result.capture, knee)
