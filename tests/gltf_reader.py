"""An independent glTF 2.0 reader for the tests and benchmarks: pygltflib parses the file (a
library mocaplib does not write with) and numpy decodes its accessors and poses its node
hierarchy, as the specification lays them out."""

from __future__ import annotations

import numpy as np
import pygltflib

#: glTF file axes from ours, as the spec states them (Y up, the asset's front facing +Z,
#: right-handed, so +X is the subject's left): file X = our Y (left), file Y = our Z (up),
#: file Z = our X (forward).
OURS_FROM_FILE = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
COMPONENTS = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read_gltf(path):
    """The pygltflib document and a reader of its accessors: accessor index -> (count, n)
    float array, decoded from the buffer as the spec lays it out (bufferView offset + accessor
    offset, tightly packed little-endian float32)."""
    gltf = pygltflib.GLTF2().load(str(path))
    if gltf.buffers[0].uri:                          # .gltf: the buffer is a base64 data URI
        gltf.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
    blob = gltf.binary_blob()

    def accessor(index: int) -> np.ndarray:
        acc = gltf.accessors[index]
        view = gltf.bufferViews[acc.bufferView]
        assert acc.componentType == pygltflib.FLOAT and view.byteStride in (None, 0)
        n = COMPONENTS[acc.type]
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        return np.frombuffer(blob, "<f4", acc.count * n, start).reshape(acc.count, n)

    return gltf, blob, accessor


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) in glTF's x, y, z, w order."""
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def animated_positions(path):
    """Keyframe times (K,) and every node's world position (K, N, 3) in OUR axes, node names,
    from the glTF's node hierarchy (rest TRS) and its animation's channels."""
    gltf, _, accessor = read_gltf(path)
    animation = gltf.animations[0]
    times = accessor(animation.samplers[0].input)[:, 0]
    n_nodes = len(gltf.nodes)
    T = np.tile([n.translation or [0.0, 0.0, 0.0] for n in gltf.nodes], (len(times), 1, 1))
    R = np.tile([n.rotation or [0.0, 0.0, 0.0, 1.0] for n in gltf.nodes], (len(times), 1, 1))
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        np.testing.assert_array_equal(accessor(sampler.input)[:, 0], times)
        target = {"translation": T, "rotation": R}[channel.target.path]
        target[:, channel.target.node] = accessor(sampler.output)
    rotation = _quat_matrix(R.astype(np.float64))
    world_R = np.zeros((len(times), n_nodes, 3, 3))
    world_p = np.zeros((len(times), n_nodes, 3))
    stack = [(root, np.eye(3), np.zeros(3)) for root in gltf.scenes[gltf.scene].nodes]
    while stack:
        node, parent_R, parent_p = stack.pop()
        world_p[:, node] = parent_p + (parent_R @ T[:, node, :, None])[..., 0]
        world_R[:, node] = parent_R @ rotation[:, node]
        stack += [(c, world_R[:, node], world_p[:, node]) for c in gltf.nodes[node].children]
    return times, world_p @ OURS_FROM_FILE.T, [n.name for n in gltf.nodes]
