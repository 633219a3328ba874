"""Read the markers and force plates of a C3D file into a :class:`~mocaplib.trial.Trial`
(metres, Z up, NaN = missing).

What :func:`read_c3d` does
    * Header and parameters: :mod:`mocaplib.io.c3d_params` (any processor format; real-world
      files the ``c3d`` package refuses are read). The point layout is validated against the
      file size (:mod:`mocaplib.io.c3d_layout`); the POINT words are decoded by
      :mod:`mocaplib.io.c3d_points` (integer or float storage, missing samples as NaN).
    * Labels from POINT:LABELS, LABELS2, LABELS3... (files with more than 255 points), NULs and
      padding stripped; duplicate labels are kept, distinct, and named in ``Trial.warnings``,
      as are the subject prefixes of a file whose labels name several (``A:LASI``, ``B:LASI``).
    * Points the file itself declares as model outputs (labels listed in POINT:ANGLES, FORCES,
      MOMENTS, POWERS, SCALARS, REACTIONS, subject prefixes aside) are dropped, with one
      warning giving the count.
    * Units from POINT:UNITS to metres: ``mm``, ``cm``, ``dm``, ``m`` in any case, or their
      names spelled out or cut short (:func:`unit_of`: ``mete``, ``mill``); missing = mm,
      with a warning.
    * Vertical axis: :func:`~mocaplib.io.c3d_axis.detect_vertical_axis` (each subject's
      markers apart); Y-up files are rotated +90 degrees about X (x, y, z) -> (x, -z, y), a
      proper rotation, so the Trial is Z up and right-handed.
    * Events from the EVENT group (CONTEXTS, LABELS, TIMES as minutes/seconds) in seconds on the
      lab clock (frame ``first_frame`` is at ``(first_frame - 1) / rate``).
    * Force plates from the FORCE_PLATFORM group and the analog samples of their channels
      (:mod:`mocaplib.io.c3d_analog`): each plate's vertical force in newtons at the analog
      rate and its corners in metres, rotated as the markers. A plate that cannot be read is
      skipped with a warning naming it; the markers are read whatever the plates hold.

Bad input (not a C3D, empty, truncated, sizes or counts that cannot be right) raises
:class:`~mocaplib.errors.C3DError` naming the file: every size is checked against the file size
before anything is allocated.
"""

from __future__ import annotations

import errno
import os
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import C3DError
from ..trial import Event, Trial, subject_prefixes
from . import open_regular
from .c3d_analog import read_force_plates
from .c3d_axis import Z_UP, detect_vertical_axis, screen_up_axis, to_z_up
from .c3d_layout import frames_past_16_bits, point_layout
from .c3d_params import label_keys, number, parse_parameters, read_metadata, strings
from .c3d_points import CHUNK_BYTES, read_points

UNITS_TO_METRES = {"mm": 1e-3, "cm": 1e-2, "dm": 1e-1, "m": 1.0}
#: Units spelled out, each the longest form of its name (:func:`unit_of` takes their starts).
_UNIT_NAMES = {f"{prefix}{spelling}": symbol for prefix, symbol in
               (("milli", "mm"), ("centi", "cm"), ("deci", "dm"), ("", "m"))
               for spelling in ("metres", "meters")}
#: POINT parameters listing the labels of model outputs (not marker positions).
MODEL_OUTPUT_PARAMETERS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS", "REACTIONS")


def read_c3d(path: str | os.PathLike, /) -> Trial:
    """Read the markers and force plates of the C3D file ``path``: a :class:`Trial` in metres,
    Z up, NaN = missing.

    Only the header, the parameter section, the POINT words and the analog samples of the
    force plates' channels are read; the frames are read :data:`CHUNK_BYTES` at a time, so
    memory holds little more than the marker array and the plates' channels, whatever the
    file's size.

    Parameters
    ----------
    path : str or os.PathLike
        The C3D file (any processor type: Intel, DEC, SGI/MIPS).

    Returns
    -------
    Trial
        Markers (F, M, 3) in metres, Z up, NaN where missing; labels, rate (Hz), events, the
        force plates (:class:`~mocaplib.io.c3d_analog.ForcePlate`) and the reader's notes
        (``warnings``).

    Raises
    ------
    C3DError
        The file cannot be read; the message names the file and the problem.
    """
    return _with_file(path, _read_trial)


def c3d_frames(path: str | os.PathLike, /) -> int:
    """The number of frames :func:`read_c3d` reads from the C3D file ``path`` (the length of
    the Trial's axis 0), from its header, parameters and size only: no marker sample is
    read. Raises :class:`~mocaplib.errors.C3DError` as :func:`read_c3d` does."""
    return _with_file(path, lambda handle, path: _point_layout(handle, path, [])[1].frames)


