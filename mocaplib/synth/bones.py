"""The synthetic walker's own body: bones, joints and landmarks, independent of the fitting skeleton.

The body is read from ``protocols/synthetic_body.toml`` (sources of every number there): its
own proportions, joint centres and axes, and where each landmark's marker sits on its bones.
Calibration and the fit never read it; they see only the markers it carries.

Bones (``pelvis``, ``lumbar``, ``thorax``, ``head``, and per side ``girdle``, ``humerus``,
``forearm``, ``hand``, ``femur``, ``tibia``, ``talus``, ``foot``, ``toes``) form a tree, each
bone's frame at the generator's zero pose parallel to the world's (X forward, Y left, Z up),
its origin at its proximal joint. The joints, each the child bone's, with the angles a pose
gives them (radians, positive as named; left and right mirror each other):

============  ======  ==========================================================================
joint         angles  motion
============  ======  ==========================================================================
lumbar        3       L5/S1: flexion, bending to the left, rotation to the left (intrinsic)
thorax        3       T12/L1: the same (a flexible spine: the trunk bends at both)
head          3       C7/T1: the same for head and neck
girdle        2       sternoclavicular: protraction (the shoulder forward), elevation
humerus       3       glenohumeral: flexion, abduction, internal rotation
forearm       1       elbow flexion about an oblique axis (carrying angle)
hand          1       wrist flexion
femur         3       hip (a ball at Bell's centre): flexion, adduction, internal rotation
tibia         1       knee flexion, with the tibia's rollback, screw-home rotation and varus
talus         1       talocrural dorsiflexion about Inman's oblique axis
foot          2       subtalar inversion about Inman's oblique axis, then inversion about the
                      longitudinal midtarsal axis (the rear foot: calcaneus, midfoot and
                      metatarsals, moving as one)
toes          1       metatarsophalangeal dorsiflexion (toes up) about the MT1-MT2 axis
============  ======  ==========================================================================

Arrays: time on axis 0; rotations (F, 3, 3), positions (F, 3), metres and radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import SynthError
from ..io.tomlfile import read_toml
from ..markersets.protocols import protocols_dir
from ..skeleton import axis_rotation

SIDES = ("l", "r")
#: The joint angles each bone's proximal joint takes (the root, the pelvis, has none: its
#: pose is given whole).
ANGLE_COUNTS = {"lumbar": 3, "thorax": 3, "head": 3, "girdle": 2, "humerus": 3, "forearm": 1,
                "hand": 1, "femur": 3, "tibia": 1, "talus": 1, "foot": 2, "toes": 1}
_X, _Y, _Z = np.eye(3)
#: Left-side axes of the ball and two-angle joints, in order (intrinsic), positive as named.
_SPINE = (_Y, -_X, _Z)
_BALL_AXES = {"lumbar": _SPINE, "thorax": _SPINE, "head": _SPINE,
              "girdle": (-_Z, _X), "humerus": (-_Y, _X, -_Z), "femur": (-_Y, -_X, -_Z)}
_MIRROR = np.diag([1.0, -1.0, 1.0])


def _deg(value) -> np.ndarray:
    return np.deg2rad(np.asarray(value, dtype=float))


def mirrored_axis(axis: np.ndarray, side: str) -> np.ndarray:
    """A left-side rotation axis (3,) (positive turn = the anatomical motion) for ``side``:
    the right side turns about (−x, y, −z) so that the same angle is the same motion."""
    return np.asarray(axis, float) * (np.array([-1.0, 1.0, -1.0]) if side == "r" else 1.0)


@dataclass(frozen=True)
class Bone:
    """One bone: its name (``femur_l``), parent's index (-1 for the root), its origin in the
    parent's frame (3,) m, its fixed turn from the parent at the zero pose (3, 3), and its
    joint's kind (its unsided name) and side (``""`` unsided)."""

    name: str
    parent: int
    origin: np.ndarray
    zero: np.ndarray
    kind: str
    side: str


@dataclass(frozen=True)
class FootShape:
    """The rear foot's sole (foot frame, m): ankle centre height above the flat sole, heel and
    toe-tip contact points (3,), the metatarsophalangeal axis (a point (3,) and unit direction
    (3,), positive turn = toes up), the sole points the swing foot clears the floor with
    (K, 3), and the toes' origin (3,) (on the axis)."""

    ankle_height: float
    heel: np.ndarray
    toe_tip: np.ndarray
    mtp_point: np.ndarray
    mtp_axis: np.ndarray
    sole: np.ndarray


