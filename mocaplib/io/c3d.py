"""Read the markers of a C3D file into a :class:`~mocaplib.trial.Trial` (metres, Z up,
NaN = missing).

What :func:`read_c3d` does
    * Header and parameters: read here (:class:`_Parameters`), only those it uses looked at,
      in the file's processor format. Valid real-world files the ``c3d`` package refuses are
      read: a parameter defined twice in one group (a Vicon subject's ``BODYMASS``: the first
      definition is kept), an ANALOG rate inconsistent with the header (CMU files: analog
      data are not read); a parameter chain whose link points backwards or ends early is
      followed record by record, with a note. The point layout is validated against the file
      size.

    * POINT data: decoded as whole numpy arrays (one ``np.frombuffer``), integer storage
      (POINT:SCALE > 0, coordinates = int16 x SCALE) or float storage (SCALE < 0), for Intel,
      DEC (VAX F-float, converted vectorised) and SGI/MIPS (big-endian) processor types.
      A sample is missing (NaN) when its residual word is negative, when a coordinate is not
      finite or lies beyond :data:`MAX_COORDINATE_M` (a corrupt word: garbage floats are mostly
      astronomically large), or when all three coordinates are exactly 0 (how Vicon/CMU files
      store a missing sample with a non-negative residual; a real marker never sits exactly at
      the origin).
    * Labels from POINT:LABELS, LABELS2, LABELS3... (files with more than 255 points), NULs and
      padding stripped; duplicate labels are kept, distinct, and named in ``Trial.warnings``,
      as are the subject prefixes of a file whose labels name several (``A:LASI``, ``B:LASI``).
    * Points the file itself declares as model outputs (labels listed in POINT:ANGLES, FORCES,
      MOMENTS, POWERS, SCALARS, REACTIONS, subject prefixes aside) are dropped, with one
      warning giving the count.
    * Units from POINT:UNITS (``mm``, ``cm``, ``m``; missing = mm with a warning) to metres.
    * Vertical axis: see :func:`detect_vertical_axis` (each subject's markers apart); Y-up
      files are rotated +90 degrees about X (x, y, z) -> (x, -z, y), a proper rotation, so the
      Trial is Z up and right-handed.
    * Events from the EVENT group (CONTEXTS, LABELS, TIMES as minutes/seconds) in seconds on the
      lab clock (frame ``first_frame`` is at ``(first_frame - 1) / rate``).

Bad input (not a C3D, empty, truncated, sizes or counts that cannot be right) raises
:class:`~mocaplib.errors.C3DError` naming the file: every size is checked against the file size
before anything is allocated.
"""

from __future__ import annotations

import errno
import math
import os
import re
import struct
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import C3DError
from ..numeric import distinct, percentile
from . import open_regular, printable
from ..trial import Event, Trial, subject_prefixes

PROCESSORS = {84: "INTEL", 85: "DEC", 86: "MIPS"}
UNITS_TO_METRES = {"mm": 1e-3, "cm": 1e-2, "dm": 1e-1, "m": 1.0}
#: POINT parameters listing the labels of model outputs (not marker positions).
MODEL_OUTPUT_PARAMETERS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS", "REACTIONS")
_LABEL_PARAMS = 100          # LABELS, LABELS2 ... LABELS99: far beyond any real file
_AXIS_SAMPLE_FRAMES = 60     # frames looked at to detect the vertical axis
_AXIS_MIN_RATIO = 1.25       # the vertical spread must exceed the next one by this factor
#: Bytes of frames (POINT words and the analog samples between them) read at a time.
CHUNK_BYTES = 1 << 23
#: The largest frame count a 16-bit field holds: a file whose count is at it may hold more.
UINT16_MAX = 65535
#: Coordinates (m) beyond this are corrupt words, read as missing: no capture volume is near
#: 10 km across, and one stray sample of 1e17 m spoils its whole marker track in the low-pass
#: filter (and, with it, the markers calibrated against it).
MAX_COORDINATE_M = 1e4


