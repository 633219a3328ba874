"""The vertical axis of a C3D file's markers (:func:`detect_vertical_axis`), the one its
screen axes name (:func:`screen_up_axis`), and the rotation of a Y-up or X-up file to Z up
(:func:`to_z_up`)."""

from __future__ import annotations

import numpy as np

from ..numeric import distinct, median
from .c3d_params import clean

_AXIS_SAMPLE_FRAMES = 60     # frames looked at to detect the vertical axis
_AXIS_MIN_RATIO = 1.25       # the vertical spread must exceed the next one by this factor
#: Metres: markers of one body are chained by steps shorter than this (the widest gap of a
#: sparse marker set, pelvis to thigh, is about 0.45 m); a point farther from all of them is
#: not on the body.
BODY_LINK_M = 0.75


def screen_up_axis(reader) -> str | None:
    """The axis ('X', 'Y' or 'Z') the file's screen shows upwards: POINT:Y_SCREEN's (``'+Z'``
    gives Z); without it, the axis neither POINT:X_SCREEN (the screen's right) nor
    POINT:Z_SCREEN (towards the viewer) names; None when the file does not say."""
    named = {}
    for key in ("X_SCREEN", "Y_SCREEN", "Z_SCREEN"):
        param = reader.get(f"POINT:{key}")
        if param is not None and param.bytes_per_element == -1:
            text = clean(param.bytes[:8]).upper()
            if text[-1:] in ("X", "Y", "Z"):
                named[key] = text[-1]
    if "Y_SCREEN" in named:
        return named["Y_SCREEN"]
    across = {named.get("X_SCREEN"), named.get("Z_SCREEN")}
    return ({"X", "Y", "Z"} - across).pop() if across <= {"X", "Y", "Z"} and \
        len(across) == 2 else None


def far_from_body(points: np.ndarray, /) -> np.ndarray:
    """Which of one subject's ``points`` (M, 3), metres, NaN = missing, of one frame lie
    outside the body's main cluster: bool (M,), False where missing.

    The main cluster holds the point nearest the median point and every point reached from
    it by steps shorter than :data:`BODY_LINK_M`; points far from the body (unlabelled
    strays, floor or equipment markers) fall outside it. When it holds fewer than half the
    points seen, or fewer than 3 (a file whose units are wrong spreads a body kilometres
    wide), no point is called far.
    """
    far = np.zeros(len(points), dtype=bool)
    seen = np.isfinite(points).all(axis=1)
    place = points[seen]
    if len(place) < 3:
        return far
    distance = np.linalg.norm(place - median(place, axis=0), axis=1)
    square = (place * place).sum(axis=1)
    near = square[:, None] + square[None] - 2.0 * place @ place.T <= BODY_LINK_M ** 2
    reach = np.arange(len(place)) == np.argmin(distance)
    frontier = reach
    while frontier.any():                   # breadth first: each point's row looked at once
        frontier = near[frontier].any(axis=0) & ~reach
        reach = reach | frontier
    if reach.sum() >= max(3, 0.5 * len(place)):
        far[seen] = ~reach
    return far


