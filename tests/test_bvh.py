"""BVH export: parsed back with an independent reader, joint positions equal Skeleton.forward."""

from __future__ import annotations

import numpy as np
import pytest
from fk_data import neutral_q

from mocaplib.errors import MocapError
from mocaplib.export.bvh import bvh_text, write_bvh
from mocaplib.model.motion import Motion
from mocaplib.skeleton import DOF_NAMES, SEGMENT_NAMES, Skeleton


def _rot(axis: str, deg: np.ndarray) -> np.ndarray:
    """Textbook right-handed rotation matrices about a coordinate axis, (F, 3, 3)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {"X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]]}[axis]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def parse_bvh(text: str):
    """Minimal BVH reader: joints (name, parent, offset, channels), frame time, values (F, C)."""
    tokens = text.split()
    joints, stack, i = [], [], 0
    while tokens[i] != "MOTION":
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            joints.append({"name": tokens[i + 1], "parent": stack[-1] if stack else None})
            i += 2
        elif tok == "End":
            joints.append({"name": None, "parent": stack[-1]})  # end site, no channels
            i += 2
        elif tok == "{":
            stack.append(len(joints) - 1)
            i += 1
        elif tok == "}":
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            joints[stack[-1]]["offset"] = np.array(tokens[i + 1:i + 4], float)
            i += 4
        elif tok == "CHANNELS":
            n = int(tokens[i + 1])
            joints[stack[-1]]["channels"] = tokens[i + 2:i + 2 + n]
            i += 2 + n
        else:
            i += 1
    n_frames = int(tokens[i + 2])
    frame_time = float(tokens[i + 5])
    values = np.array(tokens[i + 6:], float).reshape(n_frames, -1)
    return joints, frame_time, values


def bvh_positions(text: str) -> tuple[list[str], np.ndarray, float]:
    """Joint names, world positions (F, J, 3) in file coordinates, and frame time."""
    joints, frame_time, values = parse_bvh(text)
    F = len(values)
    col = 0
    R = {}
    p = {}
    names, out = [], []
    for j, joint in enumerate(joints):
        rot = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
        trans = np.broadcast_to(joint["offset"], (F, 3)).copy()
        for ch in joint.get("channels", []):
            if ch.endswith("position"):
                trans = trans + values[:, col, None] * np.eye(3)["XYZ".index(ch[0])]
            else:
                rot = rot @ _rot(ch[0], values[:, col])
            col += 1
        if joint["parent"] is None:
            R[j], p[j] = rot, trans
        else:
            k = joint["parent"]
            R[j] = R[k] @ rot
            p[j] = np.einsum("fij,fj->fi", R[k], trans) + p[k]
        if joint["name"] is not None:
            names.append(joint["name"])
            out.append(p[j])
    assert col == values.shape[1], "every value column belongs to one channel"
    return names, np.stack(out, axis=1), frame_time


# File coordinates (x, y, z)_file = (x, z, -y)_ours, so ours = (x_f, -z_f, y_f).
def _to_ours(p_file: np.ndarray) -> np.ndarray:
    return np.stack([p_file[..., 0], -p_file[..., 2], p_file[..., 1]], axis=-1)


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
    np.testing.assert_allclose(_to_ours(pos_file) / scale, expected, atol=1e-6)


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
