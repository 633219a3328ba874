"""Anatomical joint centres and segment frames of the pelvis and limbs, from landmarks.

The definitions are those of the conventional gait model (Plug-in Gait, CGM; Davis et al. 1991,
Baker et al. 2017) and of the ISB recommendations (Wu et al. 2002), which agree for these
segments; every array is world coordinates, metres, one row per frame (F, 3).

Joint centres
    * **Hip**: the conventional gait model's (Davis et al. 1991, :func:`davis_hip`) when the
      subject's leg length is known (Plug-in Gait stores it with the capture, so its hip
      centres are reproduced); otherwise Harrington et al.'s (2007, J Biomech 40:595)
      regression from pelvis width PW (ASIS–ASIS) and depth PD (mid-ASIS to mid-PSIS, or the
      sacrum), in the ASIS pelvis frame: x = −0.24 PD − 9.9 mm, y = ±(0.33 PW + 7.3 mm),
      z = −0.30 PW − 10.9 mm, which needs no measurement and is the more accurate against
      medical imaging (Harrington 2007; Sangeux et al. 2014).
    * **Knee, ankle, elbow**: the midpoint of the lateral and medial landmarks (epicondyles,
      malleoli) when both are on; otherwise the CGM *chord*: the centre lies at distance
      ``delta`` = (joint width + marker diameter) / 2 from the lateral marker, the angle
      proximal centre–centre–lateral marker is 90°, and the centre lies in the plane of the
      proximal centre, the lateral marker and the segment's wand (thigh, tibia or upper-arm
      marker; else its other markers), on the medial side (:func:`chord_centre`).
    * **Knee, ankle and elbow without landmarks** (a cluster set without a static): the
      *functional* centre, the point that moves with both segments (SCoRE, Ehrig et al. 2006,
      J Biomech 39:2798; :mod:`mocaplib.model.functional`), from the rigid frames of three markers on
      each segment over a motion that flexes the joint.

Segment frames (rotation matrices, columns = the segment's X forward, Y left, Z up axes when
the subject stands in the anatomical position, as :mod:`mocaplib.skeleton` requires)
    * **pelvis**: Y from the right to the left ASIS, Z normal to the plane of the ASIS and the
      mid-PSIS (or sacrum), X forward; origin midway between the hip centres. Pelvis tilt is
      0 when that plane is level.
    * **femur**: Z from the knee centre to the hip centre, Y along the knee's flexion axis (the
      medial–lateral epicondyle line, or the line from the knee centre to the lateral marker),
      pointing left, made perpendicular to Z; origin at the hip centre.
    * **tibia**: Y the femur's (the knee is a hinge about it), Z from the ankle centre to the
      knee centre made perpendicular to Y; origin at the knee centre. Knee flexion is 0 when
      the hip, knee and ankle centres are aligned in the knee's sagittal plane.
    * **foot**: Y the tibia's, X along the sole: the line from the heel to the toe (or
      forefoot) marker made perpendicular to Y, turned about Y by that line's pitch over the
      sole, measured where the sole lies flat on the floor (:func:`flat_soles`: a static's
      frames, as Plug-in Gait's flat-foot option, or the foot-flat frames of a capture's
      stances); without such frames, along the line. Origin at the ankle centre. Ankle
      dorsiflexion is 0 when the foot's X is perpendicular to the tibia's long axis; the foot's
      turn about the tibia's long axis (toe-out) is a fixed part of the marker offsets, as
      Plug-in Gait's static rotation offset.

    * **humerus**: as the femur, from the shoulder, elbow and lateral elbow landmark: Z from
      the elbow centre to the shoulder centre, Y along the elbow's flexion axis (epicondyles;
      with the lateral one alone, the normal of the arm's plane through the shoulder, elbow
      and wrist centres, as Plug-in Gait's humerus, when the elbow is flexed by
      :data:`ARM_PLANE_FLEXION` or more over the frames, else the elbow centre to the lateral
      marker), pointing left; origin at the shoulder centre. The chord places the elbow
      centre on the normal of the plane through the lateral marker, not the centre: when
      the elbow is nearly straight the two planes differ by tens of degrees, and an axis
      from the centre to the marker would leave the wrist 16-24° out of the plane the
      forearm flexes in on the Plug-in Gait captures, the forearm's long axis 65-103 mm off
      the wrist.
    * **forearm**: as the tibia: Y the humerus's (the elbow is a hinge), Z from the wrist
      centre (mid-styloids) to the elbow centre made perpendicular to Y; origin at the elbow
      centre. Elbow flexion is then the angle between the shoulder–elbow and elbow–wrist
      centre lines, as Plug-in Gait measures it.

The torso and head keep frames turned onto the landmark catalogue's layout
(:mod:`mocaplib.model.calibration`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..numeric import median, nanmedian
from .floor import foot_flat_frames

#: Subject measurements mocaplib can use (metres, kilograms), as :attr:`Trial.measurements`
#: keys: sided ones end in ``_l``/``_r``.
MEASUREMENTS = ("knee_width_l", "knee_width_r", "ankle_width_l", "ankle_width_r",
                "elbow_width_l", "elbow_width_r", "shoulder_offset_l", "shoulder_offset_r",
                "marker_diameter", "body_mass", "height", "leg_length_l", "leg_length_r",
                "inter_asis_distance", "asis_trochanter_l", "asis_trochanter_r")
#: The largest value of each measurement (without its side) a person can have, metres or
#: kilograms: well beyond any adult, so that only a slip of units or a typing error is refused.
MEASUREMENT_LIMITS = {"knee_width": 0.3, "ankle_width": 0.2, "elbow_width": 0.2,
                      "shoulder_offset": 0.2, "marker_diameter": 0.05, "body_mass": 500.0,
                      "height": 3.0, "leg_length": 1.6, "inter_asis_distance": 0.6,
                      "asis_trochanter": 0.3}

#: Landmarks defining the knee and ankle: (lateral, medial, joint's child segment).
HINGES = {"knee": ("KNEE_LAT", "KNEE_MED", "tibia"), "ankle": ("ANKLE_LAT", "ANKLE_MED", "foot")}
#: The wand landmarks whose plane with the joint line sets a chord's medial direction, per
#: segment (Plug-in Gait's thigh and tibia wands); without them, the segment's other markers.
WANDS = {"femur": ("THIGH",), "tibia": ("SHANK",), "humerus": ("UPPER_ARM",)}
#: Landmarks that mark the back and the front of the foot, in order of preference.
HEEL_LANDMARKS = ("HEEL", "HEEL_UPPER", "CALC_LAT")
TOE_LANDMARKS = ("TOE", "TOE2", "HALLUX")
FOREFOOT_PAIR = ("MT1", "MT5")
#: Median elbow flexion (degrees) over the frames from which an elbow with only its lateral
#: landmark takes its flexion axis from the arm's plane (shoulder, elbow and wrist centres);
#: straighter, that plane is ill-defined and the axis runs from the centre to the marker.
ARM_PLANE_FLEXION = 15.0
#: A wand whose direction from the joint line is within this angle of the medial-lateral
#: direction (degrees) sets the chord's plane; otherwise the pelvis's medial direction does.
WAND_ANGLE_LIMIT = 60.0


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` (..., 3) scaled to unit length along the last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perpendicular(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The part of ``v`` (F, 3) perpendicular to the unit ``axis`` (F, 3)."""
    return v - (v * axis).sum(axis=-1, keepdims=True) * axis


