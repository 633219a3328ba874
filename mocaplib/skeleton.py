"""The fixed full-body skeleton: topology, degrees of freedom and forward kinematics.

Frames and signs
----------------
Every segment frame, in the neutral pose (all DOFs zero, standing upright facing +X), is parallel
to the world frame: **X forward, Y to the subject's left, Z up**. A joint's DOF rotations are
applied in the order listed, each about its axis in the frame produced by the previous one
(intrinsic), after the joint's fixed offset in the parent frame. Angles are radians.

Signs follow the clinical (ISB-like) habit, *flexion positive*, whatever axis that needs:

=====================  ====================================================================
DOF                    positive means
=====================  ====================================================================
pelvis_tx/ty/tz        root translation in world X/Y/Z, metres (pelvis origin = mid hip centres)
pelvis_rotation        heading, counter-clockwise about +Z (turning left); 0 faces +X
pelvis_list            about +X: the right side drops
pelvis_tilt            about +Y: anterior tilt (the front of the pelvis drops)
trunk_flexion          trunk leans forward
trunk_bending          trunk bends to the left
trunk_rotation         trunk turns left (counter-clockwise seen from above)
neck_flexion/bending/rotation   the same for the head on the trunk
hip_flexion            thigh moves forward
hip_adduction          thigh moves towards the midline
hip_rotation           internal rotation
knee_flexion           shank moves backward (0 = straight knee)
ankle_dorsiflexion     toes move up
ankle_inversion        the sole turns to face the midline
shoulder_flexion       arm moves forward
shoulder_abduction     arm moves away from the body sideways
shoulder_rotation      internal rotation
elbow_flexion          forearm moves forward/up (0 = straight elbow)
=====================  ====================================================================

Left and right DOFs are named ``<joint>_<dof>_l`` / ``_r`` (e.g. ``hip_flexion_r``). Mirror-image
axes make the same number mean the same anatomical motion on both sides.

Arrays: joint angles ``q`` have shape ``(F, D)`` in :data:`DOF_NAMES` order; segment
transforms ``(F, S, 4, 4)`` in :data:`SEGMENT_NAMES` order map segment coordinates to world.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import MocapError

X, Y, Z = np.eye(3)
DEG = np.pi / 180.0


@dataclass(frozen=True)
class Dof:
    """One degree of freedom: a rotation (radians) or translation (metres) about/along ``axis``."""

    name: str
    segment: str
    axis: tuple[float, float, float]
    lower: float
    upper: float
    translation: bool = False


@dataclass(frozen=True)
class Segment:
    """A rigid segment, its parent and the DOFs of the joint that attaches it to the parent."""

    name: str
    parent: str | None
    dofs: tuple[str, ...]


def _rot(name, segment, axis, lo_deg, hi_deg):
    return Dof(name, segment, tuple(float(a) for a in axis), lo_deg * DEG, hi_deg * DEG)


def _sided(side: str) -> float:
    """+1 for right, -1 for left: mirrors axes so anatomical signs agree on both sides."""
    return 1.0 if side == "r" else -1.0


def _build_topology() -> tuple[tuple[Segment, ...], tuple[Dof, ...]]:
    segs: list[Segment] = []
    dofs: list[Dof] = []

    def add(name, parent, new_dofs):
        dofs.extend(new_dofs)
        segs.append(Segment(name, parent, tuple(d.name for d in new_dofs)))

    add("pelvis", None, [
        Dof("pelvis_tx", "pelvis", (1.0, 0.0, 0.0), -1e3, 1e3, translation=True),
        Dof("pelvis_ty", "pelvis", (0.0, 1.0, 0.0), -1e3, 1e3, translation=True),
        Dof("pelvis_tz", "pelvis", (0.0, 0.0, 1.0), -1e3, 1e3, translation=True),
        _rot("pelvis_rotation", "pelvis", Z, -np.inf, np.inf),
        _rot("pelvis_list", "pelvis", X, -45, 45),
        _rot("pelvis_tilt", "pelvis", Y, -45, 60),
    ])
    add("torso", "pelvis", [
        _rot("trunk_flexion", "torso", Y, -40, 90),
        _rot("trunk_bending", "torso", -X, -45, 45),
        _rot("trunk_rotation", "torso", Z, -60, 60),
    ])
    add("head", "torso", [
        _rot("neck_flexion", "head", Y, -60, 70),
        _rot("neck_bending", "head", -X, -50, 50),
        _rot("neck_rotation", "head", Z, -80, 80),
    ])
    for side in ("r", "l"):
        s = _sided(side)
        add(f"humerus_{side}", "torso", [
            _rot(f"shoulder_flexion_{side}", f"humerus_{side}", -Y, -90, 180),
            _rot(f"shoulder_abduction_{side}", f"humerus_{side}", -s * X, -30, 180),
            _rot(f"shoulder_rotation_{side}", f"humerus_{side}", s * Z, -90, 90),
        ])
        add(f"forearm_{side}", f"humerus_{side}", [
            _rot(f"elbow_flexion_{side}", f"forearm_{side}", -Y, -10, 160),
        ])
    for side in ("r", "l"):
        s = _sided(side)
        add(f"femur_{side}", "pelvis", [
            _rot(f"hip_flexion_{side}", f"femur_{side}", -Y, -40, 130),
            _rot(f"hip_adduction_{side}", f"femur_{side}", s * X, -50, 40),
            _rot(f"hip_rotation_{side}", f"femur_{side}", s * Z, -60, 60),
        ])
        add(f"tibia_{side}", f"femur_{side}", [
            _rot(f"knee_flexion_{side}", f"tibia_{side}", Y, -10, 150),
        ])
        add(f"foot_{side}", f"tibia_{side}", [
            _rot(f"ankle_dorsiflexion_{side}", f"foot_{side}", -Y, -50, 40),
            _rot(f"ankle_inversion_{side}", f"foot_{side}", s * X, -35, 40),
        ])
    return tuple(segs), tuple(dofs)


SEGMENTS, DOFS = _build_topology()
SEGMENT_NAMES: tuple[str, ...] = tuple(s.name for s in SEGMENTS)
DOF_NAMES: tuple[str, ...] = tuple(d.name for d in DOFS)
_SEGMENT_INDEX = {name: i for i, name in enumerate(SEGMENT_NAMES)}
_DOF_INDEX = {name: j for j, name in enumerate(DOF_NAMES)}
#: ``TRANSLATION[j]``: DOF ``j`` is a translation (metres), not a rotation (shape (D,), bool).
TRANSLATION = np.array([d.translation for d in DOFS])
#: The translation DOFs' indices (the root's pelvis_t*).
SHIFTS = np.flatnonzero(TRANSLATION)
#: Index of the root's heading ``pelvis_rotation`` (radians about +Z; 0 faces +X).
ROOT_HEADING = DOF_NAMES.index("pelvis_rotation")
#: Indices of the root's translations ``pelvis_tx``, ``pelvis_ty``, ``pelvis_tz`` (metres).
ROOT_X, ROOT_Y, ROOT_Z = (DOF_NAMES.index(f"pelvis_t{axis}") for axis in "xyz")
#: The joint angles (D,) bool: the rotational DOFs except the root's heading, which the library
#: stores relative to the path frame and QC and leave-one-out treat apart.
JOINT_ANGLES = ~TRANSLATION & (np.arange(len(DOF_NAMES)) != ROOT_HEADING)


def segment_dofs(*segments: str) -> tuple[int, ...]:
    """Indices into :data:`DOF_NAMES` of the DOFs of ``segments`` (names of
    :data:`SEGMENT_NAMES`), in skeleton order."""
    unknown = set(segments) - set(SEGMENT_NAMES)
    if unknown:
        raise ValueError(f"no segment {', '.join(sorted(unknown))} in the skeleton")
    return tuple(j for j, d in enumerate(DOFS) if d.segment in segments)


def partner_name(name: str) -> str:
    """The other side's name of a sided DOF or segment name (``hip_flexion_l`` ↔
    ``hip_flexion_r``, ``foot_l`` ↔ ``foot_r``); an unsided name is its own partner."""
    side = {"_l": "_r", "_r": "_l"}.get(name[-2:])
    return name[:-2] + side if side else name


def _moves() -> np.ndarray:
    """(S, D) bool: DOF ``j`` moves segment ``s`` (it belongs to ``s`` or to an ancestor)."""
    out = np.zeros((len(SEGMENTS), len(DOFS)), dtype=bool)
    for s, seg in enumerate(SEGMENTS):
        while seg is not None:
            out[s, [_DOF_INDEX[n] for n in seg.dofs]] = True
            seg = SEGMENTS[_SEGMENT_INDEX[seg.parent]] if seg.parent else None
    return out


#: ``MOVES[s, j]``: DOF ``j`` moves segment ``s`` (shape (S, D), bool).
MOVES = _moves()


def _axis_letter(j: int) -> tuple[int, float]:
    """Index (0-2 for X-Z) and sign of DOF ``j``'s axis, which must be ±X, ±Y or ±Z."""
    axis = np.asarray(DOFS[j].axis)
    k = int(np.argmax(np.abs(axis)))
    assert np.count_nonzero(axis) == 1 and abs(axis[k]) == 1.0, f"{DOFS[j].name}: not ±X/Y/Z"
    return k, float(axis[k])


