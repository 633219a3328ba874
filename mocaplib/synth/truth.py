"""The truth in the fit's conventions: the generator's body read by the fit's anatomical
definitions, a documented conversion.

The generator's body (:mod:`.bones`) has its own joints; the fit reports the angles of
:mod:`mocaplib.skeleton`'s 32 DOFs in the frames :mod:`mocaplib.model.anatomy` builds. The truth is
what those definitions give on the generator's body, exactly, without any marker error:

1. **Anatomical frames, once.** In the neutral pose (:func:`neutral_pose`) the fit's
   definitions are applied to the *true* landmarks (each marker exactly where it belongs, no
   placement error, no soft tissue): the pelvis frame from the ASIS and PSIS
   (:func:`mocaplib.model.anatomy.pelvis_axes`), the hip centres by Harrington's regression
   (:func:`mocaplib.model.anatomy.harrington_hips`; the generator's own hips are Bell's), knee and
   ankle centres midway between the lateral and medial landmarks, the femur, tibia and foot
   frames of :func:`mocaplib.model.anatomy.segment_frames` (the static's level feet). The torso,
   head, upper arms and forearms take the pelvis frame's orientation there, as a neutral static
   defines them (every joint angle 0). Each frame is then fixed in its generator bone: pelvis →
   pelvis, torso → thorax, head → head, humerus → humerus, forearm → forearm, femur → femur,
   tibia → tibia, foot → foot (the rear foot).
2. **Every frame.** Each bone carries its anatomical frame; each joint's rotation (child
   frame relative to its parent's) is decomposed into the fitting skeleton's DOFs in their
   order (:mod:`mocaplib.skeleton`: intrinsic, the DOF axes with their signs), the pelvis
   translations are the pelvis frame's origin (midway between the Harrington hip centres).

What a DOF of the fit cannot hold is left out of ``q`` and reported apart
(:func:`extra_angles`): the knee's rotation and ab/adduction (the fit's knee is a hinge), the
ankle's rotation about the shank, the toes, the shoulder girdle, the wrists, the split of the
trunk between the lumbar and thoracic joints. The neutral pose is the one in which these
definitions read zero: the pelvis frame level, each femur frame parallel to it, hip, knee and
ankle centres aligned in the knee's plane, the soles flat (:func:`neutral_pose`); it is the
generator's standing pose (``rest``), so a static in the neutral pose calibrates the fit to the
same zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from ..model.anatomy import flat_soles, harrington_hips, segment_frames
from ..skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS
from .bones import SIDES, Body, BodyPose, turn_vector

#: The generator's bone carrying each fitting segment's frame, by unsided name.
BONE_OF_SEGMENT = {"pelvis": "pelvis", "torso": "thorax", "head": "head", "humerus": "humerus",
                   "forearm": "forearm", "femur": "femur", "tibia": "tibia", "foot": "foot"}
#: Landmarks the anatomical definitions read (sided ones without their L_/R_).
_PELVIS = ("L_ASIS", "R_ASIS", "L_PSIS", "R_PSIS")
_LEG = ("KNEE_LAT", "KNEE_MED", "ANKLE_LAT", "ANKLE_MED", "HEEL", "TOE")
_SOLVE_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Convention:
    """The fit's anatomical frames fixed in the generator's bones (module docstring, step 1):
    per fitting segment (:data:`mocaplib.skeleton.SEGMENT_NAMES` order) the bone index (S,)
    and the turn from the bone's frame to the segment's (S, 3, 3); the pelvis frame's origin
    in the pelvis bone's frame (3,) m."""

    bones: np.ndarray
    turns: np.ndarray
    pelvis_origin: np.ndarray


def _bone_name(segment: str) -> str:
    bare, _, side = segment.partition("_")
    return BONE_OF_SEGMENT[bare] + (f"_{side}" if side else "")