def harrington_hips(lasi, rasi, back) -> tuple[np.ndarray, np.ndarray]:
    """Left and right hip centres (F, 3) from ASIS (F, 3) and mid-PSIS or sacrum ``back`` (F, 3).

    Harrington et al. 2007: in the frame at mid-ASIS with Y to the left ASIS, X forward (from
    ``back`` to mid-ASIS, made orthogonal to Y) and Z up, a hip centre is at
    x = −0.24 PD − 9.9 mm, |y| = 0.33 PW + 7.3 mm, z = −0.30 PW − 10.9 mm.
    """
    R = pelvis_axes(lasi, rasi, back)
    origin = 0.5 * (lasi + rasi)
    pw = np.linalg.norm(lasi - rasi, axis=1)[:, None]
    pd = np.linalg.norm(origin - back, axis=1)[:, None]
    ax, ay, az = -0.24 * pd - 0.0099, 0.33 * pw + 0.0073, -0.30 * pw - 0.0109
    x, y, z = R[..., 0], R[..., 1], R[..., 2]
    return origin + ax * x + ay * y + az * z, origin + ax * x - ay * y + az * z


def pelvis_axes(lasi, rasi, back) -> np.ndarray:
    """Pelvis rotation (F, 3, 3) from ASIS and mid-PSIS/sacrum (F, 3): Y to the left ASIS,
    X forward in the plane of the three points, Z up."""
    y = unit(lasi - rasi)
    x = unit(_perpendicular(0.5 * (lasi + rasi) - back, y))
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def chord_centre(proximal, wand, lateral, delta, medial_hint) -> np.ndarray:
    """A knee or ankle centre (F, 3) by the conventional gait model's chord.

    The centre C lies ``delta`` (metres: half the joint width plus the marker radius) from the
    ``lateral`` marker, with the angle ``proximal`` centre–C–marker at 90°, in the plane of
    ``proximal``, ``wand`` and ``lateral`` (each (F, 3)), on the side of the marker that
    ``medial_hint`` (F, 3) points to. When the wand lies in front of or behind the joint line
    rather than beside it (more than :data:`WAND_ANGLE_LIMIT` from the medial direction),
    that plane says nothing of the medial direction and ``medial_hint`` sets it instead.
    """
    to_proximal = proximal - lateral
    length = np.linalg.norm(to_proximal, axis=-1, keepdims=True)
    along = to_proximal / length
    medial = unit(_perpendicular(medial_hint, along))
    from_wand = -unit(_perpendicular(wand - lateral, along))
    in_plane = (from_wand * medial).sum(axis=-1, keepdims=True) > np.cos(
        np.deg2rad(WAND_ANGLE_LIMIT))
    across = np.where(in_plane, from_wand, medial)
    cos_a = np.clip(delta / length, 0.0, 1.0)
    return lateral + delta * (cos_a * along + np.sqrt(1.0 - cos_a ** 2) * across)