@dataclass(frozen=True, eq=False)
class Body:
    """The generator's body for a subject ``height`` m tall (:func:`synthetic_body`)."""

    height: float
    bones: tuple[Bone, ...]
    landmarks: dict[str, tuple[int, np.ndarray]]
    joints: dict = field(repr=False)
    feet: dict[str, FootShape] = field(repr=False)

    def index(self, name: str) -> int:
        """Index of the bone ``name`` (``femur_l``)."""
        return next(i for i, bone in enumerate(self.bones) if bone.name == name)

    def forward(self, pose: "BodyPose") -> tuple[np.ndarray, np.ndarray]:
        """Every bone's rotation (F, B, 3, 3) and origin (F, B, 3) in the world for ``pose``."""
        n = len(pose.root_R)
        R = np.empty((n, len(self.bones), 3, 3))
        t = np.empty((n, len(self.bones), 3))
        for b, bone in enumerate(self.bones):
            if bone.parent < 0:
                R[:, b], t[:, b] = pose.root_R, pose.root_t
            else:
                R[:, b], t[:, b] = self.child_pose(bone, R[:, bone.parent], t[:, bone.parent],
                                                   pose.angles[bone.name])
        return R, t

    def child_pose(self, bone: Bone, parent_R: np.ndarray, parent_t: np.ndarray,
                   angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``bone``'s rotation (F, 3, 3) and origin (F, 3) in the world, its parent's being
        ``parent_R`` and ``parent_t`` and its joint's angles ``angles`` (F, k)."""
        turn, shift = self.joint_motion(bone, angles)
        return (parent_R @ turn @ bone.zero,
                parent_t + np.einsum("fij,fj->fi", parent_R, bone.origin + shift))

    def joint_motion(self, bone: Bone, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A joint's turn (F, 3, 3) and the shift (F, 3) of the child's origin, both in the
        parent's frame, for its angles (F, k) rad."""
        angles = np.atleast_2d(np.asarray(angles, dtype=float).T).T
        n = len(angles)
        J = self.joints
        kind, side = bone.kind, bone.side
        if kind in _BALL_AXES:
            turn = np.broadcast_to(np.eye(3), (n, 3, 3))
            for k, axis in enumerate(_BALL_AXES[kind]):
                turn = turn @ axis_rotation(mirrored_axis(axis, side), angles[:, k])
            return turn, np.zeros((n, 3))
        if kind == "tibia":                      # the knee
            q = angles[:, 0]
            turn = (axis_rotation(_Y, q)
                    @ axis_rotation(mirrored_axis(-_Z, side), J["screw_home"][0] *
                                    np.tanh(q / J["screw_home"][1]))
                    @ axis_rotation(mirrored_axis(-_X, side), J["varus"] * q))
            return turn, J["rollback"] * q[:, None] * turn[:, :, 0]
        turn, shift = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
        for k, (axis, through) in enumerate(J["hinges"][kind][side]):
            # each hinge about its axis through its point, both in the frame the previous
            # hinges have turned to
            step = axis_rotation(axis, angles[:, k])
            shift = shift + np.einsum("fij,fj->fi", turn, through - step @ through)
            turn = turn @ step
        return turn, shift

    def landmark_points(self, pose: "BodyPose", names: list[str]) -> np.ndarray:
        """Exact marker positions (F, M, 3) of the landmarks ``names`` for ``pose``."""
        R, t = self.forward(pose)
        bones = np.array([self.landmarks[n][0] for n in names], dtype=int)
        local = np.array([self.landmarks[n][1] for n in names]).reshape(-1, 3)
        return np.einsum("fmij,mj->fmi", R[:, bones], local) + t[:, bones]


@dataclass
class BodyPose:
    """A pose of the :class:`Body` over F frames: the pelvis's rotation (F, 3, 3) and origin
    (F, 3) (between the hip centres), and each bone's joint angles (F, k) by bone name."""

    root_R: np.ndarray
    root_t: np.ndarray
    angles: dict[str, np.ndarray]

    @classmethod
    def zero(cls, body: Body, n: int) -> "BodyPose":
        """The zero pose (every bone parallel to the world), the pelvis at the origin."""
        return cls(np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), np.zeros((n, 3)),
                   {bone.name: np.zeros((n, ANGLE_COUNTS[bone.kind])) for bone in body.bones
                    if bone.parent >= 0})

    def take(self, rows) -> "BodyPose":
        """The frames ``rows`` (an index or slice) of this pose."""
        return BodyPose(self.root_R[rows], self.root_t[rows],
                        {k: v[rows] for k, v in self.angles.items()})


def turn_vector(R: np.ndarray) -> np.ndarray:
    """The rotation vector (..., 3) of rotations ``R`` (..., 3, 3) near the identity, to first
    order (the skew part)."""
    return 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                           R[..., 1, 0] - R[..., 0, 1]], axis=-1)


