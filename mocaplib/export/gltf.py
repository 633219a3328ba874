"""glTF 2.0 export of a motion, for game engines (Unity, Unreal, Godot, three.js, Blender).

Coordinates and units
---------------------
glTF is **Y up**, right-handed, the front of an asset facing **+Z**, lengths in metres. Our world
and segment frames are X forward, Y left, Z up, so file coordinates are
``(x_f, y_f, z_f) = (y, z, x)`` (:data:`TO_FILE`, a proper rotation): the subject stands on the
engine's floor (the XZ plane) facing +Z, its left towards +X.

Content
-------
- One node per skeleton segment, named as in :data:`~mocaplib.skeleton.SEGMENT_NAMES`,
  children under their parents; a node's rest translation is its joint centre in the parent's
  frame (:meth:`~mocaplib.skeleton.Skeleton.joint_offsets`), its rest rotation the
  identity (the neutral pose, every DOF 0; the root node stands the pelvis at ``hip_height``).
  Leaf nodes ``<segment>_end`` mark the top of the head, the finger tips and the toes
  (:func:`mocaplib.export.bvh.end_sites`), so that importers can draw the last bones.
- One skin listing every node as a joint, with its inverse bind matrices (the rest pose), so
  that engines import the hierarchy as a skeleton.
- One animation: per segment a ``rotation`` channel (unit quaternions ``x, y, z, w``, the
  segment's rotation in its parent's frame: its joint's DOFs composed, consecutive keys on the
  same hemisphere) and for the root a ``translation`` channel; keyframe times ``k / rate`` s,
  sampler interpolation ``LINEAR``. The rotations come from
  :meth:`~mocaplib.skeleton.Skeleton.forward`, so every DOF of the skeleton is in them.

Binary data are little-endian float32, one buffer view per accessor, every accessor with its
``min`` and ``max``. :func:`write_glb` writes the binary container (``.glb``), :func:`write_gltf`
JSON with the buffer embedded as a base64 data URI (``.gltf``). Files are written atomically.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import MocapError
from ..io.atomic import atomic_write_bytes
from ..skeleton import SEGMENT_NAMES, SEGMENTS
from .bvh import end_sites

if TYPE_CHECKING:
    from ..model.motion import Motion

#: Our coordinates to glTF file coordinates (Y up, +Z forward): file = TO_FILE @ ours.
TO_FILE = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
#: glTF's componentType FLOAT and the accessor types by component count.
_FLOAT = 5126
_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}
#: GLB chunk types and header magic.
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


class _Buffer:
    """The binary buffer under construction: float32 arrays, each in its own 4-byte aligned
    buffer view with one accessor."""

    def __init__(self):
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, values: np.ndarray, components: int) -> int:
        """Append ``values`` (N, components) or (N,) as float32; returns the accessor index."""
        array = np.ascontiguousarray(values, dtype="<f4").reshape(-1, components)
        self.data += b"\0" * (-len(self.data) % 4)
        self.views.append({"buffer": 0, "byteOffset": len(self.data),
                           "byteLength": array.nbytes})
        self.data += array.tobytes()
        self.accessors.append({"bufferView": len(self.views) - 1, "componentType": _FLOAT,
                               "count": len(array), "type": _TYPES[components],
                               "min": array.min(axis=0).astype(float).tolist(),
                               "max": array.max(axis=0).astype(float).tolist()})
        return len(self.accessors) - 1


def _rotation_keys(transforms: np.ndarray) -> np.ndarray:
    """Each segment's rotation in its parent's frame as glTF quaternions (F, S, 4) ``x y z w``
    in file coordinates, from segment-to-world transforms (F, S, 4, 4); consecutive keys of a
    segment on the same hemisphere (q and -q are one rotation; LINEAR keys interpolate along
    the shorter arc)."""
    R = transforms[..., :3, :3]
    local = R.copy()
    for s, seg in enumerate(SEGMENTS):
        if seg.parent is not None:
            local[:, s] = np.swapaxes(R[:, SEGMENT_NAMES.index(seg.parent)], -1, -2) @ R[:, s]
    in_file = TO_FILE @ local @ TO_FILE.T
    quat = Rotation.from_matrix(in_file.reshape(-1, 3, 3)).as_quat().reshape(*R.shape[:2], 4)
    turn = np.sign(np.sum(quat[1:] * quat[:-1], axis=-1))
    turn[turn == 0] = 1.0
    flips = np.concatenate([np.ones((1, quat.shape[1])), np.cumprod(turn, axis=0)])
    return quat * flips[..., None]


def gltf_document(motion: "Motion", /) -> tuple[dict, bytes]:
    """The glTF JSON (without the buffer's ``uri``) and its binary buffer for ``motion``'s
    joint coordinates (F, D) on its skeleton at its rate (module docstring)."""
    q = np.asarray(motion.q, dtype=float)
    if not np.isfinite(q).all():
        raise MocapError("glTF export needs finite joint coordinates (no NaN)",
                         path=motion.source, hint="interpolate or drop the failed frames first")
    if not (np.isfinite(motion.rate) and motion.rate > 0):
        raise MocapError(f"glTF frame rate must be > 0 Hz, got {motion.rate}", path=motion.source)
    skeleton = motion.skeleton
    transforms = skeleton.forward(q)
    offsets = skeleton.joint_offsets()
    root = SEGMENT_NAMES.index(next(s.name for s in SEGMENTS if s.parent is None))
    offsets[root] = (0.0, 0.0, skeleton.lengths["hip_height"])
    ends = end_sites(skeleton)
    nodes = [{"name": name, "translation": (TO_FILE @ offsets[s]).tolist()}
             for s, name in enumerate(SEGMENT_NAMES)]
    for seg in SEGMENTS:
        children = [SEGMENT_NAMES.index(c.name) for c in SEGMENTS if c.parent == seg.name]
        if seg.name in ends:
            children.append(len(nodes))
            nodes.append({"name": f"{seg.name}_end",
                          "translation": (TO_FILE @ np.asarray(ends[seg.name])).tolist()})
        if children:
            nodes[SEGMENT_NAMES.index(seg.name)]["children"] = children
    buffer = _Buffer()
    bind = np.tile(np.eye(4), (len(nodes), 1, 1))
    bind[:, :3, 3] = -_rest_positions(nodes, root)
    skin = {"name": "skeleton", "joints": list(range(len(nodes))), "skeleton": root,
            "inverseBindMatrices": buffer.add(bind.transpose(0, 2, 1).reshape(-1, 16), 16)}
    times = buffer.add(motion.time, 1)
    samplers, channels = [], []
    rotations = _rotation_keys(transforms)
    for s in range(len(SEGMENT_NAMES)):
        samplers.append({"input": times, "output": buffer.add(rotations[:, s], 4),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": s, "path": "rotation"}})
    samplers.append({"input": times, "interpolation": "LINEAR",
                     "output": buffer.add(transforms[:, root, :3, 3] @ TO_FILE.T, 3)})
    channels.append({"sampler": len(samplers) - 1,
                     "target": {"node": root, "path": "translation"}})
    document = {
        "asset": {"version": "2.0", "generator": "mocaplib"},
        "scene": 0, "scenes": [{"nodes": [root]}], "nodes": nodes, "skins": [skin],
        "animations": [{"name": Path(motion.source).stem if motion.source else "motion",
                        "samplers": samplers, "channels": channels}],
        "accessors": buffer.accessors, "bufferViews": buffer.views,
        "buffers": [{"byteLength": len(buffer.data)}],
    }
    return document, bytes(buffer.data)


def _rest_positions(nodes: list[dict], root: int) -> np.ndarray:
    """Each node's position (N, 3) in the scene in the rest pose (rotations all identity)."""
    out = np.zeros((len(nodes), 3))
    stack = [(root, np.zeros(3))]
    while stack:
        index, parent = stack.pop()
        out[index] = parent + nodes[index]["translation"]
        stack += [(child, out[index]) for child in nodes[index].get("children", [])]
    return out


def glb_bytes(document: dict, data: bytes) -> bytes:
    """The GLB container (glTF 2.0 binary) of a document and its buffer."""
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    data = data + b"\0" * (-len(data) % 4)
    length = 12 + 8 + len(text) + 8 + len(data)
    return (struct.pack("<III", _GLB_MAGIC, 2, length)
            + struct.pack("<II", len(text), _JSON_CHUNK) + text
            + struct.pack("<II", len(data), _BIN_CHUNK) + data)


def write_gltf(motion: "Motion", path: str | os.PathLike, /) -> Path:
    """Write ``motion`` as glTF 2.0 JSON with its buffer embedded (base64), atomically;
    returns the path."""
    document, data = gltf_document(motion)
    document["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                     + base64.b64encode(data).decode("ascii"))
    return atomic_write_bytes(path, json.dumps(document, indent=1).encode())


def write_glb(motion: "Motion", path: str | os.PathLike, /) -> Path:
    """Write ``motion`` as a glTF 2.0 binary container (.glb), atomically; returns the path."""
    return atomic_write_bytes(path, glb_bytes(*gltf_document(motion)))
