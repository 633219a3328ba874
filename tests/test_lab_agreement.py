"""Joint angles against the lab's own Plug-in Gait angles stored in the shared real captures.

Each capture is fitted as ``mocaplib fit`` fits it and compared here, frame by frame, with the
angles Plug-in Gait wrote into the same file (read with ezc3d, a reader mocaplib does not use;
``benchmarks/lab_agreement.py`` prints the same comparisons as tables). Only the list of captures
and the reading of Plug-in Gait's points come from the benchmark; the statistics, targets and
comparisons are this module's own.

Targets: hip, knee and ankle flexion within 3° median offset (5° on any capture), r ≥ 0.97 and
3° RMS after the offset; hip adduction and pelvis tilt/obliquity r ≥ 0.8 within 5°; no DOF at
a joint limit in more than 2 % of frames; the pelvis obliquity's range within 1.3× the ASIS
line's; elbow and shoulder flexion within 5° of Plug-in Gait's on every capture and side, with
r ≥ 0.9, 3° RMS after the offset and a range within 1.5× Plug-in Gait's (both models define
them from the same joint centres); the fitted shoulder centres within 20 mm of Plug-in Gait's;
hip rotation that follows knee flexion by 0.1°/° at most; the trunk within 5° of Plug-in
Gait's spine angles with and without a static. A missed target is a strict xfail
with its measured figure, and a plain test bounds that figure so that it cannot get worse.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from mocaplib.io.c3d import read_c3d
from mocaplib.model.fitting import fit_capture
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

# the captures and the reading of Plug-in Gait's points (data, not verdicts)
from lab_agreement import CAPTURES, pelvis_angles, plug_in_gait_points  # noqa: E402

#: (Plug-in Gait angle point, its component, mocaplib DOF) compared per side.
LEG_FLEXIONS = (("HipAngles", 0, "hip_flexion"), ("KneeAngles", 0, "knee_flexion"),
                ("AnkleAngles", 0, "ankle_dorsiflexion"))
ARM_FLEXIONS = (("ElbowAngles", 0, "elbow_flexion"), ("ShoulderAngles", 0, "shoulder_flexion"))
HIP_ADDUCTION = ("HipAngles", 1, "hip_adduction")
KNEES = [(Path(motion).stem, side) for motion, _ in CAPTURES for side in ("l", "r")]

#: Measured figures of the targets missed (the strict xfails' reasons); the bounds allow a
#: little more and fail beyond.
KNEE_RMS_MEASURED = 4.0            # degrees, HC030A05's right knee
ANKLE_R_MEASURED = 0.952           # PiG_Motion-FlatFoot-Full's right ankle
ELBOW_RANGE_MEASURED = 2.09        # ratio, HC030A22's right elbow
CROSSTALK_MEASURED = {("HC030A05", "r"): -0.19, ("HC030A22", "r"): -0.11,
                      ("PiG_Motion-FlatFoot-Full", "l"): -0.17}


@dataclass
class Pair:
    """One angle of one capture (degrees, over the frames both models give)."""

    capture: str
    angle: str
    ours: np.ndarray
    lab: np.ndarray

    @property
    def offset(self) -> float:
        """Mean of ours minus the lab's."""
        return float(np.mean(self.ours - self.lab))

    @property
    def rms(self) -> float:
        """RMS of the difference after the offset is removed."""
        return float(np.std(self.ours - self.lab))

    @property
    def r(self) -> float:
        """Pearson correlation of the two series."""
        return float(np.corrcoef(self.ours, self.lab)[0, 1])

    @property
    def range_ratio(self) -> float:
        """The larger of the two ranges of motion over the smaller."""
        a, b = np.ptp(self.ours), np.ptp(self.lab)
        return float(max(a / b, b / a))


@dataclass
class Capture:
    """A shared capture fitted with the functional knee axes and with the anatomical ones,
    and the points Plug-in Gait wrote into it."""

    name: str
    trial: object
    fitted: object
    anatomical: object
    lab: dict[str, np.ndarray]

    def pair(self, dof: str, lab: np.ndarray) -> Pair:
        ours = np.degrees(self.fitted.motion.q[:, DOF_NAMES.index(dof)])
        both = np.isfinite(ours) & np.isfinite(lab)
        return Pair(self.name, dof, ours[both], lab[both])


