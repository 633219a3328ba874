"""Functional joint centres and axes from the relative motion of two rigid marker clusters.

Where no landmark places a joint (a cluster set without a static), the motion does: a joint
centre is the point that moves with both segments, a hinge's axis the line that does.

* **SCoRE** (symmetrical centre of rotation estimation; Ehrig et al. 2006, J Biomech
  39:2798): with each segment's rigid frame ``(R_p, t_p)``, ``(R_c, t_c)`` per frame, the
  centre has fixed coordinates ``c_p`` in the parent and ``c_c`` in the child, so
  ``R_p c_p + t_p = R_c c_c + t_c`` in every frame: a linear least-squares system ``A x = b``
  (3F × 6) in ``x = (c_p, c_c)``; the centre is the mean of the two sides.
* **SARA** (symmetrical axis of rotation approach; Ehrig et al. 2007, J Biomech 40:2150): for
  a hinge every point of the axis solves that system, so ``A`` has a near null vector
  ``(n_p, n_c)``: its right singular vector of least singular value. The axis's direction in
  the world is ``R_p n_p`` (= ``R_c n_c``), the centre is then free along it and is taken where
  the axis passes nearest a hint (the proximal joint's centre).

Both need the joint to turn: the range of the relative rotation over the frames (degrees,
:func:`relative_range`) below :data:`FUNCTIONAL_RANGE` leaves them to the anatomical
estimate. Every array is world coordinates, metres, one row per frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..markersets.protocols import Landmark
from ..numeric import nanmedian
from ..skeleton import SEGMENT_NAMES
from .anatomy import HEEL_LANDMARKS, unit
from .solver import rigid_fits

#: Smallest range of the joint's turn (degrees) over the frames for a functional centre or
#: axis: below it they are ill-determined along the axis of turn.
FUNCTIONAL_RANGE = 15.0
#: A least singular value under this share of the largest marks a hinge: the centre slides
#: along its axis.
HINGE_RATIO = 0.1
#: Fewest frames in which both clusters are seen for a functional estimate.
MIN_FRAMES = 10


@dataclass(frozen=True)
class FunctionalJoint:
    """A joint found from the motion of its two segments.

    centre : ndarray (F, 3). The SCoRE centre in the world, metres (on a hinge, the point of
        its axis nearest the hint).
    axis : ndarray (F, 3) or None. The SARA axis in the world (unit vectors, sign arbitrary)
        when the joint is a hinge (:data:`HINGE_RATIO`), else None.
    range_deg : float. Range of the relative rotation over the frames, degrees.
    """

    centre: np.ndarray
    axis: np.ndarray | None
    range_deg: float


def marker_frames(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid frames (F, 3, 3) and origins (F, 3) of three markers ``points`` (F, 3, 3): origin
    the first, X towards the second, Z normal to the three; NaN where one is missing."""
    x = unit(points[:, 1] - points[:, 0])
    z = unit(np.cross(x, points[:, 2] - points[:, 0]))
    return np.stack([x, np.cross(z, x), z], axis=-1), points[:, 0]


def relative_range(parent_rotations: np.ndarray, child_rotations: np.ndarray) -> float:
    """Range (degrees) of the child's rotation relative to the parent over the frames where
    both rotations (F, 3, 3) are known: the largest angle between two frames' relative
    rotations (from the frame farthest from the first; exact for a hinge). 0 without frames."""
    known = np.isfinite(parent_rotations).all(axis=(1, 2)) \
        & np.isfinite(child_rotations).all(axis=(1, 2))
    if not known.any():
        return 0.0
    relative = np.einsum("fji,fjk->fik", parent_rotations[known], child_rotations[known])
    far = relative[np.argmax(_angles_from(relative, relative[0]))]
    return float(np.degrees(_angles_from(relative, far).max()))