def _levels() -> list[tuple]:
    """Segments by depth, root first, for :meth:`Skeleton.chain`: per level the segment
    indices (k,), their parents' (k,) (None for the root), their joints' rotation DOFs in order
    (k, 3), padded with ``D`` (the slot of an identity rotation), and per DOF position the
    axis letter (0-2 for X-Z) those DOFs share (3,) and their signs (k, 3, 1)."""
    depth = []
    for seg in SEGMENTS:
        depth.append(0 if seg.parent is None else depth[_SEGMENT_INDEX[seg.parent]] + 1)
    out = []
    for level in range(max(depth) + 1):
        segs = [s for s in range(len(SEGMENTS)) if depth[s] == level]
        spins = np.full((len(segs), 3), len(DOFS))
        letters = [set() for _ in range(3)]
        signs = np.ones((3, len(segs)))
        for row, s in enumerate(segs):
            rot = [_DOF_INDEX[n] for n in SEGMENTS[s].dofs if not DOFS[_DOF_INDEX[n]].translation]
            spins[row, :len(rot)] = rot
            for i, j in enumerate(rot):
                k, signs[i, row] = _axis_letter(j)
                letters[i].add(k)
        assert all(len(used) <= 1 for used in letters), f"level {level}: mixed axis orders"
        parents = None if level == 0 else np.array([_SEGMENT_INDEX[SEGMENTS[s].parent]
                                                    for s in segs])
        out.append((np.array(segs), parents, spins,
                    [used.pop() if used else 0 for used in letters], signs.T[..., None]))
    return out


