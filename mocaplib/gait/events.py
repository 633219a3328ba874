"""Gait events: left/right toe-off and heel-strike from heel and toe point trajectories.

The detector uses only features that need no direction of progression, so it works for
straight walking at any speed, curves, turning on the spot, side-steps, diagonal steps and
running, overground or on a treadmill:

1. **Gaps.** Spikes (a ghost of a heel or toe for a few frames) are gapped
   (:func:`mocaplib.model.filtering.remove_spikes`), then missing samples (NaN) are filled linearly
   over gaps up to ``max_gap_s``; longer
   gaps stay missing and no event is placed in or next to them: every event lies between two
   frames where the foot's heel and toe are known (measured, or filled inside a gap).
2. **Floor.** Heights are taken above the floor each point stands on: a plane (one offset per
   point, one slope) fitted to the samples where the point stands still relative to the ground,
   so tilted lab floors (the CMU walkway rises ~2.5 cm per stride) and raised treadmill belts
   (the running file's heels never go below 0.24 m) need no setting. The ground's velocity
   (zero overground, the belt's on a treadmill) is the horizontal velocity most of the foot's
   frames near the floor share: the foot flat on it.
3. **Swings.** On low-passed points (:func:`mocaplib.model.filtering.lowpass`: zero-lag Butterworth,
   gap-aware, ``cutoff_hz`` its -3 dB point),
   the foot is in contact when its lowest point is within ``min_clearance`` of the floor *and*
   its centre moves slower than ``contact_speed`` relative to the ground.
   A swing is a run of at least ``min_swing_s`` out of contact. No swing (standing) = no
   events = rest.
4. **Coarse times.** Toe-off: the peak upward velocity of the foot centre (mean of heel and toe)
   just before the swing (O'Connor et al. 2007, *Gait & Posture* 25:469). Heel-strike: where the
   speed of the point that touches first (heel, or toe when landing toe-first or walking
   backwards) stops falling: the knot of a two-line fit to its speed after the swing.
5. **Refinement.** A heel-strike moves to the *kink* of the unfiltered positions: the knot of
   a curve quadratic on each side and continuous at the knot (velocity and acceleration may
   jump there), fitted on a window around the coarse time and re-centred until it stays put;
   sub-frame, and free of the low-pass filter's smearing (2-3 frames). It is the median of
   three kinks: of the point that touched first in 3-D, of its height alone, and of heel and
   toe together; each alone is thrown off now and then (a landing foot rocks its markers onto
   the sole a moment later), their median is not. A toe-off is defined below.

**Toe-off** (``toe_off=``). A walking foot leaves the floor rolling: the heel rises about the
metatarsal heads, then the forefoot (where the toe marker sits) lifts while the toes turn about
their tips, and the tips leave ~40-60 ms later, smoothly: a force plate's Foot Off is not a
kinematic step of the markers. As the toes leave, the heel's rise slows while the forefoot's
quickens, so the upward velocity of a point on the foot peaks then; the further forward the
point, the later its peak.

* ``"foot_velocity"`` (default): in walking, the mean of two kinematic marks of the release
  that bracket it. (a) The upward-velocity peak (sub-frame by a parabola; peaks within 5 %
  of the highest share it, :func:`~mocaplib.gait.foot_events.crest_time`, rather than take
  turns with the noise) of the point
  :data:`TOE_OFF_WEIGHT` of the way from the other marker to the one that left the floor last
  (the toe marker, or the heel walking backwards); O'Connor et al.'s foot velocity algorithm
  takes the midpoint. It is sought only while the foot still rolls over its forefoot (until
  its pitch rate, below, is no longer positive), so a foot lifted faster later in the swing,
  stepping up onto a stair's tread, does not take it. It comes early when the push-off is
  slow (up to 14 ms on synthetic walks at 0.4-0.5 m/s). (b) The end of the roll: the foot's pitch rate (how fast the first marker
  rises over the last, :func:`_pitch_rate`) peaks while the heel rises about the metatarsal
  heads and falls as the toes leave; the release is where it has fallen to
  :data:`TOE_OFF_PITCH_FRACTION` (half) of that stride's peak, a level relative to the
  stride's own push-off, so it follows slow and fast walking alike; alone it comes ~9 ms after
  the lab's Foot Off. When the two marks lie more than
  :data:`~mocaplib.gait.foot_events.MARKS_APART_S` (30 ms) apart, one of them has missed the
  release and nothing tells which: the toe-off is placed midway and is
  :attr:`~mocaplib.gait.foot_events.GaitEvent.uncertain` (it warns). In running (a capture
  whose feet are both off the floor at once, a flight phase: :func:`running`), where the
  swing foot keeps accelerating upwards after the toes leave, the toe-off is the ``"lift"``
  below, the forefoot's fastest upswing at the release (Handsaker et al. 2016 time running
  toe-offs on forefoot accelerations too).
  Measured (docs/results/event_accuracy.md): against the lab's Foot Off, the force plates'
  unloading (20 N) and the synthetic toe-offs (the toes' tips leaving the floor). Real feet
  leave the plate at any point of their roll (pitch rate 0.24-0.99 of its push-off peak, the
  synthetic 0.40-0.69), so (b) is late on the feet that go on rolling after their toes leave;
  benchmarks/toe_off_marks.py times (a), (b) and the literature's other marks against both.
* ``"lift"``: where the low-passed upward velocity of the point that left last rises fastest,
  from 0.1 s before to 0.05 s after the foot centre's velocity peak: the lift-off of a foot
  that leaves the floor in one step (a rigid or stiff-soled foot, a running forefoot); on
  walking feet that roll over their toes it is the forefoot's fastest upswing, ~18 ms before
  Foot Off.

Units: metres, seconds, Z up; times are seconds from the capture's first frame (frame 0).
"""