def functional_joint(parent: tuple[np.ndarray, np.ndarray],
                     child: tuple[np.ndarray, np.ndarray], *,
                     hint: np.ndarray | None = None) -> FunctionalJoint | None:
    """The joint between two rigid frames by SCoRE and, for a hinge, its axis by SARA.

    Parameters
    ----------
    parent, child : (rotations (F, 3, 3), origins (F, 3))
        Each segment's rigid frame per frame (:func:`marker_frames`), NaN where unseen.
    hint : ndarray (F, 3), optional
        A point the hinge's centre is taken nearest to (the proximal joint's centre); without
        it a hinge's centre is the least-norm solution.

    Returns
    -------
    FunctionalJoint or None
        None when fewer than :data:`MIN_FRAMES` frames know both segments. The caller judges
        ``range_deg`` against :data:`FUNCTIONAL_RANGE`.
    """
    (Rp, tp), (Rc, tc) = parent, child
    known = np.isfinite(Rp).all(axis=(1, 2)) & np.isfinite(Rc).all(axis=(1, 2)) \
        & np.isfinite(tp).all(axis=1) & np.isfinite(tc).all(axis=1)
    if known.sum() < MIN_FRAMES:
        return None
    A = np.concatenate([Rp[known], -Rc[known]], axis=2).reshape(-1, 6)
    b = (tc[known] - tp[known]).reshape(-1)
    solution = np.linalg.lstsq(A, b, rcond=None)[0]
    _, values, vt = np.linalg.svd(A, full_matrices=False)

    def world(c):
        return 0.5 * (np.einsum("fij,j->fi", Rp, c[:3]) + tp
                      + np.einsum("fij,j->fi", Rc, c[3:]) + tc)

    axis = None
    if values[-1] < HINGE_RATIO * values[0]:
        null = vt[-1]
        axis = unit(np.einsum("fij,j->fi", Rp, null[:3]) + np.einsum("fij,j->fi", Rc, null[3:]))
        if hint is not None:
            along = world(null) - world(np.zeros(6))              # the axis's direction (F, 3)
            off = hint - world(solution)
            usable = np.isfinite(along).all(axis=1) & np.isfinite(off).all(axis=1)
            solution = solution + null * (np.sum(along[usable] * off[usable])
                                          / np.sum(along[usable] ** 2))
    return FunctionalJoint(world(solution), axis, relative_range(Rp, Rc))


