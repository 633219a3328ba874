"""Planting on the real entries: the library of the shared files, each entry planted on its own
skeleton as ``mocaplib query`` plants it (:func:`mocaplib.library.planting.plant_cycles`); how
far planting moves the knees and hips and the body's height.

A change of a knee or hip is either forced by the joint limits or chosen by planting. The
forced change of a DOF in a frame is how far the motion's value lies outside the DOF's limits
(the knees' lower limit 0: never hyperextended); the chosen change is how far the planted value
lies from the motion's value brought within the limits (:func:`chosen_change`). A knee the
motion hyperextends by 12 deg and planting holds at 0 changes by 12 deg, forced, 0 chosen.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import SHARED_C3D

from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.gait.fourier import RootDrift, synthesize
from mocaplib.library.foot_targets import mask_runs
from mocaplib.library.planting import (MAX_LEVEL, _padded, plant_feet, sole_points,
                                       stance_frames)
from mocaplib.skeleton import DOF_NAMES, ROOT_Z, Skeleton

RATE = 100.0
KNEES = [DOF_NAMES.index(n) for n in ("knee_flexion_l", "knee_flexion_r")]
HIPS = [DOF_NAMES.index(n) for n in ("hip_flexion_l", "hip_flexion_r")]
#: Entries moving faster than this (m/s) are walks (the rest stand or turn on the spot).
WALKING = 0.3
#: The largest knee and hip flexion change (deg) planting makes on a real walk, measured 25.9
#: and 13.2 (07_01_c0, whose left knee the motion hyperextends by 10.9 deg at the frame: held
#: at 0, then bent 14.9 deg with the hip 13.2 deg less flexed so that the foot meets its lock).
KNEE_BOUND_DEG, HIP_BOUND_DEG = 26.5, 13.5
#: The largest knee and hip flexion change (deg) planting chooses on a real walk: measured 14.9
#: and 13.2, as above (from the knee held at 0).
CHOSEN_KNEE_BOUND_DEG, CHOSEN_HIP_BOUND_DEG = 15.5, 13.5
#: The knee and hip flexion change aimed at (deg): the leg moves only as much as holding the
#: foot needs.
TARGET_DEG = 5.0
LOWER, UPPER = Skeleton.bounds()
LOWER[KNEES] = np.maximum(LOWER[KNEES], 0.0)


@pytest.fixture(scope="module")
def planted_entries():
    """Per real entry: (id, speed m/s, unplanted world poses (F, D), feet's hover in stance m,
    planted poses (F, D)), the cycle planted with one period more on each side, that period cut
    off."""
    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    library = build_library([SHARED_C3D], BuildSettings(), progress=False).library
    out = []
    for entry in library.entries:
        velocities = np.array(entry.root_drift.velocities, float)
        if not np.isfinite(velocities).all():
            continue
        period = float(entry.T)
        skeleton = library.entry_skeleton(entry.id)
        q, window = _padded(lambda t: synthesize(entry.fourier.a, entry.fourier.b, period, t),
                            RootDrift(0.0, 0.0, 0.0, *velocities), period, RATE,
                            round(period * RATE))
        stance = stance_frames(skeleton, q, RATE)
        planted = plant_feet(skeleton, q, RATE, stance=stance, window=window)
        keep = slice(*window)
        higher = sole_points(skeleton, q)[..., 2].max(axis=2)                 # (F, 2)
        hovers = [higher[start:stop, side].min() for side in (0, 1)
                  for start, stop in mask_runs(stance[:, side])]
        level = float(np.median(hovers)) if hovers else 0.0
        out.append((entry.id, float(np.hypot(*velocities[:2])), q[keep], level, planted.q))
    assert len(out) >= 10
    return out


def chosen_change(q: np.ndarray, planted: np.ndarray) -> np.ndarray:
    """The change (F, D) rad or m planting chooses: from the motion ``q`` (F, D) brought within
    the joint limits (the knees at 0 or more) to ``planted`` (F, D)."""
    return np.abs(planted - np.clip(q, LOWER, UPPER))


def _largest_change(entries, dofs, *, chosen: bool = False) -> float:
    """The largest change (deg) of ``dofs`` planting makes (``chosen``: chooses) on the walks
    among ``entries``."""
    return max(float(np.degrees((chosen_change(q, p) if chosen else np.abs(p - q))[:, dofs]
                                .max()))
               for _, speed, q, _, p in entries if speed > WALKING)


def test_planting_moves_real_knees_and_hips_no_more_than_measured(planted_entries):
    assert _largest_change(planted_entries, KNEES) <= KNEE_BOUND_DEG
    assert _largest_change(planted_entries, HIPS) <= HIP_BOUND_DEG
    assert _largest_change(planted_entries, KNEES, chosen=True) <= CHOSEN_KNEE_BOUND_DEG
    assert _largest_change(planted_entries, HIPS, chosen=True) <= CHOSEN_HIP_BOUND_DEG


def test_planting_holds_hyperextended_knees_at_zero(planted_entries):
    """The forced change: a real walk hyperextends a knee (07_01_c0, by 12.3 deg), and every
    planted knee is at 0 or more."""
    hyperextended = max(float(np.degrees(-q[:, KNEES].min()))
                        for _, speed, q, *_ in planted_entries if speed > WALKING)
    assert hyperextended > TARGET_DEG
    for name, _, _, _, planted in planted_entries:
        assert planted[:, KNEES].min() >= 0.0, name


@pytest.mark.xfail(strict=True, reason="measured on the 9 moving real entries of the shared files: "
                   "planting chooses to change a knee by up to 14.9 deg and a hip's flexion by up "
                   "to 13.2 deg (the target 5 deg): 07_01_c0's left leg, whose knee the motion "
                   "hyperextends by up to 12 deg, its stance's target keeping the motion's leg "
                   "length (the knee bent as far as the motion hyperextends it, the hip extended; "
                   "held straight, the foot ends 14 mm from its lock); "
                   "PiG_Motion-FlatFoot-Full_c1's left foot, whose fitted sole stands pitched 6.8 "
                   "deg toes up, laid flat about its heel (11.4 deg), HC030A22_c3's right foot "
                   "likewise (its toe 17-20 mm above its heel, 9.5 deg); BTS_c0's left toe 55 mm "
                   "below the floor after toe-off turns the 30 deg it may and rises (9.2 deg); "
                   "HC030A05_c0's stance knee kept bent 2 deg where its ankle lies beyond the "
                   "straight leg (7.4 deg)")
def test_planting_chooses_to_move_real_knees_and_hips_by_at_most_the_target(planted_entries):
    assert _largest_change(planted_entries, KNEES, chosen=True) <= TARGET_DEG
    assert _largest_change(planted_entries, HIPS, chosen=True) <= TARGET_DEG


def test_no_body_is_lowered_by_more_than_its_feet_hover(planted_entries):
    """An entry is lowered (median over its frames) by at most its feet's hover in stance (the
    median, over the stance runs, of the lowest height the higher of heel and toe reaches: the
    flat foot's height, at most MAX_LEVEL) and 5 mm of the pelvis's own correction; an entry
    whose feet never come near the floor is not lowered."""
    for name, _, q, level, planted in planted_entries:
        lowered = float(np.median(q[:, ROOT_Z] - planted[:, ROOT_Z]))
        assert level <= MAX_LEVEL, name
        assert lowered <= max(level, 0.0) + 0.005, (name, lowered, level)
    assert any(level == 0.0 and np.abs(p - q).max() < 1e-4 for _, _, q, level, p in planted_entries)



@pytest.fixture(scope="module")
def real_planted():
    """Per moving real entry of the shared files: its id, its own skeleton and its cycle
    planted at 100 Hz on it as `mocaplib query` plants it (a Planted)."""
    from walking_library import real_walks

    from mocaplib.library.planting import plant_cycles

    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    library = real_walks()[0]
    out = {}
    for entry in library.entries:
        velocities = np.array(entry.root_drift.velocities, float)
        if entry.poulaine is None or not np.isfinite(velocities).all():
            continue
        period, skeleton = float(entry.T), library.entry_skeleton(entry.id)
        out[entry.id] = skeleton, plant_cycles(
            skeleton, lambda t, e=entry, p=period: synthesize(e.fourier.a, e.fourier.b, p, t),
            RootDrift(0.0, 0.0, 0.0, *velocities), period, RATE, round(period * RATE))
    assert len(out) >= 10
    return out


@pytest.fixture(scope="module")
def real_feet(real_planted):
    """The ContactMeasures of each of :func:`real_planted`, over the stances planting found
    and over those found again on the planted motion (what a reader of the output sees: a foot
    touching the floor outside its locks counts there)."""
    from mocaplib.library.planting import contact_measures

    out = {}
    for entry, (skeleton, planted) in real_planted.items():
        out[entry] = planted.after
        out[entry + " (output's stances)"] = contact_measures(
            skeleton, planted.planted, RATE, stance_frames(skeleton, planted.planted, RATE),
            window=planted.window)
    return out


def _worst_feet(real_feet) -> dict:
    """The worst slide, penetration and hover (m) over the real entries, and where."""
    return {name: max((getattr(m, name), entry) for entry, m in real_feet.items())
            for name in ("slide_m", "penetration_m", "hover_m")}


def test_planted_real_walks_feet_meet_the_targets(real_feet):
    # measured on the 14 moving real entries: no slide (0.00 mm), 0.01 mm below the floor,
    # hover 1.24 mm (HC030A22_c3). Two causes of misses, each asserted away here: a stance
    # target the leg reaches only with its knee straighter than STANCE_KNEE (at 1.1 deg
    # PiG_Motion-FlatFoot-Full_c0's toe slid 5.0 mm; with the ankle left beyond the straight
    # leg 07_01_c0 and 07_12_c0 3.6 mm); a stance found as two, the lower sole point of a
    # fitted sole pitched off the foot's rising more than CONTACT_RISE as it rolls, or the toe
    # alone holding the floor after push-off (without ROLL_RISE, Walking3_c0's toe stance
    # hovered 40.5 mm and, over the output's stances, its foot slid 51.9 mm; four entries)
    assert all(m.stances >= 2 for m in real_feet.values()), real_feet
    worst = _worst_feet(real_feet)
    assert worst["slide_m"][0] <= 0.002 and worst["penetration_m"][0] <= 0.0005, worst
    assert worst["hover_m"][0] <= 0.003, worst


def test_no_real_swing_foot_touches_the_floor(real_planted):
    from mocaplib.library.foot_targets import SWING_CLEARANCE
    from mocaplib.library.planting import TOUCH

    # the rigid toe dips into the floor after push-off (BTS_c0's by 55 mm); raised only onto
    # it, it scraped along the floor in swing: an independent BVH reader found "stances" that
    # slid 127-727 mm on 8 of 14 real walks. Measured: every swing foot 4.0 mm up at least
    # past the frame next to its stance (SWING_CLEARANCE, reached at APPROACH_SPEED)
    lowest = np.inf
    for skeleton, planted in real_planted.values():
        low = sole_points(skeleton, planted.planted)[..., 2].min(axis=2)        # (F, 2)
        near = planted.stances | np.roll(planted.stances, 1, 0) | np.roll(planted.stances, -1, 0)
        swing = ~near
        swing[:planted.window[0]] = swing[planted.window[1]:] = False
        lowest = min(lowest, float(low[swing].min()))
    assert TOUCH < lowest <= SWING_CLEARANCE, lowest


@pytest.fixture(scope="module")
def real_queries():
    """``mocaplib query`` at each chosen real entry's own command, planted on the library's
    skeleton: {entry id: ContactMeasures}, and the library's body scales."""
    from walking_library import real_walks

    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.planting import plant_blend

    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    library = real_walks()[0]
    space = ControlSpace.from_library(library)
    out = {}
    for entry, point in zip(space.ids, space.points):
        answer = space.query([point])
        if not answer.inside[0]:
            answer = space.query(answer.nearest)
        out[entry] = plant_blend(space.on_body(space.blend(answer), answer),
                                 library.skeleton, rate=RATE, cycles=2).after
    return out, library.body_scales()