def detect_vertical_axis(markers: np.ndarray, /, *, screen_axis: str | None = None,
                         subjects: list[str] | None = None) -> tuple[str, list[str]]:
    """The file's vertical axis, ``"Z"``, ``"Y"`` or ``"X"``, from markers ``(F, M, 3)``
    (metres); and notes.

    Rule: a standing or walking person is longer than wide. In up to 60 evenly spaced frames,
    each subject's markers apart (``subjects``, length M, :func:`subject_prefixes`: the people
    of a file with several stand apart on the floor, which would otherwise look like one wide
    body; default: one subject), but those far from the body's main cluster in the frame
    seeing the most of them (:func:`far_from_body`: strays never decide), each marker is taken
    relative to the mean of its subject's markers in the frame, where 3 or more are seen; the
    axis with the widest spread of those offsets (10th to 90th percentile, nearest rank) is
    the body's long axis, i.e. vertical. It must beat the next axis by 25 %; otherwise (too few markers, a
    lying subject) ``screen_axis`` (:func:`screen_up_axis`) decides, and Z without it. When
    the screen axes name another axis than the markers, the markers win and a note says so.
    Without markers (M = 0) ``screen_axis`` (else Z) is returned without a note.
    """
    notes: list[str] = []
    fallback = screen_axis if screen_axis in ("X", "Y", "Z") else "Z"
    frames = markers.shape[0]
    if markers.shape[1] == 0 or frames == 0:
        return fallback, notes
    sample = markers[distinct(np.linspace(0, frames - 1, min(frames, _AXIS_SAMPLE_FRAMES))
                              .astype(int))]
    seen = np.isfinite(sample[..., 0]) & np.isfinite(sample[..., 1]) & np.isfinite(sample[..., 2])
    subjects = [""] * markers.shape[1] if subjects is None else list(subjects)
    groups = sorted(set(subjects))
    offsets = []
    for mine in [slice(None)] if len(groups) == 1 else [
            np.array([s == group for s in subjects]) for group in groups]:
        own, seen_own = sample[:, mine], seen[:, mine]
        fullest = own[np.argmax(seen_own.sum(axis=1))]         # the frame seeing the most
        seen_own = seen_own & ~far_from_body(fullest)[None]
        counts = seen_own.sum(axis=1)
        used = counts >= 3
        picked = np.take(own.reshape(-1, 3), np.flatnonzero(seen_own & used[:, None]), axis=0)
        counts = counts[used]
        mean = np.add.reduceat(picked, np.cumsum(counts) - counts) / counts[:, None] \
            if len(picked) else np.empty((0, 3))        # each frame's mean seen marker
        offsets.append(picked - np.repeat(mean, counts, axis=0))
    offsets = np.sort(np.concatenate(offsets).T, axis=1)      # (3, N), each axis sorted
    spread = np.zeros(3)
    if offsets.shape[1] >= 10:        # 10th to 90th percentile (nearest rank)
        last = offsets.shape[1] - 1
        spread = offsets[:, round(0.9 * last)] - offsets[:, round(0.1 * last)]
    order = np.argsort(spread)[::-1]
    if spread[order[0]] <= 0 or spread[order[0]] < _AXIS_MIN_RATIO * spread[order[1]]:
        notes.append(f"vertical axis unclear from the markers; {fallback} assumed"
                     + (" (the file's screen axes)" if screen_axis in ("X", "Y", "Z")
                        else ""))
        return fallback, notes
    axis = "XYZ"[order[0]]
    if screen_axis in ("X", "Y", "Z") and screen_axis != axis:
        notes.append(f"the file's screen axes (POINT:X_SCREEN, Y_SCREEN) show {screen_axis} "
                     f"up but the markers are vertical along {axis}; {axis} used")
    return axis, notes


#: How :func:`to_z_up` turns points whose vertical axis is the key: the source axis of each
#: new one (x, y, z) and its sign, and the turn in words.
Z_UP = {"Y": ((0, 2, 1), (1.0, -1.0, 1.0), "(x, y, z) -> (x, -z, y)"),
        "X": ((1, 2, 0), (1.0, 1.0, 1.0), "(x, y, z) -> (y, z, x)")}


def to_z_up(points: np.ndarray, axis: str, /) -> np.ndarray:
    """Points ``(..., 3)`` whose vertical axis is ``axis`` turned to Z up by a proper rotation
    (:data:`Z_UP`: Y up +90 degrees about X, X up by a cyclic exchange of the axes), so that
    left stays left; Z-up points unchanged (a copy)."""
    if axis == "Z":
        return points.copy()
    order, signs, _ = Z_UP[axis]
    return points[..., list(order)] * np.array(signs)