def _angles_from(rotations: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Angle (radians) of each rotation (F, 3, 3) from ``reference`` (3, 3)."""
    cosine = (np.trace(rotations @ reference.T, axis1=1, axis2=2) - 1.0) / 2.0
    return np.arccos(np.clip(cosine, -1.0, 1.0))



#: The hinges placed from the motion, as (child, parent) segments, and each one's joint name.
_LIMB_HINGES = (("tibia", "femur", "knee"), ("foot", "tibia", "ankle"),
                ("forearm", "humerus", "elbow"))
#: Hinges (by child segment) whose functional flexion axis builds the limb's frames when no
#: lateral landmark gives it: the knee and the elbow.
_FUNCTIONAL_AXES = ("tibia", "forearm")


def functional_limb_joints(X: np.ndarray, segments: np.ndarray, where: dict[str, np.ndarray],
                           centres: dict[tuple[str, float], np.ndarray], side: str, *,
                           left: np.ndarray | None, catalogue: dict[str, Landmark],
                           scale: float, heel_centre
                           ) -> tuple[dict, dict[str, str], dict[str, np.ndarray]]:
    """The knee, ankle and elbow centres of ``side`` ("L", "R") no landmark placed, from the
    motion: (centres by ``(segment, 0.0)``, methods by joint, flexion axes by upper segment).

    ``X`` (F, M, 3) markers on ``segments`` (M,) indices, ``where`` landmark positions,
    ``centres`` those already placed (the proximal centres are the hinges' hints). The ankle:
    the foot's origin where the rigid fit of its seen landmarks onto their ``catalogue``
    positions (scaled by ``scale``) puts it (:func:`catalogue_origin`), with three or more;
    else ``heel_centre(heel_landmark, "foot_l")`` (F, 3), the heel moved by its catalogue
    offset turned by the foot's nominal fit. On the synthetic cluster captures (walk, run,
    curve) SCoRE's ankle lies 27-66 mm from the malleoli's midpoint (the foot turns about
    several joints), the nominal fit's heel offset 5-39 mm (39 on the run), the rigid fit
    5-11 mm. The knee and elbow: SCoRE over the frames (:func:`functional_joint`)
    when they turn by :data:`FUNCTIONAL_RANGE` or more, and their SARA axes oriented
    laterally with ``left`` (F, 3), the right hip centre to the left one.
    """
    suffix = "_" + side.lower()
    out, methods, axes = {}, {}, {}
    for child, parent, joint in _LIMB_HINGES:
        if (child + suffix, 0.0) in centres:
            continue
        name = joint + suffix
        heel = next((f"{side}_{n}" for n in HEEL_LANDMARKS if f"{side}_{n}" in where), None)
        if child == "foot" and heel is not None:
            registered = catalogue_origin(where, child + suffix, catalogue, scale)
            if registered is not None:
                out[(child + suffix, 0.0)], on = registered
                methods[name] = (f"the foot's markers ({', '.join(on)}) fitted rigidly to "
                                 "their catalogue layout: no malleolus marks it")
            else:
                out[(child + suffix, 0.0)] = heel_centre(heel, child + suffix)
                methods[name] = ("the heel marker and its catalogue offset, turned by the "
                                 "foot's nominal fit: no malleolus marks it")
            continue
        frames = [_three_markers(X, segments, segment + suffix) for segment in (parent, child)]
        found = None if None in frames else functional_joint(
            *frames, hint={**centres, **out}.get((parent + suffix, 0.0)))
        if found is None:
            continue
        if found.range_deg < FUNCTIONAL_RANGE:
            methods[name] = (f"not found: the {parent} and {child} turn {found.range_deg:.0f}° "
                             f"relative to each other, a functional centre needs "
                             f"{FUNCTIONAL_RANGE:.0f}°, so the limb's zero pose is its "
                             "markers' nominal layout")
            continue
        out[(child + suffix, 0.0)] = found.centre
        methods[name] = (f"functional (SCoRE) from the {parent}'s and {child}'s markers over "
                         f"{found.range_deg:.0f}° of motion")
        if found.axis is not None and child in _FUNCTIONAL_AXES and left is not None:
            lateral = 1.0 if side == "L" else -1.0
            axes[parent + suffix] = found.axis * lateral * np.sign(
                nanmedian((found.axis * left).sum(axis=-1)))
            methods[name] += ", its flexion axis functional (SARA)"
    return out, methods, axes


def catalogue_origin(where: dict[str, np.ndarray], segment: str, catalogue: dict[str, Landmark],
                     scale: float) -> tuple[np.ndarray, list[str]] | None:
    """Where ``segment``'s origin (its proximal joint) lies per frame (F, 3), metres: the
    rigid fit (:func:`mocaplib.model.solver.rigid_fits`) of the segment's landmarks in
    ``where`` (name -> (F, 3)) onto their ``catalogue`` positions times ``scale``, and the
    landmarks used; None with fewer than three (NaN in frames that see fewer)."""
    on = [name for name in where if name in catalogue and catalogue[name].segment == segment]
    if len(on) < 3:
        return None
    local = np.array([catalogue[name].position for name in on]) * scale
    _, origin, ok = rigid_fits(local, np.stack([where[name] for name in on], axis=1))
    return np.where(ok[:, None], origin, np.nan), on


def _three_markers(X: np.ndarray, segments: np.ndarray, segment: str):
    """The rigid frames (:func:`marker_frames`) of the three markers of ``segment`` seen in
    the most frames of X (F, M, 3), or None when it carries fewer."""
    on = np.flatnonzero(segments == SEGMENT_NAMES.index(segment))
    if len(on) < 3:
        return None
    seen = np.isfinite(X[:, on, 0]).sum(axis=0)
    return marker_frames(X[:, on[np.argsort(-seen, kind="stable")[:3]]])
