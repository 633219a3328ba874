"""Mirror images: the DOF map derived from the skeleton, mirrored motions, entries, libraries."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.mirror import (MIRROR_INDEX, MIRROR_SIGN, REFLECTION, mirror_dofs, mirror_id,
                             partner_name)
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, TRANSLATION, Skeleton


def test_mirrored_poses_put_every_segment_at_the_mirror_image_of_its_partner():
    """Forward kinematics of the mirrored pose = reflection of the pose, segments exchanged:
    position M p, orientation M R M (each segment frame's image under y -> -y). Random poses
    over the joints' ranges, root anywhere; round-off only (products of ~6 rotations)."""
    skeleton = Skeleton.from_height(1.71)
    lo, hi = skeleton.bounds()
    lo, hi = np.where(np.isfinite(lo), lo, -3.0), np.where(np.isfinite(hi), hi, 3.0)
    lo[TRANSLATION], hi[TRANSLATION] = -2.0, 2.0
    q = np.random.default_rng(23).uniform(lo, hi, (50, len(DOF_NAMES)))
    T, T_mirror = skeleton.forward(q), skeleton.forward(mirror_dofs(q))
    for s, name in enumerate(SEGMENT_NAMES):
        image = T_mirror[:, SEGMENT_NAMES.index(partner_name(name))]
        np.testing.assert_allclose(image[:, :3, 3], T[:, s, :3, 3] @ REFLECTION, atol=1e-12,
                                   err_msg=name)
        np.testing.assert_allclose(image[:, :3, :3], REFLECTION @ T[:, s, :3, :3] @ REFLECTION,
                                   atol=1e-12, err_msg=name)


def test_the_dof_map_follows_the_skeleton_conventions():
    """What the derivation gives for the current skeleton, as its docstring's sign table
    reads: sided DOFs exchange sides with their sign (flexion stays flexion, adduction
    adduction), the root's lateral translation, heading and list and the trunk's and neck's
    bending and rotation change sign, everything sagittal keeps it."""
    mirrored = {name: (DOF_NAMES[i], int(s)) for name, i, s in
                zip(DOF_NAMES, MIRROR_INDEX, MIRROR_SIGN)}
    assert mirrored["hip_adduction_l"] == ("hip_adduction_r", 1)
    assert mirrored["shoulder_rotation_r"] == ("shoulder_rotation_l", 1)
    flipped = {name for name, (_, sign) in mirrored.items() if sign < 0}
    assert flipped == {"pelvis_ty", "pelvis_rotation", "pelvis_list", "trunk_bending",
                       "trunk_rotation", "neck_bending", "neck_rotation"}
    assert all(partner == partner_name(name) for name, (partner, _) in mirrored.items())


def test_mirroring_twice_is_the_identity():
    q = np.random.default_rng(1).normal(size=(7, len(DOF_NAMES)))
    np.testing.assert_array_equal(mirror_dofs(mirror_dofs(q)), q)
    a = np.random.default_rng(2).normal(size=(len(DOF_NAMES), 5))
    np.testing.assert_array_equal(mirror_dofs(mirror_dofs(a, axis=0), axis=0), a)


@pytest.mark.parametrize("entry_id, mirrored", [
    ("walk_curve_r2_left_normal_c0", "walk_curve_r2_left_normal_mirror_c0"),
    ("HC030A22_c3@0123abcd", "HC030A22_mirror_c3@0123abcd"),
    ("walk_01#0", "walk_01#0_mirror"),
])
def test_mirror_ids(entry_id, mirrored):
    assert mirror_id(entry_id) == mirrored
    assert mirror_id(mirrored) == entry_id
