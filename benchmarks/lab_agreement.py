"""mocaplib's joint angles against the lab's own Plug-in Gait angles stored in the same files.

    python benchmarks/lab_agreement.py [--shared DIR] [--markdown PATH]
    python benchmarks/lab_agreement.py --knee-turns -20 -10 0 10 20

Plug-in Gait (Vicon's conventional gait model) writes its angles into the C3D as points
(``LHipAngles``, ``LKneeAngles``, ``LAnkleAngles``... in degrees: x flexion, y ab/adduction,
z rotation) and its pelvis frame as the points ``PELO``, ``PELA``, ``PELL``, ``PELP`` (origin
and 100 mm along each axis). They are read with ezc3d, a reader mocaplib does not use. Each
capture is fitted as ``mocaplib fit`` fits it (:func:`mocaplib.model.fitting.fit_capture`, with its
static when it has one, and again without it, calibrated from itself: :data:`RUNS`) and every
angle both report is compared over the frames Plug-in Gait wrote: Pearson r, mean offset
(ours − Plug-in Gait), RMS after removing the offset, range of motion of each. The arms are compared too: Plug-in Gait's elbow flexion is the angle between
its shoulder–elbow and elbow–wrist centre lines, its shoulder flexion the upper arm's line
against its thorax frame (:func:`mocaplib.model.anatomy.segment_frames` builds mocaplib's arm frames
the same way). Pelvis tilt and obliquity are taken from Plug-in Gait's pelvis frame in
mocaplib's order (heading, then obliquity, then tilt): its stored pelvis angles are relative to
the lab's axes, which is not the subject's heading once the subject turns (HC030A22 turns 88°).
The trunk's flexion, bending and rotation are compared with Plug-in Gait's spine angles (its
thorax on its pelvis; the left side's, whose signs are mocaplib's).
Also printed: the share of frames each of mocaplib's DOFs spends at a joint limit, the DOFs held
because the markers cannot see them, the pelvis obliquity's range against that of the line
through the two ASIS markers, how far mocaplib's fitted shoulder centres lie from Plug-in
Gait's (``LCLO``, ``RCLO``; mean over the frames): the arm swings about its shoulder centre,
and one placed off the pivot changes the shoulder–wrist distance with the swing, which the
elbow hinge then takes up as flexion; and the knee's cross-talk: the slope of hip rotation on
knee flexion over the capture (degrees per degree), mocaplib's against Plug-in Gait's, with the
slope of Plug-in Gait's knee varus on its knee flexion (a knee flexion axis turned from the
true one shows in Plug-in Gait's three-DOF knee as varus that follows flexion, and in
mocaplib's hinge knee as hip rotation that follows it), with each knee's functional axis and,
refitted, with its anatomical one. ``--knee-turns`` refits instead with both knees' axes turned
by fixed angles. Prints Markdown, the tables of the captures with their statics, then of every
capture calibrated from itself; exit code 1 when a target of :data:`TARGETS` is missed in
either.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.model.fitting import fit_capture  # noqa: E402
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton  # noqa: E402

#: The shared real captures: ``$MOCAPLIB_SHARED_C3D``, else beside the repository (as the tests).
SHARED = Path(os.environ.get("MOCAPLIB_SHARED_C3D", ROOT.parent / "shared" / "data" / "c3d"))
#: The shared captures that carry Plug-in Gait angles, with their static (or None).
CAPTURES = (("biomechzoo/HC030A05.c3d", "biomechzoo/HC030A01.c3d"),
            ("biomechzoo/HC030A22.c3d", "biomechzoo/HC030A01.c3d"),
            ("btkdata/PiG_Motion-FlatFoot-Full.c3d", None))
#: (Plug-in Gait point, component, mocaplib DOF) compared per side.
SIDED = (("HipAngles", 0, "hip_flexion"), ("KneeAngles", 0, "knee_flexion"),
         ("AnkleAngles", 0, "ankle_dorsiflexion"), ("HipAngles", 1, "hip_adduction"),
         ("HipAngles", 2, "hip_rotation"))
#: What the page compares: each capture with its static as :data:`CAPTURES` gives it, then
#: every capture calibrated from itself (its name marked when it has a static): (motion,
#: static or None, name).
NO_STATIC = " (no static)"
RUNS = tuple((motion, static, Path(motion).stem) for motion, static in CAPTURES) + tuple(
    (motion, None, Path(motion).stem + NO_STATIC) for motion, static in CAPTURES if static)
FLEXIONS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
#: The arms' flexions (Plug-in Gait point, component, mocaplib DOF), compared per side.
ARMS = (("ElbowAngles", 0, "elbow_flexion"), ("ShoulderAngles", 0, "shoulder_flexion"))
#: The trunk on the pelvis (Plug-in Gait's spine angles: its thorax on its pelvis, the left
#: side's signs; component, mocaplib DOF).
TRUNK = ((0, "trunk_flexion"), (1, "trunk_bending"), (2, "trunk_rotation"))
#: The targets: flexions (median |offset| over captures and sides, worst |offset|,
#: r, RMS after offset), frontal angles (r, |offset|), limits, pelvis range, the arms' flexions
#: (|offset| on every capture and side, r, RMS after offset, range within this factor of
#: Plug-in Gait's either way), degrees; the shoulder centres' mean distance from Plug-in
#: Gait's, mm; the knee's cross-talk (|slope of hip rotation on knee flexion| on every
#: capture and side, degrees per degree); the trunk's |offset| on every capture, degrees.
TARGETS = {"flexion_median_offset": 3.0, "flexion_worst_offset": 5.0, "flexion_r": 0.97,
           "flexion_rms": 3.0, "frontal_r": 0.8, "frontal_offset": 5.0,
           "at_limit_share": 0.02, "obliquity_range_ratio": 1.3,
           "arm_offset": 5.0, "arm_r": 0.9, "arm_rms": 3.0, "arm_range_ratio": 1.5,
           "shoulder_centre_mm": 20.0, "crosstalk_slope": 0.1, "trunk_offset": 5.0}


@dataclass
class Comparison:
    """One angle of one capture: ours and Plug-in Gait's over the frames both have."""

    capture: str
    angle: str
    r: float
    offset: float
    rms: float
    rom_ours: float
    rom_lab: float