@pytest.fixture(scope="module")
def captures(real_c3d) -> list[Capture]:
    out = []
    for motion, static in CAPTURES:
        trial = read_c3d(real_c3d(motion))
        statics = [read_c3d(real_c3d(static))] if static else None
        out.append(Capture(Path(motion).stem, trial, fit_capture(trial, static=statics),
                           fit_capture(trial, static=statics, knee_turns={}),
                           plug_in_gait_points(real_c3d(motion))))
    return out


def sided_pairs(captures, point: str, component: int, dof: str) -> list[Pair]:
    """``dof`` of each side of each capture against Plug-in Gait's ``point`` component."""
    return [c.pair(f"{dof}_{side}", c.lab[side.upper() + point][:, component])
            for c in captures for side in ("l", "r")]


def slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of ``y`` on ``x`` over the frames both hold."""
    both = np.isfinite(x) & np.isfinite(y)
    return float(np.polyfit(x[both], y[both], 1)[0])


def hip_rotation_on_knee_flexion(fitted, side: str) -> float:
    """Slope (degrees per degree) of a fit's hip rotation on its knee flexion."""
    q = fitted.motion.q
    return slope(q[:, DOF_NAMES.index(f"knee_flexion_{side}")],
                 q[:, DOF_NAMES.index(f"hip_rotation_{side}")])


def leg_marker_rms_mm(fitted, side: str) -> float:
    """RMS residual (mm) of one side's thigh and shank markers."""
    leg = np.isin(fitted.model.marker_segments, [SEGMENT_NAMES.index(f"{name}_{side}")
                                                 for name in ("femur", "tibia")])
    return float(1000 * np.sqrt(np.nanmean(fitted.motion.residuals[:, leg] ** 2)))


def _missed(values: tuple, reason: str):
    """A parameter set whose target is missed: a strict xfail with the measured figure."""
    return pytest.param(*values, marks=pytest.mark.xfail(strict=True, reason=reason))


@pytest.mark.parametrize("point, component, dof", LEG_FLEXIONS)
def test_leg_flexion_offsets_agree_with_plug_in_gait(captures, point, component, dof):
    offsets = [abs(p.offset) for p in sided_pairs(captures, point, component, dof)]
    assert np.median(offsets) <= 3.0, offsets
    assert max(offsets) <= 5.0, offsets


@pytest.mark.parametrize("point, component, dof", [
    LEG_FLEXIONS[0], LEG_FLEXIONS[1],
    _missed(LEG_FLEXIONS[2], f"measured r {ANKLE_R_MEASURED} on PiG_Motion-FlatFoot-Full's "
                            "right ankle")])
def test_leg_flexions_follow_plug_in_gait(captures, point, component, dof):
    low = min(sided_pairs(captures, point, component, dof), key=lambda p: p.r)
    assert low.r >= 0.97, (low.capture, low.angle, low.r)


@pytest.mark.parametrize("point, component, dof", [
    LEG_FLEXIONS[0], LEG_FLEXIONS[2],
    _missed(LEG_FLEXIONS[1], f"measured {KNEE_RMS_MEASURED}° on HC030A05's right knee (Oxford "
                            "Foot Model capture, swing: mocaplib's hinge knee flexes 7° more "
                            "than Plug-in Gait's 3-DOF knee)")])
def test_leg_flexions_differ_from_plug_in_gait_by_an_offset(captures, point, component, dof):
    worst = max(sided_pairs(captures, point, component, dof), key=lambda p: p.rms)
    assert worst.rms <= 3.0, (worst.capture, worst.angle, worst.rms)


def test_the_leg_flexions_that_miss_a_target_are_no_worse_than_measured(captures):
    ankle = min(sided_pairs(captures, *LEG_FLEXIONS[2]), key=lambda p: p.r)
    assert ankle.r >= ANKLE_R_MEASURED - 0.01, (ankle.capture, ankle.angle, ankle.r)
    knee = max(sided_pairs(captures, *LEG_FLEXIONS[1]), key=lambda p: p.rms)
    assert knee.rms <= KNEE_RMS_MEASURED + 0.3, (knee.capture, knee.angle, knee.rms)


