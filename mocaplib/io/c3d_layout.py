"""Where the POINT data of a C3D file sit (:class:`PointLayout`), chosen from the header and
the parameters and checked against the file size before anything is allocated.

Each frame holds 4 words per point, then the analog words; the header and the parameters both
say how many points, analog words and frames there are, and files from some systems disagree
with themselves. :func:`point_layout` tries every combination of the values they declare:

* sources: points per frame from POINT:USED and the header (POINT:LABELS' count only votes);
  analog words per frame from the header, ANALOG:USED x ANALOG:RATE / POINT:RATE and
  ANALOG:USED x ANALOG:RATE / the header's rate; frames from TRIAL:ACTUAL_START_FIELD and
  ACTUAL_END_FIELD, the header's first and last frame, POINT:LONG_FRAMES and POINT:FRAMES
  (a count, not the last frame's number). A 16-bit frame count stopped at 65535 agrees with
  any larger one.
* A combination fits exactly when its frames fill the data section up to the zero padding of
  its last 512-byte block, loosely when the section holds more; one that needs more bytes
  than the section holds is never decoded.
* The best fits exactly before loosely, in the storage POINT:SCALE's sign declares before the
  other (floats only, and only fitting exactly: :func:`point_layout`), then agrees with more
  sources (the data section's own count of whole frames, its zero padding left out, is one),
  then comes first in the order the sources are listed above.
* A value read against another source's is named in ``notes`` with both values; when nothing
  fits, :class:`~mocaplib.errors.C3DError` names the values that disagree (or, when they all
  agree, says the file is truncated).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import C3DError
from .c3d_params import label_keys, number

#: The largest frame count a 16-bit field holds: a file whose count is at it may hold more.
UINT16_MAX = 65535
#: Writers pad the data section to whole 512-byte blocks: less than a block beyond the data
#: (the 17 real files at hand leave 0 to 416 bytes).
BLOCK = 512


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


@dataclass(frozen=True)
class _Field:
    """What the sources say of one quantity: ``values`` maps each value declared to the
    sources declaring it (in source order); ``voters`` sources that only vote (they are no
    candidates); ``saturated`` the 16-bit sources stopped at 65535."""

    name: str                                   # "points per frame", "frames"...
    values: dict[int, list[str]]
    voters: dict[int, list[str]] = field(default_factory=dict)
    saturated: frozenset[str] = frozenset()

    def agreeing(self, value: int) -> list[str]:
        """The sources that agree with ``value``: those declaring it, and the saturated ones
        below it."""
        return self.values.get(value, []) + self.voters.get(value, []) + [
            source for other, sources in self.values.items() if other < value
            for source in sources if source in self.saturated]

    def describe(self, value: int) -> str:
        """``value`` and the sources declaring it: ``"40 (the header, POINT:LABELS)"``."""
        return f"{value} ({', '.join(self.values[value] + self.voters.get(value, []))})"

    def disagreeing(self, value: int) -> list[int]:
        """The other values declared, but those only saturated sources declare below it."""
        agree = set(self.agreeing(value))
        return [v for v, sources in self.values.items() if not set(sources) <= agree]


def point_layout(reader, handle, file_size: int, path: Path, notes: list[str]) -> PointLayout:
    """The layout of the POINT data of the file open in ``handle`` (``file_size`` bytes),
    whose header and parameters ``reader`` holds
    (:class:`~mocaplib.io.c3d_params.Parameters`), chosen as the module says; a note in
    ``notes`` for each value read against another source's. C3DError naming ``path`` when no
    layout fits the file."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # corrupt words: checked below
            scale = number(reader, "POINT:SCALE", "float", float(reader.scale_factor))
            rate = number(reader, "POINT:RATE", "float", None) or float(reader.frame_rate)
            first_frame = int(reader.first_frame)
            fields = (_points(reader, path), _analog_words(reader, rate), _frames(reader))
    except C3DError:
        raise
    except Exception as exc:  # corrupt parameter values the package cannot convert
        raise C3DError(f"corrupt POINT parameters ({type(exc).__name__}: {exc})",
                       path=path) from None
    if not (np.isfinite(rate) and 0.1 <= rate < 1e6):
        raise C3DError(f"nonsense frame rate {rate} Hz", path=path, hint="the file is corrupt")
    if not np.isfinite(scale) or scale == 0:
        if any(fields[0].values):
            raise C3DError(f"nonsense POINT:SCALE {scale}", path=path,
                           hint="the file is corrupt")
        scale = 1.0              # no points: the scale only says the analog words are integers
    if not fields[2].values:
        raise C3DError(f"no frames (first frame {reader.header_first_frame}, last frame "
                       f"{reader.header_last_frame})", path=path,
                       hint="the capture is empty or the header is corrupt")
    start = (int(reader.data_block) - 1) * 512
    if start < 512:
        raise C3DError(f"nonsense data block number {int(reader.data_block)}", path=path)
    data_bytes = file_size - start
    tail = b""
    if data_bytes > 0:
        handle.seek(file_size - min(BLOCK, data_bytes))
        tail = handle.read(BLOCK)
    best = max(_fitting(fields, float(scale), data_bytes, tail), default=None)
    if best is None:
        raise _no_fit(fields, float(scale), start, file_size, path)
    count, words, frames, storage = best[1]
    for quantity, value in zip(fields, (count, words - 4 * count, frames)):
        others = quantity.disagreeing(value)
        if others:
            notes.append(f"the file disagrees with itself on the {quantity.name}: "
                         f"{quantity.describe(value)} against "
                         f"{', '.join(quantity.describe(v) for v in others)}; the data "
                         f"section ({data_bytes} bytes) fits {value}, which is read")
    if storage != scale:
        notes.append(f"POINT:SCALE {scale:g} says 16-bit integer storage, but the data section "
                     f"holds {data_bytes} bytes, what 32-bit float storage of these frames "
                     "needs: read as floats (the sign of POINT:SCALE is wrong: re-export the "
                     "file)")
    return PointLayout(reader.processor, start, frames, count, words, storage, float(rate),
                       first_frame)


