"""Left-right mirror images of fitted motions and of library entries.

The mirror is the reflection ``M = diag(1, -1, 1)``, y → −y: in the world frame of a capture
for a whole fitted motion, in the path frame for a library entry's encoded channels (the
entry's root channels are stored in that frame; a reflection of the world about a vertical
plane is this one followed by a rigid motion, which the path frame takes out).

Mirror map of the DOFs (derived, never tabulated)
-------------------------------------------------
Reflecting a posed body gives the pose of the reflected body, whose segment ``foot_l`` is the
image of ``foot_r``: each DOF ``k`` takes the value of its partner ``p(k)`` (``…_l`` ↔ ``…_r``,
itself for the root, trunk and neck), times a sign. Conjugating a rotation by a reflection turns
it about the *axial* image of its axis, ``M R(a, q) M = R(det(M)·M a, q) = R(−M a, q)``, and
moves a translation along ``M a``; so, with ``a_j`` the world axis of DOF ``j`` in the neutral
pose (:meth:`mocaplib.skeleton.Skeleton.chain` at q = 0: the DOF definitions of
:mod:`mocaplib.skeleton`, their ``_sided`` axes included),

    sign_k = (−M a_p(k)) · a_k  for a rotation,    (M a_p(k)) · a_k  for a translation.

The map needs a mirror-symmetric skeleton: every image axis ±1 times its partner's, and every
joint centre the image of its partner's (checked when this module is imported:
:class:`~mocaplib.errors.MocapError` otherwise). Because a joint's DOFs are applied one after
the other, each factor mirrors alone, so the map is exact for any pose;
``tests/test_mirror.py`` checks forward kinematics of mirrored poses against reflected
segment frames. Applied twice the map is the identity.

Mirror of a library entry (``mocaplib mirror``)
-----------------------------------------------
A library entry's cycle starts at a left toe-off; its mirror image starts at a right toe-off,
so :func:`mirror_entry` shifts the series in time by the entry's ``right_toe_off_s`` (τ): the
mirrored cycle runs from the source's right toe-off to the next one, which the reflection turns
into left toe-offs. The shift and the re-anchoring of the root channels are
:func:`mocaplib.library.phase.shifted_series`'s (an entry whose cycle starts at another event,
``cycle_start``, is first expressed from its left toe-off: :func:`mocaplib.library.phase.from_left_toe_off`).
Then the DOF map reflects every channel, and ω̂, v̂_l,
the drift's u_l and ω and the pattern (in the capture's world frame: y → −y) change sign.
Mirroring the result again (τ' = T − τ) gives the source back exactly (a ``cycle_start``
entry: the source from its left toe-off).
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import MocapError
from ..io import read_regular
from ..io.atomic import atomic_write_files
from ..io.jsonvalues import parse_json
from ..skeleton import DOF_NAMES, DOFS, SEGMENT_NAMES, SEGMENTS, Skeleton, partner_name
from .controlspace import CLOSE_DISTANCE
from .document import CHECKSUM_KEY
from .entry import EntryDrift, EntryFourier
from .format import (Library, control_scale, diagnostics_path, json_text, to_json_data,
                     with_tetrahedra)
from .phase import from_left_toe_off, shifted_poulaine, shifted_series

#: The reflection of the mirror: y -> -y (3, 3).
REFLECTION = np.diag([1.0, -1.0, 1.0])
#: A mirror image closer than this to its source in the control space (normalised distance:
#: :data:`mocaplib.library.controlspace.CLOSE_DISTANCE`, entries too close to tell apart) is left out:
#: the cycle is its own mirror image (straight walks, runs, rest), and the twin would only make
#: sliver tetrahedra.
SYMMETRIC_DISTANCE = CLOSE_DISTANCE


def _dof_mirror() -> tuple[np.ndarray, np.ndarray]:
    """(index, sign), each (D,): DOF k of a mirrored pose is ``sign[k] * q[index[k]]``
    (module docstring). Raises MocapError when the skeleton is not mirror-symmetric."""
    skeleton = Skeleton.from_height(1.75)
    _, axes, _ = skeleton.chain(np.zeros(len(DOFS)))
    axes = axes[0]
    offsets = skeleton.joint_offsets()
    for s, segment in enumerate(SEGMENTS):
        other = partner_name(segment.name)
        if other not in SEGMENT_NAMES:
            raise MocapError(f"skeleton segment {segment.name} has no mirror partner {other}")
        if not np.allclose(REFLECTION @ offsets[s], offsets[SEGMENT_NAMES.index(other)],
                           atol=1e-12):
            raise MocapError(f"skeleton segment {other}'s joint centre is not the mirror image "
                             f"of {segment.name}'s: the skeleton is not mirror-symmetric")
    index, sign = np.zeros(len(DOFS), dtype=int), np.zeros(len(DOFS))
    for k, dof in enumerate(DOFS):
        partner = partner_name(dof.name)
        if partner not in DOF_NAMES:
            raise MocapError(f"skeleton DOF {dof.name} has no mirror partner {partner}")
        p = DOF_NAMES.index(partner)
        if partner_name(DOFS[p].segment) != dof.segment:
            raise MocapError(f"skeleton DOFs {dof.name} and {partner} move segments that are "
                             "not mirror partners")
        image = REFLECTION @ axes[p] * (1.0 if dof.translation else -1.0)
        index[k], sign[k] = p, image @ axes[k]
        if not abs(abs(sign[k]) - 1.0) < 1e-12:
            raise MocapError(f"skeleton DOF {dof.name}'s axis is not ± the mirror image of "
                             f"{partner}'s: the skeleton is not mirror-symmetric")
    return index, np.sign(sign)


#: ``MIRROR_INDEX[k]``, ``MIRROR_SIGN[k]``: DOF k of a mirrored pose is
#: ``MIRROR_SIGN[k] * q[MIRROR_INDEX[k]]`` (each (D,); derived by :func:`_dof_mirror`).
MIRROR_INDEX, MIRROR_SIGN = _dof_mirror()


def mirror_dofs(values: np.ndarray, /, *, axis: int = -1) -> np.ndarray:
    """Mirror image of DOF values laid out along ``axis`` (length D, :data:`DOF_NAMES`
    order): poses (F, D) with ``axis=-1``, Fourier coefficients (D, N+1) with ``axis=0``."""
    values = np.asarray(values, dtype=np.float64)
    shape = [1] * values.ndim
    shape[axis] = len(MIRROR_SIGN)
    return np.take(values, MIRROR_INDEX, axis=axis) * MIRROR_SIGN.reshape(shape)


def mirror_motion(motion, /):
    """The mirror image (world y → −y) of a fitted :class:`~mocaplib.model.motion.Motion`: joint
    coordinates mirrored by :func:`mirror_dofs`, the same skeleton (its lengths serve both
    sides), residuals, failed and rejected frames kept (QC reads them per frame), locked DOFs
    renamed to their partners. The marker model is not mirrored (``marker_segments`` and
    ``marker_offsets`` are None)."""
    return replace(motion, q=mirror_dofs(motion.q), skeleton=mirror_skeleton(motion.skeleton),
                   marker_segments=None, marker_offsets=None,
                   locked_dofs=[partner_name(name) for name in motion.locked_dofs],
                   unobservable=mirror_names(motion.unobservable), repairs=[])


def mirror_skeleton(skeleton: Skeleton, /) -> Skeleton:
    """The mirror-image subject: the same lengths (they serve both sides), each joint shift
    moved to the partner segment with its y negated."""
    return Skeleton(skeleton.lengths, mirror_shifts(skeleton.shifts))


def mirror_shifts(shifts: dict, /) -> dict:
    """Joint shifts (segment -> [x, y, z], m) of the mirror image."""
    return {partner_name(name): [x, -y, z] for name, (x, y, z) in shifts.items()}


def mirror_names(values: dict, /) -> dict:
    """A mapping keyed by DOF or segment names with the keys of the mirror image."""
    return {partner_name(name): value for name, value in values.items()}


def mirror_events(events, /) -> list:
    """Gait events of the mirror image: the same times, left and right exchanged."""
    other = {"left": "right", "right": "left"}
    return [replace(event, side=other[event.side]) for event in events]


def mirror_pattern(pattern, /):
    """A pattern as the library stores it (:class:`mocaplib.library.entry.EntryPattern`) reflected
    y → −y: points, centres and directions reflected, an arc's ``turn`` and ``arc_angle_rad``
    negated; lengths, radii and residuals kept."""
    params = dict(pattern.parameters)
    for key in ("point", "centre", "direction"):
        if key in params:
            x, y = params[key]
            params[key] = [x, -y]
    if "turn" in params:
        params["turn"] = -params["turn"]
    angle = pattern.arc_angle_rad
    return replace(pattern, parameters=params, arc_angle_rad=None if angle is None else -angle)


#: An entry id ``<stem>_c<k>`` (+ ``@<sha>``): the stem, the cycle part and the suffix.
_CYCLE_ID = re.compile(r"^(?P<stem>.*)(?P<cycle>_c\d+)(?P<sha>@[0-9a-f]+)?$")
#: What a mirrored entry's id adds to its source's stem.
MIRROR_TAG = "_mirror"


def mirror_id(entry_id: str, /) -> str:
    """The id of an entry's mirror image: ``<stem>_mirror_c<k>`` for ``<stem>_c<k>`` (the
    ``@<sha>`` suffix kept), an id without ``_c<k>`` gets ``_mirror`` at its end; the tag is
    taken off again for an id that has it, so ``mirror_id(mirror_id(x)) == x``."""
    found = _CYCLE_ID.match(entry_id)
    stem, tail = (found["stem"], found["cycle"] + (found["sha"] or "")) if found else (entry_id, "")
    stem = stem[:-len(MIRROR_TAG)] if stem.endswith(MIRROR_TAG) else stem + MIRROR_TAG
    return stem + tail


# --------------------------------------------------------------------------- library entries
def mirror_entry(entry, /):
    """The mirror image of a :class:`~mocaplib.library.entry.LibraryEntry` (Fourier rows in
    :data:`DOF_NAMES` order), from its stored series: the module docstring says how. Its id is
    :func:`mirror_id`'s, ``mirror_of`` the entry's id, ``mirror_method`` ``"series"``; its
    cycle starts at the entry's right toe-off (``start_s + right_toe_off_s``, and
    ``right_toe_off_s`` becomes ``T - right_toe_off_s``); the QC metrics are the entry's. The
    image of such an image is its source again (its window is the source's: ``start_s`` moves
    back). Values are not rounded (the library's writer rounds them).

    Raises :class:`MocapError` for an entry without ``right_toe_off_s`` (a library written
    before entries recorded it, or a cycle whose right toe-off was not detected): there is no
    start for its mirror image.
    """

    entry = from_left_toe_off(entry)
    if entry.right_toe_off_s is None:
        raise MocapError(f"entry {entry.id} does not record its right toe-off "
                         "(right_toe_off_s), where its mirror image would start",
                         hint="build the library again (entries record it now), or build it "
                              "with --mirror, which cuts mirror images from the captures")
    period, tau = float(entry.T), float(entry.right_toe_off_s)
    # the series from the right toe-off on, re-anchored (mocaplib.library.phase)
    a, b, u_f, u_l = shifted_series(entry, tau)
    omega = float(entry.root_drift.omega_rad_s)
    start = float(entry.start_s) + tau - (period if _series_image(entry) else 0.0)
    ramp = entry.fourier.ramp
    return replace(
        entry, id=mirror_id(entry.id), start_s=start, end_s=start + period,
        right_toe_off_s=period - tau, pattern=mirror_pattern(entry.pattern),
        omega=-entry.omega, v_l=-entry.v_l,
        mirror_of=None if _series_image(entry) else entry.id,
        mirror_method=None if _series_image(entry) else "series",
        fourier=EntryFourier(entry.fourier.n, mirror_dofs(a, axis=0), mirror_dofs(b, axis=0),
                             None if ramp is None else mirror_dofs(ramp)),
        joint_shifts_m=mirror_shifts(entry.joint_shifts_m),
        held_dofs=mirror_names(entry.held_dofs), dofs_at_limit=mirror_names(entry.dofs_at_limit),
        poulaine=None if entry.poulaine is None else shifted_poulaine(
            entry.poulaine, tau / period, reflect=True),
        root_drift=EntryDrift.moving(u_f, -u_l, -omega, period))


def _series_image(entry) -> bool:
    return entry.mirror_method == "series"


def image_distance(source, image, /, *, scale=None) -> float:
    """Normalised control-space distance between a library entry's velocities (v, ω, v_l)
    and its mirror image's (each (3,), e.g. :attr:`mocaplib.library.entry.LibraryEntry.velocity`);
    ``scale``: the control space's (3,), :func:`mocaplib.library.format.control_scale` by default."""

    difference = np.asarray(source, dtype=np.float64) - np.asarray(image, dtype=np.float64)
    return float(np.linalg.norm(difference / np.asarray(control_scale() if scale is None
                                                        else scale)))


def mirror_library(library, /):
    """The library with the mirror image (:func:`mirror_entry`) of every entry added.

    Left out: entries that are mirror images, or have one in the library; entries whose image
    would lie within :data:`SYMMETRIC_DISTANCE` of them in the control space (reflected
    velocities: straight walks, runs, rest). The header (settings, skeleton, scales) is kept.

    Parameters
    ----------
    library : Library
        The library to mirror (not modified).

    Returns
    -------
    library : Library
        The entries and their added images.
    notes : list of str
        What was not added, and why, one sentence each.

    Raises
    ------
    MocapError
        Entries without ``right_toe_off_s`` (named; nothing is added then), or an image whose
        id another entry has.
    """

    if library.dof_names != list(DOF_NAMES):
        raise MocapError("the library's DOFs are not this mocaplib's skeleton's: its entries "
                         "cannot be mirrored with this version",
                         hint="mirror it with the mocaplib version that wrote it")
    entries = library.entries
    ids = {e.id for e in entries}
    imaged = {e.mirror_of for e in entries if e.mirrored}
    todo, notes = [], []
    for entry in entries:
        if entry.mirrored or entry.id in imaged:
            continue
        distance = image_distance(entry.velocity, (entry.v, -entry.omega, -entry.v_l),
                                  scale=library.control_scale)
        if distance < SYMMETRIC_DISTANCE:
            notes.append(f"{entry.id}: its mirror image would lie {distance:.3f} "
                         f"(normalised) from it, within {SYMMETRIC_DISTANCE}: left out")
        else:
            todo.append(entry)
    missing = [e.id for e in todo if e.right_toe_off_s is None]
    if missing:
        raise MocapError(f"{len(missing)} entries do not record their right toe-off "
                         f"(right_toe_off_s), where their mirror image would start: "
                         f"{', '.join(missing[:5])}{' …' if len(missing) > 5 else ''}",
                         hint="build the library again (entries record it now), or build it "
                              "with --mirror, which cuts mirror images from the captures")
    images = [mirror_entry(entry) for entry in todo]
    taken = sorted(ids & {image.id for image in images})
    if taken:
        raise MocapError(f"the mirror image of an entry would take the id {taken[0]}, which "
                         "another entry has", hint="rename that entry's capture")

    # new content: the source's checksum goes (writing the library computes its own)
    document = {**{k: v for k, v in library.document.items() if k != CHECKSUM_KEY},
                "entries": [e.to_json() for e in sorted(entries + images, key=lambda e: e.id)]}
    return Library(with_tetrahedra(to_json_data(document))), notes


def write_mirrored(library, library_path, out_path, /) -> tuple:
    """Write the mirrored ``library`` to ``out_path`` with a copy of ``library_path``'s
    diagnostics sidecar beside it, as one unit (as ``build`` writes a library and its
    sidecar: temporaries first, the sidecar renamed last, naming the new library's name and
    SHA-256). The sidecar is copied only when it belongs to ``library_path``: it names the
    SHA-256 of that file's bytes (``library_sha256``); one that names another library, or
    none, was written by another build and is left behind, never passed off as the mirrored
    library's. Returns ``(sidecar path or None, note or None)``, the note saying why a sidecar
    there was not copied. The series images :func:`mirror_library` adds have no capture
    record: the report knows them by their ``mirror_method``."""
    import hashlib      # here, where hashes are taken: OpenSSL's start-up is 3 ms

    text = library.to_json().encode("utf-8")
    files = [(Path(out_path), text)]
    source = diagnostics_path(library_path)
    note = None
    if os.path.lexists(source):
        try:
            data = parse_json(read_regular(source).decode("utf-8"))
            own = hashlib.sha256(read_regular(library_path)).hexdigest()
        except (OSError, ValueError) as exc:
            raise MocapError(f"cannot read the diagnostics sidecar: {exc}", path=source,
                             hint="move it away to mirror the library without it") from None
        if not isinstance(data, dict):
            raise MocapError("not a diagnostics sidecar", path=source,
                             hint="move it away to mirror the library without it")
        if data.get("library_sha256") != own:
            named = str(data.get("library_sha256"))[:12]
            note = (f"{source.name} was not copied: it does not belong to "
                    f"{Path(library_path).name} (it names the library whose SHA-256 is "
                    f"{named}…, this file's is {own[:12]}…); the mirrored library has no "
                    "sidecar")
        else:
            data.update(library=Path(out_path).name,
                        library_sha256=hashlib.sha256(text).hexdigest())
            files.append((diagnostics_path(out_path), json_text(data).encode("utf-8")))
    atomic_write_files(files)
    return (files[1][0] if len(files) > 1 else None), note