def _spin_entries() -> tuple[np.ndarray, ...]:
    """Where :meth:`Skeleton.chain` writes each rotation DOF's matrix, as :func:`axis_rotation`
    does, in the flat (D + 1) x 9 array of all DOFs' rotations (translations and the last,
    padding slot: the identity): flat indices of the ones, of the cosines and of the sines,
    the rotation DOF (index into :data:`_SPINS`) of each cosine and sine, and each sine's sign.
    """
    spins = np.flatnonzero(~TRANSLATION)
    one, cos, cos_dof, sin, sin_dof, sin_sign = [], [], [], [], [], []
    for j in range(len(DOFS) + 1):
        if j == len(DOFS) or DOFS[j].translation:
            one += [j * 9 + 0, j * 9 + 4, j * 9 + 8]
            continue
        k, sign = _axis_letter(j)
        a, b = (k + 1) % 3, (k + 2) % 3
        r = int(np.flatnonzero(spins == j)[0])
        one.append(j * 9 + 4 * k)
        cos += [j * 9 + 4 * a, j * 9 + 4 * b]
        cos_dof += [r, r]
        sin += [j * 9 + 3 * a + b, j * 9 + 3 * b + a]
        sin_dof += [r, r]
        sin_sign += [-sign, sign]
    return (spins, np.array(one), np.array(cos), np.array(cos_dof), np.array(sin),
            np.array(sin_dof), np.array(sin_sign))


