"""The vertical axis of a C3D file's markers (:func:`detect_vertical_axis`) and the rotation
of a Y-up file to Z up (:func:`y_up_to_z_up`)."""

from __future__ import annotations

import numpy as np

from ..numeric import distinct, percentile
from .c3d_params import clean

_AXIS_SAMPLE_FRAMES = 60     # frames looked at to detect the vertical axis
_AXIS_MIN_RATIO = 1.25       # the vertical spread must exceed the next one by this factor


def screen_up_axis(reader) -> str | None:
    """The axis POINT:Y_SCREEN shows upwards ('X', 'Y' or 'Z'), when the file says."""
    param = reader.get("POINT:Y_SCREEN")
    if param is None or param.bytes_per_element != -1:
        return None
    text = clean(param.bytes[:8]).upper()
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
    offsets = np.concatenate(offsets) if offsets else np.empty((0, 3))
    fallback = screen_axis if screen_axis in ("Y", "Z") else "Z"
    if markers.shape[1] == 0:
        return fallback, notes                  # no markers: only the file's word
    spread = np.zeros(3)
    if len(offsets) >= 10:
        low, high = percentile(offsets.T, [10, 90], axis=1)
        spread = high - low
    order = np.argsort(spread)[::-1]
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