def read_c3d(path: str | os.PathLike, /) -> Trial:
    """Read the markers of the C3D file ``path``: a :class:`Trial` in metres, Z up, NaN = missing.

    Only the header, the parameter section and the POINT words are read; the frames are read
    :data:`CHUNK_BYTES` at a time (their analog samples skipped), so memory holds little more
    than the marker array, whatever the file's size.

    Parameters
    ----------
    path : str or os.PathLike
        The C3D file (any processor type: Intel, DEC, SGI/MIPS).

    Returns
    -------
    Trial
        Markers (F, M, 3) in metres, Z up, NaN where missing; labels, rate (Hz), events and
        the reader's notes (``warnings``).

    Raises
    ------
    C3DError
        The file cannot be read; the message names the file and the problem.
    """
    path = Path(path)
    try:
        with open_regular(path) as handle:
            return _read_trial(handle, path)
    except FileNotFoundError:
        raise C3DError("no such file", path=path, hint="check the path") from None
    except IsADirectoryError:
        raise C3DError("is a folder, not a C3D file", path=path,
                       hint="give a .c3d file; build and inspect also search folders") from None
    except OSError as exc:
        hint = "give the C3D file itself" if exc.errno == errno.EINVAL else None
        raise C3DError(f"cannot read the file: {exc.strerror}", path=path, hint=hint) from None


