"""The fixed skeleton: forward-kinematics signs as the docstring table states, and Jacobians."""

import numpy as np
import pytest
from fk_data import neutral_q

from mocaplib.errors import MocapError
from mocaplib.skeleton import DOF_NAMES, MOVES, SEGMENT_NAMES, Skeleton

SK = Skeleton.from_height(1.75)


def _pose(**angles):
    q = neutral_q(SK, 1)
    for name, value in angles.items():
        q[0, DOF_NAMES.index(name)] = value
    return q


def _point(q, segment, offset):
    """World position (3,) of one point fixed in ``segment``."""
    return SK.points(q, np.array([SEGMENT_NAMES.index(segment)]), np.array([offset]))[0, 0]


def _delta(dof, segment, offset, angle=0.3):
    """Displacement (3,) of a segment point when ``dof`` goes from 0 to ``angle``."""
    return _point(_pose(**{dof: angle}), segment, offset) - _point(_pose(), segment, offset)


FOOT_TIP = (0.15, 0.0, -0.05)      # forward of the ankle
DOWN = (0.0, 0.0, -0.3)            # along a limb, below its joint
UP = (0.0, 0.0, 0.3)               # above the lumbar or neck joint


@pytest.mark.parametrize("dof,segment,offset,axis,sign", [
    # "positive means" column of the module docstring, one row each, both sides
    ("trunk_flexion", "torso", UP, 0, +1),          # leans forward: top moves +X
    ("trunk_bending", "torso", UP, 1, +1),          # bends to the left: top moves +Y
    ("neck_flexion", "head", UP, 0, +1),
    ("neck_bending", "head", UP, 1, +1),
    ("hip_flexion_r", "femur_r", DOWN, 0, +1),      # thigh forward: knee moves +X
    ("hip_flexion_l", "femur_l", DOWN, 0, +1),
    ("hip_adduction_r", "femur_r", DOWN, 1, +1),    # right thigh to the midline: +Y
    ("hip_adduction_l", "femur_l", DOWN, 1, -1),    # left thigh to the midline: -Y
    ("knee_flexion_r", "tibia_r", DOWN, 0, -1),     # shank backward: ankle moves -X
    ("knee_flexion_l", "tibia_l", DOWN, 0, -1),
    ("ankle_dorsiflexion_r", "foot_r", FOOT_TIP, 2, +1),   # toes up
    ("ankle_dorsiflexion_l", "foot_l", FOOT_TIP, 2, +1),
    ("shoulder_flexion_r", "humerus_r", DOWN, 0, +1),      # arm forward
    ("shoulder_flexion_l", "humerus_l", DOWN, 0, +1),
    ("shoulder_abduction_r", "humerus_r", DOWN, 1, -1),    # right arm out to the right: -Y
    ("shoulder_abduction_l", "humerus_l", DOWN, 1, +1),
    ("elbow_flexion_r", "forearm_r", DOWN, 0, +1),         # forearm forward/up
    ("elbow_flexion_l", "forearm_l", DOWN, 0, +1),
    ("pelvis_list", "femur_r", (0, 0, 0), 2, -1),          # the right side drops
    ("pelvis_tilt", "pelvis", (0.1, 0, 0), 2, -1),         # anterior tilt: the front drops
])
def test_positive_angles_move_as_documented(dof, segment, offset, axis, sign):
    d = _delta(dof, segment, offset)
    assert np.sign(d[axis]) == sign, f"{dof}: displacement {d} should be {sign:+d} on axis {axis}"


def test_rotations_turn_left_and_inward():
    # trunk/neck/pelvis rotation and heading: counter-clockwise seen from above
    front = (0.2, 0.0, 0.0)
    assert _delta("pelvis_rotation", "pelvis", front)[1] > 0
    assert _delta("trunk_rotation", "torso", front)[1] > 0
    assert _delta("neck_rotation", "head", front)[1] > 0
    # internal rotation turns the front of the limb (and the foot) towards the midline
    assert _delta("hip_rotation_r", "foot_r", FOOT_TIP)[1] > 0
    assert _delta("hip_rotation_l", "foot_l", FOOT_TIP)[1] < 0
    # inversion: the sole faces the midline, so a point under the foot moves medially
    sole = (0.0, 0.0, -0.05)
    assert _delta("ankle_inversion_r", "foot_r", sole)[1] > 0
    assert _delta("ankle_inversion_l", "foot_l", sole)[1] < 0