def frame(primary: np.ndarray, secondary: np.ndarray, *, order: str) -> np.ndarray:
    """Rotations (F, 3, 3) whose column ``order[0]`` is along ``primary`` (F, 3) and column
    ``order[1]`` along ``secondary`` made perpendicular to it; right-handed. ``order`` is two
    of "xyz", e.g. "zy" (long axis, then flexion axis)."""
    a = unit(primary)
    b = unit(_perpendicular(secondary, a))
    i, j = "xyz".index(order[0]), "xyz".index(order[1])
    k = 3 - i - j
    c = np.cross(a, b) if (j - i) % 3 == 1 else np.cross(b, a)
    out = np.empty(a.shape[:-1] + (3, 3))
    out[..., i], out[..., j], out[..., k] = a, b, c
    return out


def segment_frames(where: dict[str, np.ndarray], centres: dict[tuple[str, float], np.ndarray],
                   *, flat_feet: Mapping[str, np.ndarray] | None = None,
                   knee_turns: dict[str, float] | None = None,
                   axes: Mapping[str, np.ndarray] | None = None
                   ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The anatomical frames of the pelvis, legs and arms that the landmarks define.

    ``where`` maps landmark names (``L_ASIS``...) to positions (F, 3); ``centres`` maps
    ``(segment, 0.0)`` to that segment's joint centre (F, 3), as
    :func:`mocaplib.model.joint_centres.joint_centres` returns them. Returns, for each segment whose
    frame can be built, its rotation (F, 3, 3) and origin (F, 3), as the module describes;
    a segment whose landmarks are missing is left out (and so are the segments below it).
    ``flat_feet``: per side ("l", "r"), the frames (F,) bool in which that foot's sole lies
    flat on level ground (:func:`flat_soles`): the foot's long axis is along the sole they
    show; a side left out keeps the line between the markers, whose heights above the sole
    differ.
    ``knee_turns``: per side ("l", "r"), radians in the sense of ``hip_rotation`` (internal
    positive): the femur's frame is turned about its long axis by it, and with it the knee's
    flexion axis and the tibia's and foot's frames built on that axis (a functional knee axis,
    :func:`mocaplib.model.joint_centres.functional_knee_turns`).
    ``axes``: per upper segment ("femur_l", "humerus_r"...), the functional flexion axis of
    the joint below it (F, 3), unit vectors pointing laterally
    (:func:`mocaplib.model.joint_centres.joint_centres`): it stands for the lateral landmark
    a cluster set lacks.
    """
    axes = axes or {}
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    hips = centres.get(("femur_l", 0.0)), centres.get(("femur_r", 0.0))
    back = (0.5 * (where["L_PSIS"] + where["R_PSIS"]) if {"L_PSIS", "R_PSIS"} <= set(where)
            else where.get("SACRUM"))
    if {"L_ASIS", "R_ASIS"} <= set(where) and back is not None and all(h is not None for h in hips):
        out["pelvis"] = (pelvis_axes(where["L_ASIS"], where["R_ASIS"], back),
                         0.5 * (hips[0] + hips[1]))
    for side, sign in (("l", 1.0), ("r", -1.0)):
        out.update(leg_frames(where, centres, side, flat=(flat_feet or {}).get(side),
                              knee_turn=(knee_turns or {}).get(side, 0.0),
                              axis=axes.get(f"femur_{side}")))
        wrist = next((point for (segment, z), point in centres.items()
                      if segment == f"forearm_{side}" and z != 0.0), None)
        out.update(_limb_frames(where, centres, side, sign, ("humerus", "forearm"), "ELBOW",
                                wrist, axis=axes.get(f"humerus_{side}")))
    return out


def leg_frames(where: dict[str, np.ndarray], centres: dict[tuple[str, float], np.ndarray],
               side: str, *, flat: np.ndarray | None = None, knee_turn: float = 0.0,
               axis: np.ndarray | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The frames (rotations (F, 3, 3), origins (F, 3)) of the femur, tibia and foot of
    ``side`` ("l", "r") that :func:`segment_frames` builds from the same ``where`` and
    ``centres``, the foot along the sole it lies flat on in the ``flat`` frames ((F,) bool;
    None or none of them: along the marker line) and the knee's axis turned by ``knee_turn``
    (radians, internal rotation positive); ``axis`` (F, 3) the knee's functional flexion
    axis pointing laterally, used without a lateral knee landmark; those it cannot build
    left out.

    The sole is level in the ``flat`` frames: the foot's X is the marker line's (made
    perpendicular to Y) turned about Y by the median over them of the angle that makes it
    horizontal, as Plug-in Gait's flat-foot option levels it on a static."""
    out = _limb_frames(where, centres, side, 1.0 if side == "l" else -1.0, ("femur", "tibia"),
                       "KNEE", centres.get((f"foot_{side}", 0.0)), turn=knee_turn, axis=axis)
    heel, toe = _foot_line(where, side.upper())
    if f"tibia_{side}" in out and heel is not None:
        axis = out[f"tibia_{side}"][0][..., 1]
        foot = frame(axis, toe - heel, order="yx")
        # the turn about Y from the marker line to the heel-to-toe direction made horizontal
        sole = frame(axis, (toe - heel) * (1.0, 1.0, 0.0), order="yx")[..., 0]
        pitch = np.arctan2(-(sole * foot[..., 2]).sum(axis=-1), (sole * foot[..., 0]).sum(axis=-1))
        level = np.zeros(len(pitch), dtype=bool) if flat is None else flat & np.isfinite(pitch)
        if level.any():
            c, s = np.cos(median(pitch[level])), np.sin(median(pitch[level]))
            foot = foot @ np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        out[f"foot_{side}"] = (foot, centres[(f"foot_{side}", 0.0)])
    return out


#: Fewest calibration frames in which a foot stands flat for :func:`flat_soles` to take its
#: sole from a capture's stances.
MIN_FLAT_FRAMES = 5


def flat_soles(where: dict[str, np.ndarray], *, rate: float | None = None,
              frames: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The frames (bool) in which each foot's sole lies flat on level ground, per side ("l",
    "r"), for :func:`segment_frames`, and a sentence per side saying so (``sole_l``...).

    ``where`` maps landmark names to positions (F, 3). ``rate`` None: a static, every frame
    (the subject stands, feet flat, as Plug-in Gait's flat-foot option takes it). Else a
    capture at ``rate`` Hz: the frames in which the foot stands flat on its floor
    (:func:`mocaplib.model.floor.foot_flat_frames`: the middle of each stance, heel and
    forefoot both still and down), taken at ``frames`` (indices, the calibration's; default
    all). The markers sit at different heights above the sole (the Oxford Foot Model's toe
    marker 4-5° up the line from its heel marker), and a foot along their line carries that as
    an ankle angle. A side with fewer than :data:`MIN_FLAT_FRAMES` such frames (a treadmill,
    stairs all the way, a toe walker) is left out: its foot keeps the marker line.
    """
    masks, methods = {}, {}
    for side in ("l", "r"):
        heel, toe = _foot_line(where, side.upper())
        if heel is None:
            continue
        if rate is None:
            masks[side] = np.ones(len(heel), dtype=bool)
            methods[f"sole_{side}"] = "flat on the floor in the static"
            continue
        flat = foot_flat_frames(heel, toe, rate)
        flat = flat if frames is None else flat[frames]
        if flat.sum() < MIN_FLAT_FRAMES:
            methods[f"sole_{side}"] = (
                f"the heel-to-toe marker line: the foot stands flat in {int(flat.sum())} of the "
                f"calibration frames, the sole needs {MIN_FLAT_FRAMES}")
        else:
            masks[side] = flat
            methods[f"sole_{side}"] = (f"flat on the floor in {int(flat.sum())} of the "
                                       f"calibration frames (the capture's stances)")
    return masks, methods


def _limb_frames(where: dict[str, np.ndarray], centres: dict[tuple[str, float], np.ndarray],
                 side: str, sign: float, segments: tuple[str, str], joint: str,
                 distal: np.ndarray | None, *, turn: float = 0.0,
                 axis: np.ndarray | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The frames of one limb's two segments (femur and tibia, or humerus and forearm) of
    ``side`` ("l", "r"; ``sign`` +1 left, −1 right), as :func:`segment_frames` describes:
    the upper one from its joint centre, the middle joint's centre and its ``joint``'s
    lateral (and medial) landmark (an elbow with the lateral one alone: the arm's plane, the
    module docstring says when), then turned about its long axis by ``turn`` (radians,
    internal rotation positive); the lower one from the middle joint and the ``distal``
    point (ankle or wrist centre, (F, 3); without it, only the upper frame). Without the
    lateral landmark, the middle joint's functional ``axis`` (F, 3, pointing laterally) is
    its flexion axis."""
    upper, lower = segments
    top, middle = centres.get((f"{upper}_{side}", 0.0)), centres.get((f"{lower}_{side}", 0.0))
    lateral = where.get(f"{side.upper()}_{joint}_LAT")
    if top is None or middle is None or (lateral is None and axis is None):
        return {}
    medial = where.get(f"{side.upper()}_{joint}_MED")
    across = axis if lateral is None else lateral - (middle if medial is None else medial)
    if joint == "ELBOW" and lateral is not None and medial is None and distal is not None:
        normal = np.cross(distal - middle, top - middle)
        flexion = 180.0 - np.degrees(np.arctan2(np.linalg.norm(normal, axis=-1), (
            (distal - middle) * (top - middle)).sum(axis=-1)))
        if nanmedian(flexion) >= ARM_PLANE_FLEXION:
            across = normal * np.sign((normal * across).sum(axis=-1, keepdims=True))
    first = frame(top - middle, sign * across, order="zy")
    if turn:                                     # internal rotation turns -Z left, +Z right
        c, s = np.cos(-sign * turn), np.sin(-sign * turn)
        first = first @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = {f"{upper}_{side}": (first, top)}
    if distal is not None:
        out[f"{lower}_{side}"] = (frame(first[..., 1], middle - distal, order="yz"), middle)
    return out


def _foot_line(where: dict[str, np.ndarray], side: str):
    """The heel and the toe (or forefoot) landmarks' positions (F, 3) of one foot, or Nones."""
    heel = next((where[f"{side}_{n}"] for n in HEEL_LANDMARKS if f"{side}_{n}" in where), None)
    toe = next((where[f"{side}_{n}"] for n in TOE_LANDMARKS if f"{side}_{n}" in where), None)
    pair = [where.get(f"{side}_{n}") for n in FOREFOOT_PAIR]
    if toe is None and all(p is not None for p in pair):
        toe = 0.5 * (pair[0] + pair[1])
    toe = next((p for p in pair if p is not None), None) if toe is None else toe
    return (heel, toe) if heel is not None and toe is not None else (None, None)


def offsets_in_frames(X: np.ndarray, segments: np.ndarray, segment_names: tuple[str, ...],
                      frames: dict[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Each marker's mean position (M, 3) in its segment's anatomical frame, metres.

    ``X`` (F, M, 3) markers, ``segments`` (M,) indices into ``segment_names``, ``frames`` as
    :func:`segment_frames` returns them. NaN for markers on segments without a frame, or never
    seen where their frame is.
    """
    out = np.full((X.shape[1], 3), np.nan)
    for name, (R, origin) in frames.items():
        on = np.flatnonzero(segments == segment_names.index(name))
        local = np.einsum("fji,fmj->fmi", R, X[:, on] - origin[:, None])
        seen = np.isfinite(local).all(axis=2)
        count = seen.sum(axis=0)
        total = np.where(seen[..., None], local, 0.0).sum(axis=0)
        out[on] = np.where(count[:, None] > 0, total / np.maximum(count, 1)[:, None], np.nan)
    return out


def davis_hip(lasi, rasi, back, *, side: str, leg_length: float, marker_radius: float,
              asis_trochanter: float | None = None, asis_distance: float | None = None
              ) -> np.ndarray:
    """The ``side`` ("l" or "r") hip centre (F, 3) by the conventional gait model (Davis et
    al. 1991), as Plug-in Gait places it, from ASIS (F, 3), mid-PSIS or sacrum ``back``
    (F, 3), that leg's length (m), the marker radius (m) and, when measured, the
    ASIS–trochanter distance (m; else 0.1288 leg length − 48.56 mm) and the ASIS distance
    (m; else the markers').

    In the ASIS pelvis frame (:func:`pelvis_axes`, origin mid-ASIS), with
    C = 0.115 leg length − 15.3 mm, θ = 0.5 rad, β = 0.314 rad, d = ASIS–trochanter distance
    + marker radius: x = C cos θ sin β − d cos β, |y| = half the ASIS distance − C sin θ,
    z = −C cos θ cos β − d sin β.
    """
    R = pelvis_axes(lasi, rasi, back)
    origin = 0.5 * (lasi + rasi)
    half_width = 0.5 * (np.linalg.norm(lasi - rasi, axis=1)[:, None] if asis_distance is None
                        else asis_distance)
    C = 0.115 * leg_length - 0.0153
    d = (0.1288 * leg_length - 0.04856 if asis_trochanter is None else asis_trochanter) \
        + marker_radius
    theta, beta = 0.5, 0.314
    ax = C * np.cos(theta) * np.sin(beta) - d * np.cos(beta)
    ay = half_width - C * np.sin(theta)
    az = -C * np.cos(theta) * np.cos(beta) - d * np.sin(beta)
    x, y, z = R[..., 0], R[..., 1], R[..., 2]
    return origin + ax * x + (ay if side == "l" else -ay) * y + az * z
