"""The force plates of a C3D file (:func:`read_force_plates`): each plate's vertical force in
newtons at the analog rate, and its corners in metres in the Trial's frame.

A frame's analog words follow its points, ``(samples per frame, ANALOG:USED)``, stored as the
points are (int16 when POINT:SCALE > 0, uint16 when ANALOG:FORMAT is ``UNSIGNED``, float32
when < 0). Channel ``c`` reads (word - ANALOG:OFFSET[c]) x ANALOG:SCALE[c] x ANALOG:GEN_SCALE
(OFFSET 0, SCALE and GEN_SCALE 1 when absent; OFFSET2, SCALE2... past 255 channels). Only the
plates' channels are kept. The vertical force (:data:`VERTICAL_CHANNELS`) is the Fz channel
of types 1 and 2, the sum of the four Fz of type 3, CAL_MATRIX's third row applied to the six
channels of type 4; its largest deviation from the median is made positive and the median of
the samples under a tenth of the peak (the empty plate's zero) removed.

A plate that cannot be read is skipped with one note naming it and why; one whose vertical
force is constant (nobody stood on it) is left out without one. Nothing here raises.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import C3DError
from ..numeric import median
from .c3d_axis import to_z_up
from .c3d_layout import PointLayout
from .c3d_params import dec_to_ieee, number, strings
from .c3d_points import frame_chunks

#: The rows of a plate's FORCE_PLATFORM:CHANNEL column (0-based) its vertical force is made
#: of, per TYPE.
VERTICAL_CHANNELS = {1: (2,), 2: (2,), 3: (4, 5, 6, 7), 4: (0, 1, 2, 3, 4, 5)}
_CONTINUED = 100             # ANALOG:SCALE, SCALE2 ... SCALE99: far beyond any real file


@dataclass(frozen=True)
class ForcePlate:
    """One force plate of a C3D file; analog sample ``k`` lies ``k / rate`` s after the
    trial's first frame."""

    number: int            # 1-based place in the FORCE_PLATFORM group
    kind: int              # FORCE_PLATFORM:TYPE, 1 to 4
    corners: np.ndarray    # (4, 3) metres, the Trial's frame (Z up)
    force: np.ndarray      # (A,) newtons, vertical, > 0 under load, empty-plate zero removed
    rate: float            # Hz: the frame rate x the analog samples a frame holds


@dataclass(frozen=True)
class _Plate:
    """What the parameters say of one plate."""

    number: int
    kind: int
    channels: tuple[int, ...]        # 0-based analog channels, in VERTICAL_CHANNELS' order
    corners: np.ndarray              # (4, 3) metres, the Trial's frame
    weights: np.ndarray | None       # type 4: CAL_MATRIX's third row (6,); else None


def read_force_plates(handle, reader, layout: PointLayout, to_metres: float,
                      vertical_axis: str, path: Path, notes: list[str]) -> list[ForcePlate]:
    """The force plates of the C3D file open in ``handle``, whose parameters ``reader``
    holds and whose frames sit as ``layout`` says; ``to_metres`` converts POINT:UNITS to
    metres; a ``vertical_axis`` other than ``"Z"`` turns the corners to Z up as the markers. A plate
    that cannot be read is skipped with a note in ``notes``; no FORCE_PLATFORM group or
    FORCE_PLATFORM:USED 0 gives none, without a note. Never raises."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):   # corrupt words: noted as such
            return _read_plates(handle, reader, layout, to_metres, vertical_axis, path, notes)
    except Exception as exc:
        notes.append(f"force plates not read: {_reason(exc)}; gait events come from the "
                     "markers")
        return []


def _read_plates(handle, reader, layout: PointLayout, to_metres: float, vertical_axis: str,
                 path: Path, notes: list[str]) -> list[ForcePlate]:
    """:func:`read_force_plates`, raising what concerns every plate."""
    count = _values(reader, "FORCE_PLATFORM:USED", signed=False, whole=True)
    if count is None or not count.size or not count[0]:
        return []
    samples, channels_used = _samples_per_frame(reader, layout)
    unsigned = any(text.upper() == "UNSIGNED" for text in
                   strings(reader.get("ANALOG:FORMAT"), path, "ANALOG:FORMAT"))
    scales = _per_channel(reader, "SCALE", signed=True)
    offsets = _per_channel(reader, "OFFSET", signed=not unsigned)
    plates = []
    for index in range(int(count[0])):
        try:
            plates.append(_plate(reader, index, channels_used, scales, offsets, to_metres,
                                 vertical_axis))
        except Exception as exc:
            notes.append(_skipped(index + 1, exc))
    channels = sorted({channel for plate in plates for channel in plate.channels})
    if not channels:
        return []
    values = _channel_words(handle, layout, samples, channels_used, channels, unsigned,
                            path)
    values -= 0.0 if offsets is None else offsets[channels]
    values *= 1.0 if scales is None else scales[channels]
    values *= number(reader, "ANALOG:GEN_SCALE", "float", 1.0)
    out = []
    for plate in plates:
        try:
            force = _vertical(values[:, [channels.index(c) for c in plate.channels]], plate)
        except Exception as exc:
            notes.append(_skipped(plate.number, exc))
            continue
        if force is not None:
            out.append(ForcePlate(plate.number, plate.kind, plate.corners, force,
                                  layout.rate * samples))
    return out


def _skipped(number: int, exc: Exception) -> str:
    """The note on plate ``number`` (1-based), skipped for ``exc``."""
    return f"force plate {number} not read: {_reason(exc)}; gait events come from the " \
           "markers there"


def _reason(exc: Exception) -> str:
    """Why ``exc`` stopped the reading: a :class:`C3DError`'s message, else its type and text."""
    return exc.message if isinstance(exc, C3DError) else f"{type(exc).__name__}: {exc}"


