"""Small C3D files for the reader's tests, and the byte edits that damage them.

``SMALL``: 12 frames of a 20-marker standing person with one Foot Strike event, written by
mocaplib's writer. :func:`parameter_record` finds a parameter's record in a file's bytes;
:func:`with_scale` edits POINT:SCALE in the header and the parameter section alike.
"""

from __future__ import annotations

import struct
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
