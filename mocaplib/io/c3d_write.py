"""Write marker trajectories to a C3D file (with the ``c3d`` package's ``Writer``).

The file is Intel format, POINT data only (no analog channels), written atomically. The same
input always gives the same bytes. Markers go in as metres, Z up, NaN = missing; missing samples
are stored as invalid samples: residual -1 (their coordinates carry no meaning; readers go by
the residual, as the C3D standard says).

Storage
    Float (POINT:SCALE < 0) by default. With ``integer=True`` the coordinates are stored as
    16-bit integers times POINT:SCALE, where SCALE is the smallest power of two (in the file's
    units) that fits the largest coordinate; a power of two keeps the quantisation exact.
Labels
    Up to 255 in POINT:LABELS, the next 255 in POINT:LABELS2, then LABELS3... (the C3D
    convention Vicon Nexus uses); POINT:USED holds the total.
Events
    An EVENT group as Vicon Nexus writes it: USED, CONTEXTS, LABELS, DESCRIPTIONS, SUBJECTS,
    TIMES (2 x N float: minutes, seconds; time 0 is frame 1), ICON_IDS, GENERIC_FLAGS.
"""

from __future__ import annotations

import io
import math
import os
import struct
import warnings
from collections.abc import Sequence
from pathlib import Path

import c3d
import numpy as np

from ..errors import C3DError
from ..trial import Event
from .atomic import atomic_write_bytes

#: metres -> file units, for the units this writer accepts
UNIT_SCALE = {"mm": 1000.0, "cm": 100.0, "m": 1.0}
_LABELS_PER_PARAM = 255
_INT16_MAX = 32767
# Vicon Nexus' icon id, generic flag and description of the events it knows.
_EVENT_STYLE = {
    "foot strike": (1, 0, "The instant the heel strikes the ground"),
    "foot off": (2, 0, "The instant the toe leaves the ground"),
}


def write_c3d(path: str | os.PathLike, markers, labels: Sequence[str], rate: float, /, *,
              events: Sequence[Event] = (), units: str = "mm", integer: bool = False,
              first_frame: int = 1) -> Path:
    """Write markers ``(F, M, 3)`` (metres, Z up, NaN = missing) to the C3D file ``path``.

    ``labels`` has length M (at most 255 bytes each); ``rate`` is in Hz; ``units`` is
    POINT:UNITS (``"mm"``, ``"cm"`` or ``"m"``); ``events`` go into the EVENT group with their
    ``time_s`` on the lab clock (frame ``first_frame`` at ``(first_frame - 1) / rate``).
    Returns the path written. Raises :class:`C3DError` for input a C3D file cannot hold.
    """
    payload = c3d_bytes(markers, labels, rate, events=events, units=units, integer=integer,
                        first_frame=first_frame, path=path)
    return atomic_write_bytes(path, payload)


def c3d_bytes(markers, labels: Sequence[str], rate: float, /, *, events: Sequence[Event] = (),
              units: str = "mm", integer: bool = False, first_frame: int = 1,
              path: str | os.PathLike | None = None) -> bytes:
    """The bytes :func:`write_c3d` writes (``path`` only names the file in errors)."""
    markers = np.asarray(markers, dtype=np.float64)
    labels = [str(label) for label in labels]
    _check_input(markers, labels, rate, units, first_frame, path)
    values = markers * UNIT_SCALE[units]
    valid = np.isfinite(values).all(axis=2)
    scale = _integer_scale(values[valid], path) if integer else -1.0

    writer = c3d.Writer(point_rate=float(rate), point_scale=scale, point_units=units)
    point = writer.point_group
    for number, start in enumerate(range(0, len(labels), _LABELS_PER_PARAM), start=1):
        name = "LABELS" if number == 1 else f"LABELS{number}"
        _add_string_param(point, name, "Point labels", labels[start:start + _LABELS_PER_PARAM],
                          path)
    descriptions = min(len(labels), _LABELS_PER_PARAM)
    point.add_str("DESCRIPTIONS", "Point descriptions", " " * descriptions, 1, descriptions)
    writer.set_start_frame(first_frame)
    if events:
        _add_event_group(writer, events, path)

    frames = np.zeros(markers.shape[:2] + (5,))
    frames[..., :3] = np.where(valid[..., None], values, 0.0)
    if integer:  # exact multiples of the power-of-two scale: the writer's division is exact
        frames[..., :3] = np.rint(frames[..., :3] / scale) * scale
    frames[..., 3] = np.where(valid, 0.0, -1.0)
    no_analog = np.zeros((0, 0))
    for frame in frames:
        writer.add_frames([(frame, no_analog)])
    buffer = io.BytesIO()
    with warnings.catch_warnings():  # the package warns that the file has no analog data
        warnings.simplefilter("ignore")
        writer.write(buffer)
    return buffer.getvalue()


