"""Decoding the POINT words of a C3D file into markers ``(F, M, 3)`` float64, NaN = missing.

Integer storage (POINT:SCALE > 0: coordinates = int16 x SCALE) or float storage (SCALE < 0),
for Intel, DEC (VAX F-float, converted vectorised) and SGI/MIPS (big-endian) processor types,
as whole numpy arrays (no per-frame Python loop). A sample is missing (NaN) when its residual
word is negative, when a coordinate is not finite or lies beyond :data:`MAX_COORDINATE_M` (a
corrupt word: garbage floats are mostly astronomically large), or when all three coordinates
are exactly 0 (how Vicon/CMU files store a missing sample with a non-negative residual; a real
marker never sits exactly at the origin). :func:`read_points` reads a file
:data:`CHUNK_BYTES` of frames at a time, skipping the analog samples between them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import C3DError
from .c3d_layout import PointLayout
from .c3d_params import dec_to_ieee

#: Bytes of frames (POINT words and the analog samples between them) read at a time.
CHUNK_BYTES = 1 << 23
#: Coordinates (m) beyond this are corrupt words, read as missing: no capture volume is near
#: 10 km across, and one stray sample of 1e17 m spoils its whole marker track in the low-pass
#: filter (and, with it, the markers calibrated against it).
MAX_COORDINATE_M = 1e4


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
        # in float64, into place in one pass: float32 and int16 words convert exactly
        np.multiply(block[..., :3], factor if is_float else factor * layout.scale, out=markers,
                    dtype=np.float64)
        x, y, z = markers[..., 0], markers[..., 1], markers[..., 2]
        valid = (block[..., 3] >= 0) & np.isfinite(x + y + z) & ((x != 0) | (y != 0) | (z != 0))
        bounded = not is_float and 32768 * abs(factor * layout.scale) <= bound   # int16 words
        if not (bounded or markers.min(initial=0.0) >= -bound
                and markers.max(initial=0.0) <= bound):
            valid &= (np.abs(x) <= bound) & (np.abs(y) <= bound) & (np.abs(z) <= bound)
    markers[~valid] = np.nan
    return markers


def read_points(handle, layout: PointLayout, points: list[int], factor: float,
                 path: Path) -> np.ndarray:
    """Markers (F, len(points), 3) of the file open in ``handle`` (:func:`decode_points`),
    ``factor`` its units to metres, coordinates beyond :data:`MAX_COORDINATE_M` missing; read
    :data:`CHUNK_BYTES` at a time (:func:`frame_chunks`); nothing is read when ``points`` is
    empty."""
    out = np.empty((layout.frames, len(points), 3))
    if not points:
        return out
    for first, chunk, view in frame_chunks(handle, layout, path):
        _decoded(_point_words(view, chunk, points), chunk, factor,
                 out=out[first:first + chunk.frames], bound=MAX_COORDINATE_M)
    return out


def frame_chunks(handle, layout: PointLayout, path: Path):
    """The frames of the file open in ``handle``, :data:`CHUNK_BYTES` of them at a time:
    ``(first frame, the chunk's layout (start 0), its bytes)`` each, the bytes a view of one
    buffer that the next chunk overwrites. Raises :class:`C3DError` if the file is shorter
    than ``layout`` says."""
    frame_bytes = layout.frame_bytes
    step = max(1, CHUNK_BYTES // frame_bytes)
    buffer = bytearray(min(step, layout.frames) * frame_bytes)
    handle.seek(layout.start)
    for first in range(0, layout.frames, step):
        chunk = replace(layout, start=0, frames=min(step, layout.frames - first))
        view = memoryview(buffer)[:chunk.frames * frame_bytes]
        if handle.readinto(view) != len(view):
            raise C3DError("the file is shorter than when it was opened (written to while "
                           "read?)", path=path, hint="read it again once it is complete")
        yield first, chunk, view
