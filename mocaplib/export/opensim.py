"""OpenSim exports: the calibrated model (.osim), markers (.trc) and joint angles (.mot).

The .osim reproduces :mod:`mocaplib.skeleton` exactly, so OpenSim's marker positions for our q
equal ours and OpenSim's InverseKinematicsTool solves the very problem :func:`mocaplib.model.ik.fit`
solves (without the robust loss and continuity term):

- one body per segment, named as in :data:`~mocaplib.skeleton.SEGMENT_NAMES`, with its frame
  at the joint centre (X forward, Y left, Z up in the neutral pose);
- one ``CustomJoint`` per segment: its parent frame offset by the segment's joint offset, its
  ``SpatialTransform`` rotations the segment's DOFs in order about the same signed axes
  (body-fixed, as ours), unused rotation axes held at 0, the pelvis translations along the
  ground axes; coordinates named as our DOFs, with our ranges (clamped) and locked DOFs locked;
- one marker per model marker, on its segment at its calibrated offset, named by its label
  with the characters OpenSim refuses in a name (spaces, tabs, ``\\ / * +``) written ``_``
  (:func:`opensim_name`; BTS labels such as ``l should``), in the .trc as in the .osim.

Each body's mass, centre of mass and inertia about it (in the body frame, products of inertia
included) are de Leva's for the subject's segment lengths and body mass
(:func:`mocaplib.model.anthropometry.segment_inertias`; the trunk's lower part on the pelvis, the
hand on the forearm), so the bodies add up to the subject's mass and the model serves inverse
dynamics as well as inverse kinematics. World Z is up, so gravity is (0, 0, -g). Writing needs no OpenSim installation; files are
written atomically. Units: the .osim and .mot in metres, the .trc in millimetres, the .mot
angles in degrees (``inDegrees=yes``), as OpenSim expects.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import TYPE_CHECKING
from xml.etree import ElementTree as ET

import numpy as np

from ..errors import MocapError
from ..io.atomic import atomic_write_text
from ..model.anthropometry import DEFAULT_BODY_MASS, segment_inertias
from ..skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS, TRANSLATION

if TYPE_CHECKING:
    from ..model.motion import Motion
    from ..model.subject import SubjectModel
    from ..trial import Trial

#: Rotation ranges without a finite bound (the heading) are written as ± this, radians.
_OPEN_RANGE = 4 * np.pi


#: Characters OpenSim refuses in a component's name.
_NOT_IN_NAMES = re.compile(r"[\\/*+\s]")


def opensim_name(label: str) -> str:
    """``label`` as an OpenSim marker name: the characters OpenSim refuses written ``_``."""
    return _NOT_IN_NAMES.sub("_", label)


def _fmt(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib) -> ET.Element:
    element = ET.SubElement(parent, tag, attrib)
    if text is not None:
        element.text = text
    return element


def osim_text(model: "SubjectModel", /, *, body_mass: float = DEFAULT_BODY_MASS,
              name: str = "mocaplib") -> str:
    """The model of a subject of ``body_mass`` kg as OpenSim 4 XML (module docstring)."""
    if not (np.isfinite(body_mass) and body_mass > 0):
        raise MocapError(f"the body mass must be > 0 kg, got {body_mass}",
                         hint="give the subject's mass in kilograms")
    joints = model.skeleton.joint_offsets()
    inertia = segment_inertias(model.skeleton)
    doc = ET.Element("OpenSimDocument", Version="40000")
    root = _sub(doc, "Model", name=name)
    _sub(root, "gravity", "0 0 -9.80665")
    _sub(root, "length_units", "meters")
    _sub(root, "force_units", "N")
    _sub(_sub(root, "ground"), "Ground", name="ground")
    bodies = _sub(_sub(root, "BodySet", name="bodyset"), "objects")
    for s, seg in enumerate(SEGMENT_NAMES):
        body = _sub(bodies, "Body", name=seg)
        tensor = body_mass * inertia.inertia[s]
        _sub(body, "mass", repr(float(body_mass * inertia.mass[s])))
        _sub(body, "mass_center", _fmt(inertia.com[s]))
        _sub(body, "inertia", _fmt([tensor[0, 0], tensor[1, 1], tensor[2, 2],
                                    tensor[0, 1], tensor[0, 2], tensor[1, 2]]))
    joint_set = _sub(_sub(root, "JointSet", name="jointset"), "objects")
    for s, seg in enumerate(SEGMENTS):
        _joint(joint_set, seg, joints[s], set(model.locked_dofs))
    markers = _sub(_sub(root, "MarkerSet", name="markerset"), "objects")
    for label, s, offset in zip(model.labels, model.marker_segments, model.marker_offsets):
        marker = _sub(markers, "Marker", name=opensim_name(label))
        _sub(marker, "socket_parent_frame", f"/bodyset/{SEGMENT_NAMES[s]}")
        _sub(marker, "location", _fmt(offset))
        _sub(marker, "fixed", "false")
    ET.indent(doc)
    return '<?xml version="1.0" encoding="UTF-8" ?>\n' + ET.tostring(doc, encoding="unicode") + "\n"


def _joint(joint_set: ET.Element, seg, offset: np.ndarray, locked: set[str]) -> None:
    parent = seg.parent or "ground"
    parent_path = "/ground" if seg.parent is None else f"/bodyset/{seg.parent}"
    joint = _sub(joint_set, "CustomJoint", name=f"{parent}_{seg.name}")
    _sub(joint, "socket_parent_frame", f"{parent}_offset")
    _sub(joint, "socket_child_frame", f"{seg.name}_offset")
    coords = _sub(joint, "coordinates")
    for dof_name in seg.dofs:
        dof = DOFS[DOF_NAMES.index(dof_name)]
        lo = dof.lower if np.isfinite(dof.lower) else -_OPEN_RANGE
        hi = dof.upper if np.isfinite(dof.upper) else _OPEN_RANGE
        c = _sub(coords, "Coordinate", name=dof_name)
        _sub(c, "default_value", "0")
        _sub(c, "range", _fmt([lo, hi]))
        _sub(c, "clamped", "true" if np.isfinite(dof.lower) and not dof.translation else "false")
        _sub(c, "locked", "true" if dof_name in locked else "false")
    frames = _sub(joint, "frames")
    for frame_name, socket, translation in ((f"{parent}_offset", parent_path, offset),
                                            (f"{seg.name}_offset", f"/bodyset/{seg.name}",
                                             np.zeros(3))):
        frame = _sub(frames, "PhysicalOffsetFrame", name=frame_name)
        _sub(frame, "socket_parent", socket)
        _sub(frame, "translation", _fmt(translation))
        _sub(frame, "orientation", "0 0 0")
    transform = _sub(joint, "SpatialTransform")
    rotations = [d for d in seg.dofs if not DOFS[DOF_NAMES.index(d)].translation]
    translations = [d for d in seg.dofs if DOFS[DOF_NAMES.index(d)].translation]
    rot_axes = [np.asarray(DOFS[DOF_NAMES.index(d)].axis) for d in rotations]
    for spare in np.eye(3):                          # unused axes: independent, held at 0
        if len(rot_axes) < 3 and all(abs(spare @ a) < 0.5 for a in rot_axes):
            rot_axes.append(spare)
    for k in range(3):
        _transform_axis(transform, f"rotation{k + 1}", rotations[k] if k < len(rotations) else None,
                        rot_axes[k])
    for k in range(3):
        name = translations[k] if k < len(translations) else None
        axis = DOFS[DOF_NAMES.index(name)].axis if name else np.eye(3)[k]
        _transform_axis(transform, f"translation{k + 1}", name, axis)


def _transform_axis(transform: ET.Element, name: str, coordinate: str | None, axis) -> None:
    element = _sub(transform, "TransformAxis", name=name)
    _sub(element, "coordinates", coordinate or "")
    _sub(element, "axis", _fmt(axis))
    if coordinate:
        function = _sub(element, "LinearFunction", name="function")
        _sub(function, "coefficients", "1 0")
    else:
        function = _sub(element, "Constant", name="function")
        _sub(function, "value", "0")


def write_osim(model: "SubjectModel", path: str | os.PathLike, /, *,
               body_mass: float = DEFAULT_BODY_MASS, name: str = "mocaplib") -> Path:
    """Write the calibrated model of a subject of ``body_mass`` kg as an OpenSim .osim file
    (atomically). Returns the path."""
    return atomic_write_text(path, osim_text(model, body_mass=body_mass, name=name))


def write_trc(trial: "Trial", path: str | os.PathLike, /) -> Path:
    """Write ``trial``'s markers (F, M, 3), metres, as an OpenSim .trc in millimetres, named by
    its labels at its rate; NaN stays NaN."""
    markers, labels, rate = np.asarray(trial.markers, dtype=np.float64), trial.labels, trial.rate
    n_frames, n_markers = markers.shape[:2]
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{os.path.basename(os.fspath(path))}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate:g}\t{rate:g}\t{n_frames}\t{n_markers}\tmm\t{rate:g}\t1\t{n_frames}",
        "Frame#\tTime\t" + "\t\t\t".join(map(opensim_name, labels)),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, n_markers + 1)),
        "",
    ]
    mm = markers.reshape(n_frames, -1) * 1000.0
    for f in range(n_frames):
        values = "\t".join("NaN" if not np.isfinite(v) else f"{v:.6f}" for v in mm[f])
        lines.append(f"{f + 1}\t{f / rate:.6f}\t{values}")
    return atomic_write_text(path, "\n".join(lines) + "\n")


def write_mot(motion: "Motion", path: str | os.PathLike, /) -> Path:
    """Write joint angles as an OpenSim .mot: time, then one column per DOF, angles in degrees."""
    q = motion.q.copy()
    q[:, ~TRANSLATION] = np.degrees(q[:, ~TRANSLATION])
    header = [os.path.basename(os.fspath(path)), "version=1", f"nRows={len(q)}",
              f"nColumns={len(DOF_NAMES) + 1}", "inDegrees=yes", "endheader",
              "time\t" + "\t".join(DOF_NAMES)]
    rows = ["\t".join([f"{t:.6f}"] + [f"{v:.8f}" for v in row]) for t, row in zip(motion.time, q)]
    return atomic_write_text(path, "\n".join(header + rows) + "\n")