#: Segments by depth for batched kinematics: see :func:`_levels`.
LEVELS = _levels()
_SPINS, _SPIN_ONE, _SPIN_COS, _SPIN_COS_DOF, _SPIN_SIN, _SPIN_SIN_DOF, _SPIN_SIN_SIGN = \
    _spin_entries()
_AXES = np.array([d.axis for d in DOFS])
_ROOT = int(LEVELS[0][0][0])                             # the root segment (the pelvis)
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])    # cyclic shifts for cross products
_EYE = np.eye(3)[None, None]                             # the root's parent frame (1, 1, 3, 3)
assert all(SEGMENTS[_SEGMENT_INDEX[DOFS[j].segment]].parent is None
           for j in SHIFTS), "chain() takes translations at the root only"

#: Segment lengths as fractions of standing height (Winter 2009, Fig. 4.1; hip-centre width after
#: Harrington 2007's adult mean). Keys are the names used by :meth:`Skeleton.joint_offsets`.
HEIGHT_PROPORTIONS: dict[str, float] = {
    "hip_width": 0.098,        # distance between hip joint centres
    "hip_height": 0.520,       # floor to hip joint centres, standing
    "lumbar_height": 0.060,    # hip-centre midpoint to the lumbar joint (L5/S1)
    "torso_length": 0.250,     # lumbar joint to the neck joint (C7/T1)
    "shoulder_drop": 0.032,    # neck joint down to the shoulder (glenohumeral) centres
    "shoulder_width": 0.200,   # distance between the glenohumeral centres
    "head_length": 0.160,      # neck joint to the vertex
    "upper_arm": 0.186,        # shoulder to elbow centre
    "forearm": 0.146,          # elbow to wrist centre
    "hand": 0.108,             # wrist to finger tip
    "thigh": 0.245,            # hip to knee centre
    "shank": 0.246,            # knee to ankle centre
    "ankle_height": 0.039,     # ankle centre above the sole
    "foot_length": 0.152,      # heel to toe tip
}
#: Where the heel and the toe tip lie along the foot, as fractions of ``foot_length`` ahead of the
#: ankle centre, both on the sole (``ankle_height`` below it).
HEEL_AHEAD, TOE_AHEAD = -0.25, 0.75


def _joint_offsets(L) -> np.ndarray:
    """Each segment's joint centre in its parent's frame (S, 3) from lengths ``L`` (a mapping
    with every key of :data:`HEIGHT_PROPORTIONS`); linear in them."""
    off = {
        "pelvis": (0.0, 0.0, 0.0),
        "torso": (0.0, 0.0, L["lumbar_height"]),
        "head": (0.0, 0.0, L["torso_length"]),
        "humerus_r": (0.0, -L["shoulder_width"] / 2, L["torso_length"] - L["shoulder_drop"]),
        "humerus_l": (0.0, L["shoulder_width"] / 2, L["torso_length"] - L["shoulder_drop"]),
        "forearm_r": (0.0, 0.0, -L["upper_arm"]),
        "forearm_l": (0.0, 0.0, -L["upper_arm"]),
        "femur_r": (0.0, -L["hip_width"] / 2, 0.0),
        "femur_l": (0.0, L["hip_width"] / 2, 0.0),
        "tibia_r": (0.0, 0.0, -L["thigh"]),
        "tibia_l": (0.0, 0.0, -L["thigh"]),
        "foot_r": (0.0, 0.0, -L["shank"]),
        "foot_l": (0.0, 0.0, -L["shank"]),
    }
    return np.array([off[name] for name in SEGMENT_NAMES])


