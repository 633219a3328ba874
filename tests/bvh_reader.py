"""An independent BVH reader for the tests: the text parsed token by token, forward kinematics
from textbook rotation matrices (no mocaplib code), and what animation software shows of a
character's feet and pelvis measured on it (:class:`Character`).

BVH rotation channels compose in their listed order, R = R_1 · R_2 · R_3, after the joint's
OFFSET in its parent's frame; positions are in file coordinates, Y up. mocaplib's files are
(x, y, z)_file = (x, z, -y) of its Z-up world, so :func:`to_z_up` turns them back.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


def rotation(axis: str, deg: np.ndarray) -> np.ndarray:
    """Textbook right-handed rotation matrices about a coordinate axis, (F, 3, 3)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {"X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]]}[axis]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def parse_bvh(text: str):
    """Joints (name, parent, offset, channels; an end site has name None and no channels),
    frame time (s) and values (F, C)."""
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


def forward(joints, values) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (F, J, 3, 3) and positions (F, J, 3) of every joint and end site (in
    :func:`parse_bvh`'s order), file coordinates."""
    F = len(values)
    col = 0
    R, p = [], []
    for joint in joints:
        rot = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
        trans = np.broadcast_to(joint["offset"], (F, 3)).copy()
        for ch in joint.get("channels", []):
            if ch.endswith("position"):
                trans = trans + values[:, col, None] * np.eye(3)["XYZ".index(ch[0])]
            else:
                rot = rot @ rotation(ch[0], values[:, col])
            col += 1
        if joint["parent"] is None:
            R.append(rot)
            p.append(trans)
        else:
            k = joint["parent"]
            R.append(R[k] @ rot)
            p.append(np.einsum("fij,fj->fi", R[k], trans) + p[k])
    assert col == values.shape[1], "every value column belongs to one channel"
    return np.stack(R, axis=1), np.stack(p, axis=1)


def bvh_positions(text: str) -> tuple[list[str], np.ndarray, float]:
    """Joint names, world positions (F, J, 3) in file coordinates, and frame time."""
    joints, frame_time, values = parse_bvh(text)
    _, positions = forward(joints, values)
    named = [j for j, joint in enumerate(joints) if joint["name"] is not None]
    return [joints[j]["name"] for j in named], positions[:, named], frame_time


def to_z_up(p_file: np.ndarray) -> np.ndarray:
    """File coordinates (x, y, z)_file = (x, z, -y) back to Z up: (x_f, -z_f, y_f)."""
    return np.stack([p_file[..., 0], -p_file[..., 2], p_file[..., 1]], axis=-1)


#: A foot touches the floor within this (m); it stands in a stance while its lower sole point is
#: within STANCE_HEIGHT (m) for at least STANCE_FRAMES frames.
TOUCH, STANCE_HEIGHT, STANCE_FRAMES = 0.001, 0.003, 5


@dataclass
class Character:
    """A mocaplib BVH file as an animation program shows it, Z up, metres.

    The heel and the toe of each foot lie on its sole: the toe is the foot's end site; the heel
    is on the line through it parallel to the foot's long axis (the file's X of the foot joint),
    ``heel_ahead`` of the toe's distance ahead of the ankle (mocaplib's skeleton puts them at
    -1/4 and 3/4 of the foot length: ``heel_ahead`` = -1/3). A ``loop`` (one cycle a player
    repeats) continues from its last frame to its first: a stance its ends cut is one stance.
    """

    text: str
    heel_ahead: float = -1.0 / 3.0
    loop: bool = False

    @cached_property
    def _parsed(self):
        joints, frame_time, values = parse_bvh(self.text)
        R, p = forward(joints, values)
        return joints, frame_time, values, R, p

    @property
    def frame_time(self) -> float:
        return self._parsed[1]

    @property
    def frames(self) -> int:
        return len(self._parsed[2])

    def _joint(self, name: str) -> int:
        return [j["name"] for j in self._parsed[0]].index(name)

    def position(self, name: str) -> np.ndarray:
        """A joint's positions (F, 3), Z up."""
        return to_z_up(self._parsed[4][:, self._joint(name)])

    def feet(self) -> np.ndarray:
        """Heel and toe of the left and right foot: (F, 2, 2, 3) (frames, left/right,
        heel/toe, xyz), Z up."""
        joints, _, _, R, p = self._parsed
        out = []
        for name in ("foot_l", "foot_r"):
            j = self._joint(name)
            end = next(k for k, joint in enumerate(joints)
                       if joint["name"] is None and joint["parent"] == j)
            toe = joints[end]["offset"]
            heel = toe * (self.heel_ahead, 1.0, 1.0)
            points = np.einsum("fij,pj->fpi", R[:, j], np.stack([heel, toe])) + p[:, j, None]
            out.append(to_z_up(points))
        return np.stack(out, axis=1)

    def knee_flexion(self) -> np.ndarray:
        """Knee flexion (F, 2) rad, left and right, from the joint positions: the shank's angle
        behind the thigh's long axis in the thigh's sagittal plane (negative: hyperextended)."""
        _, _, _, R, p = self._parsed
        out = []
        for side in "lr":
            femur, tibia, foot = (self._joint(f"{name}_{side}") for name in ("femur", "tibia",
                                                                             "foot"))
            shank = np.einsum("fji,fj->fi", R[:, femur], p[:, foot] - p[:, tibia])  # femur frame
            out.append(np.arctan2(-shank[:, 0], -shank[:, 1]))      # file: X forward, Y up
        return np.stack(out, axis=1)

    def pelvis_heading(self) -> np.ndarray:
        """The pelvis's heading (F,) rad, unwrapped: its forward axis in the floor's plane."""
        forward_axis = to_z_up(self._parsed[3][:, 0, :, 0])
        return np.unwrap(np.arctan2(forward_axis[:, 1], forward_axis[:, 0]))

    def pelvis_acceleration(self) -> np.ndarray:
        """The pelvis's vertical acceleration (F - 2,) m/s², second differences."""
        return np.diff(self.position(self._parsed[0][0]["name"])[:, 2], 2) / self.frame_time ** 2

    def stances(self) -> list[tuple[int, int, int]]:
        """(foot 0/1, first frame, stop frame) of each stance: the lower of heel and toe within
        :data:`STANCE_HEIGHT` of the floor for :data:`STANCE_FRAMES` frames or more. A stance
        the file's ends cut is left out, unless it is a loop: its two parts are then one stance
        (of frames from the first part's start to the last frame, then from 0 to the second's
        stop: ``first > stop``)."""
        low = self.feet()[..., 2].min(axis=2)
        n, out = len(low), []
        for side in (0, 1):
            down = np.concatenate([[0], (low[:, side] <= STANCE_HEIGHT).astype(int), [0]])
            edges = np.flatnonzero(np.diff(down))
            runs = list(zip(edges[::2], edges[1::2]))
            if self.loop and len(runs) > 1 and runs[0][0] == 0 and runs[-1][1] == n:
                runs = [(runs[-1][0], runs[0][1])] + runs[1:-1]
            out += [(side, a, b) for a, b in runs
                    if (b - a) % n >= STANCE_FRAMES and (self.loop or (a > 0 and b < n))]
        return out

    def slide(self) -> float:
        """The largest horizontal travel (m) of a heel or toe while it touches the floor
        (:data:`TOUCH`) in one stance."""
        feet, worst = self.feet(), 0.0
        for side, a, b in self.stances():
            # a loop's stance across its ends: each part on its own (the file holds no
            # displacement from the last frame to the first)
            for part in ((a, b),) if a < b else ((a, len(feet)), (0, b)):
                for point in (0, 1):
                    run = feet[slice(*part), side, point]
                    touching = run[run[:, 2] <= TOUCH, :2]
                    if len(touching):
                        worst = max(worst, np.linalg.norm(touching - touching[0], axis=1).max())
        return float(worst)

    def penetration(self) -> float:
        """How far (m) a heel or toe goes below the floor at worst (0 if never)."""
        return float(max(0.0, -self.feet()[..., 2].min()))

    def hover(self) -> float:
        """The largest, over the stances, of the lowest height (m) the higher of heel and toe
        reaches in it: how far a flat foot stays above the floor."""
        higher = self.feet()[..., 2].max(axis=2)                              # (F, 2)
        frames = np.arange(len(higher))
        return float(max((higher[(frames >= a) & (frames < b) if a < b else
                                 (frames >= a) | (frames < b), side].min()
                          for side, a, b in self.stances()), default=np.inf))
