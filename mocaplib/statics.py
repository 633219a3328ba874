"""Standing statics: how far a capture's markers move, its quietest stretch, whether it stands
still enough to calibrate on, and the names people read for statics.

Markers are ``(F, M, 3)`` arrays in metres, NaN where unseen; times are seconds from a trial's
first frame.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from .errors import CalibrationError
from .numeric import median, nanmedian
from .trial import Trial

#: What a static trial's pose is taken to be: "neutral" (anatomical, every joint angle 0) or
#: "free" (unknown: fitted, like a motion).
STATIC_POSES = ("neutral", "free")


#: How far (m) a static trial's markers may move, each over the whole trial (median over the
#: markers), and the trial still count as standing. Measured: 1-9 mm on the statics at hand
#: (the samples' rest, motonms Static1, biomechzoo HC030A01, btkdata PiG_Calibration2), 0.2 m
#: turning on the spot, metres walking.
STANDING_EXTENT = 0.05


#: Shortest stretch (s) of a static that moves (a step-in, a turn) taken for calibration: the
#: quietest one of that length (:func:`standing_part`).
STATIC_WINDOW_S = 1.0


#: Fewest markers with a finite position, and least span of their median heights (m), of a
#: trial that shows a standing person (:func:`check_person`): a pelvis and a foot marker
#: already span 0.8 m on an adult.
MIN_STATIC_MARKERS = 3
MIN_STATIC_HEIGHT = 0.3


def check_standing(static: Trial, *, moved: float | None = None) -> None:
    """Raise :class:`CalibrationError` naming ``static`` when it shows no person
    (:func:`check_person`) or its markers move like a motion's (median extent over the markers
    above :data:`STANDING_EXTENT`): a walk given as the static calibrates a subject in
    mid-stride. ``moved``: :func:`moved_extent` of its markers, when already computed."""
    check_person(static)
    moved = moved_extent(static.markers) if moved is None else moved
    if moved > STANDING_EXTENT:   # NaN, no marker seen: calibration refuses it with its reason
        raise CalibrationError(
            f"is not a standing static trial: its markers move {moved:.2f} m (median over the "
            f"markers; a static moves less than {STANDING_EXTENT * 100:.0f} cm)",
            path=static.source, hint="give the static calibration trial (the subject standing "
                                     "still) as --static, and the motion as a capture")


def check_person(static: Trial) -> None:
    """Raise :class:`CalibrationError` naming ``static`` unless it shows a person: at least
    :data:`MIN_STATIC_MARKERS` markers with finite positions, whose median heights span at
    least :data:`MIN_STATIC_HEIGHT` (no marker seen, all NaN or all beyond the reader's range,
    or every marker at one place, stands still but is no one to calibrate)."""
    seen = np.isfinite(static.markers).all(axis=2).any(axis=0)
    hint = "give the static calibration trial (the subject standing still, markers seen)"
    if seen.sum() < MIN_STATIC_MARKERS:
        raise CalibrationError(
            f"is not a standing static trial: {seen.sum()} of its {static.n_markers} markers "
            f"have a finite position in some frame (a person shows at least "
            f"{MIN_STATIC_MARKERS})", path=static.source, hint=hint)
    heights = nanmedian(static.markers[:, seen, 2], axis=0)
    if not np.ptp(heights) >= MIN_STATIC_HEIGHT:
        raise CalibrationError(
            f"is not a standing static trial: its markers span {np.ptp(heights):.3g} m in "
            f"height (a standing person at least {MIN_STATIC_HEIGHT:g} m: markers at one "
            "place)", path=static.source, hint=hint)


def standing_part(static: Trial, /, *, window: tuple[float, float] | None = None
                  ) -> tuple[Trial, tuple[float, float]]:
    """The stretch of a static trial to calibrate on, and its (start, end) seconds from the
    static's first frame.

    ``window`` (start, end) seconds: that stretch (the frames within it). Without one, the
    whole static when it stands still (:func:`check_standing`), otherwise its quietest stretch
    of :data:`STATIC_WINDOW_S` (a subject stepping in or turning before standing still): the
    one whose markers move least (median over the markers seen in most of it of each marker's
    extent). A static shorter than that, a single frame included, is taken whole. Raises
    :class:`CalibrationError` naming the static when the stretch does not stand still, or a
    ``window`` holds no frame of it.
    """
    n = static.n_frames
    if window is not None:
        start, end = (float(value) for value in window)
        frames = np.flatnonzero((static.time >= start - 1e-9) & (static.time <= end + 1e-9))
        if not (end > start or (end == start and frames.size)) or not frames.size:
            raise CalibrationError(f"the static window {start:g}-{end:g} s holds no frame of "
                                   f"the static ({n} frames, 0-{static.duration:.3g} s)",
                                   path=static.source,
                                   hint="give START:END within the static, in seconds from "
                                        "its first frame")
        lo, hi, moved = int(frames[0]), int(frames[-1]) + 1, None
    else:
        lo, hi = 0, n
        length = int(round(STATIC_WINDOW_S * static.rate)) + 1
        moved = moved_extent(static.markers)
        if n > length and moved > STANDING_EXTENT:
            lo = quietest_stretch(static.markers, length)
            hi = lo + length
    span = (lo / static.rate, (hi - 1) / static.rate)
    if (lo, hi) == (0, n):
        check_standing(static, moved=moved)
        return static, span
    part = replace(static, markers=static.markers[lo:hi], first_frame=static.first_frame + lo,
                   events=[], warnings=list(static.warnings))
    check_person(part)
    moved = moved_extent(part.markers)
    if moved > STANDING_EXTENT:
        which = "the window" if window is not None else f"its quietest {STATIC_WINDOW_S:g} s"
        raise CalibrationError(
            f"is not a standing static trial: even {which} ({span[0]:.2f}-{span[1]:.2f} s) "
            f"moves {moved:.2f} m (median over the markers; a static moves less than "
            f"{STANDING_EXTENT * 100:.0f} cm)", path=static.source,
            hint="give the static calibration trial (the subject standing still) as --static, "
                 "or the stretch where the subject stands with --static-window START:END")
    return part, span


def moved_extent(markers: np.ndarray, /) -> float:
    """Median over the markers seen in ``markers`` (F, M, 3) of each one's extent (m), NaN
    when none is seen."""
    seen = np.isfinite(markers).all(axis=2).any(axis=0)
    if not seen.any():
        return float("nan")
    points = markers[:, seen]
    return float(median(np.linalg.norm(np.nanmax(points, axis=0) - np.nanmin(points, axis=0),
                                          axis=1)))


def quietest_stretch(markers: np.ndarray, length: int, /) -> int:
    """First frame of the ``length`` frames of ``markers`` (F, M, 3) whose markers move least:
    the median over the markers seen in at least half of the stretch of their extent, among
    the stretches that see at least 90 % of the most markers any stretch sees."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    n = len(markers) - length + 1
    origin = -(length // 2)     # each filter value covers [i, i + length)
    highest = maximum_filter1d(np.nan_to_num(markers, nan=-np.inf), length, axis=0,
                               origin=origin)[:n]
    lowest = minimum_filter1d(np.nan_to_num(markers, nan=np.inf), length, axis=0,
                              origin=origin)[:n]
    seen = np.isfinite(markers).all(axis=2).astype(float)
    counts = np.cumsum(np.vstack([np.zeros((1, seen.shape[1])), seen]), axis=0)
    enough = (counts[length:length + n] - counts[:n]) >= 0.5 * length          # (n, M)
    with np.errstate(invalid="ignore"):
        extent = np.linalg.norm(highest - lowest, axis=2)                      # (n, M)
    extent = np.where(enough & np.isfinite(extent), extent, np.nan)
    markers_seen = enough.sum(axis=1)
    candidates = markers_seen >= 0.9 * markers_seen.max()
    moved = nanmedian(extent, axis=1)                        # a stretch seeing no marker: NaN
    moved[~candidates | ~np.isfinite(moved)] = np.inf
    return int(np.argmin(moved))


def static_names(paths: Sequence[str]) -> list[str]:
    """Each static trial's name for people: its file name, with as many parent folders as it
    takes to tell apart statics whose names clash (``S1/Static.c3d``, ``S2/Static.c3d``)."""
    parts = [Path(os.path.abspath(path)).parts for path in paths]
    names = []
    for i, own in enumerate(parts):
        depth = 1
        while depth < len(own) and any(other[-depth:] == own[-depth:]
                                       for j, other in enumerate(parts) if j != i):
            depth += 1
        names.append("/".join(own[-depth:]))
    return names
