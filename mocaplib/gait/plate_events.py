"""Gait events timed by force plates: where one foot alone loads a plate, the heel strike and
toe-off the markers place there are moved to the plate's loading and unloading, and the
markers' other toe-offs by how far the plates found them off.

A plate measures the instant a foot starts and stops bearing on it; the markers only show the
foot's motion about it (a toe-off from foot markers lies 5-20 ms from the plate's on the lab
files, docs/results/event_accuracy.md). Labs with force plates time their events on them where
a foot lands cleanly on one, and so does :func:`plate_timed`:

1. **Force.** A plate gives events when someone stood on it (its vertical force reaches
   :data:`PLATE_MIN_PEAK_N`) and it reads only its noise empty (the SD of its readings under a
   tenth of its peak is at most :data:`PLATE_MAX_EMPTY_SD_N`: an instrumented treadmill's
   belts, under both feet at once and shaken by the belt, read more), :func:`readable`.
2. **Loading and unloading.** Each run of at least :data:`PLATE_MIN_STANCE_S` above
   :data:`PLATE_THRESHOLD_N` is one stance on the plate: it starts at its first sample above
   the threshold and ends at the first sample below it (:func:`load_spans`). A recording that
   cut the force to zero from above the threshold (the software that wrote it zeroes a plate
   under a level of its own, 10-41 N on the files here) has the crossing extrapolated along
   the force's tangent (:func:`unloadings`).
3. **Whose foot.** The stance is one foot's when that foot's heel or toe marker lies over the
   plate (its corners' outline, :data:`ON_PLATE_MARGIN_M` inside) through the middle half of
   the stance and the other foot is never down with a marker over it (a swing foot passing
   over a plate bears nothing on it; a foot down on the next plate, a few millimetres away,
   is not on this one) (:func:`plate_contacts`). The plate times the foot's
   heel strike when its heel marker lies over it, its toe-off when its toe marker does (a
   foot half on a plate loads it late, or leaves it early, with the part that is off). A
   plate two feet share times nothing.
4. **Which events.** The plate's loading replaces that foot's heel strike, its unloading that
   foot's toe-off, when the markers placed the event (or saw it happen, not placed) within
   :data:`PLATE_MATCH_S`; an event the markers did not find is not added from a plate alone.
5. **The other toe-offs.** How late or early the markers place a toe-off depends on the foot
   and where its markers sit (on the shared files -6 to +20 ms from the plates, within
   1.4-6.8 ms of each other in five of the six captures with two or more): the toe-offs the
   markers place off the plates are moved by the median of the plates' unloadings minus the
   markers' toe-offs they replaced (those whose two marks agree, :attr:`GaitEvent.uncertain`,
   around which the foot's markers were measured),
   unless that median exceeds :data:`MAX_PLATE_SHIFT_S` (:func:`_shifted`). Heel strikes are
   left to the markers (moved the same way, theirs would lie farther from a left-out plate:
   docs/results/event_accuracy.md).

Forces in newtons, positions in metres (Z up), times in seconds from the capture's first frame
(analog sample ``k`` of a plate at ``k / rate``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..runs import valid_runs
from .foot_events import FootTrack, GaitEvent, nearest_frame
from .qc import QC_LIMITS

#: Vertical force (N) above which a plate is loaded: the common 20 N of the field's 10-50 N
#: thresholds (Tirosh & Sparrow 2003 compare them), 3 to 10 times the noise of the plates at
#: hand (SD 2-7.5 N).
PLATE_THRESHOLD_N = 20.0
#: Least peak force (N) of a plate someone stood on.
PLATE_MIN_PEAK_N = 100.0
#: Shortest stance (s) on a plate: a running stance lasts 0.15-0.3 s.
PLATE_MIN_STANCE_S = 0.1
#: Largest spread (SD, N) of a plate's readings under a tenth of its peak for it to time
#: events: the overground plates at hand spread 1.6-7.5 N; an instrumented treadmill's belts
#: 16-56 N (gaitalytics' treadmill test capture).
PLATE_MAX_EMPTY_SD_N = 10.0
#: How much of a plate's force (s) before the recording cut it to zero, or after it resumed,
#: gives the tangent a cut crossing is extrapolated along (:func:`unloadings`).
CLIP_TANGENT_S = 0.01
#: How far inside the plate's outline (m) a stance foot's heel and toe markers lie.
ON_PLATE_MARGIN_M = 0.01
#: Largest difference (s) between a plate's event and the markers' event it replaces.
PLATE_MATCH_S = 0.1
#: Largest shift (s) of the markers' toe-offs off the plates (step 5 of the module
#: docstring): on the shared files the markers' toe-offs lie -6 to +20 ms from the plates'
#: unloadings; a median farther away says a plate contact was misread, not a foot.
MAX_PLATE_SHIFT_S = 0.03
#: The least ``quality`` of a markers' toe-off that tells the others' shift (:func:`_calibrates`).
MIN_EVENT_QUALITY = QC_LIMITS["event_quality"][0]


class Unloading(NamedTuple):
    """One plate's unloading (:func:`unloadings`): when (s), and where the recording cut the
    force to zero from above the threshold, the force (N) and time (s) of the cut (None, None
    where it did not)."""

    time_s: float
    cut_n: float | None = None
    cut_s: float | None = None


@dataclass(frozen=True)
class PlateContact:
    """One foot's stance on a plate: the plate's ``number`` (1-based), the foot's ``side``,
    and the plate's loading and unloading (s; None where the recording starts or ends on
    it)."""

    plate: int
    side: str
    strike_s: float | None
    off_s: float | None


def readable(force: np.ndarray) -> bool:
    """Whether a plate's vertical force (A,) N can time events (step 1 of the module
    docstring)."""
    force = np.asarray(force, dtype=float)
    if not force.size or not np.isfinite(force).all():
        return False
    empty = force < 0.1 * force.max()
    return bool(force.max() >= PLATE_MIN_PEAK_N and empty.any()
                and np.std(force[empty]) <= PLATE_MAX_EMPTY_SD_N)


def unloadings(force: np.ndarray, rate: float, /, *, threshold_n: float = PLATE_THRESHOLD_N
               ) -> list[Unloading]:
    """When the vertical force (A,) N of one plate sampled at ``rate`` Hz falls below
    ``threshold_n`` after each run of at least :data:`PLATE_MIN_STANCE_S` above it that ends
    inside the recording (analog sample ``k`` at ``k / rate`` s).

    The unloading is the first sample below the threshold, unless the recording cut the force
    to zero from above it (the last loaded sample exceeds the next by more than the threshold
    itself: a foot leaving a plate unloads it at 1-5 N/ms, such a drop is the recording's own
    threshold); the crossing is then extrapolated along the falling force's tangent, a line
    fitted to its last :data:`CLIP_TANGENT_S` before the cut. The force decelerates as it
    falls (the toes' last push), so the tangent crosses the threshold no later than the force
    would have: an unloading so found is an early bound."""
    force = np.asarray(force, dtype=float)
    return [_unloading(force, rate, end, threshold_n)
            for _, end in _stances(force, rate, threshold_n) if end < len(force)]


def load_spans(force: np.ndarray, rate: float, /, *, threshold_n: float = PLATE_THRESHOLD_N
               ) -> list[tuple[float | None, float | None]]:
    """(loading, unloading) times (s) of each stance on a plate (step 2 of the module
    docstring): vertical force (A,) N at ``rate`` Hz; None where the recording starts or ends
    loaded. A loading the recording cut is extrapolated back along the rising force's tangent
    over its first :data:`CLIP_TANGENT_S`, as :func:`unloadings` does forwards."""
    force = np.asarray(force, dtype=float)
    return [(_loading(force, rate, start, end, threshold_n) if start > 0 else None,
             _unloading(force, rate, end, threshold_n).time_s if end < len(force) else None)
            for start, end in _stances(force, rate, threshold_n)]


def _unloading(force: np.ndarray, rate: float, end: int, threshold_n: float) -> Unloading:
    """The :func:`unloadings` entry of a stance whose force (A,) N stays above
    ``threshold_n`` up to the sample before ``end``."""
    if force[end - 1] - force[end] <= threshold_n:
        return Unloading(end / rate)
    crossing = _tangent_crossing(force, range(max(0, end - _window(rate)), end), threshold_n,
                                 end)
    return Unloading(crossing / rate, float(force[end - 1]), end / rate)


def _loading(force: np.ndarray, rate: float, start: int, end: int, threshold_n: float
             ) -> float:
    """When (s) a stance whose force (A,) N is above ``threshold_n`` from sample ``start`` to
    ``end`` (exclusive) starts: its first sample, or, where the recording cut the force to
    zero before it, where the rising force's tangent crosses the threshold."""
    if force[start] - force[start - 1] <= threshold_n:
        return start / rate
    return _tangent_crossing(force, range(start, min(end, start + _window(rate))), threshold_n,
                             start - 1) / rate


def _stances(force: np.ndarray, rate: float, threshold_n: float) -> list[tuple[int, int]]:
    """[start, end) samples of each run of at least :data:`PLATE_MIN_STANCE_S` above
    ``threshold_n``."""
    return [(s, e) for s, e in valid_runs(force > threshold_n).tolist()
            if e - s >= PLATE_MIN_STANCE_S * rate]


def _window(rate: float) -> int:
    """Samples (at least 2) of :data:`CLIP_TANGENT_S` at ``rate`` Hz."""
    return max(2, round(CLIP_TANGENT_S * rate))


def _tangent_crossing(force: np.ndarray, samples: range, threshold_n: float, cut: int) -> float:
    """Where (samples) the line fitted to ``force[samples]`` crosses ``threshold_n`` beyond
    the recording's ``cut`` (the first sample it zeroed after them, or the last before them:
    the crossing lies past it, as the force there was under the recording's level); the cut
    itself when the line does not cross past it."""
    frames = np.asarray(samples)
    if len(frames) >= 2:
        slope, intercept = np.polyfit(frames, force[frames], 1)
        crossing = (threshold_n - intercept) / slope if slope != 0 else np.nan
        if cut > frames[-1] and slope < 0 and crossing > cut:
            return float(crossing)
        if cut < frames[0] and slope > 0 and crossing < cut:
            return float(crossing)
    return float(cut if cut > frames[-1] else frames[0])


def plate_contacts(plates, feet: list[FootTrack], contact: dict[str, np.ndarray], rate: float
                   ) -> list[PlateContact]:
    """Each stance on a readable plate of ``plates`` (:class:`mocaplib.io.c3d_analog.ForcePlate`:
    ``number``, ``corners`` (4, 3) m, vertical ``force`` (A,) N, analog ``rate`` Hz) that one
    foot of ``feet`` (sampled at ``rate`` Hz; ``contact``: {side: (F,) bool} where each is
    down) alone makes (steps 1-3 of the module docstring), plate by plate; its loading is
    None unless the foot's heel lies over the plate, its unloading unless its toe does."""
    contacts = []
    for plate in plates:
        if not readable(plate.force):
            continue
        outline = _outline(plate.corners)
        for strike, off in load_spans(plate.force, plate.rate):
            first = 0.0 if strike is None else strike
            last = (len(plate.force) - 1) / plate.rate if off is None else off
            found = _stance_foot(outline, feet, contact, rate, first, last)
            if found is not None:
                side, heel, toe = found
                contacts.append(PlateContact(plate.number, side, strike if heel else None,
                                             off if toe else None))
    return contacts


def _outline(corners: np.ndarray) -> np.ndarray:
    """The plate's corners' horizontal outline (4, 2) m, in order around its centre."""
    xy = np.asarray(corners, dtype=float)[:, :2]
    centre = xy.mean(axis=0)
    return xy[np.argsort(np.arctan2(*(xy - centre).T[::-1]))]


def _inside(outline: np.ndarray, points: np.ndarray, margin: float) -> np.ndarray:
    """Whether each horizontal point (..., 2) m lies at least ``margin`` m inside the convex
    ``outline`` (4, 2) (a negative margin: at most that far outside); False where NaN."""
    edges = np.roll(outline, -1, axis=0) - outline                        # (4, 2)
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)               # outwards, any turn
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    centre = outline.mean(axis=0)
    sign = np.sign(np.einsum("ij,ij->i", centre - outline, normals))[:, None]
    normals = -sign * normals                                             # point outwards
    distance = np.einsum("...ij,ij->...i", points[..., None, :] - outline, normals)  # (..., 4)
    with np.errstate(invalid="ignore"):
        return (distance <= -margin).all(axis=-1)