def _fitting(fields: tuple[_Field, _Field, _Field], scale: float, data_bytes: int,
             tail: bytes):
    """``(rank, (points, words, frames, scale))`` of each combination of the declared values
    that fits a data section of ``data_bytes`` ending in ``tail``; the higher the rank, the
    better (see the module). Float storage against an integer POINT:SCALE only fits exactly:
    floats read as integers would be garbage (a subject hundreds of metres tall), so a file
    holding just what floats need has the sign of its POINT:SCALE wrong."""
    points, analog, frames = fields
    storages = [(True, scale)] + ([(False, -scale)] if scale > 0 else [])
    for (i, count), (j, samples), (k, n) in itertools.product(
            enumerate(points.values), enumerate(analog.values), enumerate(frames.values)):
        words = 4 * count + samples
        for declared, storage in storages:
            frame_bytes = words * (4 if storage < 0 else 2)
            needed = n * frame_bytes
            exact = 0 <= data_bytes - needed < BLOCK
            if needed > data_bytes or not (declared or exact):
                continue
            votes = (len(points.agreeing(count)) + len(analog.agreeing(samples))
                     + len(frames.agreeing(n))
                     + (frame_bytes > 0 and _held(data_bytes, frame_bytes, tail) == n))
            yield (exact, declared, votes, -i, -j, -k), (count, words, n, storage)


def _held(data_bytes: int, frame_bytes: int, tail: bytes) -> int:
    """The whole frames of ``frame_bytes`` a data section of ``data_bytes`` holds, those at
    its end whose bytes are all zero and start in its last 512 bytes (``tail``) left out: the
    padding of the last block."""
    held, offset = data_bytes // frame_bytes, data_bytes - len(tail)
    while held > 0 and (held - 1) * frame_bytes >= offset and not tail[
            (held - 1) * frame_bytes - offset:held * frame_bytes - offset].strip(b"\0"):
        held -= 1
    return held