def _check_input(markers, labels, rate, units, first_frame, path) -> None:
    if markers.ndim != 3 or markers.shape[2] != 3:
        raise C3DError(f"markers must have shape (F, M, 3), got {markers.shape}", path=path)
    frames, count, _ = markers.shape
    if frames == 0 or count == 0:
        raise C3DError(f"nothing to write: {frames} frames of {count} markers", path=path)
    if len(labels) != count:
        raise C3DError(f"{len(labels)} labels for {count} markers", path=path)
    if count > 65535:
        raise C3DError(f"a C3D file holds at most 65535 points, got {count}", path=path)
    too_long = [label for label in labels if len(label.encode("utf-8")) > 255]
    if too_long:
        raise C3DError(f"label {too_long[0][:40]!r}... is longer than 255 bytes", path=path)
    if not (np.isfinite(rate) and rate > 0):
        raise C3DError(f"frame rate must be > 0 Hz, got {rate}", path=path)
    if units not in UNIT_SCALE:
        raise C3DError(f"units must be one of {sorted(UNIT_SCALE)}, got {units!r}", path=path)
    if not 1 <= first_frame <= 65535 or first_frame + frames - 1 > 2 ** 31:
        raise C3DError(f"first_frame must be in 1..65535, got {first_frame}", path=path)
    if np.isinf(markers).any():
        raise C3DError("markers contain infinite values; missing samples must be NaN",
                       path=path)


def _integer_scale(values: np.ndarray, path) -> float:
    """Smallest power-of-two POINT:SCALE such that every coordinate fits in an int16."""
    largest = float(np.abs(values).max()) if values.size else 0.0
    if largest == 0.0:
        return 1.0
    scale = 2.0 ** math.ceil(math.log2(largest / _INT16_MAX))
    if largest / scale > _INT16_MAX:  # rounding of the logarithm
        scale *= 2.0
    if not np.isfinite(scale) or scale > 1e30:
        raise C3DError(f"coordinates up to {largest:g} cannot be stored as integers",
                       path=path, hint="write float storage (integer=False)")
    return scale


def _pack_strings(texts: Sequence[str], width: int) -> bytes:
    return b"".join(text.encode("utf-8").ljust(width, b" ") for text in texts)


def _add_string_param(group, name: str, desc: str, texts: Sequence[str], path) -> None:
    """A C3D string array (at most 255 strings of at most 255 bytes) padded with spaces."""
    width = max(1, max(len(text.encode("utf-8")) for text in texts))
    if width > 255:
        raise C3DError(f"{group.name}:{name}: a text is longer than 255 bytes", path=path)
    group.add_param(name, desc=desc, bytes_per_element=-1, bytes=_pack_strings(texts, width),
                    dimensions=[width, len(texts)])


def _add_event_group(writer, events: Sequence[Event], path) -> None:
    events = sorted(events, key=lambda e: (e.time_s, e.context, e.label))
    if len(events) > 255:
        raise C3DError(f"a C3D EVENT group holds at most 255 events, got {len(events)}",
                       path=path)
    count = len(events)
    styles = [_EVENT_STYLE.get(e.label.strip().lower(), (0, 1, "")) for e in events]
    group = writer.add_group(writer.numeric_key_next, "EVENT", "Event group")
    group.add("USED", "Number of events", 2, "<h", count)
    _add_string_param(group, "CONTEXTS", "Context", [e.context for e in events], path)
    _add_string_param(group, "LABELS", "Label", [e.label for e in events], path)
    _add_string_param(group, "DESCRIPTIONS", "Description", [s[2] for s in styles], path)
    _add_string_param(group, "SUBJECTS", "Subject", [""] * count, path)
    minutes = [math.floor(e.time_s / 60.0) for e in events]
    times = [value for e, m in zip(events, minutes) for value in (m, e.time_s - 60.0 * m)]
    group.add("TIMES", "Time (minutes, seconds)", 4, None,
              struct.pack(f"<{2 * count}f", *times), 2, count)
    group.add("ICON_IDS", "Icon id", 2, None,
              struct.pack(f"<{count}h", *[s[0] for s in styles]), count)
    group.add("GENERIC_FLAGS", "Generic flag", 2, None,
              struct.pack(f"<{count}h", *[s[1] for s in styles]), count)