def _stance_foot(outline: np.ndarray, feet: list[FootTrack], contact: dict[str, np.ndarray],
                 rate: float, first: float, last: float) -> tuple[str, bool, bool] | None:
    """The foot standing alone on the plate of ``outline`` from ``first`` to ``last`` (s), or
    None (step 3 of the module docstring): its side and whether its heel, and its toe, lie
    over the plate through the middle half of the stance (the plate then times its heel
    strike, and its toe-off). ``contact``: {side: (F,) bool} where each foot is down."""
    n_frames = len(feet[0].given) if feet else 0
    span = slice(max(0, int(np.floor(first * rate))), min(n_frames, int(np.ceil(last * rate)) + 1))
    quarter = (span.stop - span.start) // 4
    middle = slice(span.start + quarter, span.stop - quarter)
    if middle.stop <= middle.start:                          # beyond the frames
        return None
    on, near = {}, []
    for foot in feet:
        horizontal = foot.raw[:, :, :2]                                   # (2, F, 2)
        heel, toe = _inside(outline, horizontal[:, middle], ON_PLATE_MARGIN_M).all(axis=1)
        if heel or toe:
            on[foot.side] = (bool(heel), bool(toe))
        over = _inside(outline, horizontal[:, span], 0.0).any(axis=0)
        if (over & contact[foot.side][span]).any():
            near.append(foot.side)
    if len(on) != 1 or set(near) - set(on):
        return None
    side, (heel, toe) = next(iter(on.items()))
    return side, heel, toe


