"""Small C3D files for the reader's tests, and the byte edits that damage them.

``SMALL``: 12 frames of a 20-marker standing person with one Foot Strike event, written by
mocaplib's writer. :func:`parameter_record` finds a parameter's record in a file's bytes;
:func:`with_scale` edits POINT:SCALE in the header and the parameter section alike.
"""

from __future__ import annotations

import io
import struct
import warnings
from pathlib import Path

import numpy as np

from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_params import parameter_records
from mocaplib.io.c3d_write import c3d_bytes
from mocaplib.trial import Event, Trial


def standing_person(frames=50, seed=5):
    """A crude 1.7 m person walking along +X, Z up: (F, 20, 3) metres."""
    rng = np.random.default_rng(seed)
    heights = np.linspace(0.05, 1.7, 20)
    body = np.column_stack([rng.normal(0, 0.08, 20), rng.normal(0, 0.15, 20), heights])
    travel = np.linspace(0, 2.0, frames)[:, None, None] * np.array([1.0, 0, 0])
    return body[None] + travel


def small_file_bytes() -> bytes:
    markers = standing_person(frames=12)
    markers[4:6, 3] = np.nan
    return c3d_bytes(markers, [f"M{i}" for i in range(20)], 100.0,
                     events=[Event("Left", "Foot Strike", 0.05)])


SMALL = small_file_bytes()
#: The byte after SMALL's last frame (12 frames of 20 points, 4 float words each).
SMALL_DATA_END = (struct.unpack_from("<H", SMALL, 16)[0] - 1) * 512 + 12 * 20 * 4 * 4


def parameter_record(data: bytes, group: str, name: str):
    """The record of parameter GROUP:NAME in a file's parameter section."""
    records, _ = parameter_records(data)
    groups = {-r.group: r.name.decode() for r in records if r.group < 0}
    return next(r for r in records if r.group > 0 and groups[r.group] == group
                and r.name.decode() == name)


def with_scale(data: bytes, factor: float) -> bytes:
    """``data`` with POINT:SCALE (parameter and header) multiplied by ``factor``."""
    out = bytearray(data)
    record = parameter_record(data, "POINT", "SCALE")
    at = record.link_at + 2 + 2 + data[record.link_at + 3]  # after type, dimensions
    for offset in (at, 12):  # the parameter, and the header's copy (words 7-8)
        struct.pack_into("<f", out, offset, struct.unpack_from("<f", data, offset)[0] * factor)
    return bytes(out)


def read_c3d_bytes(data: bytes, folder: Path) -> Trial:
    path = folder / "original.c3d"
    path.write_bytes(data)
    return read_c3d(path)


# ----------------------------------------------------------------------------- any layout
def capture_bytes(markers, labels, rate: float = 100.0, *, analog: tuple[int, int] = (0, 1),
                  scale: float = -1.0, point_params: dict[str, list[str]] | None = None,
                  screen: tuple[str, str] | None = None) -> bytes:
    """A C3D file (Intel) written by the ``c3d`` package: ``markers`` (F, M, 3) metres (NaN =
    missing: residual -1) stored in mm, float storage (``scale`` < 0) or int16 x ``scale``
    mm; ``analog`` = (channels, samples per frame) of made-up samples, ANALOG:RATE = rate x
    samples per frame; ``point_params`` adds POINT string parameters (``{"ANGLES":
    ["LHipAngles"]}``); ``screen`` sets POINT:X_SCREEN and Y_SCREEN (``("+X", "+Z")``)."""
    import c3d

    markers = np.asarray(markers, dtype=np.float64)
    channels, per_frame = analog
    writer = c3d.Writer(point_rate=rate, analog_rate=rate * per_frame, point_scale=scale)
    if len(labels):
        writer.set_point_labels(list(labels))
    if channels:
        writer.set_analog_labels([f"CH{i}" for i in range(channels)])
    for name, texts in (point_params or {}).items():
        width = max(1, max(len(text) for text in texts))
        writer.point_group.add_str(name, name, "".join(t.ljust(width) for t in texts),
                                   width, len(texts))
    if screen:
        writer.set_screen_axis(*screen)
    samples = 1.0 + np.arange(channels * per_frame, dtype=np.float32).reshape(channels,
                                                                            per_frame)
    frames = np.empty((len(markers), 2), dtype=object)  # (points, analog) pairs, any shapes
    for pair, frame in zip(frames, markers):
        seen = np.isfinite(frame).all(axis=1)
        points = np.zeros((len(frame), 5))
        points[seen, :3] = frame[seen] * 1000.0
        points[:, 3] = np.where(seen, 0.0, -1.0)
        pair[0], pair[1] = points, samples
    writer.add_frames(frames)
    buffer = io.BytesIO()
    with warnings.catch_warnings():      # "No analog data found in file."
        warnings.simplefilter("ignore")
        writer.write(buffer)
    return buffer.getvalue()


def data_start(data: bytes) -> int:
    """Byte offset of the first frame (header word 9: the data block)."""
    return (struct.unpack_from("<H", data, 16)[0] - 1) * 512


def with_header_word(data: bytes, word: int, value: int) -> bytes:
    """``data`` with the header's 16-bit word number ``word`` (1-based, as the C3D standard
    counts: 2 points, 3 analog words per frame, 4 first frame, 5 last frame) set to ``value``."""
    out = bytearray(data)
    struct.pack_into("<H", out, 2 * (word - 1), value)
    return bytes(out)


def _record(data: bytes, key: str):
    group, name = key.split(":")
    return parameter_record(data, group, name)


def with_parameter(data: bytes, key: str, *values) -> bytes:
    """``data`` with the numbers of parameter ``GROUP:NAME`` overwritten in place by
    ``values``, in the parameter's own type (16-bit integers or floats)."""
    record, out = _record(data, key), bytearray(data)
    kind = {2: "<H", 4: "<f"}[data[record.link_at + 2]]
    at = record.link_at + 4 + data[record.link_at + 3]         # after type and dimensions
    for i, value in enumerate(values):
        struct.pack_into(kind, out, at + i * struct.calcsize(kind), value)
    return bytes(out)


def with_text(data: bytes, key: str, text: str) -> bytes:
    """``data`` with the text parameter ``GROUP:NAME`` overwritten in place by ``text``,
    padded with spaces to the stored width (it must fit)."""
    record, out = _record(data, key), bytearray(data)
    width = data[record.link_at + 4]                           # the first dimension
    assert len(text) <= width, f"{text!r} is longer than {key}'s {width} characters"
    at = record.link_at + 4 + data[record.link_at + 3]
    out[at:at + width] = text.ljust(width).encode()
    return bytes(out)


def without(data: bytes, key: str) -> bytes:
    """``data`` with parameter ``GROUP:NAME`` renamed ``X...`` in place: a reader looking for
    it finds nothing (as in files whose writer leaves it out)."""
    record, out = _record(data, key), bytearray(data)
    out[record.position + 2] = ord("X")
    return bytes(out)


def cut_after(data: bytes, frames: int, frame_bytes: int) -> bytes:
    """``data`` cut right after its ``frames``-th frame of ``frame_bytes`` bytes: no padding."""
    return data[:data_start(data) + frames * frame_bytes]