def test_frontal_angles_and_the_pelvis_agree_with_plug_in_gait(captures):
    pairs = sided_pairs(captures, *HIP_ADDUCTION)
    for c in captures:
        tilt, obliquity = pelvis_angles(c.lab)
        pairs += [c.pair("pelvis_tilt", tilt), c.pair("pelvis_list", obliquity)]
    for p in pairs:
        assert p.r >= 0.8, (p.capture, p.angle, p.r)
        assert abs(p.offset) <= 5.0, (p.capture, p.angle, p.offset)


@pytest.mark.parametrize("point, component, dof", ARM_FLEXIONS)
def test_arm_flexions_agree_with_plug_in_gait(captures, point, component, dof):
    for p in sided_pairs(captures, point, component, dof):
        assert abs(p.offset) <= 5.0, (p.capture, p.angle, p.offset)
        assert p.r >= 0.9, (p.capture, p.angle, p.r)
        assert p.rms <= 3.0, (p.capture, p.angle, p.rms)


@pytest.mark.parametrize("point, component, dof", [
    ARM_FLEXIONS[1],
    _missed(ARM_FLEXIONS[0], f"measured {ELBOW_RANGE_MEASURED}× on HC030A22's right elbow "
                            "(15.0° / 7.2°): Plug-in Gait's elbow centre slides 10-14 mm "
                            "fore-aft in the upper arm as the elbow flexes")])
def test_arm_flexion_ranges_within_1_5_times_plug_in_gaits(captures, point, component, dof):
    wide = max(sided_pairs(captures, point, component, dof), key=lambda p: p.range_ratio)
    assert wide.range_ratio <= 1.5, (wide.capture, wide.angle, wide.range_ratio)


def test_the_elbow_flexion_range_is_no_wider_than_measured(captures):
    wide = max(sided_pairs(captures, *ARM_FLEXIONS[0]), key=lambda p: p.range_ratio)
    assert wide.range_ratio <= ELBOW_RANGE_MEASURED + 0.1, (wide.capture, wide.angle,
                                                            wide.range_ratio)


def test_the_arms_swing_about_plug_in_gaits_shoulder_centres(captures):
    # with the subject's measured shoulder offset the shoulder centre hangs below the acromion
    # marker; placed by the torso's catalogue layout instead it sat 36-44 mm away
    for c in captures:
        T = c.fitted.motion.skeleton.forward(c.fitted.motion.q)
        for side in ("L", "R"):
            centre = 1000 * T[:, SEGMENT_NAMES.index(f"humerus_{side.lower()}"), :3, 3]
            gap = np.nanmean(np.linalg.norm(centre - c.lab[side + "CLO"], axis=1))
            assert gap <= 20.0, (c.name, side, gap)


def test_no_dof_sits_at_a_joint_limit_and_the_pelvis_follows_its_markers(captures):
    lower, upper = Skeleton.bounds()
    for c in captures:
        q = c.fitted.motion.q
        share = ((q <= lower + 1e-3) | (q >= upper - 1e-3)).mean(axis=0)
        assert share.max() <= 0.02, (c.name, DOF_NAMES[int(share.argmax())], share.max())
        # the pelvis obliquity's range against that of the line through the two ASIS markers
        asis = c.trial.marker("LASI") - c.trial.marker("RASI")
        asis_deg = np.degrees(np.arcsin(asis[:, 2] / np.linalg.norm(asis, axis=1)))
        obliquity = np.degrees(q[:, DOF_NAMES.index("pelvis_list")])
        assert np.ptp(obliquity) <= 1.3 * (np.nanmax(asis_deg) - np.nanmin(asis_deg)), c.name
    # the heel and toe markers of Plug-in Gait cannot show inversion: held, and said so
    pig = next(c for c in captures if c.name == "PiG_Motion-FlatFoot-Full")
    held = pig.fitted.model.unobservable
    assert sorted(held) == ["ankle_inversion_l", "ankle_inversion_r"]
    assert all(np.degrees(sd) > 5.0 for sd in held.values())


@pytest.mark.parametrize("capture, side", [
    _missed(knee, f"measured {CROSSTALK_MEASURED[knee]:+.2f}") if knee in CROSSTALK_MEASURED
    else knee for knee in KNEES])