# ----------------------------------------------------------------------------- parameters
def _values(reader, key: str, *, signed: bool = True, whole: bool = False
            ) -> np.ndarray | None:
    """The numbers of parameter ``key`` (bytes, 16-bit integers or floats) as float64, None
    when it is absent or text; ``whole``: they must be whole numbers, returned as int64."""
    param = reader.get(key)
    if param is None or param.bytes_per_element == -1:
        return None
    size = abs(param.bytes_per_element)
    if size == 4:
        values = param.float_array.astype(np.float64)
    elif size == 2:
        words = param.uint16_array
        values = (words.view(np.int16) if signed else words).astype(np.float64)
    else:
        values = np.frombuffer(param.bytes, np.int8 if signed else np.uint8).astype(np.float64)
    if not whole:
        return values
    if not (np.isfinite(values) & (values == np.round(values))).all():
        raise C3DError(f"{key} holds values that are not whole numbers")
    return values.astype(np.int64)


def _samples_per_frame(reader, layout: PointLayout) -> tuple[int, int]:
    """The analog samples per frame and ANALOG:USED, the channels of each sample."""
    words = layout.words - 4 * layout.count
    used = _values(reader, "ANALOG:USED", signed=False, whole=True)
    used = int(used[0]) if used is not None and used.size else 0
    if not used or not words:
        raise C3DError(f"the file holds no analog samples (ANALOG:USED {used}, {words} "
                          "analog words a frame)")
    if words % used:
        raise C3DError(f"the {words} analog words of a frame are no whole number of "
                          f"samples of the {used} channels of ANALOG:USED")
    return words // used, used


def _per_channel(reader, name: str, *, signed: bool) -> np.ndarray | None:
    """ANALOG:``name`` continued by ``name``2, ``name``3... (files of over 255 channels),
    one value per channel; None when absent."""
    parts = []
    for index in range(1, _CONTINUED):
        values = _values(reader, f"ANALOG:{name}{index if index > 1 else ''}", signed=signed)
        if values is None:
            break
        parts.append(values)
    return np.concatenate(parts) if parts else None