def test_neutral_pose_stands_on_the_floor_facing_x():
    T = SK.forward(neutral_q(SK, 1))[0]
    np.testing.assert_allclose(T[:, :3, :3], np.broadcast_to(np.eye(3), (len(SEGMENT_NAMES), 3, 3)),
                               atol=1e-12)  # exact: every rotation is the identity
    ankle = T[SEGMENT_NAMES.index("foot_r"), :3, 3]
    np.testing.assert_allclose(ankle[2], SK.lengths["ankle_height"], atol=1e-12)


def test_marker_jacobian_matches_finite_differences():
    rng = np.random.default_rng(3)
    q = neutral_q(SK, 5) + rng.normal(0, 0.4, (5, len(DOF_NAMES)))
    segments = rng.integers(0, len(SEGMENT_NAMES), 30)
    offsets = rng.normal(0, 0.1, (30, 3))
    points, jac = SK.marker_jacobian(q, segments, offsets)
    np.testing.assert_allclose(points, SK.points(q, segments, offsets), atol=1e-12)
    numeric = np.empty_like(jac)
    h = 1e-6
    for j in range(len(DOF_NAMES)):
        dq = np.zeros(len(DOF_NAMES))
        dq[j] = h
        numeric[..., j] = (SK.points(q + dq, segments, offsets)
                           - SK.points(q - dq, segments, offsets)) / (2 * h)
    # central differences with h = 1e-6 on ~1 m lever arms: truncation ~h² and rounding
    # ~1e-16/h, both far below 1e-8
    np.testing.assert_allclose(jac, numeric, atol=1e-8)


def test_length_jacobian_is_the_change_of_points_with_each_length():
    # points are affine in the lengths, so a whole metre's step is exact (to rounding)
    rng = np.random.default_rng(4)
    q = neutral_q(SK, 4) + rng.normal(0, 0.4, (4, len(DOF_NAMES)))
    segments = rng.integers(0, len(SEGMENT_NAMES), 25)
    offsets = rng.normal(0, 0.1, (25, 3))
    jac = SK.length_jacobian(q, segments)
    base = SK.points(q, segments, offsets)
    for k, key in enumerate(SK.lengths):
        moved = Skeleton({**SK.lengths, key: SK.lengths[key] + 1.0})
        np.testing.assert_allclose(jac[..., k], moved.points(q, segments, offsets) - base,
                                   atol=1e-12, err_msg=key)
    assert np.abs(jac).max() > 0.5          # the legs' lengths move the feet


def test_jacobian_is_zero_for_dofs_that_do_not_move_a_segment():
    segments = np.arange(len(SEGMENT_NAMES))
    _, jac = SK.marker_jacobian(neutral_q(SK, 1), segments, np.full((len(segments), 3), 0.1))
    moving = np.abs(jac[0]).max(axis=1) > 0          # (S, D)
    assert not (moving & ~MOVES).any()
    assert MOVES[SEGMENT_NAMES.index("foot_l"), DOF_NAMES.index("hip_flexion_l")]
    assert not MOVES[SEGMENT_NAMES.index("foot_l"), DOF_NAMES.index("hip_flexion_r")]


def test_bad_q_shape_is_reported():
    with pytest.raises(MocapError, match=r"q must have shape \(F, 32\)"):
        SK.forward(np.zeros((3, 5)))