def test_queries_of_the_real_walks_stand_on_the_librarys_body(real_queries):
    # each blend's pelvis height scaled to the library's body by its entries' legs
    # (ControlSpace.on_body): unscaled, Walking1_c0 and Walking3_c0 (legs 92 mm longer)
    # floated 64-102 mm above the floor with no stance found. Measured: every query planted
    # with 5 stances, slide 0.00 mm, 0.01 mm below the floor, hover 0.00 mm
    feet, scales = real_queries
    assert scales.min() < 0.95 and scales.max() > 1.02          # subjects of several sizes
    assert len(feet) == 10 and all(m.stances >= 2 for m in feet.values()), feet
    worst = _worst_feet(feet)
    assert worst["slide_m"][0] <= 0.002 and worst["penetration_m"][0] <= 0.0005, worst
    assert worst["hover_m"][0] <= 0.003, worst


@pytest.fixture(scope="module")
def real_viewer_feet():
    """{entry id: ContactMeasures} of each moving real entry's cycle as the report's viewer
    poses it in JavaScript (tests/viewer_poses.py), measured at 100 Hz."""
    from viewer_poses import viewer_contact
    from walking_library import real_walks

    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    if shutil.which("node") is None:
        pytest.skip("node is not installed")
    return {entry: m for entry, m, _ in viewer_contact(real_walks()[0])
            if not entry.startswith("running")}


def test_the_report_viewers_real_walks_meet_the_targets(real_viewer_feet):
    # measured, each entry drawn on the library's body (its pelvis height scaled by its legs:
    # Library.on_header_body), every one with its stances: slide 1.43 mm
    # (PiG_Motion-FlatFoot-Full_c1), nothing below the floor, hover 1.35 mm (Gait_c0).
    # Unscaled, Walking1_c0 and Walking3_c0 floated 64-102 mm above the floor, no stance found
    # (vacuously "met"); posed with the series' pitch where the leg cannot reach it, the viewer
    # slid up to 265 mm (HC030A05_c0); with the stances read at the series' 30 Hz
    # (STANCE_RATE), 07_12_c0's lock began 0.15 s late (18.1 mm); with each lock starting at
    # the series' first stance frame, up to a frame after the foot comes down,
    # PiG_Motion-FlatFoot-Full_c0 hovered 4.7 mm (its heel down between two frames)
    assert all(m.stances >= 2 for m in real_viewer_feet.values()), real_viewer_feet
    worst = _worst_feet(real_viewer_feet)
    assert worst["slide_m"][0] <= 0.002 and worst["penetration_m"][0] <= 0.0005, worst
    assert worst["hover_m"][0] <= 0.003, worst
