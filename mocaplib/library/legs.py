"""Both legs' forward kinematics below a fixed pelvis, with the Jacobian of each foot's ankle,
heel and toe, and planting's solve (:func:`solve_feet`;
:func:`mocaplib.library.planting.plant_feet`, step 4), which evaluates them at every
Gauss-Newton step.

Planting moves only the legs (hip, knee and ankle DOFs, :data:`LEG_DOFS`) and the pelvis
height; the pelvis's orientation and horizontal position stay those of the motion. So
:class:`LegChains` composes the pelvis's frames once, from its DOFs, and at each step only
the legs: both legs and all frames at once, in (F, 2, ...) arrays (left, right: the order of
:data:`mocaplib.gait.poulaine.FEET`), each DOF turning two columns of its segment's rotation
(its axis is ±X, ±Y or ±Z, as :meth:`Skeleton.chain` composes it). The numbers are those of
:meth:`Skeleton.marker_jacobian` on the same poses, to round-off (tests/test_legs.py).
"""

from __future__ import annotations

import numpy as np

from ..gait.poulaine import FEET
from ..skeleton import (DOF_NAMES, DOFS, ROOT_Z, SEGMENT_NAMES, SEGMENTS, Skeleton,
                        segment_dofs)

#: The segments of each leg (2, 3), rows left and right: femur, tibia, foot.
LEG_SEGMENTS = np.array([[SEGMENT_NAMES.index(f"{name}_{s}") for name in ("femur", "tibia",
                                                                           "foot")]
                         for s in "lr"])
#: Each leg's K DOFs (2, K), rows left and right, in chain order (hip flexion, adduction,
#: rotation; knee flexion; ankle dorsiflexion, inversion: K = 6).
LEG_DOFS = np.array([[DOF_NAMES.index(name) for segment in row
                      for name in SEGMENTS[segment].dofs] for row in LEG_SEGMENTS])
#: How many of a leg's DOFs (in :data:`LEG_DOFS` order) each segment of it holds.
SEGMENT_DOF_COUNTS = tuple(len(SEGMENTS[segment].dofs) for segment in LEG_SEGMENTS[0])
_PELVIS = SEGMENT_NAMES.index("pelvis")
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])    # cyclic shifts for cross products


def _letter(j: int) -> tuple[int, float]:
    """The axis letter (0-2 for X-Z) and sign of DOF ``j``, which turns about ±X, ±Y or ±Z."""
    axis = np.asarray(DOFS[j].axis)
    k = int(np.argmax(np.abs(axis)))
    assert np.abs(axis).sum() == abs(axis[k]) == 1.0, f"{DOFS[j].name}: not about ±X, ±Y or ±Z"
    return k, float(axis[k])


def _turn(R: np.ndarray, letter: int, cos: np.ndarray, sin: np.ndarray) -> None:
    """Rotations ``R`` (..., 3, 3) times the turn about their axis ``letter`` (0-2 for X-Z) by
    angles of cosine ``cos`` and sine ``sin`` (..., 1), in place: as
    :meth:`Skeleton.chain` composes a DOF's rotation (only two columns change)."""
    i, j = (letter + 1) % 3, (letter + 2) % 3
    R[..., i], R[..., j] = R[..., i] * cos + R[..., j] * sin, R[..., j] * cos - R[..., i] * sin


#: The pelvis's DOFs that planting keeps: its horizontal slides, its turns in chain order.
_PELVIS_DOFS = [DOF_NAMES.index(name) for name in SEGMENTS[_PELVIS].dofs]
_PELVIS_SLIDES = [j for j in _PELVIS_DOFS if DOFS[j].translation and j != ROOT_Z]
_PELVIS_TURNS = [j for j in _PELVIS_DOFS if not DOFS[j].translation]
_AXES = np.array([d.axis for d in DOFS])
_LETTERS = np.array([_letter(j)[0] for j in LEG_DOFS[0]])
_SIGNS = np.array([[_letter(j)[1] for j in row] for row in LEG_DOFS])             # (2, K)
assert all(_letter(j)[0] == k for row in LEG_DOFS for j, k in zip(row, _LETTERS)), \
    "both legs' DOFs turn about the same axes, in the same order"
assert SEGMENT_DOF_COUNTS == tuple(len(SEGMENTS[s].dofs) for s in LEG_SEGMENTS[1]) \
    and not any(DOFS[j].translation for j in LEG_DOFS.ravel()), "two legs alike, turns only"
assert list(FEET) == LEG_SEGMENTS[:, 2].tolist(), "legs in the order of the feet"