from __future__ import annotations

import bisect
import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import MIN_MARKER_SPREAD, SPREAD_HINT, UNITS_HINT, EventError
from ..model.filtering import lowpass, remove_spikes
from ..model.floor import floor_height
from ..runs import valid_runs
from ..trial import check_gait_rate
from .feet import feet_of
from .foot_events import (FootTrack, GaitEvent, arrival_time, gait_event, lift_time, median_kink,
                          peak_time, swing_spans, toe_off_signals, toe_off_time,
                          unplaced_event)
from .plate_events import plate_timed

SIDES = ("left", "right")
#: Toe-off definitions, see the module docstring.
TOE_OFF_DEFINITIONS = ("foot_velocity", "lift")
#: Median heel-to-toe marker distance (m) a foot can have; outside it the units are wrong.
PLAUSIBLE_FOOT = (0.03, 1.0)


@dataclass(frozen=True)
class EventSettings:
    """The detector's settings (module docstring), each with its default.

    toe_off : ``"foot_velocity"`` (the mean of the upward-velocity peak of a point of the foot
        near the marker that leaves last and the end of the foot's roll; in running the lift;
        default) or ``"lift"`` (a foot leaving in one step: the forefoot's fastest upswing).
    cutoff_hz : the detection's low-pass cutoff (Hz, -3 dB point).
    min_clearance, contact_speed : a foot is in contact when its lowest point is within
        ``min_clearance`` of the floor (m) and its centre moves slower than ``contact_speed``
        relative to the ground (m/s).
    min_swing_s : shortest swing (s).
    refine_s : half-width of the window the heel-strike kinks are fitted on (s).
    max_gap_s : longest gap filled linearly (s).
    force_plates : whether :func:`capture_events` times the heel strikes and toe-offs of a foot
        standing alone on a force plate by the plate (:mod:`mocaplib.gait.plate_events`);
        False: every event from the foot markers.
    """

    toe_off: str = "foot_velocity"
    cutoff_hz: float = 12.0
    min_clearance: float = 0.01
    contact_speed: float = 0.5
    min_swing_s: float = 0.08
    refine_s: float = 0.08
    max_gap_s: float = 0.25
    force_plates: bool = True

    def __post_init__(self):
        if self.toe_off not in TOE_OFF_DEFINITIONS:
            raise EventError(f"toe_off must be one of {', '.join(TOE_OFF_DEFINITIONS)}, "
                             f"got {self.toe_off!r}")


#: Slowest ground velocity (m/s) taken for a treadmill belt's; slower estimates are overground.
MIN_BELT_SPEED = 0.2