def test_chain_equals_joint_by_joint_composition():
    """chain() batches segments by depth; it must equal composing each joint's offset and
    elementary rotations (axis_rotation) segment by segment, root first."""
    from mocaplib.skeleton import axis_rotation, DOFS, SEGMENTS

    rng = np.random.default_rng(3)
    q = rng.normal(size=(7, len(DOF_NAMES)))
    T, axes, pivots = SK.chain(q)
    offsets = SK.joint_offsets()
    for f in range(len(q)):
        rot, pos = {}, {}
        for s, seg in enumerate(SEGMENTS):
            R = np.eye(3) if seg.parent is None else rot[seg.parent]
            p = offsets[s] if seg.parent is None else R @ offsets[s] + pos[seg.parent]
            for name in seg.dofs:
                j = DOF_NAMES.index(name)
                np.testing.assert_allclose(axes[f, j], R @ DOFS[j].axis, atol=1e-12)
                if DOFS[j].translation:
                    p = p + q[f, j] * np.asarray(DOFS[j].axis)
                else:
                    R = R @ axis_rotation(DOFS[j].axis, q[f, j:j + 1])[0]
            for name in seg.dofs:
                j = DOF_NAMES.index(name)
                expected = np.zeros(3) if DOFS[j].translation else p
                np.testing.assert_allclose(pivots[f, j], expected, atol=1e-12)
            rot[seg.name], pos[seg.name] = R, p
            # round-off only: products of a few unit rotations and metre offsets
            np.testing.assert_allclose(T[f, s, :3, :3], R, atol=1e-12)
            np.testing.assert_allclose(T[f, s, :3, 3], p, atol=1e-12)
            np.testing.assert_array_equal(T[f, s, 3], [0.0, 0.0, 0.0, 1.0])


def test_the_library_format_doc_poses_the_skeleton_as_mocaplib_does():
    """docs/library-format.md, *Posing the skeleton*: its table and formula alone (parsed
    here, no mocaplib kinematics) put every segment where Skeleton.forward does."""
    import re
    from pathlib import Path
    from scipy.spatial.transform import Rotation

    doc = (Path(__file__).parents[1] / "docs" / "library-format.md").read_text()
    section = doc[doc.index("### Posing the skeleton"):]
    rows = re.findall(r"^\| `(\w+)` \| (?:`(\w+)`|—) \| \(([^)]*)\) \| (.*) \|$", section, re.M)
    assert [r[0] for r in rows] == list(SEGMENT_NAMES)
    shifts = {"foot_l": (0.004, 0.03, -0.01), "tibia_r": (0.0, 0.0, 0.006)}
    skeleton = Skeleton(Skeleton.from_height(1.68).lengths, shifts)
    q = np.random.default_rng(4).uniform(-0.6, 0.6, len(DOF_NAMES))
    world = {}
    for name, parent, offset, dofs in rows:
        expression = offset.replace("−", "-")
        centre = np.array([eval(part, {}, dict(skeleton.lengths))
                           for part in expression.split(",")]) + shifts.get(name, 0.0)
        pose = np.eye(4) if not parent else world[parent].copy()
        pose[:3, 3] += pose[:3, :3] @ centre
        for dof, sign, letter in re.findall(r"`(\w+)` ([+−])([XYZ])", dofs):
            value = q[DOF_NAMES.index(dof)] * (1 if sign == "+" else -1)
            axis = np.eye(3)["XYZ".index(letter)]
            if dof in ("pelvis_tx", "pelvis_ty", "pelvis_tz"):
                pose[:3, 3] += value * axis                       # along the world axis
            else:
                pose[:3, :3] = pose[:3, :3] @ Rotation.from_rotvec(value * axis).as_matrix()
        world[name] = pose
    expected = skeleton.forward(q)[0]
    for s, name in enumerate(SEGMENT_NAMES):
        np.testing.assert_allclose(world[name], expected[s], atol=1e-12, err_msg=name)


def test_joint_shifts_move_a_joint_centre_in_its_parents_frame():
    plain = Skeleton.from_height(1.75)
    shifted = Skeleton(plain.lengths, {"foot_r": (0.0, -0.03, 0.002)})
    q = np.random.default_rng(1).uniform(-0.5, 0.5, (3, len(DOF_NAMES)))
    a, b = plain.forward(q), shifted.forward(q)
    foot = SEGMENT_NAMES.index("foot_r")
    tibia = a[:, SEGMENT_NAMES.index("tibia_r")]
    # the ankle moves by the shift, expressed in the tibia's frame; nothing above it moves
    np.testing.assert_allclose(b[:, foot, :3, 3] - a[:, foot, :3, 3],
                               tibia[:, :3, :3] @ [0.0, -0.03, 0.002], atol=1e-12)
    np.testing.assert_array_equal(a[:, :foot], b[:, :foot])
    with pytest.raises(MocapError, match="unknown segments: toe_r"):
        Skeleton(plain.lengths, {"toe_r": (0.0, 0.0, 0.0)})