def plate_timed(events: list[GaitEvent], plates, feet: list[FootTrack],
                contact: dict[str, np.ndarray], rate: float) -> list[GaitEvent]:
    """``events`` with each heel strike and toe-off a plate times instead (step 4 of the
    module docstring): the markers' event of the plate contact's side and kind nearest the
    plate's, within :data:`PLATE_MATCH_S` (or whose not-placed window holds it), moved to the
    plate's time, placed, quality 1 and :attr:`GaitEvent.plate` set; the markers' other
    toe-offs shifted as the plates measured them (step 5, :func:`_shifted`); sorted by time.
    ``contact`` as for :func:`plate_contacts`."""
    out = list(events)
    n_frames = len(feet[0].given)
    measured = []                           # (plate - markers) of each toe-off a plate timed
    for stance in plate_contacts(plates, feet, contact, rate):
        for kind, time_s in (("heel_strike", stance.strike_s), ("toe_off", stance.off_s)):
            if time_s is None:
                continue
            near = [i for i, e in enumerate(out) if e.side == stance.side and e.kind == kind
                    and e.plate is None and _matches(e, time_s)]
            if near:
                i = min(near, key=lambda i: abs(out[i].time_s - time_s))
                if kind == "toe_off" and _calibrates(out[i]):
                    measured.append(time_s - out[i].time_s)
                out[i] = replace(out[i], time_s=float(time_s),
                                 frame=nearest_frame(time_s, rate, n_frames), quality=1.0,
                                 window=None, reason="", plate=stance.plate, spread_s=0.0)
    return sorted(_shifted(out, measured, rate, n_frames), key=lambda e: (e.time_s, e.side))