def detect_events(feet: Mapping[str, tuple[np.ndarray, np.ndarray]], rate: float, /, *,
                  measured: Mapping[str, np.ndarray] | None = None,
                  source: str | os.PathLike | None = None, **settings) -> list[GaitEvent]:
    """Toe-offs and heel-strikes of both feet, sorted by time.

    Parameters
    ----------
    feet
        ``{"left": (heel, toe), "right": (heel, toe)}``, each point an array (F, 3) in metres,
        Z up, NaN where missing. A side may be left out.
    rate
        Frame rate, Hz.
    measured
        ``{side: (F,) bool}``: the frames where that foot's heel and toe were both measured
        (:func:`feet_of` gives it); the events' ``quality`` counts only them. Default: where
        both are finite (nothing was filled in before).
    source
        The capture's file, named in errors.
    settings
        Fields of :class:`EventSettings` to change, e.g. ``toe_off="lift"``.

    Returns
    -------
    list of GaitEvent
        Every toe-off and heel strike found, sorted by time (seconds from the first frame).
    """
    config = EventSettings(**settings)
    return _events(_prepared_feet(feet, rate, config, source), measured, rate, config,
                   source)[0]


def foot_events(heel: np.ndarray, toe: np.ndarray, rate: float, /, *, side: str,
                measured: np.ndarray | None = None, source: str | os.PathLike | None = None,
                **settings) -> list[GaitEvent]:
    """Toe-offs and heel-strikes of one foot from its heel and toe points (F, 3), metres;
    ``measured`` (F,) bool and ``settings`` as for :func:`detect_events`."""
    return detect_events({side: (heel, toe)}, rate, source=source, **settings,
                         measured=None if measured is None else {side: measured})


def ground_velocity(feet: Mapping[str, tuple[np.ndarray, np.ndarray]], rate: float, /, *,
                    min_speed: float = MIN_BELT_SPEED, source: str | os.PathLike | None = None,
                    **settings) -> np.ndarray:
    """Horizontal velocity (3,) m/s of the surface the feet stand on: a treadmill belt's, or
    zeros overground (an estimate slower than ``min_speed`` counts as overground).

    ``feet`` and ``settings`` as for :func:`detect_events`. The estimate is the median, over
    the feet, of the horizontal velocity each foot shares with the floor (module docstring,
    step 2).
    Pass it to :func:`mocaplib.gait.cycles.analyse_cycles` so treadmill cycles are measured relative
    to the belt (a runner on a belt at 2.2 m/s runs at 2.2 m/s, not on the spot).
    """
    return _ground(_prepared_feet(feet, rate, EventSettings(**settings), source), min_speed)


def capture_events(trial, match, /, *, motion=None, **settings
                   ) -> tuple[list[GaitEvent], np.ndarray]:
    """A capture's gait events (:func:`detect_events`) and the velocity (3,) m/s of the ground
    under it (:func:`ground_velocity`), each foot prepared once; what ``mocaplib events``,
    ``mocaplib cycles`` and ``mocaplib build`` run.

    The feet are the markers ``match``
    (:class:`mocaplib.markersets.matching.ProtocolMatch`) names, gaps filled from the fitted
    ``motion`` when given (:func:`feet_of`); the events' ``quality`` counts only the samples
    the capture measured. Where one foot alone stands on one of the
    trial's force plates, the plate times its heel strike and toe-off
    (:func:`~mocaplib.gait.plate_events.plate_timed`; ``force_plates=False``: never).
    ``settings`` as for :func:`detect_events`.
    """
    config = EventSettings(**settings)
    prepared, measured = capture_feet(trial, match, motion=motion, **settings)
    events, contact = _events(prepared, measured, trial.rate, config, trial.source)
    if config.force_plates and trial.force_plates:
        events = plate_timed(events, trial.force_plates, prepared, contact, trial.rate)
    return events, _ground(prepared, MIN_BELT_SPEED)


def capture_feet(trial, match, /, *, motion=None, **settings
                 ) -> tuple[list[FootTrack], dict[str, np.ndarray]]:
    """A capture's feet prepared for detection (steps 1-2 of the module docstring), one
    :class:`FootTrack` per side, and the frames (F,) bool each side's heel and toe were
    measured; arguments as for :func:`capture_events`."""
    feet, measured = feet_of(trial, match, motion=motion)
    return _prepared_feet(feet, trial.rate, EventSettings(**settings), trial.source), measured