def anatomical_frames(body: Body, pose: BodyPose, *, flat_feet: bool = False
                      ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The pelvis, femur, tibia and foot frames (rotation (F, 3, 3), origin (F, 3)) the fit's
    definitions give on the true landmarks of ``pose`` (module docstring, step 1); with
    ``flat_feet`` the feet along their soles, flat in ``pose`` as on a static."""
    names = list(_PELVIS) + [f"{s.upper()}_{n}" for s in SIDES for n in _LEG]
    points = body.landmark_points(pose, names)
    where = {name: points[:, i] for i, name in enumerate(names)}
    back = 0.5 * (where["L_PSIS"] + where["R_PSIS"])
    hips = harrington_hips(where["L_ASIS"], where["R_ASIS"], back)
    centres = {}
    for side, hip in zip(SIDES, hips):
        S = side.upper()
        centres[(f"femur_{side}", 0.0)] = hip
        centres[(f"tibia_{side}", 0.0)] = 0.5 * (where[f"{S}_KNEE_LAT"] + where[f"{S}_KNEE_MED"])
        centres[(f"foot_{side}", 0.0)] = 0.5 * (where[f"{S}_ANKLE_LAT"] + where[f"{S}_ANKLE_MED"])
    return segment_frames(where, centres, flat_feet=flat_soles(where)[0] if flat_feet else None)


def _neutral_residuals(body: Body, pose: BodyPose) -> np.ndarray:
    """Per frame (F, 12): for each leg, the femur frame's turn from the pelvis frame (3), the
    knee's flexion (the tibia frame's turn about Y from the femur's, 1) and the sole's tilt
    (the foot bone's Z axis off vertical, 2), all zero in the neutral pose."""
    frames = anatomical_frames(body, pose)
    R, _ = body.forward(pose)
    pelvis = frames["pelvis"][0]
    out = []
    for side in SIDES:
        femur, tibia = frames[f"femur_{side}"][0], frames[f"tibia_{side}"][0]
        out.append(turn_vector(np.swapaxes(pelvis, -1, -2) @ femur))
        out.append(turn_vector(np.swapaxes(femur, -1, -2) @ tibia)[:, 1:2])
        out.append(R[:, body.index(f"foot_{side}"), :2, 2])
    return np.concatenate(out, axis=1)


@lru_cache(maxsize=8)
def _neutral(body: Body) -> BodyPose:
    pose = BodyPose.zero(body, 1)
    # the pelvis bone turned so that its anatomical frame is the world's
    pelvis = anatomical_frames(body, pose)["pelvis"][0][0]
    pose.root_R[:] = pelvis.T
    leg = [(f"{bone}_{side}", k) for side in SIDES for bone, count in
           (("femur", 3), ("tibia", 1), ("talus", 1), ("foot", 1)) for k in range(count)]
    step = 1e-7
    for _ in range(30):
        trial = pose.take(np.zeros(len(leg) + 1, dtype=int))
        for row, (name, k) in enumerate(leg, start=1):
            trial.angles[name] = trial.angles[name].copy()
            trial.angles[name][row, k] += step
        residual = _neutral_residuals(body, trial)
        jacobian = (residual[1:] - residual[0]).T / step
        move = np.linalg.solve(jacobian, -residual[0])
        for (name, k), value in zip(leg, move):
            pose.angles[name][0, k] += value
        if np.abs(move).max() < _SOLVE_TOLERANCE:
            break
    R, t = body.forward(pose)
    soles = [t[0, body.index(f"foot_{s}")] + R[0, body.index(f"foot_{s}")] @ body.feet[s].heel
             for s in SIDES]
    pose.root_t[0, 2] -= min(p[2] for p in soles)
    pose.root_t[0, :2] -= anatomical_frames(body, pose)["pelvis"][1][0, :2]
    return pose


def neutral_pose(body: Body, n: int = 1) -> BodyPose:
    """The generator's standing pose in which the fit's definitions read every joint angle 0
    (module docstring), ``n`` frames, the pelvis frame facing +X over the origin, the soles
    flat on the floor (z = 0); the arms hang (the upper body's joints at 0)."""
    return _neutral(body).take(np.zeros(n, dtype=int))


@lru_cache(maxsize=8)
def convention(body: Body) -> Convention:
    """The fit's anatomical frames fixed in ``body``'s bones (module docstring, step 1)."""
    pose = _neutral(body)
    frames = anatomical_frames(body, pose, flat_feet=True)
    R, t = body.forward(pose)
    pelvis = frames["pelvis"][0][0]
    bones, turns = [], []
    for segment in SEGMENT_NAMES:
        b = body.index(_bone_name(segment))
        anatomical = frames[segment][0][0] if segment in frames else pelvis
        bones.append(b)
        turns.append(R[0, b].T @ anatomical)
    p = body.index("pelvis")
    origin = R[0, p].T @ (frames["pelvis"][1][0] - t[0, p])
    return Convention(np.array(bones), np.array(turns), origin)


def segment_rotations(body: Body, pose: BodyPose) -> tuple[np.ndarray, np.ndarray]:
    """The fitting segments' anatomical frames over ``pose``: rotations (F, S, 3, 3) in
    :data:`mocaplib.skeleton.SEGMENT_NAMES` order and the pelvis frame's origin (F, 3)."""
    conv = convention(body)
    R, t = body.forward(pose)
    p = body.index("pelvis")
    return (R[:, conv.bones] @ conv.turns,
            t[:, p] + np.einsum("fij,j->fi", R[:, p], conv.pelvis_origin))


def _decomposition(dofs: tuple[str, ...]) -> tuple[str, np.ndarray, list[int]]:
    """The intrinsic Euler letters of a joint's rotation DOFs (completed to three), their
    axes' signs (3,), and the DOFs' indices."""
    index = [DOF_NAMES.index(n) for n in dofs if not DOFS[DOF_NAMES.index(n)].translation]
    axes = [np.asarray(DOFS[j].axis) for j in index]
    letters = [int(np.argmax(np.abs(a))) for a in axes]
    letters += [k for k in range(3) if k not in letters][:3 - len(letters)]
    signs = np.ones(3)
    signs[:len(axes)] = [a[k] for a, k in zip(axes, letters)]
    return "".join("XYZ"[k] for k in letters), signs, index


_JOINTS = [(s, SEGMENT_NAMES.index(seg.parent) if seg.parent else -1,
            *_decomposition(seg.dofs)) for s, seg in enumerate(SEGMENTS)]


def joint_turns(rotations: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """Each fitting segment's rotation relative to its parent's frame, (segment index,
    (F, 3, 3)), from the segments' world rotations (F, S, 3, 3); the root's is its own."""
    return [(s, rotations[:, s] if parent < 0 else
             np.swapaxes(rotations[:, parent], -1, -2) @ rotations[:, s])
            for s, parent, *_ in _JOINTS]


def true_angles(body: Body, pose: BodyPose) -> np.ndarray:
    """The fitting skeleton's DOFs (F, 32) (rad; ``pelvis_t*`` m) that the fit's
    definitions read on ``pose`` (module docstring)."""
    rotations, origin = segment_rotations(body, pose)
    q = np.zeros((len(origin), len(DOF_NAMES)))
    q[:, [DOF_NAMES.index(n) for n in ("pelvis_tx", "pelvis_ty", "pelvis_tz")]] = origin
    for (s, turn), (_, _, letters, signs, index) in zip(joint_turns(rotations), _JOINTS):
        if index:
            euler = Rotation.from_matrix(turn).as_euler(letters) / signs
            q[:, index] = euler[:, :len(index)]
    heading = DOF_NAMES.index("pelvis_rotation")
    q[:, heading] = np.unwrap(q[:, heading])
    return q


#: The extra angles of :func:`extra_angles`: name -> (fitting segment, Euler position), the
#: joint's rotation components beyond its DOFs.
EXTRA_ANGLES = {f"knee_{name}_{s}": (f"tibia_{s}", k)
                for s in SIDES for k, name in ((1, "adduction"), (2, "rotation"))}
EXTRA_ANGLES.update({f"ankle_rotation_{s}": (f"foot_{s}", 2) for s in SIDES})


def extra_angles(body: Body, pose: BodyPose) -> dict[str, np.ndarray]:
    """The generator's motion the fitting skeleton's DOFs cannot hold (F,) rad each, by name:
    the knee's ab/adduction and rotation and the ankle's rotation (the further Euler angles
    of the joint's decomposition, signed as the hip's adduction and rotation), the toes'
    dorsiflexion (``mtp_l``, ``mtp_r``), the girdle's protraction and elevation, the wrists'
    flexion."""
    rotations, _ = segment_rotations(body, pose)
    turns = dict(joint_turns(rotations))
    out = {}
    for name, (segment, k) in EXTRA_ANGLES.items():
        s = SEGMENT_NAMES.index(segment)
        _, _, letters, signs, _ = _JOINTS[s]
        side = 1.0 if segment.endswith("_r") else -1.0
        out[name] = side * Rotation.from_matrix(turns[s]).as_euler(letters)[:, k]
    for side in SIDES:
        out[f"mtp_{side}"] = pose.angles[f"toes_{side}"][:, 0]
        out[f"girdle_protraction_{side}"] = pose.angles[f"girdle_{side}"][:, 0]
        out[f"girdle_elevation_{side}"] = pose.angles[f"girdle_{side}"][:, 1]
        out[f"wrist_flexion_{side}"] = pose.angles[f"hand_{side}"][:, 0]
    return out
