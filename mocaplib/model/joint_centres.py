"""Anatomical joint centres and the subject's size from a calibration trial's landmarks
(steps 2-4 of :mod:`mocaplib.model.calibration`): the height, the hip, knee, ankle, shoulder,
elbow and wrist centres, the shoulder drops along the thorax axis, the joint shifts, the
neutral static's offsets and the functional knee axes.

Positions are metres in the world frame (Z up), per frame ``(F, 3)`` or per segment.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import MIN_MARKER_SPREAD, SPREAD_HINT, UNITS_HINT, CalibrationError
from ..markersets import protocols as _protocols
from ..numeric import distinct, median, nanmedian
from ..skeleton import DOF_NAMES, ROOT_HEADING, SEGMENT_NAMES, SEGMENTS, Skeleton, partner_name
from .anatomy import WANDS, chord_centre, davis_hip, harrington_hips, segment_frames
from .functional import functional_limb_joints
from .solver import initial_pose, solve_poses

#: Joints a static in the neutral pose moves to their anatomical centres (:func:`neutral_shifts`):
#: the shoulders (from the acromion) and the elbows. The hips, knees and ankles keep the
#: nominal layout while the motion's markers mark the knees and ankles (else
#: :data:`mocaplib.model.calibration.NEUTRAL_LEG_CENTRES`). Moved to Harrington's centres, the
#: hips lower the knee's flexion error
#: (exact markers of ``run_3p0``: 3.6° to 2.4° RMS) but take the leg down with them, the ankle
#: from 18 mm above its true centre to 7 mm below, and ankle inversion's error grows as that
#: pivot nears the foot markers (2.5° to 6.9°): the fit's ankle has no DOF for the foot's turn
#: about the shank that an oblique subtalar axis gives, and reads it as a roll about the pivot,
#: less the higher the pivot. A modelling difference, not an inconsistent calibration
#: (``python benchmarks/fit_accuracy.py --only ankle``; docs/results/fit_accuracy.md).
NEUTRAL_CENTRES = ("humerus_r", "humerus_l", "forearm_r", "forearm_l")


#: The chord joints of a static in the neutral pose: not the elbow, whose centre is then its
#: lateral landmark moved by the catalogue offset turned by the pelvis's orientation (every
#: segment's in that pose), i.e. along the mediolateral axis, a hanging arm's flexion axis.
#: The chord's plane (shoulder centre, upper-arm marker, lateral epicondyle) is nearly
#: edge-on to that axis and leans with millimetres of the markers' fore-aft placement: 11 mm
#: forward on the samples' exact markers.
NEUTRAL_CHORD_JOINTS = ("tibia", "foot")


#: Turns of each knee's flexion axis about the femur's long axis (radians) that step 4b tries
#: (:func:`functional_knee_turns`); the chosen one is the vertex of the parabola through the
#: best of them and its neighbours, so within this span.
KNEE_AXIS_TURNS = np.radians(np.arange(-30.0, 31.0, 15.0))


#: Every how many of step 5's frames step 4b fits. On the 8 shared real captures with a
#: moving knee, every second frame and turns 15° apart, started from the anatomical axes'
#: poses, choose turns within 0.9° of every frame's with turns 10° apart started cold (1.8°
#: on PiG_Motion-FlatFoot-Full's right knee, turned −3.2° against −1.4°), at 40 % of the cost.
KNEE_AXIS_FRAME_STEP = 2


#: Knee flexion range (radians) the calibration frames must show for a functional knee axis;
#: a knee that flexes less (a static, standing) keeps its anatomical axis.
KNEE_AXIS_MIN_FLEXION = np.radians(20.0)


#: Joint centres from landmarks: child segment (its origin is the joint) and its landmarks
#: (lateral, medial); the lateral one alone is used with its catalogue offset.
_LANDMARK_JOINTS = {
    "tibia": ("KNEE_LAT", "KNEE_MED"),
    "foot": ("ANKLE_LAT", "ANKLE_MED"),
    "humerus": ("ACROMION", None),
    "forearm": ("ELBOW_LAT", "ELBOW_MED"),
}


#: The joint at each child segment's origin, as named in joint widths and reports.
_JOINT_NAMES = {"tibia": "knee", "foot": "ankle", "humerus": "shoulder", "forearm": "elbow"}


#: Marker diameter (m) assumed when a file gives joint widths but no diameter: Plug-in Gait's.
DEFAULT_MARKER_DIAMETER = 0.014


#: Lengths the joint centres of the pelvis, legs and arms set, which refinement keeps when both
#: centres (the origins of the two segments named) are known on both sides.
ANATOMICAL_LENGTHS = {"hip_width": ("femur", "femur"), "thigh": ("femur", "tibia"),
                       "shank": ("tibia", "foot"), "upper_arm": ("humerus", "forearm")}


#: Joints whose centre a lateral marker and a segment wand give by the chord.
_CHORD_JOINTS = ("tibia", "foot", "forearm")


def neutral_offsets(skeleton: Skeleton, X: np.ndarray, segments: np.ndarray, *,
                    nominal: np.ndarray, heading_offset: float = 0.0,
                    centres: dict[tuple[str, float], np.ndarray] | None = None,
                    joints: tuple[str, ...] = NEUTRAL_CENTRES
                    ) -> tuple[np.ndarray, float, np.ndarray, Skeleton]:
    """Marker offsets (M, 3) measured on a static trial in the anatomical neutral pose.

    ``X`` (F, M, 3) static markers, ``segments`` (M,), ``nominal`` (M, 3) catalogue offsets
    (scaled) for the start (NaN for tracking markers: they are left out of the root's fit).
    Every joint angle is held at 0; the root pose (pelvis 6 DOFs) is fitted to the landmark
    markers with the nominal offsets, its heading turned by ``heading_offset``
    (radians, counter-clockwise), then each offset is the mean of ``R_s^T (x − t_s)`` over the
    frames where its marker is seen (not turned onto the catalogue: the pose, not the layout,
    defines the segment frames). With the anatomical joint ``centres`` (:func:`joint_centres`)
    the skeleton's ``joints`` (segment names) are first moved onto them (:func:`neutral_shifts`).
    Returns the offsets, the RMS (m) of the static markers about the neutral model with them,
    the poses (F, D) and the skeleton.
    """
    root = np.isin(DOF_NAMES, SEGMENTS[0].dofs)
    X_known, known = landmark_markers(X, nominal)
    q0 = np.where(root, initial_pose(skeleton, X_known, segments, known), 0.0)
    q = solve_poses(skeleton, X_known, segments, known, q0=q0, free=root, smoothing=0.0).q
    q[:, ROOT_HEADING] += heading_offset
    if centres:
        skeleton = Skeleton(skeleton.lengths, neutral_shifts(skeleton, q, centres, joints))
    T = skeleton.forward(q)
    offsets = register_offsets(skeleton, q, X, segments, nominal=nominal, align=(), transforms=T)
    residual = np.linalg.norm(skeleton.points(q, segments, offsets, transforms=T) - X, axis=2)
    return offsets, float(np.sqrt(np.nanmean(residual ** 2))), q, skeleton


def neutral_shifts(skeleton: Skeleton, q: np.ndarray,
                   centres: dict[tuple[str, float], np.ndarray],
                   joints: tuple[str, ...] = NEUTRAL_CENTRES
                   ) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that put the ``joints`` (segment names, each after its
    parent) at their anatomical centres on a static in the neutral pose.

    ``q`` (F, D) the static's poses (every joint angle 0, so every segment's frame is the
    root's), ``centres`` the anatomical joint centres (:func:`joint_centres`, world, (F, 3)).
    A joint is placed after its parent (an elbow in the moved upper arm's frame), and both
    sides take the mean of their shifts, mirrored. Without the shifts a shoulder sits where
    the nominal layout puts it, straight above the hip centres, and the elbow straight below
    it: an elbow hinged about a point off the true one reads the wrong flexion, more as it
    flexes more (docs/results/fit_accuracy.md).
    """
    T = skeleton.forward(q)
    frames = {}
    for name in joints:
        if (name, 0.0) in centres:
            parent = SEGMENT_NAMES.index(SEGMENTS[SEGMENT_NAMES.index(name)].parent)
            frames.setdefault(SEGMENT_NAMES[parent], (T[:, parent, :3, :3], T[:, parent, :3, 3]))
            frames[name] = (T[:, parent, :3, :3], centres[(name, 0.0)])
    return _mirrored_mean(joint_shifts(skeleton, frames))


def _mirrored_mean(shifts: dict[str, tuple[float, float, float]]
                   ) -> dict[str, tuple[float, float, float]]:
    """One shift (metres) for both sides of each segment in ``shifts``: the mean of the
    sides' own, the right's mirrored (y negated). The skeleton stays left-right symmetric
    (its lengths are the sides' means), so the shoulder line keeps the torso's heading (θ_S)."""
    sides: dict[str, list] = {}
    for name, (x, y, z) in shifts.items():
        for key, sign in ((name, 1.0), (partner_name(name), -1.0)):
            sides.setdefault(key, []).append((x, sign * y, z))
    return {name: tuple(float(v) for v in np.mean(values, axis=0))
            for name, values in sides.items()}


def anatomical_frames(skeleton: Skeleton, q: np.ndarray, X: np.ndarray, landmarks: list[str],
                      centres: dict[tuple[str, float], np.ndarray], drops: dict[str, float],
                      *, flat_feet: dict[str, np.ndarray] | None = None,
                      axes: dict[str, np.ndarray] | None = None
                      ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`mocaplib.model.anatomy.segment_frames` of the markers ``X`` (F, M, 3) (``landmarks``
    (M,) their landmarks) and joint ``centres`` (:func:`joint_centres`), the arms hanging
    from the shoulder centres where the torso's layout puts them at the poses ``q`` (F, D)
    of ``skeleton``, except on the sides ``drops`` (:func:`shoulder_drops`) places below the
    acromion; the feet along the soles they lie flat on in the ``flat_feet`` frames
    (:func:`mocaplib.model.anatomy.flat_soles`); the knees and elbows without a lateral landmark
    hinged on their functional ``axes`` (:func:`joint_centres`)."""
    T = skeleton.forward(q)
    shoulders = {(name, 0.0): T[:, SEGMENT_NAMES.index(name), :3, 3]
                 for name in ("humerus_l", "humerus_r")
                 if (name, 0.0) in centres and name[-1] not in drops}
    return segment_frames({name: X[:, i] for i, name in enumerate(landmarks)},
                          {**centres, **shoulders}, flat_feet=flat_feet, axes=axes)


def shoulder_drops(measurements: dict[str, float]) -> dict[str, float]:
    """How far (metres) each side's shoulder centre lies below its acromion marker when the
    subject's shoulder offset is measured (``shoulder_offset_l``/``_r``, Plug-in Gait's
    ``ShoulderOffset``): that offset plus the marker radius, as Plug-in Gait places it. Keys
    "l", "r"; a side not measured is left out."""
    radius = 0.5 * measurements.get("marker_diameter", DEFAULT_MARKER_DIAMETER)
    return {side: measurements[f"shoulder_offset_{side}"] + radius for side in "lr"
            if measurements.get(f"shoulder_offset_{side}")}


def thorax_axis(where: dict[str, np.ndarray]) -> np.ndarray | None:
    """Plug-in Gait's thorax long axis, unit, (..., 3): from the middle of T10 and STRN to the
    middle of C7 and CLAV (``where`` maps landmark names to positions (..., 3)); None without
    those four landmarks."""
    if not {"C7", "CLAV", "T10", "STRN"} <= set(where):
        return None
    return _unit(where["C7"] + where["CLAV"] - where["T10"] - where["STRN"])


def shoulder_shifts(skeleton: Skeleton, offsets: np.ndarray, landmarks: list[str],
                    drops: dict[str, float]) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that hang the arms from the shoulder centres
    :func:`shoulder_drops` places: ``drops[side]`` below the acromion marker's offset (M, 3)
    in the torso's frame (``landmarks`` (M,) names the markers' landmarks). Both sides take
    the mean of their shifts, mirrored, so the shoulder line keeps the torso's heading (θ_S).
    Empty without a measured side or its acromion marker.

    Where the torso's catalogue layout puts them instead, the shoulders of the Plug-in Gait
    captures sit 36-44 mm from Plug-in Gait's centres, 17-39 mm higher: the arm swings about
    a point that far from the pivot, the distance from the shoulder centre to the wrist
    changes with the swing, and the elbow hinge takes the change up, about doubling its
    range on the walks (docs/guide/fitting.md, The arms)."""
    nominal = Skeleton(skeleton.lengths).joint_offsets()
    up = thorax_axis({name: offsets[i] for i, name in enumerate(landmarks)})
    up = np.array([0.0, 0.0, 1.0]) if up is None else up
    return _mirrored_mean({
        f"humerus_{side}": tuple(offsets[landmarks.index(f"{side.upper()}_ACROMION")] - drop * up
                                 - nominal[SEGMENT_NAMES.index(f"humerus_{side}")])
        for side, drop in drops.items() if f"{side.upper()}_ACROMION" in landmarks})


def estimate_height(X: np.ndarray, segments: np.ndarray, nominal: np.ndarray, *,
                    source: str | None = None) -> float:
    """Standing height, metres, from marker distances within segments vs nominal (1.75 m),
    clipped to 0.8-2.3 m.

    X (F, M, 3) markers; segments (M,); nominal (M, 3) catalogue positions for 1.75 m. Falls
    back to 1.75 m when no segment carries two markers seen together. Raises
    :class:`CalibrationError` naming ``source`` when the markers lie at one place (no pair
    :data:`mocaplib.errors.MIN_MARKER_SPREAD` apart: no body) or the distances suggest a
    height outside :data:`PLAUSIBLE_HEIGHT` (the file's units are wrong).
    """
    ratios = []
    distances, pairs = segment_distances(X, segments)
    seen = distances[np.isfinite(distances)]
    if seen.size and seen.max() < MIN_MARKER_SPREAD:
        raise CalibrationError(
            f"the markers on each segment lie at one place ({seen.max():.2g} m apart): they "
            "do not spread like markers on a body", path=source, hint=SPREAD_HINT)
    for (a, b), d in zip(pairs, distances):
        ref = np.linalg.norm(nominal[a] - nominal[b])
        if ref > 0.05 and np.isfinite(d):
            ratios.append(d / ref)
    if not ratios:
        return _protocols.REFERENCE_HEIGHT
    height = float(median(ratios) * _protocols.REFERENCE_HEIGHT)
    if not PLAUSIBLE_HEIGHT[0] <= height <= PLAUSIBLE_HEIGHT[1]:
        raise CalibrationError(
            f"the distances between markers on one segment suggest a subject {height:.3g} m "
            "tall: the coordinates are not in the units the file states", path=source,
            hint=UNITS_HINT)
    return float(np.clip(height, 0.8, 2.3))


def joint_centres(X: np.ndarray, landmarks: list[str], segments: np.ndarray,
                  skeleton: Skeleton, q: np.ndarray, *, scale: float,
                  measurements: dict[str, float] | None = None, neutral: bool = False
                  ) -> tuple[dict[tuple[str, float], np.ndarray], dict[str, str],
                             dict[str, np.ndarray]]:
    """Anatomical joint centres per frame, world (F, 3) metres, how each was found, and the
    functional flexion axes of the knees and elbows no landmark gives.

    Keys are ``(segment, z)``: the point ``(0, 0, z)`` of that segment's frame (z = 0: its
    joint; the wrist is the forearm's end). Hip: :func:`mocaplib.model.anatomy.harrington_hips`.
    Knee and ankle: the midpoint of the lateral and medial landmarks; else the chord
    (:func:`mocaplib.model.anatomy.chord_centre`) from the proximal centre, the lateral marker and
    the segment's other markers, with ``delta`` = (joint width + marker diameter) / 2 from
    ``measurements`` (metres; :data:`mocaplib.model.anatomy.MEASUREMENTS`) or, without them, the
    catalogue's distance from the lateral landmark to the joint; else (no other marker on
    the segment) the lateral landmark moved by its catalogue offset turned by the nominal fit
    ``q`` (F, D). Elbow: likewise; shoulder: the acromion lowered by the measured shoulder
    offset (:func:`shoulder_drops`) along Plug-in Gait's thorax axis (:func:`thorax_axis`;
    without its landmarks, the torso's), else the acromion's catalogue offset; wrist:
    mid-styloids. On a static in the neutral pose (``neutral``) catalogue offsets are turned
    by the pelvis's orientation (every segment's in that pose) and the elbow is not placed by
    the chord (:data:`NEUTRAL_CHORD_JOINTS`). A knee, ankle or elbow none of these place is
    the functional centre of three markers of each of its segments
    (:func:`mocaplib.model.functional.functional_joint`, SCoRE, the proximal centre as the
    hinge's hint), when the joint turns by :data:`mocaplib.model.functional.FUNCTIONAL_RANGE`
    or more over the frames; such a knee's or elbow's flexion axis (SARA) is returned, per
    upper segment (``"femur_l"``...), as unit vectors (F, 3) pointing laterally, for
    :func:`mocaplib.model.anatomy.segment_frames`. ``scale`` = height / 1.75 scales catalogue
    offsets. The methods (str per joint, e.g. ``{"knee_l": "chord, knee width from the
    measurements"}``) are returned beside the centres.
    """
    where = {name: X[:, i] for i, name in enumerate(landmarks)}
    catalogue = _protocols.load_landmarks()
    measurements = measurements or {}
    drops = shoulder_drops(measurements)
    T = skeleton.forward(q)
    joints = skeleton.joint_offsets()
    out: dict[tuple[str, float], np.ndarray] = {}
    methods: dict[str, str] = {}
    axes: dict[str, np.ndarray] = {}
    back = _mean_of(where, ["L_PSIS", "R_PSIS"]) if {"L_PSIS", "R_PSIS"} <= set(where) \
        else where.get("SACRUM")
    if {"L_ASIS", "R_ASIS"} <= set(where) and back is not None:
        hips = dict(zip("lr", harrington_hips(where["L_ASIS"], where["R_ASIS"], back)))
        for side, centre in hips.items():
            leg = measurements.get(f"leg_length_{side}")
            if leg:
                centre = davis_hip(
                    where["L_ASIS"], where["R_ASIS"], back, side=side, leg_length=leg,
                    marker_radius=0.5 * measurements.get("marker_diameter",
                                                         DEFAULT_MARKER_DIAMETER),
                    asis_trochanter=measurements.get(f"asis_trochanter_{side}"),
                    asis_distance=measurements.get("inter_asis_distance"))
            out[(f"femur_{side}", 0.0)] = centre
            methods[f"hip_{side}"] = ("Davis (conventional gait model), leg length from the "
                                      "measurements" if leg else "Harrington regression")
    left = (out[("femur_l", 0.0)] - out[("femur_r", 0.0)]
            if ("femur_l", 0.0) in out and ("femur_r", 0.0) in out else None)

    def from_catalogue(lat, child):
        mark = catalogue[lat]
        s = 0 if neutral else SEGMENT_NAMES.index(mark.segment)
        local = np.asarray(mark.position) * scale - joints[SEGMENT_NAMES.index(child)]
        return where[lat] - T[:, s, :3, :3] @ local, local

    chord_joints = NEUTRAL_CHORD_JOINTS if neutral else _CHORD_JOINTS

    for side in ("L", "R"):
        suffix = "_" + side.lower()
        for child, (lateral, medial) in _LANDMARK_JOINTS.items():
            lat, med = f"{side}_{lateral}", f"{side}_{medial}"
            joint = _JOINT_NAMES.get(child, child) + suffix
            if lat in where and med in where:
                out[(child + suffix, 0.0)] = 0.5 * (where[lat] + where[med])
                methods[joint] = "midpoint of the lateral and medial landmarks"
            elif lat in where:
                centre, local = from_catalogue(lat, child + suffix)
                parent = SEGMENT_NAMES.index(catalogue[lat].segment)
                proximal = out.get((SEGMENT_NAMES[parent], 0.0))
                wand = _wand(landmarks, segments, parent, side, (lat, med))
                wand_point, medial_hint = None, centre - where[lat]
                if child in chord_joints and proximal is not None:
                    if wand:
                        with warnings.catch_warnings():
                            warnings.simplefilter("ignore", RuntimeWarning)  # wand unseen: NaN
                            wand_point = np.nanmean(X[:, wand], axis=1)
                    elif child == "forearm":
                        torso_left = T[:, SEGMENT_NAMES.index("torso"), :3, 1]
                        axis = _elbow_axis(where, side, proximal, where[lat],
                                           medial=torso_left if side == "R" else -torso_left)
                        if axis is not None:
                            wand_point, medial_hint = where[lat] - axis, axis
                if wand_point is not None:
                    width = measurements.get(f"{_JOINT_NAMES[child]}_width{suffix}")
                    delta = (0.5 * (width + measurements.get("marker_diameter",
                                                             DEFAULT_MARKER_DIAMETER))
                             if width else float(np.linalg.norm(local)))
                    centre = chord_centre(proximal, wand_point, where[lat], delta,
                                          medial_hint=medial_hint)
                    methods[joint] = (f"chord, {_JOINT_NAMES[child]} width "
                                      + ("from the measurements" if width
                                         else "from the landmark catalogue"))
                elif child == "humerus" and suffix[1] in drops:
                    up = thorax_axis(where)
                    if up is None:
                        up = T[:, SEGMENT_NAMES.index(catalogue[lat].segment), :3, 2]
                    centre = where[lat] - drops[suffix[1]] * up
                    methods[joint] = "acromion lowered by the measured shoulder offset"
                else:
                    methods[joint] = "lateral landmark and its catalogue offset"
                out[(child + suffix, 0.0)] = centre
        placed, found_methods, found_axes = functional_limb_joints(
            X, segments, where, out, side, left=left, catalogue=catalogue, scale=scale,
            heel_centre=lambda heel, foot: where[heel] - T[:, SEGMENT_NAMES.index(foot), :3, :3]
            @ (np.asarray(catalogue[heel].position) * scale))
        out.update(placed)
        methods.update(found_methods)
        axes.update(found_axes)
        rad, uln = f"{side}_WRIST_RAD", f"{side}_WRIST_ULN"
        if rad in where and uln in where:
            out[("forearm" + suffix, -skeleton.lengths["forearm"])] = (
                0.5 * (where[rad] + where[uln]))
            methods["wrist" + suffix] = "midpoint of the styloids"
    return out, methods, axes


def _elbow_axis(where: dict[str, np.ndarray], side: str, shoulder: np.ndarray,
                lateral: np.ndarray, *, medial: np.ndarray) -> np.ndarray | None:
    """The normal (F, 3), unit, pointing medially, of the arm's plane through the
    ``shoulder`` centre, the lateral elbow marker ``lateral`` and the middle of
    the wrist landmarks of ``side`` (each (F, 3)), turned to the side of ``medial`` (F, 3),
    the body's medial direction (the torso's). Plug-in Gait's elbow chord sets its plane with
    it (the plane of the shoulder centre, the elbow marker and a point along this normal), so
    the centre lies on this normal. None without both wrist landmarks."""
    wrist = [where.get(f"{side}_{name}") for name in ("WRIST_RAD", "WRIST_ULN")]
    if any(point is None for point in wrist):
        return None
    normal = _unit(np.cross(shoulder - lateral, 0.5 * (wrist[0] + wrist[1]) - lateral))
    return normal * np.where((normal * medial).sum(axis=-1, keepdims=True) < 0.0, -1.0, 1.0)


def _wand(landmarks: list[str], segments: np.ndarray, parent: int, side: str,
          joint_landmarks: tuple[str, str]) -> list[int]:
    """Markers (indices) whose plane with a joint line sets a chord's medial direction: the
    segment's wand landmarks (:data:`mocaplib.model.anatomy.WANDS`) when on, else its other
    markers (not the joint's own ``joint_landmarks``)."""
    names = {f"{side}_{w}" for w in WANDS.get(SEGMENT_NAMES[parent][:-2], ())}
    wand = [i for i, name in enumerate(landmarks) if name in names]
    return wand or [i for i, name in enumerate(landmarks)
                    if segments[i] == parent and name not in joint_landmarks]


def joint_shifts(skeleton: Skeleton, frames: dict[str, tuple[np.ndarray, np.ndarray]]
                 ) -> dict[str, tuple[float, float, float]]:
    """:attr:`Skeleton.shifts` (metres) that put each joint centre where the anatomical
    ``frames`` (:func:`mocaplib.model.anatomy.segment_frames`: the origin of a segment's frame is its
    joint centre) place it in its parent's frame: the median over frames, minus where the
    lengths alone put it."""
    joints = Skeleton(skeleton.lengths).joint_offsets()
    out = {}
    for name, (_, origin) in frames.items():
        parent = SEGMENTS[SEGMENT_NAMES.index(name)].parent
        if parent not in frames:
            continue
        R, at = frames[parent]
        local = np.einsum("fji,fj->fi", R, origin - at)
        shift = nanmedian(local, axis=0) - joints[SEGMENT_NAMES.index(name)]  # NaN: never seen
        if np.isfinite(shift).all():
            out[name] = tuple(float(x) for x in shift)
    return out


def functional_knee_turns(anatomical_model, X: np.ndarray, segments: np.ndarray, *,
                          free: np.ndarray) -> tuple[dict[str, float], dict[str, str]]:
    """Each knee's functional flexion axis (step 4b): its turn about the femur's long axis
    from the anatomical one, radians in the sense of ``hip_rotation`` per side ("l", "r"),
    and a sentence per side for ``SubjectModel.centre_methods`` (``knee_axis_l``...).

    ``anatomical_model(knee_turns)`` returns the model (offsets (M, 3), kept (M,), skeleton) whose
    leg frames have the knees' axes turned by ``knee_turns`` (step 4's frames,
    :func:`mocaplib.model.anatomy.segment_frames`); ``X`` (F, M, 3) are the markers of step 5 (the
    motion's), of which every :data:`KNEE_AXIS_FRAME_STEP`-th frame is fitted. The poses are
    fitted with both knees turned by each of :data:`KNEE_AXIS_TURNS`, starting from the
    anatomical axes' poses; a side's turn is the vertex of the parabola through the smallest
    mean squared residual of its thigh and shank markers and its two neighbours. A side whose
    knee flexes less than :data:`KNEE_AXIS_MIN_FLEXION` over ``X`` (a static, standing) keeps
    its anatomical axis: a hinge's axis shows only when it turns.
    """
    X = X[::KNEE_AXIS_FRAME_STEP]

    def fit(turns, q0=None):
        offsets, _, skeleton = anatomical_model(turns)
        return solve_poses(skeleton, X, segments, offsets, q0=q0, free=free)

    start = fit(None)
    sides, methods = [], {}
    for side in ("l", "r"):
        knee = DOF_NAMES.index(f"knee_flexion_{side}")
        leg = np.isin(segments, [SEGMENT_NAMES.index(f"{name}_{side}")
                                 for name in ("femur", "tibia")])
        if not free[knee] or not leg.any():
            continue
        flexion = float(np.ptp(start.q[:, knee])) if len(X) else 0.0
        if flexion < KNEE_AXIS_MIN_FLEXION:
            methods[f"knee_axis_{side}"] = (
                f"anatomical: the knee flexes {np.degrees(flexion):.0f}° in the calibration "
                f"frames, a functional axis needs {np.degrees(KNEE_AXIS_MIN_FLEXION):.0f}°")
        else:
            sides.append((side, leg, flexion))
    if not sides:
        return {}, methods
    costs = np.array([[np.nanmean(pose_fit.residuals[:, leg] ** 2) for _, leg, _ in sides]
                      for pose_fit in (fit({side: turn for side, _, _ in sides}, start.q)
                                       for turn in KNEE_AXIS_TURNS)])
    step = KNEE_AXIS_TURNS[1] - KNEE_AXIS_TURNS[0]
    turns = {}
    for (side, _, flexion), cost in zip(sides, costs.T):
        i = int(np.clip(np.argmin(cost), 1, len(cost) - 2))
        a, b, c = cost[i - 1:i + 2]
        vertex = 0.5 * step * (a - c) / (a - 2 * b + c) if a - 2 * b + c > 0 else 0.0
        turns[side] = float(np.clip(KNEE_AXIS_TURNS[i] + vertex, KNEE_AXIS_TURNS[0],
                                    KNEE_AXIS_TURNS[-1]))
        methods[f"knee_axis_{side}"] = (
            f"functional: turned {np.degrees(turns[side]):+.1f}° (internal rotation positive) "
            f"about the thigh from the anatomical axis, fitting the thigh and shank markers over "
            f"{np.degrees(flexion):.0f}° of knee flexion")
    return turns, methods


def lengths_from_centres(skeleton: Skeleton,
                          centres: dict[tuple[str, float], np.ndarray]) -> dict[str, float]:
    """Segment lengths (metres): median distances between joint centres, else the nominal."""
    lengths = dict(skeleton.lengths)
    c = {seg: pos for (seg, z), pos in centres.items() if z == 0.0}
    wrist = {seg: pos for (seg, z), pos in centres.items() if z != 0.0}

    def dist(a, b):
        return nanmedian(np.linalg.norm(a - b, axis=1))

    def both_sides(key, a, b, table_b=c):
        values = [dist(c[a + s], table_b[b + s]) for s in ("_l", "_r")
                  if a + s in c and b + s in table_b]
        values = [v for v in values if np.isfinite(v)]
        if values:
            lengths[key] = float(np.mean(values))

    if "femur_l" in c and "femur_r" in c:
        lengths["hip_width"] = float(dist(c["femur_l"], c["femur_r"]))
    both_sides("thigh", "femur", "tibia")
    both_sides("shank", "tibia", "foot")
    both_sides("upper_arm", "humerus", "forearm")
    both_sides("forearm", "forearm", "forearm", wrist)
    if "humerus_l" in c and "humerus_r" in c:
        lengths["shoulder_width"] = float(dist(c["humerus_l"], c["humerus_r"]))
    return {k: (v if np.isfinite(v) and v > 0.01 else skeleton.lengths[k])
            for k, v in lengths.items()}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _mean_of(where: dict[str, np.ndarray], names: list[str]) -> np.ndarray:
    return np.mean([where[n] for n in names], axis=0)


#: Heights (m) the markers may suggest before the capture is refused as having wrong units:
#: a factor of 10 (cm read as mm or mm as cm) or more off any walking person's 0.8-2.3 m.
PLAUSIBLE_HEIGHT = (0.4, 5.0)


def segment_distances(X: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median distance (P,) metres over the frames of X (F, M, 3) of every marker pair on one
    segment (``segments`` (M,)), and the pairs (P, 2) as marker indices; NaN for a pair never
    seen together."""
    pairs = np.array([(i, j) for i in range(len(segments)) for j in range(i + 1, len(segments))
                      if segments[i] == segments[j]], dtype=int).reshape(-1, 2)
    d = nanmedian(np.linalg.norm(X[:, pairs[:, 0]] - X[:, pairs[:, 1]], axis=2), axis=0) \
        if len(X) and len(pairs) else np.full(len(pairs), np.nan)      # a pair never seen: NaN
    return d, pairs


def register_offsets(skeleton: Skeleton, q: np.ndarray, X: np.ndarray, segments: np.ndarray, *,
                     nominal: np.ndarray, align=SEGMENT_NAMES,
                     unseen: np.ndarray | None = None,
                     transforms: np.ndarray | None = None) -> np.ndarray:
    """Marker offsets (M, 3) in their segments for poses q (F, D) and markers X (F, M, 3).

    Each offset is first the least-squares one, the mean of ``R_s^T (x − t_s)`` over the frames
    where the marker is seen (never seen: its row of ``unseen``, by default ``nominal``).
    Offsets fix a segment's markers but not its frame: a constant rotation of the frame could
    be absorbed by the offsets. So each segment's offsets are then turned about their centroid
    by the rotation that best aligns its landmark markers with the catalogue layout
    ``nominal`` (M, 3) (Kabsch; with two landmark markers the segment origin joins them; a lone
    one is turned about the origin onto its nominal direction); a tracking marker (NaN row of
    ``nominal``) turns with its segment's landmark markers. The frame is thus anatomical: zero
    angles put the landmark markers in the catalogue's layout, as the DOF sign table
    describes. Only segments named in ``align`` are turned. ``transforms``:
    :meth:`Skeleton.forward` (q), when already computed.
    """
    T = (skeleton.forward(q) if transforms is None else transforms)[:, segments]
    local = np.einsum("fmji,fmj->fmi", T[..., :3, :3], X - T[..., :3, 3])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # a marker never seen: NaN
        mean = np.nanmean(local, axis=0) if len(q) else np.full_like(nominal, np.nan)
    out = np.where(np.isfinite(mean), mean, nominal if unseen is None else unseen)
    catalogued = np.isfinite(nominal).all(axis=1) & np.isfinite(out).all(axis=1)
    for s in distinct(segments):
        idx = np.flatnonzero(segments == s)
        ref = idx[catalogued[idx]]
        if SEGMENT_NAMES[s] not in align or not len(ref):
            continue
        if len(ref) == 1:                # the turn taking its direction onto the nominal one
            out[idx] = out[idx] @ _turn_between(out[ref[0]], nominal[ref[0]]).T
            continue
        reg, nom = out[ref], nominal[ref]
        if len(ref) == 2:                          # the origin fixes the turn about their line
            reg, nom = np.vstack([reg, np.zeros(3)]), np.vstack([nom, np.zeros(3)])
        c_reg, c_nom = reg.mean(axis=0), nom.mean(axis=0)
        U, _, Vt = np.linalg.svd((reg - c_reg).T @ (nom - c_nom))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
        R = U @ D @ Vt                              # rotation taking nominal to registered
        out[idx] = c_reg + (out[idx] - c_reg) @ R
    return out


def _turn_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking the direction of ``a`` (3,) onto that of ``b``."""
    a, b = _unit(a), _unit(b)
    v, c = np.cross(a, b), float(a @ b)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c) if c > -1.0 + 1e-12 else -np.eye(3)


def landmark_markers(X: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Markers X (F, M, 3) and offsets (M, 3) for a fit that leaves out the tracking markers
    whose offsets are not measured yet (NaN rows): their columns NaN, their offsets 0."""
    unknown = ~np.isfinite(offsets).all(axis=1)
    return (np.where(unknown[None, :, None], np.nan, X),
            np.where(unknown[:, None], 0.0, offsets))