#: Gauss-Newton steps; Levenberg damping; weights (m² per rad², m² per m²) pulling each leg DOF
#: and the pelvis height to the motion's values.
IK_ITERATIONS, DAMPING, PRIOR, PELVIS_PRIOR = 12, 1e-5, 1e-6, 3e-2
#: A solve stops when no DOF (the first solve: no pelvis height) moves by more than this in a
#: step (rad, m).
STEP_TOLERANCE = 1e-6
#: A knee a solve would start straight or hyperextended starts flexed this much (rad): at a
#: straight knee the Jacobian cannot tell bending from straightening, and a solve started there
#: stays straight where the foot's target needs the knee bent (on 07_01_c0, whose knee the
#: motion hyperextends by 12 deg, 14 mm from it; started at 0.02 rad, on it).
KNEE_START = 0.02
#: The DOFs solved: both legs, then the pelvis height.
LEGS = tuple(segment_dofs("femur_l", "tibia_l", "foot_l") + segment_dofs("femur_r", "tibia_r",
                                                                         "foot_r"))
SOLVED = LEGS + (ROOT_Z,)
KNEES = (DOF_NAMES.index("knee_flexion_l"), DOF_NAMES.index("knee_flexion_r"))


def level_frames(pitch: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Foot orientations (n, 3, 3) with ``pitch`` (n,) rad, ``heading`` (n,) rad and no roll."""
    c, s = np.cos(pitch), np.sin(pitch)
    x = np.stack([c * np.cos(heading), c * np.sin(heading), s], axis=-1)
    y = np.stack([-np.sin(heading), np.cos(heading), np.zeros_like(heading)], axis=-1)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


class LegChains:
    """Both legs of ``skeleton`` hanging from the pelvis of poses ``q`` (F, D): the pelvis's
    orientation and horizontal position are those of ``q``; its height and the legs' DOFs are
    given to :meth:`feet`."""

    def __init__(self, skeleton: Skeleton, q: np.ndarray, /):
        q = np.asarray(q, dtype=np.float64)
        self.rotation = np.repeat(np.eye(3)[None], len(q), axis=0)         # (F, 3, 3)
        for j in _PELVIS_TURNS:
            k, sign = _letter(j)
            _turn(self.rotation, k, np.cos(q[:, j, None]), sign * np.sin(q[:, j, None]))
        joints = skeleton.joint_offsets()
        self.origin = (joints[_PELVIS]                                    # at height 0
                       + q[:, _PELVIS_SLIDES] @ _AXES[_PELVIS_SLIDES])
        self.hips = np.einsum("fij,sj->fsi", self.rotation, joints[LEG_SEGMENTS[:, 0]])
        #: knee centres in the femurs' frames and ankle centres in the tibias' (2, 2, 3, 1)
        self.offsets = joints[LEG_SEGMENTS[:, 1:].T, :, None]
        self.sole = skeleton.sole().T                                     # (3, 2) heel, toe

    def feet(self, angles: np.ndarray, height: np.ndarray, /
             ) -> tuple[np.ndarray, np.ndarray]:
        """Each foot's ankle, heel and toe (F, 2, 3, 3) m (frames, left/right, point, xyz) for
        the legs' DOFs ``angles`` (F, 2, K) rad (:data:`LEG_DOFS`) and pelvis heights
        ``height`` (F,) m, and their Jacobian (F, 2, 3, 3, K) with respect to the leg's own
        DOFs, m/rad (a leg's DOFs move only its own foot; the pelvis height moves every point
        by 1 m/m along Z)."""
        points, axes, pivots, _ = self._posed(angles, height)
        arm = points[..., None] - pivots[:, :, None]                      # (F, 2, 3, 3, K)
        jacobian = (axes[:, :, None, _NEXT] * arm[..., _AFTER, :]         # ω × (x − c)
                    - axes[:, :, None, _AFTER] * arm[..., _NEXT, :])
        return points, jacobian

    def points(self, angles: np.ndarray, height: np.ndarray, /) -> np.ndarray:
        """Each foot's ankle, heel and toe (F, 2, 3, 3) m, as :meth:`feet` gives them."""
        return self._posed(angles, height)[0]

    def frames(self, angles: np.ndarray, height: np.ndarray, /
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each foot's ankle, heel and toe (F, 2, 3, 3) m as :meth:`feet` gives them, its
        orientation (F, 2, 3, 3) in the world and each hip joint centre (F, 2, 3) m."""
        points, _, pivots, R = self._posed(angles, height)
        return points, R, pivots[..., 0]

    def _posed(self, angles: np.ndarray, height: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The foot points of :meth:`feet` (F, 2, 3, 3), each leg DOF's world axis and pivot
        (F, 2, 3, K) (xyz by DOF), composed down each leg as :meth:`Skeleton.chain` does, and
        each foot's orientation (F, 2, 3, 3)."""
        n = len(angles)
        R = np.repeat(self.rotation[:, None], 2, axis=1)                  # (F, 2, 3, 3)
        pivot = self.origin[:, None] + self.hips
        pivot[..., 2] += height[:, None]
        cos, sin = np.cos(angles), np.sin(angles) * _SIGNS
        axes, pivots = (np.empty((n, 2, 3, LEG_DOFS.shape[1])) for _ in range(2))
        dof = 0
        for segment, count in enumerate(SEGMENT_DOF_COUNTS):
            if segment:
                pivot = pivot + (R @ self.offsets[segment - 1])[..., 0]
            pivots[..., dof:dof + count] = pivot[..., None]
            for _ in range(count):
                axes[..., dof] = R[..., _LETTERS[dof]] * _SIGNS[:, dof, None]
                _turn(R, _LETTERS[dof], cos[:, :, dof, None], sin[:, :, dof, None])
                dof += 1
        points = np.empty((n, 2, 3, 3))
        points[:, :, 0] = pivot
        points[:, :, 1:] = pivot[:, :, None] + (R @ self.sole).transpose(0, 1, 3, 2)
        return points, axes, pivots, R


def solve_feet(skeleton: Skeleton, q: np.ndarray, targets: np.ndarray, dofs: tuple[int, ...], *,
               initial: np.ndarray | None = None) -> np.ndarray:
    """Poses (F, D) whose foot points meet ``targets`` (F, 2, 3, 3), solving the DOFs ``dofs``
    (:data:`LEGS`, or :data:`SOLVED`: with the pelvis height) near those of ``q`` (F, D), from
    those of ``initial`` (default ``q``; the knees flexed :data:`KNEE_START` at least) on, until
    no DOF (with the pelvis height: no pelvis height) moves by :data:`STEP_TOLERANCE`
    (:func:`mocaplib.library.planting.plant_feet`, step 4). Each frame's normal equations are
    solved with the pelvis height eliminated (Schur complement): the two legs' blocks do not
    couple."""
    assert set(dofs) - {ROOT_Z} == set(LEGS), "planting solves both legs, maybe the pelvis height"
    pelvis = ROOT_Z in dofs
    bounds = Skeleton.bounds()
    lower, upper = (bound[LEG_DOFS] for bound in bounds)                      # (2, K)
    lower = np.where(np.isin(LEG_DOFS, KNEES), np.maximum(lower, 0.0), lower)
    lowest, highest = (bound[ROOT_Z] for bound in bounds)
    start, height = q[:, LEG_DOFS], q[:, ROOT_Z]
    out = q.copy() if initial is None else np.where(np.isin(np.arange(q.shape[1]), dofs),
                                                    initial, q)
    angles = np.clip(out[:, LEG_DOFS], np.where(np.isin(LEG_DOFS, KNEES), KNEE_START, lower),
                     upper)                                                    # (F, 2, K)
    z = np.clip(out[:, ROOT_Z], lowest, highest) if pelvis else out[:, ROOT_Z]
    chains = LegChains(skeleton, out)
    wanted = targets.reshape(len(q), 2, 9)
    diagonal = (PRIOR + DAMPING) * np.eye(LEG_DOFS.shape[1])
    for _ in range(IK_ITERATIONS):
        points, jacobian = chains.feet(angles, z)
        J = jacobian.reshape(len(q), 2, 9, -1)
        Jt = J.transpose(0, 1, 3, 2)
        gap = wanted - points.reshape(len(q), 2, 9)
        normal = Jt @ J + diagonal                                             # (F, 2, K, K)
        rhs = (Jt @ gap[..., None])[..., 0] - PRIOR * (angles - start)
        if pelvis:                           # the pelvis height moves every point along Z
            coupling = J[:, :, 2::3].sum(axis=2)                               # (F, 2, K)
            legs = np.linalg.solve(normal, np.stack([rhs, coupling], axis=-1))  # (F, 2, K, 2)
            across = (coupling[..., None] * legs).sum(axis=(1, 2))             # (F, 2)
            lift = ((gap[:, :, 2::3].sum(axis=(1, 2)) - PELVIS_PRIOR * (z - height)
                     - across[:, 0])          # 6.0: the six foot points rise with the pelvis
                    / (6.0 + PELVIS_PRIOR + DAMPING - across[:, 1]))
            step = legs[..., 0] - legs[..., 1] * lift[:, None, None]
            z = np.clip(z + lift, lowest, highest)
        else:
            step, lift = np.linalg.solve(normal, rhs[..., None])[..., 0], np.zeros(1)
        angles = np.clip(angles + step, lower, upper)
        if np.abs(lift if pelvis else step).max() < STEP_TOLERANCE:
            break
    out[:, LEG_DOFS], out[:, ROOT_Z] = angles, z
    return out
