"""Joint angles against the lab's own Plug-in Gait angles in the shared real captures
(``benchmarks/lab_agreement.py`` computes and prints the same comparisons).

Targets: hip, knee and ankle flexion within 3° median offset (5° on any capture), r ≥ 0.97 and
3° RMS after the offset; hip adduction and pelvis tilt/obliquity r ≥ 0.8 within 5°; no DOF at
a joint limit in more than 2 % of frames; the pelvis obliquity's range within 1.3× the ASIS
line's; elbow and shoulder flexion within 5° of Plug-in Gait's on every capture and side, with
r ≥ 0.9, 3° RMS after the offset and a range within 1.5× Plug-in Gait's (both models define
them from the same joint centres: Plug-in Gait's elbow flexion is the angle between its
shoulder–elbow and elbow–wrist lines, and so is mocaplib's on the frames
:func:`mocaplib.anatomy.segment_frames` builds); the fitted shoulder centres within 20 mm of
Plug-in Gait's."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from lab_agreement import ARMS, CAPTURES, TARGETS, agreement, target_checks  # noqa: E402

#: Targets missed on the shared captures, with the measured figure (honest xfails).
MISSED = {
    "knee_flexion: RMS after offset ≤ 3°": "measured 3.9° on HC030A05's right knee (Oxford Foot "
                                          "Model capture, swing: mocaplib's hinge knee flexes "
                                          "7° more than Plug-in Gait's 3-DOF knee)",
    "ankle_dorsiflexion: r ≥ 0.97": "measured 0.958 on PiG_Motion-FlatFoot-Full's right ankle",
    "elbow_flexion: range within 1.5× Plug-in Gait's": "measured 2.07× on HC030A22's right "
                                                       "elbow (14.9° / 7.2°): Plug-in Gait's "
                                                       "elbow centre slides 10-14 mm fore-aft "
                                                       "in the upper arm as the elbow flexes",
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
    # the shoulder centres
    assert len(checks) == 3 * 4 + 3 * 2 + 2 + 2 * 4 + 1
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