#: Change of every joint offset per metre of each length (S, 3, K), K in
#: :data:`HEIGHT_PROPORTIONS` order (the offsets are linear in the lengths).
_OFFSETS_PER_LENGTH = np.stack([_joint_offsets({k: float(k == key) for k in HEIGHT_PROPORTIONS})
                                for key in HEIGHT_PROPORTIONS], axis=-1)


@dataclass
class Skeleton:
    """The fixed topology with one subject's segment lengths and joint centres (metres).

    Attributes
    ----------
    lengths : dict[str, float]
        Every key of :data:`HEIGHT_PROPORTIONS`, in metres.
    shifts : dict[str, tuple[float, float, float]]
        Per segment name, how far its joint centre lies from where the lengths put it, in the
        parent's frame, metres (segments not named: no shift). Calibration measures them where
        a subject's anatomy differs from the symmetric, straight model: an ankle centre that
        lies lateral of the knee's sagittal plane, a shank longer on one side.
    """

    lengths: dict[str, float] = field(default_factory=dict)
    shifts: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    def __post_init__(self):
        missing = set(HEIGHT_PROPORTIONS) - set(self.lengths)
        if missing:
            raise MocapError(f"skeleton lengths missing: {', '.join(sorted(missing))}")
        bad = {k: v for k, v in self.lengths.items() if not (np.isfinite(v) and v > 0)}
        if bad:
            raise MocapError(f"skeleton lengths must be finite and > 0, got {bad}")
        self.lengths = {k: float(v) for k, v in self.lengths.items()}
        unknown = set(self.shifts) - set(SEGMENT_NAMES)
        if unknown:
            raise MocapError(f"joint shifts for unknown segments: {', '.join(sorted(unknown))}")
        shifts = {k: tuple(float(x) for x in v) for k, v in self.shifts.items()}
        if any(len(v) != 3 or not np.isfinite(v).all() for v in shifts.values()):
            raise MocapError(f"joint shifts must be 3 finite numbers (metres), got {self.shifts}")
        self.shifts = shifts
        shift_array = np.zeros((len(SEGMENTS), 3))
        for name, value in shifts.items():
            shift_array[_SEGMENT_INDEX[name]] = value
        self._joints = _joint_offsets(self.lengths) + shift_array     # read by every chain()

    def scaled(self, factor: float) -> "Skeleton":
        """This skeleton with every length and joint shift multiplied by ``factor``."""
        return Skeleton({k: v * factor for k, v in self.lengths.items()},
                        {k: tuple(factor * x for x in v) for k, v in self.shifts.items()})

    @classmethod
    def from_height(cls, height: float = 1.75) -> "Skeleton":
        """A nominal skeleton scaled from standing height in metres."""
        if not 0.5 < height < 2.6:
            raise MocapError(f"standing height must be in (0.5, 2.6) m, got {height}")
        return cls({k: f * height for k, f in HEIGHT_PROPORTIONS.items()})

    # ----------------------------------------------------------------- topology
    @staticmethod
    def bounds() -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper DOF limits, each shape (D,), radians or metres."""
        return (np.array([d.lower for d in DOFS]), np.array([d.upper for d in DOFS]))

    def sole(self) -> np.ndarray:
        """The heel and the toe tip on the sole, in the foot segments' frames: (2, 3) m, rows
        heel then toe, :data:`HEEL_AHEAD` and :data:`TOE_AHEAD` of ``foot_length`` ahead of the
        ankle centre and ``ankle_height`` below it (the same for both feet)."""
        L = self.lengths
        return np.array([(ahead * L["foot_length"], 0.0, -L["ankle_height"])
                         for ahead in (HEEL_AHEAD, TOE_AHEAD)])

    def joint_offsets(self) -> np.ndarray:
        """Each segment's joint centre in its parent's frame, neutral pose, shape (S, 3), metres.

        The root's row is zero (its position is the pelvis_t* DOFs). The lengths place each
        centre (:data:`HEIGHT_PROPORTIONS`), then :attr:`shifts` move it.
        """
        return self._joints.copy()

    def length_jacobian(self, q: np.ndarray, segments: np.ndarray, *,
                        transforms: np.ndarray | None = None) -> np.ndarray:
        """Derivative of the position of a point fixed on each of ``segments`` (M,) with respect
        to each length (:data:`HEIGHT_PROPORTIONS` order), in poses ``q`` (F, D): shape
        (F, M, 3, K), metres per metre. Exact, as positions are linear in the joint offsets and
        those in the lengths: a joint centre moves along its parent's axes, and with it all
        below it. ``transforms``: :meth:`forward` (q), when already computed."""
        T = self.forward(q) if transforms is None else transforms
        origin = np.zeros(T.shape[:2] + _OFFSETS_PER_LENGTH.shape[1:])         # (F, S, 3, K)
        for segs, parents, *_ in LEVELS[1:]:
            origin[:, segs] = (origin[:, parents]
                               + T[:, parents, :3, :3] @ _OFFSETS_PER_LENGTH[segs])
        return origin[:, np.asarray(segments)]

    # ----------------------------------------------------------------- kinematics
    def forward(self, q: np.ndarray, *, segments: np.ndarray | None = None) -> np.ndarray:
        """Segment-to-world transforms for every frame, :data:`FRAME_BLOCK` frames at a time.

        Parameters
        ----------
        q : ndarray, shape (F, D) or (D,)
            Joint coordinates in :data:`DOF_NAMES` order.
        segments : int ndarray, shape (K,), optional
            Only these segments' transforms (default all S).

        Returns
        -------
        ndarray, shape (F, S, 4, 4) or (F, K, 4, 4)
        """
        chosen = slice(None) if segments is None else np.asarray(segments, dtype=int)
        return _by_blocks(_poses(q), lambda rows: self.chain(rows)[0][:, chosen])

    def chain(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Transforms (F, S, 4, 4) plus each DOF's world axis (F, D, 3) and pivot (F, D, 3).

        A DOF's axis is its unit axis in the frame reached after the joint's earlier DOFs; its
        pivot is the joint centre (for translations, the pivot is unused and set to zero).
        """
        q = _poses(q)
        n = q.shape[0]
        offsets = self._joints
        local = elementary_rotations(q)
        out = np.empty((n, len(SEGMENTS), 4, 4))
        out[:, :, 3, :] = (0.0, 0.0, 0.0, 1.0)
        axes = np.zeros((n, len(DOFS) + 1, 3))
        pivots = np.zeros((n, len(DOFS) + 1, 3))
        axes[:, SHIFTS] = _AXES[SHIFTS]                        # the root's, unrotated
        for segments, parents, spins, letters, signs in LEVELS:
            if parents is None:
                R = _EYE
                p = offsets[segments] + (q[:, SHIFTS] @ _AXES[SHIFTS])[:, None]
            else:
                parent = np.take(out, parents, axis=1)
                R = parent[..., :3, :3]
                p = (R @ offsets[segments, :, None])[..., 0] + parent[..., :3, 3]
            turns = np.take(local, spins, axis=1)       # (F, k, 3, 3, 3): each joint's rotations
            columns = np.empty((n, len(segments), 3, 3))
            for i, letter in enumerate(letters):
                columns[:, :, i] = R[..., letter]    # a DOF's axis: a column of the rotation so far
                R = R @ turns[:, :, i]
            axes[:, spins] = columns * signs
            pivots[:, spins] = p[:, :, None]
            out[:, segments, :3, :3] = R
            out[:, segments, :3, 3:] = p[..., None]
        return out, axes[:, :-1], pivots[:, :-1]

    def marker_jacobian(self, q: np.ndarray, segments: np.ndarray, offsets: np.ndarray, *,
                        chain: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Points fixed in segments and their analytic Jacobian with respect to ``q``.

        Parameters
        ----------
        q : ndarray, shape (F, D)
        segments : int ndarray, shape (M,)
        offsets : ndarray, shape (M, 3), metres in each segment's frame.
        chain : :meth:`chain` (q), when already computed.

        Returns
        -------
        points : ndarray, shape (F, M, 3), metres (as :meth:`points`).
        jacobian : ndarray, shape (F, M, 3, D): d point / d q, metres per radian (or per metre
            for ``pelvis_t*``). A rotation DOF moves the points of its segment and descendants
            by ``axis x (point - pivot)``; a translation DOF by its axis (a view of
            :func:`twist_jacobian`'s (F, 3, M, D) array).
        """
        segments = np.asarray(segments, dtype=int)
        chain = self.chain(q) if chain is None else chain
        T = chain[0][:, segments]
        pts = (T[..., :3, :3] @ np.asarray(offsets, float)[..., None])[..., 0] + T[..., :3, 3]
        twist, origin = twists(chain)
        about = (pts - origin[:, None]).transpose(0, 2, 1)
        return pts, twist_jacobian(twist, about, MOVES[segments]).transpose(0, 2, 1, 3)

    def points(self, q: np.ndarray, segments: np.ndarray, offsets: np.ndarray, *,
               transforms: np.ndarray | None = None) -> np.ndarray:
        """World positions of points fixed in segments (markers, joint centres).

        Parameters
        ----------
        q : ndarray, shape (F, D)
        segments : int ndarray, shape (M,)
            Segment index of each point.
        offsets : ndarray, shape (M, 3)
            Each point in its segment's frame, metres.
        transforms : :meth:`forward` (q), when already computed.

        Returns
        -------
        ndarray, shape (F, M, 3), metres.
        """
        segments, offsets = np.asarray(segments, dtype=int), np.asarray(offsets, dtype=float)
        if transforms is not None:
            return _placed(transforms[:, segments], offsets)
        return _by_blocks(_poses(q), lambda rows: _placed(self.chain(rows)[0][:, segments],
                                                          offsets))


#: Frames :meth:`Skeleton.forward` and :meth:`Skeleton.points` compute at once: their work
#: arrays (each DOF's rotation, the chain's transforms, axes and pivots, about 10 kB a frame)
#: stay near 40 MB whatever the capture's length. Each frame's numbers are the same in any
#: block.
FRAME_BLOCK = 4096


def _poses(q: np.ndarray) -> np.ndarray:
    """Joint coordinates ``q`` (F, D) or (D,) as a float (F, D) array; MocapError otherwise."""
    q = np.asarray(q, dtype=np.float64)
    if q.ndim == 1:
        q = q[None, :]
    if q.ndim != 2 or q.shape[1] != len(DOF_NAMES):
        raise MocapError(f"q must have shape (F, {len(DOF_NAMES)}), got {q.shape}")
    return q


def _by_blocks(q: np.ndarray, compute) -> np.ndarray:
    """``compute(q)`` for poses ``q`` (F, D), a function whose result has one row per frame,
    computed :data:`FRAME_BLOCK` frames at a time and stacked."""
    if len(q) <= FRAME_BLOCK:
        return compute(q)
    first = compute(q[:FRAME_BLOCK])
    out = np.empty((len(q),) + first.shape[1:], dtype=first.dtype)
    out[:FRAME_BLOCK] = first
    for start in range(FRAME_BLOCK, len(q), FRAME_BLOCK):
        out[start:start + FRAME_BLOCK] = compute(q[start:start + FRAME_BLOCK])
    return out


def _placed(transforms: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """World positions (F, M, 3) of points at ``offsets`` (M, 3) in the frames
    ``transforms`` (F, M, 4, 4)."""
    return (transforms[..., :3, :3] @ offsets[..., None])[..., 0] + transforms[..., :3, 3]


def elementary_rotations(q: np.ndarray) -> np.ndarray:
    """Each DOF's own rotation for poses ``q`` (F, D): shape (F, D + 1, 3, 3), the identity for
    translations and in the last slot (the padding of :data:`LEVELS`); entries as
    :func:`axis_rotation` writes them."""
    n = len(q)
    local = np.zeros((n, (len(DOFS) + 1) * 9))
    local[:, _SPIN_ONE] = 1.0
    spin = q[:, _SPINS]
    local[:, _SPIN_COS] = np.cos(spin)[:, _SPIN_COS_DOF]
    local[:, _SPIN_SIN] = np.sin(spin)[:, _SPIN_SIN_DOF] * _SPIN_SIN_SIGN
    return local.reshape(n, len(DOFS) + 1, 3, 3)


def axis_rotation(axis, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices about a fixed unit ``axis`` (3,) by ``angle`` (F,) radians: (F, 3, 3)."""
    a = np.asarray(axis, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    if np.count_nonzero(a) == 1:                  # ±X, ±Y or ±Z: write the entries directly
        k = int(np.flatnonzero(a)[0])
        i, j = (k + 1) % 3, (k + 2) % 3
        s = s * a[k]
        out = np.zeros(angle.shape + (3, 3))
        out[..., k, k] = 1.0
        out[..., i, i] = out[..., j, j] = c
        out[..., i, j], out[..., j, i] = -s, s
        return out
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return (np.eye(3) + s[:, None, None] * K + (1.0 - c)[:, None, None] * (K @ K))


def twists(chain: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Each DOF's twist (F, 6, D) about the root's origin (F, 3), from :meth:`Skeleton.chain`:
    its world axis ω (0 for a translation) over ``v`` (``c × ω`` about its pivot ``c`` for a
    rotation, its axis for a translation). DOF d moves a point ``p`` (about the origin: moments
    about the pelvis keep round-off small) at ``ω_d × p + v_d``."""
    transforms, axes, pivots = chain
    origin = transforms[:, _ROOT, :3, 3]
    twist = np.empty((len(axes), 6, axes.shape[1]))
    axes = axes.transpose(0, 2, 1)
    np.multiply(axes, ~TRANSLATION, out=twist[:, :3])
    twist[:, 3:] = np.where(TRANSLATION, axes,
                            cross_rows((pivots - origin[:, None]).transpose(0, 2, 1), axes))
    return twist, origin


def twist_jacobian(twist: np.ndarray, points: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """Jacobians (F, 3, M, D) of points (F, 3, M) (coordinates on axis 1, about the origin of
    the twists (F, 6, D) of :func:`twists`): DOF d moves point m at ``ω_d × p_m + v_d`` where
    ``moved`` (M, D) is 1 (``MOVES[segments]``), not at all where it is 0. The batched form of
    :meth:`Skeleton.marker_jacobian`, for twists and points already at hand."""
    n, m = points.shape[0], points.shape[2]
    out = np.empty((n, 3, m, twist.shape[2]))
    for c, (a, b) in enumerate(zip(_NEXT, _AFTER)):
        out[:, c] = (twist[:, a, None] * points[:, b, :, None]
                     - twist[:, b, None] * points[:, a, :, None] + twist[:, 3 + c, None])
    out *= moved
    return out


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of vectors stored along axis 1 (shapes (F, 3, N)), without np.cross's
    axis shuffling (np.take: cheaper than indexing for these small gathers)."""
    return (np.take(a, _NEXT, axis=1) * np.take(b, _AFTER, axis=1)
            - np.take(a, _AFTER, axis=1) * np.take(b, _NEXT, axis=1))