def _shifted(events: list[GaitEvent], measured: list[float], rate: float, n_frames: int
             ) -> list[GaitEvent]:
    """``events`` (of a capture of ``n_frames`` frames at ``rate`` Hz) with the toe-offs the
    markers placed moved by the median of ``measured`` (s: each plate's unloading minus the
    markers' toe-off it replaced), their :attr:`GaitEvent.plate_shift_s` set; unchanged
    without one or beyond :data:`MAX_PLATE_SHIFT_S` (step 5 of the module docstring), and a
    toe-off the move would take out of the capture stays."""
    if not measured or abs(shift := float(np.median(measured))) > MAX_PLATE_SHIFT_S:
        return events
    last = (n_frames - 1) / rate
    return [replace(e, time_s=e.time_s + shift,
                    frame=nearest_frame(e.time_s + shift, rate, n_frames), plate_shift_s=shift)
            if e.kind == "toe_off" and e.placed and e.plate is None
            and 0.0 <= e.time_s + shift <= last else e for e in events]


def _calibrates(event: GaitEvent) -> bool:
    """Whether the markers' toe-off a plate replaced tells how late or early the markers place
    the others (step 5 of the module docstring): placed, its two marks agreeing (not
    :attr:`GaitEvent.uncertain`) and its foot's markers measured around it (``quality`` at
    least the library QC's least event quality; not a foot the fitted model filled in)."""
    return event.placed and not event.uncertain and event.quality >= MIN_EVENT_QUALITY


def _matches(event: GaitEvent, time_s: float) -> bool:
    """Whether the markers' ``event`` is the one a plate times at ``time_s`` (s)."""
    if event.placed:
        return abs(event.time_s - time_s) <= PLATE_MATCH_S
    return event.window[0] - PLATE_MATCH_S <= time_s <= event.window[1] + PLATE_MATCH_S
