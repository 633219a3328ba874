"""Segment masses, centres of mass and inertias of the fixed skeleton, per kilogram of body mass.

Source: P. de Leva (1996), *Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters*,
J. Biomech. 29(9):1223-1230, Table 4, male subjects (mocaplib does not know the subject's sex;
the female table's largest difference is the trunk's mass, 42.57 % instead of 43.46 %). Each
de Leva segment is given by two endpoints; its mass is a fraction of the body mass, its centre
of mass lies on the line between the endpoints at a fraction of the length from the first one,
and its radii of gyration about the sagittal, transverse and longitudinal axes are fractions of
the length. The sagittal column is read as the antero-posterior axis (X of our segment frames),
the transverse column as the medio-lateral axis (Y) and the longitudinal one as the segment's
long axis (Z; X for the foot), as R. Gurchiek's lookup of the same table reads them.

Scaling to a subject: every de Leva segment is laid on the subject's own skeleton — its
endpoints are the joint centres of :meth:`mocaplib.skeleton.Skeleton.joint_offsets` (or the end
points the skeleton's lengths give: top of the head, finger tip, heel and toe tip), so lengths,
centres of mass and radii follow the subject's segment lengths; masses are fractions of the body
mass, so every quantity here is **per kilogram of body mass** (masses in kg/kg, inertias in
m² = kg·m²/kg) and energies computed from them are J/kg.

The trunk is de Leva's three parts (upper: suprasternale to xiphoid; middle: xiphoid to
omphalion; lower: omphalion to the mid-point of the hip joint centres), laid end to end on the
line from the hip-centre midpoint to the neck joint (C7/T1) in proportion to de Leva's mean
lengths (170.7, 215.5, 145.7 mm of 531.9): the lower trunk rides on the pelvis segment, the
middle and upper trunk on the torso. The head is de Leva's vertex-to-C7 head; the hand the
wrist-to-middle-finger-tip hand, on the forearm segment (the skeleton has no wrist joint); the
foot runs from the heel, a quarter of the foot length behind the ankle centre, to the toe tip,
three quarters ahead of it, both ``ankle_height`` below the ankle centre (where the BVH export
draws the foot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..skeleton import SEGMENT_NAMES, Skeleton

#: de Leva (1996), Table 4, males: mass fraction of the body, centre of mass from the first
#: endpoint (fraction of the length), radii of gyration (sagittal, transverse, longitudinal;
#: fractions of the length).
DE_LEVA = {
    "head": (0.0694, 0.5002, (0.303, 0.315, 0.261)),          # vertex -> C7
    "upper_trunk": (0.1596, 0.2999, (0.716, 0.659, 0.454)),   # suprasternale -> xiphoid
    "middle_trunk": (0.1633, 0.4502, (0.482, 0.468, 0.383)),  # xiphoid -> omphalion
    "lower_trunk": (0.1117, 0.6115, (0.615, 0.551, 0.587)),   # omphalion -> mid hip centres
    "upper_arm": (0.0271, 0.5772, (0.285, 0.269, 0.158)),     # shoulder -> elbow centre
    "forearm": (0.0162, 0.4574, (0.276, 0.265, 0.121)),       # elbow -> wrist centre
    "hand": (0.0061, 0.3624, (0.288, 0.235, 0.184)),          # wrist centre -> finger tip
    "thigh": (0.1416, 0.4095, (0.329, 0.329, 0.149)),         # hip -> knee centre
    "shank": (0.0433, 0.4395, (0.251, 0.246, 0.102)),         # knee -> ankle centre
    "foot": (0.0137, 0.4415, (0.257, 0.245, 0.124)),          # heel -> toe tip
}
#: Body mass (kg) an exported model assumes when neither the user nor the calibration file
#: gives one (``mocaplib fit`` warns when it does).
DEFAULT_BODY_MASS = 70.0
#: de Leva's mean lengths (mm) of the trunk's parts, top down: where each part lies on the line
#: from the neck joint down to the hip-centre midpoint.
TRUNK_PARTS = {"upper_trunk": 170.7, "middle_trunk": 215.5, "lower_trunk": 145.7}


@dataclass(frozen=True)
class Bodies:
    """The rigid bodies of a subject, per kilogram of body mass.

    Attributes
    ----------
    names : tuple[str, ...], length B
        de Leva segment of each body, with ``_l``/``_r`` for the limbs.
    segments : int ndarray, shape (B,)
        Skeleton segment (:data:`~mocaplib.skeleton.SEGMENT_NAMES` index) each body rides on.
    mass : ndarray, shape (B,)
        Mass, kg per kg of body mass.
    com : ndarray, shape (B, 3)
        Centre of mass in its segment's frame, metres.
    inertia : ndarray, shape (B, 3)
        Principal moments about the centre of mass along the segment frame's X, Y, Z, m² (kg·m²
        per kg of body mass).
    """

    names: tuple[str, ...]
    segments: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray


def bodies(skeleton: Skeleton) -> Bodies:
    """de Leva's segments laid on ``skeleton`` (see the module docstring)."""
    joints = skeleton.joint_offsets()
    L = skeleton.lengths
    rows = []

    def add(key, side, segment, first, second, long_axis=2):
        """de Leva's segment ``key`` from endpoint ``first`` to ``second`` (frame of
        ``segment``, m); ``long_axis``: the frame axis (0-2) along it."""
        fraction, at, (sagittal, transverse, longitudinal) = DE_LEVA[key]
        first, second = np.asarray(first, float), np.asarray(second, float)
        length = float(np.linalg.norm(second - first))
        radii = [sagittal, transverse, longitudinal] if long_axis == 2 else \
            [longitudinal, sagittal, transverse]
        rows.append((f"{key}_{side}" if side else key, SEGMENT_NAMES.index(segment), fraction,
                     first + at * (second - first), fraction * (np.asarray(radii) * length) ** 2))

    lumbar = joints[SEGMENT_NAMES.index("torso")]     # in the pelvis frame
    neck = joints[SEGMENT_NAMES.index("head")]        # in the torso frame
    trunk = float(np.linalg.norm(lumbar) + np.linalg.norm(neck))
    up_pelvis, up_torso = lumbar / np.linalg.norm(lumbar), neck / np.linalg.norm(neck)
    total, top = sum(TRUNK_PARTS.values()), trunk
    for part, millimetres in TRUNK_PARTS.items():     # top down, heights above the hips
        bottom = top - trunk * millimetres / total
        if part == "lower_trunk":
            add(part, "", "pelvis", top * up_pelvis, bottom * up_pelvis)
        else:
            below = np.linalg.norm(lumbar)
            add(part, "", "torso", (top - below) * up_torso, (bottom - below) * up_torso)
        top = bottom
    add("head", "", "head", (0.0, 0.0, L["head_length"]), (0.0, 0.0, 0.0))
    for side in ("l", "r"):
        add("upper_arm", side, f"humerus_{side}", (0.0, 0.0, 0.0),
            joints[SEGMENT_NAMES.index(f"forearm_{side}")])
        wrist = (0.0, 0.0, -L["forearm"])
        add("forearm", side, f"forearm_{side}", (0.0, 0.0, 0.0), wrist)
        add("hand", side, f"forearm_{side}", wrist, (0.0, 0.0, -L["forearm"] - L["hand"]))
        add("thigh", side, f"femur_{side}", (0.0, 0.0, 0.0),
            joints[SEGMENT_NAMES.index(f"tibia_{side}")])
        add("shank", side, f"tibia_{side}", (0.0, 0.0, 0.0),
            joints[SEGMENT_NAMES.index(f"foot_{side}")])
        add("foot", side, f"foot_{side}", *skeleton.sole(), long_axis=0)
    names, segments, mass, com, inertia = zip(*rows)
    return Bodies(tuple(names), np.array(segments), np.array(mass), np.array(com),
                  np.array(inertia))