def test_knee_crosstalk(captures, capture, side):
    # a knee hinge whose axis is turned from the knee's own makes the fit turn the hip as the
    # knee flexes; calibration turns each axis to fit the thigh and shank markers
    c = next(c for c in captures if c.name == capture)
    assert c.fitted.model.centre_methods[f"knee_axis_{side}"].startswith("functional")
    slope_deg_per_deg = hip_rotation_on_knee_flexion(c.fitted, side)
    assert abs(slope_deg_per_deg) <= 0.1, (capture, side, slope_deg_per_deg)


def test_the_knee_crosstalk_that_misses_the_target_is_no_worse_than_measured(captures):
    for (capture, side), measured in CROSSTALK_MEASURED.items():
        c = next(c for c in captures if c.name == capture)
        ours = hip_rotation_on_knee_flexion(c.fitted, side)
        assert abs(ours) <= abs(measured) + 0.03, (capture, side, ours)


def test_the_functional_knee_axis_fits_the_legs_better_than_the_anatomical(captures):
    for c in captures:
        for side in ("l", "r"):
            # least squares on the thigh and shank markers: never worse than the chord's axis
            assert leg_marker_rms_mm(c.fitted, side) < leg_marker_rms_mm(c.anatomical, side)
            if c.name.startswith("HC030"):
                # the biomechZoo knees' cross-talk (-0.18 to -0.36 with the chord's axis)
                # falls by a third at least
                ours, chord = (hip_rotation_on_knee_flexion(f, side)
                               for f in (c.fitted, c.anatomical))
                assert abs(ours) < 0.67 * abs(chord), (c.name, side, ours, chord)


@pytest.fixture(scope="module")
def captures_without_statics(real_c3d) -> list[Capture]:
    """Every capture calibrated from itself (the captures with a static too), functional
    knee axes only."""
    out = []
    for motion, _ in CAPTURES:
        trial = read_c3d(real_c3d(motion))
        fitted = fit_capture(trial)
        out.append(Capture(Path(motion).stem, trial, fitted, fitted,
                           plug_in_gait_points(real_c3d(motion))))
    return out


@pytest.mark.parametrize("point, component, dof", LEG_FLEXIONS)
def test_leg_flexion_offsets_agree_with_plug_in_gait_without_a_static(
        captures_without_statics, point, component, dof):
    # without a static the foot's zero comes from the soles flat in the capture's stances:
    # along the heel-to-toe marker line the biomechZoo ankles (Oxford Foot Model markers, the
    # toe marker 4-5° up the line) read +4.9° to +6.7° more dorsiflexion than Plug-in Gait's
    offsets = [abs(p.offset) for p in sided_pairs(captures_without_statics, point, component,
                                                  dof)]
    assert len(offsets) == 2 * len(CAPTURES)
    assert np.median(offsets) <= 3.0, offsets
    assert max(offsets) <= 5.0, offsets


#: (Plug-in Gait's spine angle component: the thorax on the pelvis, its left side's signs,
#: mocaplib's trunk DOF).
TRUNK = ((0, "trunk_flexion"), (1, "trunk_bending"), (2, "trunk_rotation"))


@pytest.mark.parametrize("component, dof", TRUNK)
def test_the_trunk_agrees_with_plug_in_gaits_spine_with_and_without_a_static(
        captures, captures_without_statics, component, dof):
    # the trunk's zero is the catalogue's marker layout, not a posture of the capture: fitted
    # with or without the static, its offsets from Plug-in Gait's thorax-on-pelvis angles stay
    # within 5° (measured: flexion +2.4° to +4.2°, bending and rotation within 2.8°), and
    # calibrating from the walk moves them by 1° at most (a standing moment could not do better)
    pairs = {(fitted, c.name): c.pair(dof, c.lab["LSpineAngles"][:, component])
             for fitted, group in (("static", captures), ("itself", captures_without_statics))
             for c in group}
    assert all(abs(p.offset) <= 5.0 for p in pairs.values()), pairs
    for (fitted, name), pair in pairs.items():
        if fitted == "itself":
            assert abs(pair.offset - pairs["static", name].offset) <= 1.5, (name, pair.offset)