def _with_file(path: str | os.PathLike, read):
    """``read(handle, path)`` on the regular file ``path`` opened for reading; a file that
    cannot be opened raises :class:`~mocaplib.errors.C3DError` naming it."""
    path = Path(path)
    try:
        with open_regular(path) as handle:
            return read(handle, path)
    except FileNotFoundError:
        raise C3DError("no such file", path=path, hint="check the path") from None
    except IsADirectoryError:
        raise C3DError("is a folder, not a C3D file", path=path,
                       hint="give a .c3d file; build and inspect also search folders") from None
    except OSError as exc:
        hint = "give the C3D file itself" if exc.errno == errno.EINVAL else None
        raise C3DError(f"cannot read the file: {exc.strerror}", path=path, hint=hint) from None


def _point_layout(handle, path: Path, notes: list[str]):
    """The parsed parameters and the POINT layout of the open file; notes go to ``notes``."""
    size = os.fstat(handle.fileno()).st_size
    reader = parse_parameters(read_metadata(handle, size, path), path, notes)
    layout = frames_past_16_bits(handle, point_layout(reader, handle, size, path, notes),
                                 size, notes)
    return reader, layout


def _read_trial(handle, path: Path) -> Trial:
    notes: list[str] = []
    reader, layout = _point_layout(handle, path, notes)

    labels = _point_labels(reader, layout.count, path, notes)
    declared = _model_outputs(reader, path)
    keep = [i for i, label in enumerate(labels) if label.rpartition(":")[2] not in declared]
    if len(keep) < len(labels):
        notes.append(f"dropped {len(labels) - len(keep)} model outputs stored as points "
                     f"(POINT:{', '.join(MODEL_OUTPUT_PARAMETERS)})")
        labels = [labels[i] for i in keep]
    if keep:
        units, to_metres = _point_units(reader, path, notes)
    else:          # no marker points: the units convert the plates' corners only, unchecked
        found = strings(reader.get("POINT:UNITS"), path, "POINT:UNITS")
        units = found[0] if found and found[0] else "mm"
        to_metres = UNITS_TO_METRES[unit_of(units) or "mm"]
    markers = read_points(handle, layout, keep, to_metres, path)

    duplicates = sorted(label for label, n in Counter(labels).items() if n > 1)
    if duplicates:
        notes.append(f"duplicate labels kept as separate markers: {', '.join(duplicates)}")

    subjects = subject_prefixes(labels)
    prefixes = sorted(set(subjects) - {""})
    if len(prefixes) > 1:
        notes.append(f"labels of {len(prefixes)} subjects ({', '.join(prefixes)}): the "
                     "protocol is matched on the subject whose labels give the most of its "
                     "markers; export one subject per file to fit each")
    axis, axis_notes = detect_vertical_axis(markers, screen_axis=screen_up_axis(reader),
                                            subjects=subjects)
    notes.extend(axis_notes)
    if axis != "Z" and markers.size:
        for chunk in np.array_split(markers, max(1, markers.nbytes // CHUNK_BYTES)):
            chunk[:] = to_z_up(chunk, axis)          # in place, a chunk at a time
        notes.append(f"{axis}-up file rotated to Z up: {Z_UP[axis][2]}")
    plates = read_force_plates(handle, reader, layout, to_metres, axis, path, notes)

    analog = layout.words - 4 * layout.count
    channels = (number(reader, "ANALOG:USED", "uint16") or analog) if analog else 0
    return Trial(markers, labels, layout.rate, first_frame=layout.first_frame, units=units,
                 vertical_axis=axis, events=_events(reader, path, notes), source=str(path),
                 warnings=notes, measurements=subject_measurements(reader),
                 analog_channels=channels, force_plates=plates)


# ----------------------------------------------------------------------------- labels, units
def _point_labels(reader, count: int, path: Path, notes: list[str]) -> list[str]:
    labels: list[str] = []
    for key in label_keys(reader):
        if len(labels) >= count:
            break
        labels.extend(strings(reader.get(key), path, key))
    if len(labels) < count:
        notes.append(f"{count - len(labels)} points have no label; named POINT{len(labels) + 1}...")
        labels.extend(f"POINT{i + 1}" for i in range(len(labels), count))
    return labels[:count]


def _point_units(reader, path: Path, notes: list[str]) -> tuple[str, float]:
    """POINT:UNITS as found and its factor to metres (:func:`unit_of`); missing: mm, noted."""
    found = strings(reader.get("POINT:UNITS"), path, "POINT:UNITS")
    units = found[0] if found else ""
    if not units:
        notes.append("POINT:UNITS missing: assumed mm")
        return "mm", UNITS_TO_METRES["mm"]
    unit = unit_of(units)
    if unit is None:
        raise C3DError(f"unknown POINT:UNITS {units!r}", path=path,
                       hint=f"mocaplib knows {', '.join(UNITS_TO_METRES)} in any case, and their "
                            "names spelled out or cut short (millimetres, mill, metres, mete...): "
                            "set POINT:UNITS to the one the coordinates are in, or re-export "
                            "the file")
    if unit != units:
        notes.append(f"POINT:UNITS {units!r} read as {unit}")
    return units, UNITS_TO_METRES[unit]


def unit_of(text: str, /) -> str | None:
    """The unit (a key of :data:`UNITS_TO_METRES`) a POINT:UNITS ``text`` names: its symbol in
    any case (``'MM'``), or the start of its name spelled out, British or American, singular or
    plural, at least 3 letters (2 for metres): writers cut the text to its stored width
    (``'mete'``, ``'mill'``, ``'centi'``, ``'Meters'``). None for anything else."""
    key = text.strip().lower()
    if key in UNITS_TO_METRES:
        return key
    for name, unit in _UNIT_NAMES.items():
        if name.startswith(key) and len(key) >= (2 if unit == "m" else 3):
            return unit
    return None


def _model_outputs(reader, path: Path) -> set[str]:
    """Labels the file declares as model outputs (angles, forces...), as stripped strings
    without their subject prefix: a file may list ``LHipAngles`` for ``Subj01:LHipAngles``."""
    declared: set[str] = set()
    for name in MODEL_OUTPUT_PARAMETERS:
        key = f"POINT:{name}"
        param = reader.get(key)
        if param is not None and param.bytes_per_element == -1:
            declared.update(text.rpartition(":")[2] for text in strings(param, path, key))
    declared.discard("")
    return declared


#: Vicon's PROCESSING parameters (Plug-in Gait subject measurements, mm and kg) and the
#: :attr:`Trial.measurements` key and factor to SI each becomes.
PROCESSING_MEASUREMENTS = {
    "LKNEEWIDTH": ("knee_width_l", 1e-3), "RKNEEWIDTH": ("knee_width_r", 1e-3),
    "LANKLEWIDTH": ("ankle_width_l", 1e-3), "RANKLEWIDTH": ("ankle_width_r", 1e-3),
    "LELBOWWIDTH": ("elbow_width_l", 1e-3), "RELBOWWIDTH": ("elbow_width_r", 1e-3),
    "LSHOULDEROFFSET": ("shoulder_offset_l", 1e-3),
    "RSHOULDEROFFSET": ("shoulder_offset_r", 1e-3),
    "MARKERDIAMETER": ("marker_diameter", 1e-3), "BODYMASS": ("body_mass", 1.0),
    "HEIGHT": ("height", 1e-3), "LLEGLENGTH": ("leg_length_l", 1e-3),
    "RLEGLENGTH": ("leg_length_r", 1e-3), "INTERASISDISTANCE": ("inter_asis_distance", 1e-3),
    "LASISTROCANTERDISTANCE": ("asis_trochanter_l", 1e-3),
    "RASISTROCANTERDISTANCE": ("asis_trochanter_r", 1e-3),
}


def subject_measurements(reader) -> dict[str, float]:
    """The subject measurements in the PROCESSING group (Vicon's Plug-in Gait names, mm and
    kg) in metres and kilograms; values that are absent, not numbers, zero or negative (how
    Vicon stores "not measured") are left out."""
    out = {}
    for name, (key, factor) in PROCESSING_MEASUREMENTS.items():
        value = number(reader, f"PROCESSING:{name}", "float")
        if value is not None and np.isfinite(value) and value > 0:
            out[key] = value * factor
    return out


def _events(reader, path: Path, notes: list[str]) -> list[Event]:
    """The EVENT group as events; a malformed group is reported in ``notes`` and skipped."""
    if reader.get("EVENT") is None:
        return []
    try:
        count = number(reader, "EVENT:USED", "uint16", 0)
        if count == 0:
            return []
        labels = strings(reader.get("EVENT:LABELS"), path, "EVENT:LABELS")
        contexts = strings(reader.get("EVENT:CONTEXTS"), path, "EVENT:CONTEXTS")
        times = reader.get("EVENT:TIMES")
        if times is None or times.bytes_per_element != 4:
            raise C3DError("EVENT:TIMES missing or not float", path=path)
        # (minutes, seconds) pairs: 2 x N as the standard says, or flat 2N (BTK, some Vicon)
        values = np.asarray(times.float_array, dtype=np.float64).reshape(-1)
        values = values[:values.size // 2 * 2].reshape(-1, 2)
        if len(values) < count or len(labels) < count:
            raise C3DError(f"EVENT:USED is {count} but fewer events are stored", path=path)
        contexts = contexts + ["General"] * (count - len(contexts))
        seconds = values[:count, 0] * 60.0 + values[:count, 1]
        if not np.isfinite(seconds).all():
            raise C3DError("EVENT:TIMES holds non-finite times", path=path)
        return [Event(contexts[i] or "General", labels[i], float(seconds[i]))
                for i in range(count)]
    except Exception as exc:
        reason = exc.message if isinstance(exc, C3DError) else f"{type(exc).__name__}: {exc}"
        notes.append(f"EVENT group ignored: {reason}")
        return []