def _prepared_feet(feet, rate, config: EventSettings, source) -> list[FootTrack]:
    """Each foot of ``feet`` checked and prepared (steps 1-2 of the module docstring)."""
    unknown = set(feet) - set(SIDES)
    if unknown:
        raise EventError(f"unknown foot side(s) {sorted(unknown)}; use 'left' and 'right'",
                         path=source)
    prepared = []
    for side in (side for side in SIDES if side in feet):
        heel, toe = _checked_points(*feet[side], rate, side, source)
        heel, toe = remove_spikes(np.stack([heel, toe], axis=1), rate).transpose(1, 0, 2)
        given = np.isfinite(heel).all(axis=1) & np.isfinite(toe).all(axis=1)
        raw, points, velocity = _prepared(heel, toe, rate, config.cutoff_hz, config.max_gap_s)
        prepared.append(FootTrack(side, given, raw, points, velocity,
                                  *floor_height(points, velocity, rate)))
    return prepared


def _ground(feet: list[FootTrack], min_speed: float) -> np.ndarray:
    """The median of the feet's ground velocities (3,) m/s; zeros below ``min_speed``."""
    if not feet:
        return np.zeros(3)
    ground = np.median([foot.ground for foot in feet], axis=0)
    return ground if np.hypot(*ground[:2]) >= min_speed else np.zeros(3)


def _events(feet: list[FootTrack], measured, rate: float, config: EventSettings,
            source=None) -> tuple[list[GaitEvent], dict[str, np.ndarray]]:
    """Every foot's events, sorted by time, and the frames (F,) bool each side is in contact
    (:func:`_contact`); ``measured`` as for :func:`detect_events`."""
    events: list[GaitEvent] = []
    runs = _running(feet, rate, config)
    airborne = {}
    contact = {foot.side: _contact(foot, config) for foot in feet}
    for foot in feet:
        seen = foot.given
        if measured is not None:
            mask = np.asarray(measured[foot.side], dtype=bool)
            if mask.shape != seen.shape:
                raise EventError(f"{foot.side} measured mask has shape {mask.shape}, the foot "
                                 f"{seen.shape}", path=source)
            seen = seen & mask
        found, airborne[foot.side] = _foot_events(foot, seen, rate, config,
                                                  contact[foot.side],
                                                  lift=runs or config.toe_off == "lift")
        events += found
    events += _lost_stances(airborne, rate, len(feet[0].given) if feet else 0)
    return sorted(events, key=lambda e: (e.time_s, e.side)), contact


def _lost_stances(airborne: dict[str, list[tuple[int, int]]], rate: float, n_frames: int
                  ) -> list[GaitEvent]:
    """The heel-strike and toe-off of a stance the detector did not see, not placed: a span
    a foot seems in the air ([start, end) frames, per side: a swing, or swings a gap in its
    markers separates) that holds a whole swing of the other foot. Whether walking or running,
    a foot comes down while the other is in the air, so such a span holds a stance that was
    missed: hidden in the gap, or on a floor other than the one the foot stood on before (a
    raised tread of a stair)."""
    out = []
    for side, other in ((a, b) for a in airborne for b in airborne if a != b):
        spans = airborne[other]                  # in time order, disjoint: ends in order too
        starts = [swing_start for swing_start, _ in spans]
        for start, end in airborne[side]:
            k = bisect.bisect_right(starts, start)       # the first of them starting after it
            while k < len(spans) and spans[k][1] < end:
                out += lost_stance(side, (start, end), other, spans[k], rate, n_frames)
                k += 1
    return out


def lost_stance(side: str, span: tuple[int, int], other: str, swing: tuple[int, int],
                rate: float, n_frames: int) -> list[GaitEvent]:
    """The heel strike and toe-off, not placed, of the stance of ``side`` hidden in its
    ``span`` in the air ([start, end) frames) around a whole ``swing`` of the ``other`` foot
    (:func:`_lost_stances`)."""
    (start, end), (inner_start, inner_end) = span, swing
    reason = (f"the foot seems in the air from {start / rate:.2f} to {end / rate:.2f} s while "
              f"the {other} foot swings (a stance hidden by missing markers or on another "
              "floor)")
    return [unplaced_event(side, "heel_strike", (start, inner_start), rate, n_frames, reason),
            unplaced_event(side, "toe_off", (inner_end, end), rate, n_frames, reason)]


#: Shortest flight phase (s, both feet off the floor) that makes a capture a run.
MIN_FLIGHT_S = 0.03