def _read_trial(handle, path: Path) -> Trial:
    size = os.fstat(handle.fileno()).st_size
    metadata = _read_metadata(handle, size, path)
    notes: list[str] = []
    reader = _parse_parameters(metadata, path, notes)
    layout = _frames_past_16_bits(handle, _point_layout(reader, size, path, notes), size, notes)

    labels = _point_labels(reader, layout.count, path, notes)
    units, to_metres = _point_units(reader, path, notes)
    declared = _model_outputs(reader, path)
    keep = [i for i, label in enumerate(labels) if label.rpartition(":")[2] not in declared]
    if len(keep) < len(labels):
        notes.append(f"dropped {len(labels) - len(keep)} model outputs stored as points "
                     f"(POINT:{', '.join(MODEL_OUTPUT_PARAMETERS)})")
        labels = [labels[i] for i in keep]
    markers = _read_points(handle, layout, keep, to_metres, path)

    duplicates = sorted(label for label, n in Counter(labels).items() if n > 1)
    if duplicates:
        notes.append(f"duplicate labels kept as separate markers: {', '.join(duplicates)}")

    subjects = subject_prefixes(labels)
    prefixes = sorted(set(subjects) - {""})
    if len(prefixes) > 1:
        notes.append(f"labels of {len(prefixes)} subjects ({', '.join(prefixes)}): the "
                     "protocol is matched on the subject whose labels give the most of its "
                     "markers; export one subject per file to fit each")
    axis, axis_notes = detect_vertical_axis(markers, screen_axis=_screen_up_axis(reader),
                                            subjects=subjects)
    notes.extend(axis_notes)
    if axis == "Y":
        for chunk in np.array_split(markers, max(1, markers.nbytes // CHUNK_BYTES)):
            chunk[:] = y_up_to_z_up(chunk)          # in place, a chunk at a time
        notes.append("Y-up file rotated to Z up: (x, y, z) -> (x, -z, y)")

    return Trial(markers, labels, layout.rate, first_frame=layout.first_frame, units=units,
                 vertical_axis=axis, events=_events(reader, path, notes), source=str(path),
                 warnings=notes, measurements=subject_measurements(reader))


# ----------------------------------------------------------------------------- file and header
def _read_metadata(handle, size: int, path: Path) -> bytes:
    """The header and the parameter section (the blocks up to the end of the section, as its
    first bytes count them), checked (:func:`_check_header`)."""
    data = handle.read(512)
    if len(data) == 512 and data[1] == 0x50 and data[0] >= 2:
        start = (data[0] - 1) * 512
        handle.seek(start + 2)
        blocks = handle.read(1)
        end = start + 512 * (blocks[0] if blocks else 0)
        handle.seek(0)
        data = handle.read(min(max(end, start + 4), size))
    _check_header(data, size, path)
    return data


def _check_header(data: bytes, size: int, path: Path) -> None:
    """The checks the ``c3d`` package would fail on with an unhelpful exception: ``data`` is
    the start of a file of ``size`` bytes, through the parameter section's first 4 bytes."""
    if size == 0:
        raise C3DError("the file is empty", path=path,
                       hint="re-export it from the capture software")
    if size < 512:
        raise C3DError(f"only {size} bytes: too short for a C3D file (header is 512 bytes)",
                       path=path, hint="the file is truncated or not a C3D file")
    if data[1] != 0x50:
        raise C3DError(f"not a C3D file: byte 2 is 0x{data[1]:02x}, a C3D file has 0x50",
                       path=path, hint="give the trial exported as C3D by the capture software")
    start = (data[0] - 1) * 512
    if data[0] < 2:
        raise C3DError(f"the header points to a parameter section at block {data[0]}, inside the "
                       f"header", path=path, hint="the file is corrupt")
    if start + 4 > size:
        raise C3DError(f"the header points to a parameter section at block {data[0]}, beyond the "
                       f"end of the file ({size} bytes)", path=path,
                       hint="the file is truncated or corrupt")
    processor = data[start + 3]
    if processor not in PROCESSORS:
        raise C3DError(f"unknown processor type {processor} (expected 84 Intel, 85 DEC or 86 MIPS)",
                       path=path, hint="the file is corrupt")


# ----------------------------------------------------------------------------- parameters
def _parse_parameters(data: bytes, path: Path, notes: list[str]) -> "_Parameters":
    """The header and parameters of ``data`` (the file's first blocks, through its parameter
    section), with a note for each broken link of the parameter chain."""
    try:
        return _Parameters(data, notes)
    except Exception as exc:     # a value a corrupt section makes impossible
        raise _corrupt(exc, path) from None


def _corrupt(exc: Exception, path: Path) -> C3DError:
    return C3DError(f"corrupt header or parameter section ({type(exc).__name__}: {exc})",
                    path=path, hint="the file is truncated or corrupt")


@dataclass(frozen=True)
class _Record:
    """One record of the parameter section: a group (``group`` < 0) or a parameter."""

    position: int       # byte offset of the record
    group: int          # group id, negative for a group record
    name: bytes         # upper case
    link_at: int        # byte offset of the int16 link to the next record
    link: int           # the link as stored
    length: int | None  # the link the record's own content gives (None: cannot be measured)


def _parameter_records(data: bytes) -> tuple[list[_Record], str]:
    """The records of the parameter section in the order their links give, and the int16
    byte order (``"<"`` or ``">"``).

    C3D records are ``[name length: int8][group id: int8][name][link to next: int16]
    [content]``, the link counted from its own first byte; 0 ends the chain. A record whose
    link is 0 or negative while a well-formed record follows its content is taken as a broken
    link (the walk goes on at the end of its content), so the groups after it are not lost.
    """
    start = (data[0] - 1) * 512 + 4
    end = min(len(data), start - 4 + 512 * data[start - 2])
    endian = ">" if data[start - 1] == 86 else "<"
    records: list[_Record] = []
    position, seen = start, set()
    while position + 4 <= end and position not in seen:
        seen.add(position)
        length, group = struct.unpack_from("bb", data, position)
        link_at = position + 2 + abs(length)
        if length == 0 or group == 0 or link_at + 2 > end:
            break
        link, = struct.unpack_from(endian + "h", data, link_at)
        record = _Record(position, group, bytes(data[position + 2:link_at]).upper(), link_at,
                         link, _content_length(data, link_at + 2, group, end))
        records.append(record)
        if link > 0:
            position = link_at + link
        elif record.length is not None and _record_starts(data, link_at + record.length, end):
            position = link_at + record.length
        else:
            break
    return records, endian


def _content_length(data: bytes, at: int, group: int, end: int) -> int | None:
    """The link a record's content gives (2 + its size), or None when it runs past ``end``.

    A group holds ``[description length][description]``; a parameter ``[type: int8]
    [dimensions: uint8][each dimension: uint8][values][description length][description]``.
    """
    size = 0
    if group > 0:
        if at + 2 > end:
            return None
        kind, n_dims = struct.unpack_from("bB", data, at)
        if at + 2 + n_dims > end:
            return None
        size = 2 + n_dims + abs(kind) * math.prod(data[at + 2:at + 2 + n_dims])
    if at + size >= end:
        return None
    size += 1 + data[at + size]
    return 2 + size if at + size <= end else None


def _record_starts(data: bytes, position: int, end: int) -> bool:
    """Whether a well-formed record starts at ``position``: a name of letters, digits and
    underscores, a group id, and a link inside the section."""
    if position + 4 > end:
        return False
    length, group = struct.unpack_from("bb", data, position)
    name = data[position + 2:position + 2 + abs(length)]
    return (length != 0 and group != 0 and position + 4 + abs(length) <= end
            and bool(re.fullmatch(rb"[A-Za-z0-9_]+", name)))


@dataclass(frozen=True)
class _Parameter:
    """One parameter as stored: element size (-1 text, 1 byte, 2 16-bit integer, 4 float),
    dimensions (the first varying fastest) and its bytes, in ``processor``'s format."""

    bytes_per_element: int
    dimensions: tuple[int, ...]
    bytes: bytes
    processor: str

    @property
    def float_array(self) -> np.ndarray:
        endian = ">" if self.processor == "MIPS" else "<"
        raw = self.bytes[:len(self.bytes) // 4 * 4]
        if self.processor == "DEC":
            return dec_to_ieee(np.frombuffer(raw, "<u4"))
        return np.frombuffer(raw, endian + "f4")

    @property
    def uint16_array(self) -> np.ndarray:
        endian = ">" if self.processor == "MIPS" else "<"
        return np.frombuffer(self.bytes[:len(self.bytes) // 2 * 2], endian + "u2")

    @property
    def float_value(self) -> float:
        return float(self.float_array[0])

    @property
    def uint16_value(self) -> int:
        return int(self.uint16_array[0])


class _Parameters:
    """The header and the parameter section of a C3D file: :meth:`get` ``"GROUP:NAME"`` (a
    parameter, the first definition of a name in its group) or ``"GROUP"``; the header's
    words as attributes; :attr:`first_frame` and :attr:`last_frame` from the parameters
    that extend the header's 16-bit frame numbers."""

    def __init__(self, data: bytes, notes: list[str]):
        records, endian = _parameter_records(data)
        self.processor = PROCESSORS[data[(data[0] - 1) * 512 + 3]]
        self._header(data, endian)
        for record in records[:-1]:
            if record.link <= 0:
                where = "points backwards" if record.link < 0 else "ends the chain early"
                notes.append(f"parameter section: the link after "
                             f"{record.name.decode('latin-1')} {where} ({record.link:+d} "
                             "bytes); the records that follow it in the file were read in "
                             "order (the file is damaged: re-export it)")
        groups: dict[int, str] = {}
        for record in records:
            if record.group < 0:
                groups.setdefault(-record.group, record.name.decode("latin-1"))
        self._groups = set(groups.values())
        self._data = data
        self._section_end = min(len(data),
                                (data[0] - 1) * 512 + 512 * data[(data[0] - 1) * 512 + 2])
        self._records: dict[str, _Record] = {}          # read when asked for (:meth:`get`)
        for record in records:
            if record.group > 0 and record.group in groups:
                key = f"{groups[record.group]}:{record.name.decode('latin-1')}"
                self._records.setdefault(key, record)

    def _header(self, data: bytes, endian: str) -> None:
        (self.point_count, self.analog_count, self.header_first_frame,
         self.header_last_frame) = struct.unpack_from(endian + "4H", data, 2)
        self.data_block, = struct.unpack_from(endian + "H", data, 16)
        words = _Parameter(4, (2,), data[12:16] + data[20:24], self.processor).float_array
        self.scale_factor, self.frame_rate = float(words[0]), float(words[1])

    def get(self, key: str) -> _Parameter | str | None:
        """The parameter ``"GROUP:NAME"`` (None when absent or its record is cut short), the
        group's name for ``"GROUP"``, or None."""
        if ":" not in key:
            return key if key in self._groups else None
        record = self._records.get(key)
        if record is None:
            return None
        at, data = record.link_at + 2, self._data
        end = record.link_at + record.link if record.link > 0 else (
            record.link_at + record.length if record.length else self._section_end)
        if at + 2 > end:
            return None
        size, n_dims = struct.unpack_from("bB", data, at)
        dims = tuple(data[at + 2:at + 2 + n_dims])
        start = at + 2 + n_dims
        count = abs(size) * math.prod(dims)
        return _Parameter(size, dims, bytes(data[start:min(start + count, end)]),
                          self.processor)

    @property
    def first_frame(self) -> int:
        """TRIAL:ACTUAL_START_FIELD (two 16-bit words), else the header's first frame."""
        param = self.get("TRIAL:ACTUAL_START_FIELD")
        if param is not None:
            words = param.uint16_array
            return int(words[0]) + int(words[1]) * 65536
        return int(self.header_first_frame)

    @property
    def last_frame(self) -> int:
        """The last frame, from the first of TRIAL:ACTUAL_END_FIELD (two 16-bit words),
        POINT:LONG_FRAMES and POINT:FRAMES (float or 16-bit) that is not below the header's
        (16-bit) last frame; else the header's."""
        header = int(self.header_last_frame)
        param = self.get("TRIAL:ACTUAL_END_FIELD")
        if param is not None:
            words = param.uint16_array
            if header <= int(words[0]) + int(words[1]) * 65536:
                return int(words[0]) + int(words[1]) * 65536
        for key in ("POINT:LONG_FRAMES", "POINT:FRAMES"):
            param = self.get(key)
            if param is not None:
                end = int(param.float_value) if param.bytes_per_element >= 4 \
                    else param.uint16_value
                if header <= end:
                    return end
        return header


def _strings(param, path: Path, key: str) -> list[str]:
    """A string parameter as a list of stripped strings (validated before slicing)."""
    if param is None:
        return []
    dims = [int(d) for d in param.dimensions]
    if param.bytes_per_element != -1:
        raise C3DError(f"parameter {key} should hold text", path=path)
    if not dims:
        return [_clean(param.bytes)]
    width = dims[0]
    count = math.prod(dims[1:])
    if width == 0:  # zero-width strings: nothing stored, whatever the count says
        return []
    if width * count > len(param.bytes):
        raise C3DError(f"parameter {key} declares {count} strings of {width} characters but "
                       f"holds {len(param.bytes)} bytes", path=path, hint="the file is corrupt")
    raw = param.bytes
    return [_clean(raw[i * width:(i + 1) * width]) for i in range(count)]


def _clean(raw: bytes) -> str:
    """Text of a C3D string: UTF-8 (else Latin-1), NULs and padding removed, control
    characters escaped (:func:`mocaplib.io.printable`)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    text = text.replace("\x00", "").strip()
    return text if text.isprintable() else printable(text, keep="")   # most labels: as they are


def _number(reader, key: str, kind: str, default=None):
    """One numeric parameter value (``kind`` 'float' or 'uint16'), or ``default`` when absent."""
    param = reader.get(key)
    if param is None:
        return default
    size = 4 if kind == "float" else 2
    if len(param.bytes) < size:
        return default
    if kind == "float":
        return float(param.float_value) if param.bytes_per_element == 4 else default
    return int(param.uint16_value) if abs(param.bytes_per_element) == 2 else default


# ----------------------------------------------------------------------------- point data
@dataclass(frozen=True)
class PointLayout:
    """Where and how the POINT data sit in the file."""

    processor: str      # "INTEL", "DEC" or "MIPS"
    start: int          # byte offset of the first frame
    frames: int
    count: int          # points per frame
    words: int          # words per frame (4 per point + analog samples)
    scale: float        # POINT:SCALE (< 0: float storage)
    rate: float         # Hz
    first_frame: int


def _point_layout(reader, file_size: int, path: Path, notes: list[str]) -> PointLayout:
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # corrupt words: checked below
            processor = reader.processor
            count = _number(reader, "POINT:USED", "uint16", int(reader.point_count))
            scale = _number(reader, "POINT:SCALE", "float", float(reader.scale_factor))
            rate = _number(reader, "POINT:RATE", "float", None) or float(reader.frame_rate)
            first_frame = int(reader.first_frame)
            last_frame = int(reader.last_frame)
    except Exception as exc:  # corrupt parameter values the package cannot convert
        raise C3DError(f"corrupt POINT parameters ({type(exc).__name__}: {exc})",
                       path=path) from None
    if not (np.isfinite(rate) and 0.1 <= rate < 1e6):
        raise C3DError(f"nonsense frame rate {rate} Hz", path=path, hint="the file is corrupt")
    if not np.isfinite(scale) or scale == 0:
        raise C3DError(f"nonsense POINT:SCALE {scale}", path=path, hint="the file is corrupt")
    frames = last_frame - first_frame + 1
    if frames <= 0:
        raise C3DError(f"no frames (first frame {first_frame}, last frame {last_frame})",
                       path=path, hint="the capture is empty or the header is corrupt")
    start = (int(reader.data_block) - 1) * 512
    if start < 512:
        raise C3DError(f"nonsense data block number {int(reader.data_block)}", path=path)
    words = 4 * count + int(reader.analog_count)
    scale = _storage_scale(float(scale), file_size - start, frames * words, notes)
    needed = start + frames * words * (4 if scale < 0 else 2)
    if needed > file_size:
        halved = " (or POINT:SCALE's sign is wrong: the file holds what 16-bit integer " \
                 "storage of these frames needs)" if scale < 0 and _fits(
                     file_size - start, 2 * frames * words) else ""
        raise C3DError(f"truncated: {frames} frames of {count} points need {needed} bytes, the "
                       f"file has {file_size}{halved}", path=path,
                       hint="copy the file again or re-export it")
    return PointLayout(processor, start, frames, count, words, scale, float(rate),
                       first_frame)


def _fits(data_bytes: int, needed: int) -> bool:
    """Whether a data section of ``data_bytes`` holds ``needed`` bytes of data plus padding.

    Writers pad the data section to whole 512-byte blocks (less than a block beyond the data:
    the 17 real files at hand leave 0 to 416 bytes)."""
    return needed <= data_bytes < needed + 512


def _storage_scale(scale: float, data_bytes: int, n_words: int, notes: list[str]) -> float:
    """POINT:SCALE, turned negative (with a note) when it says 16-bit integer storage (> 0) of
    ``n_words`` words, but the data section holds a block or more beyond that and just what
    32-bit float storage needs: the floats read as integers would be garbage (a subject
    hundreds of metres tall), so the sign is what is wrong. (The other way round, floats
    claimed for integer data, the file looks truncated and the error says why.)"""
    if scale > 0 and not _fits(data_bytes, 2 * n_words) and _fits(data_bytes, 4 * n_words):
        notes.append(f"POINT:SCALE {scale:g} says 16-bit integer storage, but the data section "
                     f"holds {data_bytes} bytes, what 32-bit float storage of these frames "
                     "needs: read as floats (the sign of POINT:SCALE is wrong: re-export the "
                     "file)")
        return -scale
    return scale


def decode_points(data, layout: PointLayout, /, *, factor: float = 1.0,
                  points: list[int] | None = None) -> np.ndarray:
    """Markers ``(F, M, 3)`` float64 of ``data`` (bytes or a buffer) laid out as ``layout``:
    file coordinates times ``factor``, NaN where invalid; ``points`` (indices) keeps only those
    points, in that order (default all)."""
    return _decoded(_point_words(data, layout, points), layout, factor)


def _point_words(data, layout: PointLayout, points: list[int] | None) -> np.ndarray:
    """The stored words (F, M, 4) of the points (all, or the indices ``points``), as stored."""
    is_float = layout.scale < 0
    endian = ">" if layout.processor == "MIPS" else "<"
    if is_float:
        dtype = np.dtype(endian + ("u4" if layout.processor == "DEC" else "f4"))
    else:
        dtype = np.dtype(endian + "i2")
    block = np.frombuffer(data, dtype=dtype, count=layout.frames * layout.words,
                          offset=layout.start).reshape(layout.frames, layout.words)
    block = block[:, :4 * layout.count].reshape(layout.frames, layout.count, 4)
    return block if points is None or len(points) == layout.count and \
        np.array_equal(points, np.arange(layout.count)) else block[:, points]


def _decoded(block: np.ndarray, layout: PointLayout, factor: float,
             out: np.ndarray | None = None, bound: float = np.inf) -> np.ndarray:
    """Markers (F, M, 3) float64 of stored words ``block`` (F, M, 4), written into ``out``
    when given; NaN where invalid, a coordinate beyond ``bound`` (output units) included."""
    is_float = layout.scale < 0
    if is_float and layout.processor == "DEC":
        block = dec_to_ieee(block)
    with np.errstate(invalid="ignore", over="ignore"):  # corrupt words: NaN/inf, masked below
        markers = np.empty(block.shape[:2] + (3,)) if out is None else out
        markers[...] = block[..., :3]                  # exact: float32 and int16 fit float64
        markers *= factor if is_float else factor * layout.scale
        x, y, z = markers[..., 0], markers[..., 1], markers[..., 2]
        valid = (block[..., 3] >= 0) & np.isfinite(x + y + z) & ((x != 0) | (y != 0) | (z != 0))
        bounded = not is_float and 32768 * abs(factor * layout.scale) <= bound   # int16 words
        if not (bounded or markers.min(initial=0.0) >= -bound
                and markers.max(initial=0.0) <= bound):
            valid &= (np.abs(x) <= bound) & (np.abs(y) <= bound) & (np.abs(z) <= bound)
    np.copyto(markers, np.nan, where=~valid[..., None])
    return markers


def _read_points(handle, layout: PointLayout, points: list[int], factor: float,
                 path: Path) -> np.ndarray:
    """Markers (F, len(points), 3) of the file open in ``handle`` (:func:`decode_points`),
    ``factor`` its units to metres, coordinates beyond :data:`MAX_COORDINATE_M` missing; read
    :data:`CHUNK_BYTES` of frames at a time."""
    frame_bytes = _frame_bytes(layout)
    step = max(1, CHUNK_BYTES // frame_bytes)
    out = np.empty((layout.frames, len(points), 3))
    buffer = bytearray(min(step, layout.frames) * frame_bytes)
    handle.seek(layout.start)
    for first in range(0, layout.frames, step):
        chunk = replace(layout, start=0, frames=min(step, layout.frames - first))
        view = memoryview(buffer)[:chunk.frames * frame_bytes]
        if handle.readinto(view) != len(view):
            raise C3DError("the file is shorter than when it was opened (written to while "
                           "read?)", path=path, hint="read it again once it is complete")
        _decoded(_point_words(view, chunk, points), chunk, factor,
                 out=out[first:first + chunk.frames], bound=MAX_COORDINATE_M)
    return out


def _frame_bytes(layout: PointLayout) -> int:
    return max(1, layout.words * (4 if layout.scale < 0 else 2))


def _frames_past_16_bits(handle, layout: PointLayout, size: int, notes: list[str]
                         ) -> PointLayout:
    """``layout`` with every frame the data section holds when the file counts
    :data:`UINT16_MAX` frames and holds more: a writer that stores the count in 16 bits only
    (ezc3d 1.7 does) can write no more, though it writes every frame. Whole frames past the
    count are read but those at the end whose words are all zero: the padding of the last
    512-byte block."""
    held = (size - layout.start) // _frame_bytes(layout)
    if layout.first_frame + layout.frames - 1 != UINT16_MAX or held <= layout.frames:
        return layout
    tail = min(held - layout.frames, -(-512 // _frame_bytes(layout)))
    handle.seek(layout.start + (held - tail) * _frame_bytes(layout))
    words = np.frombuffer(handle.read(tail * _frame_bytes(layout)), np.uint8)
    padding = words.reshape(tail, -1).any(axis=1)[::-1].argmax() if words.any() else tail
    frames = held - padding
    if frames > layout.frames:
        notes.append(f"the file counts {layout.frames} frames, the most 16 bits hold, and its "
                     f"data section holds {frames}: all read")
    return replace(layout, frames=max(frames, layout.frames))


def dec_to_ieee(words: np.ndarray) -> np.ndarray:
    """DEC (VAX F-float) 32-bit words, read as little-endian uint32, to IEEE float32 values.

    A VAX F-float keeps sign, 8-bit exponent (bias 128) and the high mantissa bits in its first
    16-bit word, the low mantissa bits in the second, with a hidden bit worth 0.5: swapping the two
    halves gives the IEEE bit layout of 4 x the value. Exponents >= 3 are divided by 4 exactly by
    lowering the exponent by 2; smaller ones (|x| < 1e-38) are divided in floating point.
    DEC zero (exponent 0) maps to 0.
    """
    words = np.asarray(words, dtype=np.uint32)
    swapped = (words >> np.uint32(16)) | (words << np.uint32(16))
    exponent = (swapped >> np.uint32(23)) & np.uint32(0xFF)
    lowered = np.where(exponent >= 3, swapped - np.uint32(2 << 23), swapped).view(np.float32)
    tiny = swapped.view(np.float32) / np.float32(4.0)
    return np.where(exponent >= 3, lowered, np.where(exponent == 0, np.float32(0.0), tiny))


# ----------------------------------------------------------------------------- labels, units
def _point_labels(reader, count: int, path: Path, notes: list[str]) -> list[str]:
    labels: list[str] = []
    for number in range(1, _LABEL_PARAMS):
        key = "POINT:LABELS" if number == 1 else f"POINT:LABELS{number}"
        param = reader.get(key)
        if param is None or len(labels) >= count:
            break
        labels.extend(_strings(param, path, key))
    if len(labels) < count:
        notes.append(f"{count - len(labels)} points have no label; named POINT{len(labels) + 1}...")
        labels.extend(f"POINT{i + 1}" for i in range(len(labels), count))
    return labels[:count]


def _point_units(reader, path: Path, notes: list[str]) -> tuple[str, float]:
    found = _strings(reader.get("POINT:UNITS"), path, "POINT:UNITS")
    units = found[0] if found else ""
    if not units:
        notes.append("POINT:UNITS missing: assumed mm")
        return "mm", UNITS_TO_METRES["mm"]
    factor = UNITS_TO_METRES.get(units.lower())
    if factor is None:
        raise C3DError(f"unknown POINT:UNITS {units!r}", path=path,
                       hint=f"mocaplib knows {', '.join(UNITS_TO_METRES)}: set POINT:UNITS to "
                            "the one the coordinates are in, or re-export the file")
    return units, factor


def _model_outputs(reader, path: Path) -> set[str]:
    """Labels the file declares as model outputs (angles, forces...), as stripped strings
    without their subject prefix: a file may list ``LHipAngles`` for ``Subj01:LHipAngles``."""
    declared: set[str] = set()
    for name in MODEL_OUTPUT_PARAMETERS:
        key = f"POINT:{name}"
        param = reader.get(key)
        if param is not None and param.bytes_per_element == -1:
            declared.update(text.rpartition(":")[2] for text in _strings(param, path, key))
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
        value = _number(reader, f"PROCESSING:{name}", "float")
        if value is not None and np.isfinite(value) and value > 0:
            out[key] = value * factor
    return out


def _events(reader, path: Path, notes: list[str]) -> list[Event]:
    """The EVENT group as events; a malformed group is reported in ``notes`` and skipped."""
    if reader.get("EVENT") is None:
        return []
    try:
        count = _number(reader, "EVENT:USED", "uint16", 0)
        if count == 0:
            return []
        labels = _strings(reader.get("EVENT:LABELS"), path, "EVENT:LABELS")
        contexts = _strings(reader.get("EVENT:CONTEXTS"), path, "EVENT:CONTEXTS")
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


# ----------------------------------------------------------------------------- vertical axis
def _screen_up_axis(reader) -> str | None:
    """The axis POINT:Y_SCREEN shows upwards ('X', 'Y' or 'Z'), when the file says."""
    param = reader.get("POINT:Y_SCREEN")
    if param is None or param.bytes_per_element != -1:
        return None
    text = _clean(param.bytes[:8]).upper()
    return text[-1] if text[-1:] in ("X", "Y", "Z") else None


def detect_vertical_axis(markers: np.ndarray, /, *, screen_axis: str | None = None,
                         subjects: list[str] | None = None) -> tuple[str, list[str]]:
    """The file's vertical axis, ``"Z"`` or ``"Y"``, from markers ``(F, M, 3)``; and notes.

    Rule: a standing or walking person is longer than wide. In up to 60 evenly spaced frames each
    marker is taken relative to the mean of its subject's markers in the frame (``subjects``,
    length M, :func:`subject_prefixes`: the people of a file with several stand apart on the
    floor, which would otherwise look like one wide body; default: one subject), where 3 or
    more of them are seen; the axis with the widest spread of those offsets (10th to 90th
    percentile) is the body's long axis, i.e. vertical. It must beat the next axis by 25 %;
    otherwise (too few markers, a lying subject) POINT:Y_SCREEN decides, and Z without it. When
    POINT:Y_SCREEN names another axis than the data, the data win and a note says so. Only Y
    and Z are supported as vertical axes.
    """
    notes: list[str] = []
    frames = markers.shape[0]
    sample = markers[distinct(np.linspace(0, frames - 1, min(frames, _AXIS_SAMPLE_FRAMES))
                              .astype(int))]
    seen = np.isfinite(sample[..., 0]) & np.isfinite(sample[..., 1]) & np.isfinite(sample[..., 2])
    subjects = np.array([""] * markers.shape[1] if subjects is None else subjects)
    groups = sorted(set(subjects))
    offsets = []
    for mine in [slice(None)] if len(groups) == 1 else [subjects == s for s in groups]:
        own, seen_own = sample[:, mine], seen[:, mine]
        counts = seen_own.sum(axis=1)
        mean = np.where(seen_own[..., None], own, 0.0).sum(axis=1) / np.maximum(
            counts, 1)[:, None]                            # each frame's mean seen marker
        seen_own &= (counts >= 3)[:, None]
        offsets.append((own - mean[:, None])[seen_own])
    offsets = np.concatenate(offsets)
    spread = np.zeros(3)
    if len(offsets) >= 10:
        low, high = percentile(offsets.T, [10, 90], axis=1)
        spread = high - low
    order = np.argsort(spread)[::-1]
    fallback = screen_axis if screen_axis in ("Y", "Z") else "Z"
    if spread[order[0]] <= 0 or spread[order[0]] < _AXIS_MIN_RATIO * spread[order[1]]:
        notes.append(f"vertical axis unclear from the markers; {fallback} assumed"
                     + (" (POINT:Y_SCREEN)" if screen_axis in ("Y", "Z") else ""))
        return fallback, notes
    axis = "XYZ"[order[0]]
    if axis == "X":
        notes.append(f"the markers look vertical along X, which is not supported; "
                     f"{fallback} assumed")
        return fallback, notes
    if screen_axis in ("X", "Y", "Z") and screen_axis != axis:
        notes.append(f"POINT:Y_SCREEN shows {screen_axis} up but the markers are vertical "
                     f"along {axis}; {axis} used")
    return axis, notes


def y_up_to_z_up(markers: np.ndarray, /) -> np.ndarray:
    """Rotate Y-up points ``(..., 3)`` by +90 degrees about X: (x, y, z) -> (x, -z, y)."""
    out = np.empty_like(markers)
    out[..., 0] = markers[..., 0]
    out[..., 1] = -markers[..., 2]
    out[..., 2] = markers[..., 1]
    return out