@dataclass(frozen=True)
class SegmentInertias:
    """Mass properties of each skeleton segment, per kilogram of body mass: the :class:`Bodies`
    riding on it taken as one rigid body.

    Attributes
    ----------
    mass : ndarray, shape (S,)
        kg per kg of body mass, :data:`~mocaplib.skeleton.SEGMENT_NAMES` order (sums to 1).
    com : ndarray, shape (S, 3)
        Centre of mass in the segment's frame, metres.
    inertia : ndarray, shape (S, 3, 3)
        Inertia tensor about the centre of mass in the segment's frame, m² (kg·m² per kg).
    """

    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray


def segment_inertias(skeleton: Skeleton) -> SegmentInertias:
    """de Leva's bodies (:func:`bodies`) merged per skeleton segment: masses added, centres of
    mass averaged by mass, inertias moved to the merged centre by the parallel-axis theorem."""
    parts = bodies(skeleton)
    n = len(SEGMENT_NAMES)
    mass = np.bincount(parts.segments, weights=parts.mass, minlength=n)
    com = np.stack([np.bincount(parts.segments, weights=parts.mass * parts.com[:, k],
                                minlength=n) for k in range(3)], axis=1) / mass[:, None]
    away = parts.com - com[parts.segments]
    shifted = (np.eye(3) * np.sum(away ** 2, axis=1)[:, None, None]
               - away[:, :, None] * away[:, None, :])
    own = parts.inertia[:, :, None] * np.eye(3) + parts.mass[:, None, None] * shifted
    inertia = np.zeros((n, 3, 3))
    np.add.at(inertia, parts.segments, own)
    return SegmentInertias(mass, com, inertia)