def _contact(foot: FootTrack, config: EventSettings) -> np.ndarray:
    """The frames (F,) bool a prepared foot is in contact (step 3 of the module docstring)."""
    centre_speed = np.linalg.norm(foot.velocity.mean(axis=0) - foot.ground, axis=1)
    with np.errstate(invalid="ignore"):
        return (foot.heights.min(axis=0) < config.min_clearance) & (
            centre_speed < config.contact_speed)


def _running(feet: list[FootTrack], rate: float, config: EventSettings) -> bool:
    """Whether both feet are off the floor at once for :data:`MIN_FLIGHT_S` or longer (a
    run's flight phase: every point of both feet higher than ``min_clearance``; walking always
    has a foot down)."""
    if len(feet) < 2:
        return False
    with np.errstate(invalid="ignore"):
        airborne = np.logical_and.reduce([f.heights.min(axis=0) > config.min_clearance
                                          for f in feet])
    runs = valid_runs(airborne)
    return bool(len(runs)) and bool(np.max(runs[:, 1] - runs[:, 0]) >= MIN_FLIGHT_S * rate)


def running(feet: Mapping[str, tuple[np.ndarray, np.ndarray]], rate: float, /, *,
            source: str | os.PathLike | None = None, **settings) -> bool:
    """Whether a capture's feet (as for :func:`detect_events`) run: both off the floor at once
    for :data:`MIN_FLIGHT_S` or longer; the default toe-off definition takes the ``lift`` then
    (module docstring)."""
    config = EventSettings(**settings)
    return _running(_prepared_feet(feet, rate, config, source), rate, config)


def _foot_events(foot: FootTrack, measured: np.ndarray, rate: float, config: EventSettings,
                 contact: np.ndarray, *, lift: bool
                 ) -> tuple[list[GaitEvent], list[tuple[int, int]]]:
    """Steps 3-5 of the module docstring on one prepared foot, and when it is in the air
    ([start, end) frames: its swings, those a gap in its markers separates joined);
    ``measured`` (F,) bool; ``contact`` (F,) bool its :func:`_contact`; ``lift``: toe-offs by
    the lift definition, else the default's (module docstring). An event a swing shows but
    that cannot be placed (no clear mark, the markers missing where it lies, or hidden in a
    gap longer than ``max_gap_s`` between a contact and the swing) is returned not placed
    (:attr:`GaitEvent.window`)."""
    raw, velocity, heights = foot.raw, foot.velocity, foot.heights
    clearance = heights.min(axis=0)
    centre_velocity = velocity.mean(axis=0)
    speeds = np.linalg.norm(velocity - foot.ground, axis=2)                     # (2, F)

    supported = np.isfinite(raw).all(axis=(0, 2))
    events: list[GaitEvent] = []
    swings = swing_spans(contact, clearance, max(1, round(config.min_swing_s * rate)))
    window = max(3, round(0.15 * rate))
    half = max(3, round(config.refine_s * rate))
    n_frames = len(clearance)
    seen = np.flatnonzero(np.isfinite(clearance))
    marks: dict[int, object] = {}       # the toe-off signals by marker leaving last, made once

    def not_placed(kind, lo, hi, reason):
        events.append(unplaced_event(foot.side, kind, (lo, hi), rate, n_frames, reason))

    for n, (start, end) in enumerate(swings):
        before = swings[n - 1][1] if n else 0
        after = swings[n + 1][0] if n + 1 < len(swings) else n_frames
        top = start + int(np.nanargmax(clearance[start:end]))
        if start > 0 and np.isfinite(clearance[start - 1]):
            last = int(np.argmin(heights[:, start]))  # the point that left last
            lo, hi = max(before, start - window), top + 1
            if last not in marks:
                marks[last] = (np.gradient(velocity[last, :, 2]) if lift
                               else toe_off_signals(foot, last, rate))
            spread = 0.0
            if lift:
                t = peak_time(centre_velocity[:, 2], lo, hi)
                t = None if t is None else lift_time(marks[last], t, rate)
            else:
                t, spread = toe_off_time(marks[last], lo, hi)
            if t is not None and _supported(supported, t):
                events.append(gait_event(foot.side, "toe_off", t / rate, measured, rate,
                                         spread_s=spread / rate))
            else:
                not_placed("toe_off", lo, hi, "the foot's release shows no clear mark" if t is None
                           else "the foot markers are missing where it lies")
        elif start > 0:                           # a gap too long to fill before the swing
            gap = seen[seen < start]
            if gap.size and contact[gap[-1]]:      # down before it: it left in the gap
                not_placed("toe_off", gap[-1], start, "the foot markers are missing then")
        if end < n_frames and np.isfinite(clearance[end]):
            first = int(np.argmin(heights[:, end]))  # the point that touched first
            t = arrival_time(speeds[first], top, end, min(after, end + window), window)
            t = median_kink(raw, first, float(end) if t is None else t, half)
            if _supported(supported, t):
                events.append(gait_event(foot.side, "heel_strike", t / rate, measured, rate))
            else:
                not_placed("heel_strike", top, min(after, end + window),
                           "the foot markers are missing where it lies")
        elif end < n_frames:                      # a gap too long to fill after the swing
            gap = seen[seen >= end]
            if gap.size and contact[gap[0]]:       # down after it: it landed in the gap
                not_placed("heel_strike", end - 1, gap[0], "the foot markers are missing then")
    airborne = []                     # swings, joined across the gaps that separate them
    for start, end in swings:
        if airborne and not np.isfinite(clearance[airborne[-1][1]:start]).any():
            airborne[-1] = (airborne[-1][0], end)
        else:
            airborne.append((start, end))
    return events, airborne