def _plate(reader, index: int, used: int, scales: np.ndarray | None,
           offsets: np.ndarray | None, to_metres: float, vertical_axis: str) -> _Plate:
    """The plate at ``index`` (0-based) as the parameters describe it; :class:`C3DError`
    saying why it cannot be read; ``used`` is ANALOG:USED, ``scales`` and ``offsets``
    ANALOG:SCALE and OFFSET (None when absent)."""
    types = _values(reader, "FORCE_PLATFORM:TYPE", whole=True)
    if types is None or types.size <= index:
        raise C3DError("FORCE_PLATFORM:TYPE gives no type for it")
    kind = int(types[index])
    if kind not in VERTICAL_CHANNELS:
        raise C3DError(f"FORCE_PLATFORM:TYPE {kind} is none of the types 1 to 4")
    rows = VERTICAL_CHANNELS[kind]
    numbers = _values(reader, "FORCE_PLATFORM:CHANNEL", whole=True)
    dimensions = reader.get("FORCE_PLATFORM:CHANNEL").dimensions if numbers is not None else ()
    per_plate = dimensions[0] if dimensions else 0
    if per_plate <= rows[-1] or numbers.size < (index + 1) * per_plate:
        raise C3DError(f"FORCE_PLATFORM:CHANNEL gives it no channel {rows[-1] + 1} "
                          f"(type {kind} needs channels {rows[0] + 1} to {rows[-1] + 1})")
    chosen = numbers[index * per_plate + np.array(rows)]
    for channel in chosen:
        if not 1 <= channel <= used:
            raise C3DError(f"FORCE_PLATFORM:CHANNEL names channel {channel} of {used}")
    for name, values in (("SCALE", scales), ("OFFSET", offsets)):
        if values is not None and values.size < chosen.max():
            raise C3DError(f"ANALOG:{name} holds {values.size} values, none for channel "
                              f"{chosen.max()}")
    corners = _values(reader, "FORCE_PLATFORM:CORNERS")
    if corners is None or corners.size < 12 * (index + 1):
        raise C3DError("FORCE_PLATFORM:CORNERS gives no corners for it")
    corners = corners[12 * index:12 * index + 12].reshape(4, 3) * to_metres
    weights = None
    if kind == 4:
        matrix = _values(reader, "FORCE_PLATFORM:CAL_MATRIX")
        if matrix is None or matrix.size < 36 * (index + 1) or \
                reader.get("FORCE_PLATFORM:CAL_MATRIX").dimensions[:2] != (6, 6):
            raise C3DError("FORCE_PLATFORM:CAL_MATRIX gives no 6 x 6 matrix for it")
        # stored column by column (the first index varies fastest): its third row
        weights = matrix[36 * index:36 * index + 36].reshape(6, 6)[:, 2]
    if not (np.isfinite(corners).all() and (weights is None or np.isfinite(weights).all())):
        raise C3DError("FORCE_PLATFORM:CORNERS or CAL_MATRIX hold values that are not finite")
    return _Plate(index + 1, kind, tuple(int(c) - 1 for c in chosen),
                  to_z_up(corners, vertical_axis), weights)


# ----------------------------------------------------------------------------- samples
def _channel_words(handle, layout: PointLayout, samples: int, used: int,
                   channels: list[int], unsigned: bool, path: Path) -> np.ndarray:
    """The words of analog ``channels`` (0-based) as stored, DEC floats converted: (frames x
    ``samples``, len(channels)) float64, read a chunk of frames at a time
    (:func:`~mocaplib.io.c3d_points.frame_chunks`)."""
    is_float = layout.scale < 0
    kind = ("u4" if layout.processor == "DEC" else "f4") if is_float else \
        "u2" if unsigned else "i2"
    dtype = np.dtype((">" if layout.processor == "MIPS" else "<") + kind)
    out = np.empty((layout.frames * samples, len(channels)))
    for first, chunk, view in frame_chunks(handle, layout, path):
        words = np.frombuffer(view, dtype=dtype, count=chunk.frames * layout.words)
        block = words.reshape(chunk.frames, layout.words)[:, 4 * layout.count:]
        block = block.reshape(chunk.frames, samples, used)[:, :, channels]
        if is_float and layout.processor == "DEC":
            block = dec_to_ieee(block)
        out[first * samples:(first + chunk.frames) * samples] = block.reshape(-1, len(channels))
    return out


def _vertical(values: np.ndarray, plate: _Plate) -> np.ndarray | None:
    """The vertical force (A,) N of a plate's channels ``values`` (A, K), physical units:
    > 0 under load, the median of the samples under a tenth of the peak removed; None when
    it is constant (nobody stood on the plate) or never under a tenth of its peak (someone
    stood on it throughout, a static, or its zero is far off: its empty zero is unknown, and
    it holds no stance's start or end)."""
    force = values @ plate.weights if plate.weights is not None else values.sum(axis=1)
    if not np.isfinite(force).all():
        raise C3DError("its channels hold values that are not finite")
    if force.min() == force.max():
        return None
    force = force * np.sign(force[np.argmax(np.abs(force - median(force)))])
    empty = force < 0.1 * force.max()
    return force - median(force[empty]) if empty.any() else None
