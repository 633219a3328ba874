"""The header and the parameter section of a C3D file, in any processor format.

:func:`read_metadata` reads the header and the parameter section (the blocks the section's
first bytes count) and checks what the ``c3d`` package would fail on with an unhelpful
exception; :class:`Parameters` parses them. A parameter is decoded only when asked for
(:meth:`Parameters.get`). Valid real-world files the ``c3d`` package refuses are read: a
parameter defined twice in one group (the first definition is kept); a parameter chain whose
link points backwards, ends early or points past the end of the section (0x7fff) is followed
record by record, with a note naming the record.

Processor formats: Intel (little-endian IEEE), DEC (VAX F-float, :func:`dec_to_ieee`) and
SGI/MIPS (big-endian IEEE). Errors are :class:`~mocaplib.errors.C3DError` naming the file.
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import C3DError
from . import printable

PROCESSORS = {84: "INTEL", 85: "DEC", 86: "MIPS"}
_LABEL_PARAMS = 100          # LABELS, LABELS2 ... LABELS99: far beyond any real file


# ----------------------------------------------------------------------------- file and header
def read_metadata(handle, size: int, path: Path) -> bytes:
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
def parse_parameters(data: bytes, path: Path, notes: list[str]) -> "Parameters":
    """The header and parameters of ``data`` (the file's first blocks, through its parameter
    section), with a note for each broken link of the parameter chain."""
    try:
        return Parameters(data, notes)
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
    length: int | None  # the link the record's own content gives (None: cannot be measured,
                        # or not needed: measured only where ``link`` <= 0 or leaves the
                        # section)


def parameter_records(data: bytes) -> tuple[list[_Record], str]:
    """The records of the parameter section in the order their links give, and the int16
    byte order (``"<"`` or ``">"``).

    C3D records are ``[name length: int8][group id: int8][name][link to next: int16]
    [content]``, the link counted from its own first byte; 0 ends the chain. A record whose
    link is 0, negative or points past the end of the section (0x7fff) while a well-formed
    record follows its content is taken as a broken link (the walk goes on at the end of its
    content), so the groups after it are not lost.
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
        inside = 0 < link and link_at + link + 4 <= end
        record = _Record(position, group, bytes(data[position + 2:link_at]).upper(), link_at,
                         link, None if inside else _content_length(data, link_at + 2, group,
                                                                   end))
        records.append(record)
        if inside:
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
class Parameter:
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
        """The first value as a float (its bytes must hold one)."""
        if self.processor == "DEC":
            return float(self.float_array[0])
        return struct.unpack_from(">f" if self.processor == "MIPS" else "<f", self.bytes)[0]

    @property
    def uint16_value(self) -> int:
        """The first value as a 16-bit unsigned integer (its bytes must hold one)."""
        return struct.unpack_from(">H" if self.processor == "MIPS" else "<H", self.bytes)[0]


class Parameters:
    """The header and the parameter section of a C3D file: :meth:`get` ``"GROUP:NAME"`` (a
    parameter, the first definition of a name in its group) or ``"GROUP"``; the header's
    words as attributes; :attr:`first_frame` from the parameters that extend the header's
    16-bit frame numbers."""

    def __init__(self, data: bytes, notes: list[str]):
        records, endian = parameter_records(data)
        self.processor = PROCESSORS[data[(data[0] - 1) * 512 + 3]]
        self._header(data, endian)
        groups: dict[int, str] = {}
        for record in records:
            if record.group < 0:
                groups.setdefault(-record.group, record.name.decode("latin-1"))
        for record, following in zip(records, records[1:]):
            if following.position != record.link_at + record.link:   # a broken link
                where = ("points backwards" if record.link < 0 else "ends the chain early"
                         if record.link == 0 else "points past the end of the section")
                name = record.name.decode("latin-1")
                if record.group > 0:
                    name = f"{groups.get(record.group, f'group {record.group}')}:{name}"
                notes.append(f"parameter section: the link after {name} {where} "
                             f"({record.link:+d} bytes); the records that follow it in the "
                             "file were read in order (the file is damaged: re-export it)")
        self._groups = set(groups.values())
        self._data = data
        self._section_end = min(len(data),
                                (data[0] - 1) * 512 + 512 * data[(data[0] - 1) * 512 + 2])
        self._records: dict[str, _Record] = {}          # read when asked for (:meth:`get`)
        self._decoded: dict[str, Parameter | None] = {}
        for record in records:
            if record.group > 0 and record.group in groups:
                key = f"{groups[record.group]}:{record.name.decode('latin-1')}"
                self._records.setdefault(key, record)

    def _header(self, data: bytes, endian: str) -> None:
        (self.point_count, self.analog_count, self.header_first_frame,
         self.header_last_frame) = struct.unpack_from(endian + "4H", data, 2)
        self.data_block, = struct.unpack_from(endian + "H", data, 16)
        words = Parameter(4, (2,), data[12:16] + data[20:24], self.processor).float_array
        self.scale_factor, self.frame_rate = float(words[0]), float(words[1])

    def get(self, key: str) -> Parameter | str | None:
        """The parameter ``"GROUP:NAME"`` (None when absent or its record is cut short), the
        group's name for ``"GROUP"``, or None. A parameter is decoded once, when first asked
        for."""
        if ":" not in key:
            return key if key in self._groups else None
        if key not in self._decoded:
            self._decoded[key] = self._parameter(key)
        return self._decoded[key]

    def _parameter(self, key: str) -> Parameter | None:
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
        return Parameter(size, dims, bytes(data[start:min(start + count, end)]),
                          self.processor)

    @property
    def first_frame(self) -> int:
        """TRIAL:ACTUAL_START_FIELD (two 16-bit words), else the header's first frame."""
        param = self.get("TRIAL:ACTUAL_START_FIELD")
        if param is not None:
            words = param.uint16_array
            return int(words[0]) + int(words[1]) * 65536
        return int(self.header_first_frame)


def label_keys(reader) -> list[str]:
    """The label parameters of a file, in order: POINT:LABELS, POINT:LABELS2... (files with
    more than 255 points) up to the first missing one."""
    keys = []
    for index in range(1, _LABEL_PARAMS):
        key = "POINT:LABELS" if index == 1 else f"POINT:LABELS{index}"
        if reader.get(key) is None:
            break
        keys.append(key)
    return keys


def strings(param, path: Path, key: str) -> list[str]:
    """A string parameter as a list of stripped strings (validated before slicing)."""
    if param is None:
        return []
    dims = [int(d) for d in param.dimensions]
    if param.bytes_per_element != -1:
        raise C3DError(f"parameter {key} should hold text", path=path)
    if not dims:
        return [clean(param.bytes)]
    width = dims[0]
    count = math.prod(dims[1:])
    if width == 0:  # zero-width strings: nothing stored, whatever the count says
        return []
    if width * count > len(param.bytes):
        raise C3DError(f"parameter {key} declares {count} strings of {width} characters but "
                       f"holds {len(param.bytes)} bytes", path=path, hint="the file is corrupt")
    raw = param.bytes
    return [clean(raw[i * width:(i + 1) * width]) for i in range(count)]


def clean(raw: bytes) -> str:
    """Text of a C3D string: UTF-8 (else Latin-1), NULs and padding removed, control
    characters escaped (:func:`mocaplib.io.printable`)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    text = text.replace("\x00", "").strip()
    return text if text.isprintable() else printable(text, keep="")   # most labels: as they are


def number(reader, key: str, kind: str, default=None):
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