def _no_fit(fields: tuple[_Field, _Field, _Field], scale: float, start: int, file_size: int,
            path: Path) -> C3DError:
    """The error of a file no declared layout fits: truncated when every source agrees, else
    the values that disagree."""
    if any(len(quantity.values) > 1 for quantity in fields):
        said = "; ".join(f"{q.name}: {', '.join(q.describe(v) for v in q.values)}"
                         for q in fields)
        return C3DError(f"no layout the header and the parameters describe fits the data "
                        f"section ({file_size - start} bytes from byte {start}): {said}",
                        path=path, hint="they disagree with each other and with the file "
                                        "size; re-export the file (or copy it again: it may "
                                        "be truncated)")
    count, analog, frames = (next(iter(quantity.values)) for quantity in fields)
    words = 4 * count + analog
    needed = start + frames * words * (4 if scale < 0 else 2)
    halved = " (or POINT:SCALE's sign is wrong: the file holds what 16-bit integer storage " \
             "of these frames needs)" if scale < 0 and 0 <= file_size - start - \
        2 * frames * words < BLOCK else ""
    return C3DError(f"truncated: {frames} frames of {count} points need {needed} bytes, the "
                    f"file has {file_size}{halved}", path=path,
                    hint="copy the file again or re-export it")


# ----------------------------------------------------------------------------- the sources
def _points(reader, path: Path) -> _Field:
    """Points per frame: POINT:USED, the header; the labels' count votes."""
    declared: dict[int, list[str]] = {}
    used = number(reader, "POINT:USED", "uint16")
    for value, source in ((used, "POINT:USED"), (int(reader.point_count), "the header")):
        if value is not None:
            declared.setdefault(value, []).append(source)
    labels = 0
    for key in label_keys(reader):
        param = reader.get(key)
        dims = param.dimensions if param.bytes_per_element == -1 else (0,)
        labels += 0 if dims and dims[0] == 0 else math.prod(dims[1:])   # width x count
    return _Field("points per frame", declared, {labels: ["POINT:LABELS"]} if labels else {})


def _analog_words(reader, rate: float) -> _Field:
    """Analog words per frame: the header; ANALOG:USED x the analog samples a frame holds,
    ANALOG:RATE over POINT:RATE and over the header's rate (a whole number, or no source)."""
    declared: dict[int, list[str]] = {int(reader.analog_count): ["the header"]}
    used = number(reader, "ANALOG:USED", "uint16")
    analog_rate = number(reader, "ANALOG:RATE", "float")
    if used is None or analog_rate is None:
        return _Field("analog words per frame", declared)
    point_rate = "POINT:RATE" if number(reader, "POINT:RATE", "float") else "the header's rate"
    for name, per_second in {point_rate: rate,
                             "the header's rate": float(reader.frame_rate)}.items():
        ratio = analog_rate / per_second if per_second else math.nan
        whole = round(ratio) if np.isfinite(ratio) and ratio >= 0.5 else 0
        if used == 0 or whole and abs(ratio - whole) <= 1e-3 * whole:
            declared.setdefault(used * whole, []).append(f"ANALOG:USED x ANALOG:RATE / {name}")
    return _Field("analog words per frame", declared)


def _frames(reader) -> _Field:
    """Frames: TRIAL:ACTUAL_START_FIELD/ACTUAL_END_FIELD (32 bits each), the header's first
    and last frame, POINT:LONG_FRAMES and POINT:FRAMES (counts); the 16-bit ones stopped at
    :data:`UINT16_MAX` are saturated."""
    declared: dict[int, list[str]] = {}
    saturated = set()

    def add(value: float, source: str, at_most_16_bits: bool = False) -> None:
        if np.isfinite(value) and value > 0:
            declared.setdefault(int(value), []).append(source)
            if at_most_16_bits:
                saturated.add(source)

    begin, end = (reader.get(f"TRIAL:ACTUAL_{key}_FIELD") for key in ("START", "END"))
    if begin is not None and end is not None and min(len(begin.bytes), len(end.bytes)) >= 4:
        (a, b), (c, d) = begin.uint16_array[:2], end.uint16_array[:2]
        add(int(c) + 65536 * int(d) - int(a) - 65536 * int(b) + 1,
            "TRIAL:ACTUAL_START_FIELD/ACTUAL_END_FIELD")
    last = int(reader.header_last_frame)
    add(last - int(reader.header_first_frame) + 1, "the header", last == UINT16_MAX)
    for key in ("POINT:LONG_FRAMES", "POINT:FRAMES"):
        param = reader.get(key)
        if param is None or len(param.bytes) < 2 or param.bytes_per_element not in (2, 4):
            continue
        if param.bytes_per_element == 4 and len(param.bytes) >= 4:
            add(param.float_value, key)
        elif param.bytes_per_element == 2:
            add(param.uint16_value, key, param.uint16_value == UINT16_MAX)
    return _Field("frames", declared, saturated=frozenset(saturated))



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