def _supported(supported: np.ndarray, t: float) -> bool:
    """Whether time ``t`` (frames) lies between two frames of ``supported`` (F,) bool, those
    where the foot's heel and toe are both known (given or filled): an event is never placed
    beyond the samples it is found from."""
    lo, hi = int(np.floor(t)), int(np.ceil(t))
    return 0 <= lo and hi < len(supported) and bool(supported[lo] and supported[hi])


def _prepared(heel, toe, rate, cutoff_hz, max_gap_s):
    """Gap-filled raw points (2, F, 3), their low-passed version and its velocity (m/s)."""
    raw = np.stack([_fill_gaps(p, round(max_gap_s * rate)) for p in (heel, toe)])
    # time is axis 1 here; lowpass filters along axis 0, each trailing column on its own
    points = (raw if cutoff_hz >= 0.5 * rate else
              lowpass(raw.transpose(1, 0, 2), rate, cutoff_hz).transpose(1, 0, 2))
    velocity = np.gradient(points, axis=1) * rate if points.shape[1] > 1 else 0 * points
    return raw, points, velocity


def _checked_points(heel, toe, rate, side, source):
    check_gait_rate(rate, source, EventError)
    heel = np.asarray(heel, dtype=np.float64)
    toe = np.asarray(toe, dtype=np.float64)
    for name, points in (("heel", heel), ("toe", toe)):
        if points.ndim != 2 or points.shape[1] != 3:
            raise EventError(f"{side} {name} must have shape (F, 3), got {points.shape}",
                             path=source)
    if heel.shape != toe.shape:
        raise EventError(f"{side} heel {heel.shape} and toe {toe.shape} differ in length",
                         path=source)
    for name, points in (("heel", heel), ("toe", toe)):
        if not np.isfinite(points[:, 2]).any():
            raise EventError(f"{side} {name} is missing in every frame", path=source,
                             hint="check the protocol matched the foot markers")
    both = np.isfinite(heel).all(axis=1) & np.isfinite(toe).all(axis=1)
    if both.any():
        spacing = float(np.median(np.linalg.norm(heel[both] - toe[both], axis=1)))
        if spacing < MIN_MARKER_SPREAD:
            raise EventError(
                f"the {side} heel and toe markers lie at one place ({spacing:.2g} m apart): "
                "they do not spread like markers on a foot", path=source, hint=SPREAD_HINT)
        if not PLAUSIBLE_FOOT[0] <= spacing <= PLAUSIBLE_FOOT[1]:
            raise EventError(
                f"the {side} heel and toe markers are {spacing:.3g} m apart: the coordinates "
                "are not in the units the file states", path=source, hint=UNITS_HINT)
    return heel, toe


def _fill_gaps(points: np.ndarray, max_gap: int) -> np.ndarray:
    """Linear interpolation over interior NaN runs of at most ``max_gap`` frames (F, 3)."""
    out = points.copy()
    missing = ~np.isfinite(points).all(axis=1)
    frames = np.arange(len(points))
    for start, end in valid_runs(missing).tolist():
        if start > 0 and end < len(points) and end - start <= max_gap:
            for axis in range(3):
                out[start:end, axis] = np.interp(frames[start:end], [start - 1, end],
                                                 points[[start - 1, end], axis])
    return out


