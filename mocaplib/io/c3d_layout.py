"""Where the POINT data of a C3D file sit: :class:`PointLayout`, chosen from the header and
the parameters and checked against the file size before anything is allocated."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import C3DError
from .c3d_params import number

#: The largest frame count a 16-bit field holds: a file whose count is at it may hold more.
UINT16_MAX = 65535


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

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame (at least 1): its words, 4 bytes each in float storage, else 2."""
        return max(1, self.words * (4 if self.scale < 0 else 2))


def point_layout(reader, file_size: int, path: Path, notes: list[str]) -> PointLayout:
    """The layout of the POINT data of the file of ``file_size`` bytes whose header and
    parameters ``reader`` holds (:class:`~mocaplib.io.c3d_params.Parameters`); C3DError
    naming ``path`` when the file cannot hold it."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # corrupt words: checked below
            processor = reader.processor
            count = number(reader, "POINT:USED", "uint16", int(reader.point_count))
            scale = number(reader, "POINT:SCALE", "float", float(reader.scale_factor))
            rate = number(reader, "POINT:RATE", "float", None) or float(reader.frame_rate)
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


def frames_past_16_bits(handle, layout: PointLayout, size: int, notes: list[str]
                        ) -> PointLayout:
    """``layout`` with every frame the data section holds when the file counts
    :data:`UINT16_MAX` frames and holds more: a writer that stores the count in 16 bits only
    (ezc3d 1.7 does) can write no more, though it writes every frame. Whole frames past the
    count are read but those at the end whose words are all zero: the padding of the last
    512-byte block."""
    held = (size - layout.start) // layout.frame_bytes
    if layout.first_frame + layout.frames - 1 != UINT16_MAX or held <= layout.frames:
        return layout
    tail = min(held - layout.frames, -(-512 // layout.frame_bytes))
    handle.seek(layout.start + (held - tail) * layout.frame_bytes)
    words = np.frombuffer(handle.read(tail * layout.frame_bytes), np.uint8)
    padding = words.reshape(tail, -1).any(axis=1)[::-1].argmax() if words.any() else tail
    frames = held - padding
    if frames > layout.frames:
        notes.append(f"the file counts {layout.frames} frames, the most 16 bits hold, and its "
                     f"data section holds {frames}: all read")
    return replace(layout, frames=max(frames, layout.frames))