def vector_turn(vectors: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3) (axis × angle, rad;
    Rodrigues)."""
    angle = np.linalg.norm(vectors, axis=-1)[..., None, None]
    k = np.zeros(vectors.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -vectors[..., 2], vectors[..., 1], -vectors[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    with np.errstate(invalid="ignore", divide="ignore"):
        sin = np.where(angle > 0, np.sin(angle) / angle, 1.0)
        cos = np.where(angle > 0, (1 - np.cos(angle)) / angle ** 2, 0.5)
    return np.eye(3) + sin * k + cos * (k @ k)


def ball_angles(turn: np.ndarray, kind: str, side: str) -> np.ndarray:
    """The angles (F, 3) of a three-angle joint of kind ``kind`` (``humerus``, ``femur``, a
    spine joint) on ``side`` that give its turn (F, 3, 3) (Euler decomposition in the joint's
    order, signs of its axes)."""
    axes = [mirrored_axis(axis, side) for axis in _BALL_AXES[kind]]
    letters = [int(np.argmax(np.abs(axis))) for axis in axes]
    signs = np.array([axis[k] for axis, k in zip(axes, letters)])
    return Rotation.from_matrix(turn).as_euler("".join("XYZ"[k] for k in letters)) / signs


def _inversion_axis(elevation_medial) -> np.ndarray:
    """The left foot's axis (3,) of positive inversion for an axis pointing forwards,
    ``elevation_medial`` = (degrees above the sole, degrees medial of the long axis)."""
    elevation, medial = _deg(elevation_medial)
    return -np.array([np.cos(elevation) * np.cos(medial), -np.cos(elevation) * np.sin(medial),
                      np.sin(elevation)])


def _mirror_point(point, side: str) -> np.ndarray:
    return np.asarray(point, float) * (np.array([1.0, -1.0, 1.0]) if side == "r" else 1.0)


@lru_cache(maxsize=None)
def _definition() -> dict:
    path = protocols_dir() / "synthetic_body.toml"
    return read_toml(path, error=SynthError, what="synthetic body",
                     hint="it ships with mocaplib: reinstall it")


@lru_cache(maxsize=8)
def synthetic_body(height: float = 1.75) -> Body:
    """The generator's body scaled to a subject ``height`` m tall (every length by
    height / 1.75; angles unchanged)."""
    spec = _definition()
    scale = height / float(spec["reference_height"])
    joints_spec = spec["joints"]
    bones: list[Bone] = []
    for name, entry in spec["bones"].items():
        for side in (SIDES if entry.get("sided") else ("",)):
            parent = entry["parent"]
            names = [b.name for b in bones]
            parent_index = (names.index(f"{parent}_{side}" if f"{parent}_{side}" in names
                                        else parent) if parent else -1)
            zero = np.eye(3)
            if name == "talus":
                zero = axis_rotation(_Z, _deg([joints_spec["foot_toe_out"]]))[0]
                zero = _MIRROR @ zero @ _MIRROR if side == "r" else zero
            bones.append(Bone(name + (f"_{side}" if side else ""), parent_index,
                              _mirror_point(entry["origin"], side) * scale, zero, name, side))

    tilt, turn = _deg(joints_spec["elbow_axis_tilt"])
    elbow = -(axis_rotation(_Z, [turn])[0] @ axis_rotation(_X, [tilt])[0] @ _Y)
    outward, down = _deg(joints_spec["talocrural"])
    talocrural = -(axis_rotation(_Z, [outward])[0] @ axis_rotation(_X, [-down])[0] @ _Y)
    oblique = _deg(joints_spec["mtp_obliquity"])
    mtp = -np.array([-np.sin(oblique), np.cos(oblique), 0.0])
    origin = np.zeros(3)
    left_hinges = {"forearm": [(elbow, origin)], "hand": [(-_X, origin)],
                   "talus": [(talocrural, origin)], "toes": [(mtp, origin)],
                   "foot": [(_inversion_axis(joints_spec[name]),
                             np.asarray(joints_spec[f"{name}_through"], float) * scale)
                            for name in ("subtalar", "midtarsal")]}
    joints = {
        "hinges": {kind: {side: [(mirrored_axis(axis, side), _mirror_point(point, side))
                                 for axis, point in hinges] for side in SIDES}
                   for kind, hinges in left_hinges.items()},
        "rollback": float(joints_spec["knee_rollback"]) * scale,
        "screw_home": tuple(_deg(joints_spec["knee_screw_home"])),
        "varus": float(_deg(joints_spec["knee_varus"])),
    }

    index = {bone.name: i for i, bone in enumerate(bones)}
    landmarks = {}
    for name, entry in spec["landmarks"].items():
        for side in (SIDES if entry.get("sided") else ("",)):
            bone = index.get(f"{entry['bone']}_{side}", index.get(entry["bone"]))
            key = f"{side.upper()}_{name}" if side else name
            landmarks[key] = (bone, _mirror_point(entry["position"], side) * scale)

    foot_spec = spec["foot"]
    feet = {}
    for side in SIDES:
        toes = bones[index[f"toes_{side}"]]
        feet[side] = FootShape(
            ankle_height=float(foot_spec["ankle_height"]) * scale,
            heel=_mirror_point(foot_spec["heel"], side) * scale,
            toe_tip=_mirror_point(foot_spec["toe_tip"], side) * scale,
            mtp_point=toes.origin, mtp_axis=joints["hinges"]["toes"][side][0][0],
            sole=np.array([_mirror_point(p, side) for p in foot_spec["sole"]]) * scale)
    return Body(float(height), tuple(bones), landmarks, joints, feet)
