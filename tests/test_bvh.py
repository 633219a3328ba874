"""BVH export: parsed back with an independent reader, joint positions equal Skeleton.forward."""

from __future__ import annotations

import numpy as np
import pytest
from bvh_reader import bvh_positions, parse_bvh, to_z_up
from fk_data import neutral_q

from mocaplib.errors import MocapError
from mocaplib.export.bvh import bvh_text, write_bvh
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton


@pytest.fixture
def random_pose():
    sk = Skeleton.from_height(1.68)
    rng = np.random.default_rng(3)
    lo, hi = sk.bounds()
    lo, hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)
    q = rng.uniform(lo, hi, size=(7, len(DOF_NAMES)))
    q[:, :3] = rng.uniform(-3, 3, size=(7, 3))  # root translation, metres
    return sk, q


@pytest.mark.parametrize("units, scale", [("m", 1.0), ("cm", 100.0)])
def test_bvh_joint_positions_equal_forward_kinematics(random_pose, units, scale):
    sk, q = random_pose
    names, pos_file, frame_time = bvh_positions(bvh_text(Motion(q, sk, 120.0), units=units))
    assert names == list(SEGMENT_NAMES)
    np.testing.assert_allclose(frame_time, 1 / 120.0, rtol=1e-9)
    expected = sk.forward(q)[:, :, :3, 3]
    # 10 significant digits in the file: 1e-10 relative on angles and lengths, far below 1 µm.
    np.testing.assert_allclose(to_z_up(pos_file) / scale, expected, atol=1e-6)


def test_bvh_is_y_up_for_blender():
    sk = Skeleton.from_height(1.75)
    names, pos_file, _ = bvh_positions(bvh_text(Motion(neutral_q(sk, 1), sk, 100.0)))
    head = pos_file[0, names.index("head")]
    foot = pos_file[0, names.index("foot_l")]
    # Standing upright: the head is high on file +Y, the left foot at file -Z (our +Y, left).
    assert head[1] > 1.2 and abs(head[2]) < 1e-12
    assert foot[2] < 0 and foot[1] < 0.1


def test_bvh_three_rotation_channels_per_joint():
    sk = Skeleton.from_height(1.75)
    joints, _, values = parse_bvh(bvh_text(Motion(neutral_q(sk, 2), sk, 100.0)))
    real = [j for j in joints if j["name"] is not None]
    for j in real:
        rot = sorted(c[0] for c in j["channels"] if c.endswith("rotation"))
        assert rot == ["X", "Y", "Z"], j["name"]
    assert values.shape == (2, 3 + 3 * len(SEGMENT_NAMES))


def test_write_bvh_atomic_and_errors(tmp_path):
    sk = Skeleton.from_height(1.75)
    out = write_bvh(Motion(neutral_q(sk, 3), sk, 100.0), tmp_path / "sub" / "walk.bvh")
    assert out.read_text().startswith("HIERARCHY\nROOT pelvis")
    q = neutral_q(sk, 3)
    q[1, 5] = np.nan
    with pytest.raises(MocapError, match="finite"):
        bvh_text(Motion(q, sk, 100.0))
    with pytest.raises(MocapError, match="units"):
        bvh_text(Motion(neutral_q(sk, 1), sk, 100.0), units="inch")
