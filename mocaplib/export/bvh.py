"""BVH export of joint angles on the fixed skeleton, for animators (Blender opens BVH).

Coordinates and units
---------------------
BVH files are conventionally **Y up**; Blender's importer (defaults *Forward -Z, Up Y*) turns
them back into its Z-up world. We therefore write file coordinates
``(x_f, y_f, z_f) = (x, z, -y)`` of our world/segment coordinates ``(x, y, z)`` (X forward,
Y left, Z up): a proper rotation by -90° about X. Imported into Blender with its defaults, the
subject stands on Blender's floor facing +X exactly as in mocaplib. Lengths are metres by default
(Blender's default import scale 1 then gives true size); ``units="cm"`` writes centimetres.

Channels
--------
A BVH joint's rotation channels are Euler angles in degrees about the *file's* coordinate axes,
applied in the listed order as ``R = R_1 · R_2 · R_3`` (intrinsic), after the joint's OFFSET in
the parent frame: the same composition as :meth:`mocaplib.skeleton.Skeleton.forward`. Every
skeleton DOF turns about ±X, ±Y or ±Z of its segment; its axis maps through the change of
coordinates above to ±one file axis (X→X, Y→-Z, Z→Y), so each DOF becomes exactly one channel
whose value is ``sign · degrees(q)``. Joints with fewer than three DOFs get the remaining axes
as zero-valued channels (three rotation channels per joint suit every importer). The root has
``Xposition Yposition Zposition`` (the root's translation DOFs in file coordinates) first. Joint names are
:data:`mocaplib.skeleton.SEGMENT_NAMES`; end sites mark the vertex, the finger tips and the toes
(display only: the toe tip of :meth:`~mocaplib.skeleton.Skeleton.sole`, ahead of the ankle on
the sole).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import MocapError
from ..io.atomic import atomic_write_text
from ..skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS, SHIFTS, Skeleton

if TYPE_CHECKING:
    from ..model.motion import Motion

#: Our coordinates to BVH file coordinates (Y up): file = TO_FILE @ ours.
TO_FILE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
UNIT_SCALE = {"m": 1.0, "cm": 100.0}
_AXIS_NAMES = "XYZ"


def _file_axis(axis) -> tuple[int, float]:
    """(file axis index, sign) of a DOF axis that is ±X, ±Y or ±Z of our frames."""
    f = TO_FILE @ np.asarray(axis, dtype=float)
    j = int(np.argmax(np.abs(f)))
    return j, float(np.sign(f[j]))


def end_sites(skeleton: Skeleton) -> dict[str, tuple]:
    """The end segments' tips in their frames (m), for display: the top of the head, the
    finger tips, the toes (3/4 of the foot length ahead of the ankle, on the sole)."""
    L = skeleton.lengths
    hand = (0.0, 0.0, -(L["forearm"] + L["hand"]))
    toe = tuple(skeleton.sole()[1])
    return {"head": (0.0, 0.0, L["head_length"]), "forearm_r": hand, "forearm_l": hand,
            "foot_r": toe, "foot_l": toe}


def _channels() -> dict[str, list[tuple[str, int | None, float]]]:
    """Per segment: (channel name, DOF column or None for a zero channel, sign)."""
    out = {}
    for seg in SEGMENTS:
        chans: list[tuple[str, int | None, float]] = []
        used = set()
        for name in seg.dofs:
            j = DOF_NAMES.index(name)
            if DOFS[j].translation:
                continue
            axis, sign = _file_axis(DOFS[j].axis)
            used.add(axis)
            chans.append((f"{_AXIS_NAMES[axis]}rotation", j, sign))
        chans += [(f"{_AXIS_NAMES[k]}rotation", None, 1.0) for k in range(3) if k not in used]
        if seg.parent is None:
            pos = [(f"{_AXIS_NAMES[k]}position", None, 1.0) for k in range(3)]
            chans = pos + chans
        out[seg.name] = chans
    return out


def bvh_text(motion: "Motion", /, *, units: str = "m") -> str:
    """The BVH text of ``motion``'s joint coordinates (F, D) on its skeleton at its rate."""
    q, skeleton, rate = np.asarray(motion.q, dtype=float), motion.skeleton, motion.rate
    if not np.isfinite(q).all():
        raise MocapError("BVH export needs finite joint coordinates (no NaN)",
                         path=motion.source, hint="interpolate or drop the failed frames first")
    if units not in UNIT_SCALE:
        raise MocapError(f"unknown BVH units {units!r}; use 'm' or 'cm'")
    if not rate > 0:
        raise MocapError(f"BVH frame rate must be > 0 Hz, got {rate}", path=motion.source)
    scale = UNIT_SCALE[units]
    offsets = skeleton.joint_offsets()
    ends = end_sites(skeleton)
    channels = _channels()
    children = {s.name: [c.name for c in SEGMENTS if c.parent == s.name] for s in SEGMENTS}

    def vec(v) -> str:
        return " ".join(f"{x:.10g}" for x in TO_FILE @ np.asarray(v, float) * scale + 0.0)

    lines = ["HIERARCHY"]

    def emit(name: str, depth: int):
        pad = "  " * depth
        keyword = "ROOT" if depth == 0 else "JOINT"
        lines.append(f"{pad}{keyword} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {vec(offsets[SEGMENT_NAMES.index(name)])}")
        chans = channels[name]
        lines.append(f"{pad}  CHANNELS {len(chans)} {' '.join(c[0] for c in chans)}")
        for child in children[name]:
            emit(child, depth + 1)
        if name in ends:
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET {vec(ends[name])}", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    emit(SEGMENT_NAMES[0], 0)
    # Motion values: root position in file coordinates, then every channel in hierarchy order
    # (SEGMENTS is depth-first, parents before children, the order emit() writes them).
    columns = []
    root_pos = q[:, SHIFTS] @ np.asarray([DOFS[j].axis for j in SHIFTS]) @ TO_FILE.T * scale
    for seg in SEGMENTS:
        for k, (name, j, sign) in enumerate(channels[seg.name]):
            if name.endswith("position"):
                columns.append(root_pos[:, k])
            elif j is None:
                columns.append(np.zeros(len(q)))
            else:
                columns.append(sign * np.degrees(q[:, j]))
    values = np.column_stack(columns) + 0.0  # + 0.0 turns -0.0 into 0.0
    lines += ["MOTION", f"Frames: {len(q)}", f"Frame Time: {1.0 / rate:.10g}"]
    lines += [" ".join(f"{x:.10g}" for x in row) for row in values]
    return "\n".join(lines) + "\n"


def write_bvh(motion: "Motion", path: str | os.PathLike, /, *, units: str = "m") -> Path:
    """Write ``motion`` as a BVH file atomically; returns the path."""
    return atomic_write_text(path, bvh_text(motion, units=units))