def plug_in_gait_points(path: Path) -> dict[str, np.ndarray]:
    """Every point of the file by label (subject prefix dropped): (F, 3), NaN where Plug-in
    Gait wrote nothing (all zeros) or the residual says missing, as ezc3d reads them."""
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    point = c3d["parameters"]["POINT"]
    labels = [label for key in ("LABELS", "LABELS2", "LABELS3") if key in point
              for label in point[key]["value"]]
    data = c3d["data"]["points"][:3].transpose(2, 1, 0).copy()         # (F, N, 3)
    data[(data == 0).all(axis=2)] = np.nan
    return {label.split(":")[-1].strip(): data[:, i] for i, label in enumerate(labels)}


def pelvis_angles(points: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Plug-in Gait's pelvis tilt and obliquity (F,) in mocaplib's convention, degrees: its
    pelvis frame (PELO origin; PELA, PELL, PELP along X, Y, Z) decomposed as mocaplib's root,
    heading about Z, then obliquity about X, then tilt about Y."""
    origin = points["PELO"]
    axes = [points[k] - origin for k in ("PELA", "PELL", "PELP")]
    R = np.stack([a / np.linalg.norm(a, axis=1, keepdims=True) for a in axes], axis=-1)
    obliquity = np.arcsin(np.clip(R[:, 2, 1], -1.0, 1.0))
    tilt = np.arctan2(-R[:, 2, 0], R[:, 2, 2])
    return np.degrees(tilt), np.degrees(obliquity)


def compare(capture: str, angle: str, ours: np.ndarray, lab: np.ndarray) -> Comparison:
    """Statistics of ``ours`` against ``lab`` (F,) degrees over the frames both hold."""
    both = np.isfinite(ours) & np.isfinite(lab)
    a, b = ours[both], lab[both]
    difference = a - b
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                    # a held DOF: r NaN
        r = float(np.corrcoef(a, b)[0, 1])
    return Comparison(capture, angle, r, float(difference.mean()), float(difference.std()),
                      float(np.ptp(a)), float(np.ptp(b)))


@dataclass
class CaptureResult:
    """One capture's comparisons, limits, held DOFs and pelvis ranges."""

    capture: str
    comparisons: list[Comparison]
    at_limit: dict[str, float]
    held: dict[str, float]
    obliquity_range: float
    asis_range: float
    marker_rms_mm: float
    shoulder_gap_mm: dict[str, float]
    crosstalk: list[Crosstalk]


@dataclass
class Crosstalk:
    """One knee's cross-talk over a capture: slopes (degrees per degree) of mocaplib's hip
    rotation on its knee flexion (functional knee axis, and refitted with the anatomical
    axis), of Plug-in Gait's, and of Plug-in Gait's knee varus on its knee flexion; the knee
    axis calibration chose (``SubjectModel.centre_methods``); the RMS (mm) of the thigh and
    shank markers of that side with each axis."""

    side: str
    ours: float
    anatomical: float
    lab: float
    lab_varus: float
    axis: str
    leg_rms_mm: float
    anatomical_leg_rms_mm: float


def slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of ``y`` on ``x`` (F,) over the frames both hold."""
    both = np.isfinite(x) & np.isfinite(y)
    return float(np.polyfit(x[both], y[both], 1)[0])


def knee_crosstalk(fitted, side: str) -> tuple[float, float]:
    """The slope of hip rotation on knee flexion of ``side`` ("l", "r") of a
    :class:`~mocaplib.model.fitting.FittedCapture` (degrees per degree), and the RMS (mm) of that
    side's thigh and shank markers."""
    q = fitted.motion.q
    leg = np.isin(fitted.model.marker_segments, [SEGMENT_NAMES.index(f"{name}_{side}")
                                                 for name in ("femur", "tibia")])
    return (slope(q[:, DOF_NAMES.index(f"knee_flexion_{side}")],
                  q[:, DOF_NAMES.index(f"hip_rotation_{side}")]),
            float(1000 * np.sqrt(np.nanmean(fitted.motion.residuals[:, leg] ** 2))))


def agreement(motion_path: Path, static_path: Path | None, name: str) -> CaptureResult:
    """Fit ``motion_path`` as ``mocaplib fit`` does and compare it with Plug-in Gait."""
    trial = read_c3d(motion_path)
    statics = [read_c3d(static_path)] if static_path else None
    fitted = fit_capture(trial, static=statics)
    motion, model = fitted.motion, fitted.model
    points = plug_in_gait_points(motion_path)
    q = np.degrees(motion.q)
    out = []
    for side in ("L", "R"):
        for label, component, dof in SIDED + ARMS:
            out.append(compare(name, f"{dof}_{side.lower()}",
                               q[:, DOF_NAMES.index(f"{dof}_{side.lower()}")],
                               points[side + label][:, component]))
    tilt, obliquity = pelvis_angles(points)
    out.append(compare(name, "pelvis_tilt", q[:, DOF_NAMES.index("pelvis_tilt")], tilt))
    out.append(compare(name, "pelvis_list", q[:, DOF_NAMES.index("pelvis_list")], obliquity))
    for component, dof in TRUNK:
        out.append(compare(name, dof, q[:, DOF_NAMES.index(dof)],
                           points["LSpineAngles"][:, component]))
    lower, upper = Skeleton.bounds()
    at_limit = ((motion.q <= lower + 1e-3) | (motion.q >= upper - 1e-3)).mean(axis=0)
    anatomical = fit_capture(trial, static=statics, knee_turns={})
    crosstalk = []
    for side in ("l", "r"):
        knee, hip = (points[side.upper() + label] for label in ("KneeAngles", "HipAngles"))
        (ours, leg_rms), (before, before_rms) = (knee_crosstalk(f, side)
                                                 for f in (fitted, anatomical))
        crosstalk.append(Crosstalk(side, ours, before, slope(knee[:, 0], hip[:, 2]),
                                   slope(knee[:, 0], knee[:, 1]),
                                   model.centre_methods.get(f"knee_axis_{side}", "anatomical"),
                                   leg_rms, before_rms))
    asis = trial.marker("LASI") - trial.marker("RASI")
    asis_angle = np.degrees(np.arcsin(asis[:, 2] / np.linalg.norm(asis, axis=1)))
    T = motion.skeleton.forward(motion.q)
    gaps = {side: float(np.nanmean(np.linalg.norm(
        1000 * T[:, SEGMENT_NAMES.index(f"humerus_{side.lower()}"), :3, 3]
        - points[side + "CLO"], axis=1))) for side in ("L", "R")}
    return CaptureResult(name, out, dict(zip(DOF_NAMES, at_limit.tolist())),
                         {k: float(np.degrees(v)) for k, v in model.unobservable.items()},
                         float(np.ptp(q[:, DOF_NAMES.index("pelvis_list")])),
                         float(np.nanmax(asis_angle) - np.nanmin(asis_angle)),
                         float(1000 * np.sqrt(np.nanmean(motion.residuals ** 2))), gaps,
                         crosstalk)


def target_checks(results: list[CaptureResult]) -> list[tuple[str, str, bool]]:
    """(target, measured, met) for each of :data:`TARGETS`."""
    rows = [c for r in results for c in r.comparisons]
    checks = []
    for dof in FLEXIONS:
        mine = [c for c in rows if c.angle.startswith(dof)]
        median = float(np.median([abs(c.offset) for c in mine]))
        worst = max(mine, key=lambda c: abs(c.offset))
        low = min(mine, key=lambda c: c.r)
        rms = max(mine, key=lambda c: c.rms)
        checks += [
            (f"{dof}: median abs. offset ≤ {TARGETS['flexion_median_offset']:g}°",
             f"{median:.1f}°", median <= TARGETS["flexion_median_offset"]),
            (f"{dof}: every abs. offset ≤ {TARGETS['flexion_worst_offset']:g}°",
             f"{worst.offset:+.1f}° ({worst.capture} {worst.angle})",
             abs(worst.offset) <= TARGETS["flexion_worst_offset"]),
            (f"{dof}: r ≥ {TARGETS['flexion_r']:g}", f"{low.r:.3f} ({low.capture} {low.angle})",
             low.r >= TARGETS["flexion_r"]),
            (f"{dof}: RMS after offset ≤ {TARGETS['flexion_rms']:g}°",
             f"{rms.rms:.1f}° ({rms.capture} {rms.angle})", rms.rms <= TARGETS["flexion_rms"])]
    for dof in ("hip_adduction", "pelvis_tilt", "pelvis_list"):
        mine = [c for c in rows if c.angle.startswith(dof)]
        low = min(mine, key=lambda c: c.r)
        worst = max(mine, key=lambda c: abs(c.offset))
        checks += [(f"{dof}: r ≥ {TARGETS['frontal_r']:g}",
                    f"{low.r:.3f} ({low.capture} {low.angle})", low.r >= TARGETS["frontal_r"]),
                   (f"{dof}: abs. offset ≤ {TARGETS['frontal_offset']:g}°",
                    f"{worst.offset:+.1f}° ({worst.capture} {worst.angle})",
                    abs(worst.offset) <= TARGETS["frontal_offset"])]
    for _, _, dof in ARMS:
        mine = [c for c in rows if c.angle.startswith(dof)]
        worst = max(mine, key=lambda c: abs(c.offset))
        low = min(mine, key=lambda c: c.r)
        rms = max(mine, key=lambda c: c.rms)
        def spread(c):
            return max(c.rom_ours / c.rom_lab, c.rom_lab / c.rom_ours)
        wide = max(mine, key=spread)
        ratio = spread(wide)
        checks += [(f"{dof}: every abs. offset ≤ {TARGETS['arm_offset']:g}°",
                    f"{worst.offset:+.1f}° ({worst.capture} {worst.angle})",
                    abs(worst.offset) <= TARGETS["arm_offset"]),
                   (f"{dof}: r ≥ {TARGETS['arm_r']:g}",
                    f"{low.r:.3f} ({low.capture} {low.angle})", low.r >= TARGETS["arm_r"]),
                   (f"{dof}: RMS after offset ≤ {TARGETS['arm_rms']:g}°",
                    f"{rms.rms:.1f}° ({rms.capture} {rms.angle})", rms.rms <= TARGETS["arm_rms"]),
                   (f"{dof}: range within {TARGETS['arm_range_ratio']:g}× Plug-in Gait's",
                    f"{ratio:.2f}× ({wide.capture} {wide.angle}, {wide.rom_ours:.1f}° / "
                    f"{wide.rom_lab:.1f}°)", ratio <= TARGETS["arm_range_ratio"])]
    trunk = max((c for c in rows if c.angle.startswith("trunk_")), key=lambda c: abs(c.offset))
    checks.append((f"trunk: every abs. offset ≤ {TARGETS['trunk_offset']:g}°",
                   f"{trunk.offset:+.1f}° ({trunk.capture} {trunk.angle})",
                   abs(trunk.offset) <= TARGETS["trunk_offset"]))
    gap, capture, side = max((g, r.capture, s) for r in results
                             for s, g in r.shoulder_gap_mm.items())
    checks.append((f"shoulder centres within {TARGETS['shoulder_centre_mm']:g} mm of Plug-in "
                   "Gait's", f"{gap:.0f} mm ({capture} {side})",
                   gap <= TARGETS["shoulder_centre_mm"]))
    share, capture, dof = max((share, r.capture, d) for r in results
                              for d, share in r.at_limit.items())
    checks.append((f"no DOF at a joint limit in more than {TARGETS['at_limit_share']:.0%} of "
                   "frames", f"{share:.1%} ({capture} {dof})",
                   share <= TARGETS["at_limit_share"]))
    worst, capture, side = max((abs(k.ours), r.capture, k.side) for r in results
                               for k in r.crosstalk)
    checks.append((f"hip rotation on knee flexion: every abs. slope ≤ "
                   f"{TARGETS['crosstalk_slope']:g}", f"{worst:.2f} ({capture} {side})",
                   worst <= TARGETS["crosstalk_slope"]))
    ratio, capture = max((r.obliquity_range / r.asis_range, r.capture) for r in results)
    checks.append((f"pelvis obliquity range ≤ {TARGETS['obliquity_range_ratio']:g}× the ASIS "
                   "line's", f"{ratio:.2f}× ({capture})",
                   ratio <= TARGETS["obliquity_range_ratio"]))
    return checks


def print_tables(results: list[CaptureResult]) -> bool:
    """Print the Markdown tables; True when every target is met."""
    print("| capture | angle | r | offset (°) | RMS after offset (°) | range ours / PiG (°) |")
    print("|---|---|---|---|---|---|")
    for result in results:
        for c in result.comparisons:
            print(f"| {c.capture} | {c.angle} | {c.r:.3f} | {c.offset:+.1f} | {c.rms:.1f} | "
                  f"{c.rom_ours:.1f} / {c.rom_lab:.1f} |")
    print("\n| capture | marker RMS (mm) | held DOFs (σ, °) | DOFs at a limit > 2 % of frames "
          "| pelvis obliquity / ASIS line range (°) | shoulder centres to Plug-in Gait's, "
          "L / R (mm) |")
    print("|---|---|---|---|---|---|")
    for r in results:
        held = ", ".join(f"{k} ({v:.0f})" for k, v in sorted(r.held.items())) or "none"
        limits = ", ".join(f"{k} {v:.0%}" for k, v in r.at_limit.items() if v > 0.02) or "none"
        print(f"| {r.capture} | {r.marker_rms_mm:.1f} | {held} | {limits} | "
              f"{r.obliquity_range:.1f} / {r.asis_range:.1f} | "
              f"{r.shoulder_gap_mm['L']:.0f} / {r.shoulder_gap_mm['R']:.0f} |")
    print("\n| capture | side | hip rotation / knee flexion: anatomical axis → ours | "
          "Plug-in Gait's | Plug-in Gait's knee varus / knee flexion | thigh and shank "
          "markers' RMS (mm): anatomical axis → ours | knee axis |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        for k in r.crosstalk:
            print(f"| {r.capture} | {k.side} | {k.anatomical:+.3f} → {k.ours:+.3f} | "
                  f"{k.lab:+.3f} | {k.lab_varus:+.3f} | {k.anatomical_leg_rms_mm:.1f} → "
                  f"{k.leg_rms_mm:.1f} | {k.axis} |")
    checks = target_checks(results)
    print("\n| target | measured | met |")
    print("|---|---|---|")
    for target, measured, met in checks:
        print(f"| {target} | {measured} | {'yes' if met else '**no**'} |")
    return all(met for _, _, met in checks)


def print_turned_knees(shared: Path, turns_deg: list[float]) -> None:
    """Print, per capture, side and fixed knee axis turn (degrees), the slope of hip rotation
    on knee flexion, Plug-in Gait's, and the thigh and shank markers' RMS."""
    print("| capture | side | turn (°) | hip rotation / knee flexion | Plug-in Gait's | thigh "
          "and shank markers' RMS (mm) |")
    print("|---|---|---|---|---|---|")
    for motion, static in CAPTURES:
        trial = read_c3d(shared / motion)
        statics = [read_c3d(shared / static)] if static else None
        points = plug_in_gait_points(shared / motion)
        for turn in turns_deg:
            fitted = fit_capture(trial, static=statics,
                                 knee_turns={"l": np.radians(turn), "r": np.radians(turn)})
            for side in ("l", "r"):
                ours, leg_rms = knee_crosstalk(fitted, side)
                lab = slope(points[side.upper() + "KneeAngles"][:, 0],
                            points[side.upper() + "HipAngles"][:, 2])
                print(f"| {Path(motion).stem} | {side} | {turn:+g} | {ours:+.3f} | {lab:+.3f} | "
                      f"{leg_rms:.1f} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shared", type=Path, default=SHARED,
                        help="folder of the shared real captures (default: %(default)s)")
    parser.add_argument("--knee-turns", type=float, nargs="+", metavar="DEG",
                        help="instead: refit every capture with both knees' axes turned by each "
                             "of these angles (degrees, internal rotation positive) from the "
                             "anatomical ones and print the cross-talk slope and the thigh and "
                             "shank markers' RMS per turn")
    add_markdown_option(parser)
    args = parser.parse_args(argv)
    if args.knee_turns:
        print_turned_knees(args.shared, args.knee_turns)
        return 0
    with markdown_page(args.markdown, __file__, argv):
        results = [agreement(args.shared / motion, static and args.shared / static, name)
                   for motion, static, name in RUNS]
        with_statics = [r for r in results if not r.capture.endswith(NO_STATIC)]
        from_themselves = [r for r, (_, static, _) in zip(results, RUNS) if static is None]
        print("### With the captures' statics\n")
        met = print_tables(with_statics)
        print("\n### Every capture calibrated from itself\n")
        met = print_tables(from_themselves) and met
    return 0 if met else 1


if __name__ == "__main__":
    raise SystemExit(main())
