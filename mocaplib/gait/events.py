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
  that bracket it. (a) The upward-velocity peak (sub-frame by a parabola) of the point
  :data:`TOE_OFF_WEIGHT` of the way from the other marker to the one that left the floor last
  (the toe marker, or the heel walking backwards); O'Connor et al.'s foot velocity algorithm
  takes the midpoint. It comes early when the push-off is slow (up to 14 ms on synthetic walks
  at 0.4-0.5 m/s). (b) The end of the roll: the foot's pitch rate (how fast the first marker
  rises over the last, :func:`_pitch_rate`) peaks while the heel rises about the metatarsal
  heads and falls as the toes leave; the release is where it has fallen to
  :data:`TOE_OFF_PITCH_FRACTION` (half) of that stride's peak, a level relative to the
  stride's own push-off, so it follows slow and fast walking alike; alone it comes ~9 ms after
  the lab's Foot Off. In running (a capture whose feet are both off the floor at once, a
  flight phase: :func:`running`), where the swing foot keeps accelerating upwards after the
  toes leave, the toe-off is the ``"lift"`` below, the forefoot's fastest upswing at the
  release (Handsaker et al. 2016 time running toe-offs on forefoot accelerations too).
  Measured (docs/results/event_accuracy.md): against the lab's Foot Off, and on the synthetic
  toe-offs (the toes' tips leaving the floor).
* ``"lift"``: where the low-passed upward velocity of the point that left last rises fastest,
  from 0.1 s before to 0.05 s after the foot centre's velocity peak: the lift-off of a foot
  that leaves the floor in one step (a rigid or stiff-soled foot, a running forefoot); on
  walking feet that roll over their toes it is the forefoot's fastest upswing, ~18 ms before
  Foot Off.

Units: metres, seconds, Z up; times are seconds from the capture's first frame (frame 0).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import UNITS_HINT, EventError
from ..model.filtering import lowpass, remove_spikes
from ..runs import valid_runs
from ..trial import check_gait_rate

SIDES = ("left", "right")
#: Toe-off definitions, see the module docstring.
TOE_OFF_DEFINITIONS = ("foot_velocity", "lift")
#: Where the default toe-off's velocity-peak point lies between a foot's two markers: this
#: share of the way from the one that left the floor first to the one that left last.
TOE_OFF_WEIGHT = 0.6
#: Share of its push-off peak the foot's pitch rate has fallen to at the default toe-off's
#: end-of-roll mark (half: the peak's half-maximum on its falling side).
TOE_OFF_PITCH_FRACTION = 0.5
#: Median heel-to-toe marker distance (m) a foot can have; outside it the units are wrong.
PLAUSIBLE_FOOT = (0.03, 1.0)


@dataclass(frozen=True)
class GaitEvent:
    """One detected gait event.

    Attributes
    ----------
    side : ``"left"`` or ``"right"``
    kind : ``"toe_off"`` or ``"heel_strike"``
    time_s : float
        Seconds from the capture's first frame, with sub-frame precision.
    frame : int
        Nearest frame index (0-based).
    quality : float
        Fraction (0..1) of the frames within 50 ms of the event where the capture measured both
        the heel and the toe (not filled in, linearly or from a fitted model).
    """

    side: str
    kind: str
    time_s: float
    frame: int
    quality: float


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
    """

    toe_off: str = "foot_velocity"
    cutoff_hz: float = 12.0
    min_clearance: float = 0.01
    contact_speed: float = 0.5
    min_swing_s: float = 0.08
    refine_s: float = 0.08
    max_gap_s: float = 0.25

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
    """
    config = EventSettings(**settings)
    return _events(_prepared_feet(feet, rate, config, source), measured, rate, config, source)


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

    The feet are the markers ``match`` (:class:`mocaplib.markersets.matching.ProtocolMatch`) names, gaps
    filled from the fitted ``motion`` when given (:func:`feet_of`); the events' ``quality``
    counts only the samples the capture measured. ``settings`` as for :func:`detect_events`.
    """
    config = EventSettings(**settings)
    feet, measured = feet_of(trial, match, motion=motion)
    prepared = _prepared_feet(feet, trial.rate, config, trial.source)
    return (_events(prepared, measured, trial.rate, config, trial.source),
            _ground(prepared, MIN_BELT_SPEED))


@dataclass(frozen=True)
class _Foot:
    """One foot ready for detection: the frames (F,) bool where heel and toe were both given,
    the gap-filled raw heel and toe (2, F, 3) m, their low-passed version and its velocity
    (m/s), their heights above the floor (2, F) m and the floor's horizontal velocity (3,) m/s.
    """

    side: str
    given: np.ndarray
    raw: np.ndarray
    points: np.ndarray
    velocity: np.ndarray
    heights: np.ndarray
    ground: np.ndarray


def _prepared_feet(feet, rate, config: EventSettings, source) -> list[_Foot]:
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
        prepared.append(_Foot(side, given, raw, points, velocity, *_floor(points, velocity)))
    return prepared


def _ground(feet: list[_Foot], min_speed: float) -> np.ndarray:
    """The median of the feet's ground velocities (3,) m/s; zeros below ``min_speed``."""
    if not feet:
        return np.zeros(3)
    ground = np.median([foot.ground for foot in feet], axis=0)
    return ground if np.hypot(*ground[:2]) >= min_speed else np.zeros(3)


def _events(feet: list[_Foot], measured, rate: float, config: EventSettings,
            source=None) -> list[GaitEvent]:
    """Every foot's events, sorted by time; ``measured`` as for :func:`detect_events`."""
    events: list[GaitEvent] = []
    runs = _running(feet, rate, config)
    for foot in feet:
        seen = foot.given
        if measured is not None:
            mask = np.asarray(measured[foot.side], dtype=bool)
            if mask.shape != seen.shape:
                raise EventError(f"{foot.side} measured mask has shape {mask.shape}, the foot "
                                 f"{seen.shape}", path=source)
            seen = seen & mask
        events += _foot_events(foot, seen, rate, config, lift=runs or config.toe_off == "lift")
    return sorted(events, key=lambda e: (e.time_s, e.side))


#: Shortest flight phase (s, both feet off the floor) that makes a capture a run.
MIN_FLIGHT_S = 0.03


def _contact(foot: _Foot, config: EventSettings) -> np.ndarray:
    """The frames (F,) bool a prepared foot is in contact (step 3 of the module docstring)."""
    centre_speed = np.linalg.norm(foot.velocity.mean(axis=0) - foot.ground, axis=1)
    with np.errstate(invalid="ignore"):
        return (foot.heights.min(axis=0) < config.min_clearance) & (
            centre_speed < config.contact_speed)


def _running(feet: list[_Foot], rate: float, config: EventSettings) -> bool:
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


def _foot_events(foot: _Foot, measured: np.ndarray, rate: float, config: EventSettings, *,
                 lift: bool) -> list[GaitEvent]:
    """Steps 3-5 of the module docstring on one prepared foot; ``measured`` (F,) bool;
    ``lift``: toe-offs by the lift definition, else the default's (module docstring)."""
    raw, velocity, heights = foot.raw, foot.velocity, foot.heights
    clearance = heights.min(axis=0)
    centre_velocity = velocity.mean(axis=0)
    speeds = np.linalg.norm(velocity - foot.ground, axis=2)                     # (2, F)
    contact = _contact(foot, config)

    supported = np.isfinite(raw).all(axis=(0, 2))
    events: list[GaitEvent] = []
    swings = _swings(contact, clearance, max(1, round(config.min_swing_s * rate)))
    window = max(3, round(0.15 * rate))
    half = max(3, round(config.refine_s * rate))
    for n, (start, end) in enumerate(swings):
        before = swings[n - 1][1] if n else 0
        after = swings[n + 1][0] if n + 1 < len(swings) else len(clearance)
        top = start + int(np.nanargmax(clearance[start:end]))
        if start > 0 and np.isfinite(clearance[start - 1]):
            last = int(np.argmin(heights[:, start]))  # the point that left last
            lo = max(before, start - window)
            if lift:
                t = _peak_time(centre_velocity[:, 2], lo, top + 1)
                t = None if t is None else _lift_time(velocity[last, :, 2], t, rate)
            else:
                t = _toe_off_time(foot, last, lo, top + 1, rate)
            if t is not None:
                if _supported(supported, t):
                    events.append(_event(foot.side, "toe_off", t / rate, measured, rate))
        if end < len(clearance) and np.isfinite(clearance[end]):
            first = int(np.argmin(heights[:, end]))  # the point that touched first
            t = _arrival_time(speeds[first], top, end, min(after, end + window), window)
            t = _median_kink(raw, first, float(end) if t is None else t, half)
            if _supported(supported, t):
                events.append(_event(foot.side, "heel_strike", t / rate, measured, rate))
    return events


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


def _floor(points: np.ndarray, velocity: np.ndarray, *, still_speed: float = 0.2,
           min_extent: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Heights (2, F) of heel and toe above the floor they stand on (m), and the floor's
    horizontal velocity (3,) (m/s: zero overground, the belt's on a treadmill).

    The ground velocity is the horizontal velocity most of the frames where the foot's
    lowest point is within 3 cm of its lowest height share (:func:`_shared_velocity`, within
    ``still_speed``): the foot flat on the floor. Samples where a point moves slower
    than ``still_speed`` relative to the ground are standing on the floor; the floor is the
    plane ``z = a_p + slope·xy`` (an offset per point, one slope) fitted to them by least
    squares, dropping samples more than 1 cm off and refitting. Lab floors and calibrations
    tilt by a degree or so (2-3 cm over a stride in the CMU files) and treadmill belts are
    raised (0.24 m in the running file); a percentile of the raw height would take either for
    swing. The slope is fitted only along horizontal directions the standing samples span by
    ``min_extent`` or more (none when standing or turning on the spot, one on a straight walk).
    """
    z = points[:, :, 2]
    rough = z - np.nanpercentile(z, 5, axis=1)[:, None]
    centre_velocity = velocity.mean(axis=0)
    with np.errstate(invalid="ignore"):
        near = (rough.min(axis=0) < 0.03) & np.isfinite(centre_velocity[:, 0])
    ground = np.zeros(3)
    if near.any():
        ground[:2] = _shared_velocity(centre_velocity[near, :2], still_speed)
        if not _is_belt(centre_velocity, near, ground, still_speed):
            ground[:] = 0.0
    with np.errstate(invalid="ignore"):
        still = np.linalg.norm(velocity - ground, axis=2) < still_speed
    still &= np.isfinite(z)
    if still.sum() < 10:  # never still (odd data): the lowest tenth of each point's samples
        with np.errstate(invalid="ignore"):
            still = rough < np.nanpercentile(rough, 10, axis=1)[:, None]
    owner, frame = np.nonzero(still)
    if len(owner) <= len(points):  # too few samples for a floor: heights above the lowest
        return rough, ground
    xy = points[owner, frame, :2]
    centre = xy.mean(axis=0)
    _, _, axes = np.linalg.svd(xy - centre, full_matrices=False)
    axes = axes[np.ptp((xy - centre) @ axes.T, axis=0) >= min_extent]
    design = np.column_stack([owner[:, None] == np.arange(len(points)),
                              (xy - centre) @ axes.T]).astype(float)
    target = z[owner, frame]
    keep = np.ones(len(target), dtype=bool)
    for _ in range(5):
        coef, *_ = np.linalg.lstsq(design[keep], target[keep], rcond=None)
        new_keep = np.abs(target - design @ coef) < 0.01
        if np.array_equal(new_keep, keep) or new_keep.sum() <= design.shape[1]:
            break
        keep = new_keep
    floor = coef[:len(points), None] + (points[:, :, :2] - centre) @ axes.T @ coef[len(points):]
    return z - floor, ground


def _shared_velocity(velocity: np.ndarray, radius: float, /) -> np.ndarray:
    """The horizontal velocity (2,) m/s most of ``velocity`` (N, 2) share: of 256 evenly
    spaced samples, the one with the most of 4096 evenly spaced samples within ``radius``/2;
    then, twice, the median of the samples within ``radius`` of it.

    A foot near the floor is flat on it (moving with the ground) for most of its stance, and
    arriving or leaving for the rest, each at its own speed: the median of all lies between
    the two, 0.17 m/s off a belt's speed on a short treadmill capture, and may sit further
    than ``radius`` from it; the velocity most samples share is the flat foot's.
    """
    sample = velocity[np.linspace(0, len(velocity) - 1, min(len(velocity), 4096)).astype(int)]
    picks = sample[np.linspace(0, len(sample) - 1, min(len(sample), 256)).astype(int)]
    close = np.linalg.norm(sample[None] - picks[:, None], axis=2) < radius / 2     # (256, 4096)
    shared = picks[np.argmax(close.sum(axis=1))]
    for _ in range(2):
        shared = np.median(velocity[np.linalg.norm(velocity - shared, axis=1) < radius], axis=0)
    return shared


def _is_belt(centre_velocity: np.ndarray, low: np.ndarray, ground: np.ndarray,
             still_speed: float) -> bool:
    """Whether ``ground`` (3,) m/s, estimated from the foot centre's velocity (F, 3) over the
    ``low`` frames (F,) bool, is a treadmill belt's rather than a foot's on a fixed floor.

    The median over the low frames is not zero overground: at fast walking and running the
    frames within 3 cm of the floor include the foot arriving and leaving, which pull it to
    ~0.25 m/s along the travel. A belt needs both kinds of evidence: (1) more low frames move
    with ``ground`` than stand still (each within ``still_speed``/2), as a foot flat on a belt
    does for most of its stance; (2) the foot's mean horizontal velocity over the capture (its
    net travel / duration) is under half the belt's speed: a treadmill walker stays in place,
    while overground the foot travels at the walking speed, several times the false estimate.
    """
    speed = float(np.hypot(*ground[:2]))
    if speed == 0.0:
        return False
    tolerance = 0.5 * still_speed
    horizontal = centre_velocity[low, :2]
    moving = np.sum(np.linalg.norm(horizontal - ground[:2], axis=1) < tolerance)
    standing = np.sum(np.linalg.norm(horizontal, axis=1) < tolerance)
    travel = np.hypot(*np.nanmean(centre_velocity[:, :2], axis=0))
    return bool(moving > standing and travel < 0.5 * speed)


def _swings(contact: np.ndarray, clearance: np.ndarray, min_frames: int) -> list[tuple[int, int]]:
    """[start, end) of each run of at least ``min_frames`` measured frames out of contact; a
    run cut short by either end of the capture needs only 3 (its one visible event is seen)."""
    runs = valid_runs(~contact & np.isfinite(clearance)).tolist()
    return [(s, e) for s, e in runs
            if e - s >= min_frames or ((s == 0 or e == len(contact)) and e - s >= 3)]


def _peak_time(signal: np.ndarray, lo: int, hi: int) -> float | None:
    """Sub-frame time (frames) of the maximum of ``signal[lo:hi]`` by a parabola; None if none."""
    window = signal[lo:hi]
    if window.size == 0 or not np.isfinite(window).any():
        return None
    i = lo + int(np.nanargmax(window))
    if 0 < i < len(signal) - 1 and np.isfinite(signal[i - 1:i + 2]).all():
        y0, y1, y2 = signal[i - 1:i + 2]
        curvature = y0 - 2 * y1 + y2
        if curvature < 0:
            return i + 0.5 * (y0 - y2) / curvature
    return float(i)


def _toe_off_time(foot: _Foot, last: int, lo: int, hi: int, rate: float) -> float | None:
    """The default toe-off (frames) of a walking foot in ``[lo, hi)`` (frames): the mean of
    the upward-velocity peak of the point :data:`TOE_OFF_WEIGHT` of the way from the other
    marker to the one that left last (index ``last``) and the time the foot's pitch rate falls
    to :data:`TOE_OFF_PITCH_FRACTION` of its push-off peak (module docstring); None when
    either is not found."""
    velocity = foot.velocity[:, :, 2]
    push = TOE_OFF_WEIGHT * velocity[last] + (1.0 - TOE_OFF_WEIGHT) * velocity[1 - last]
    peak = _peak_time(push, lo, hi)
    release = _release_time(_pitch_rate(foot.points, last, rate), lo, hi)
    return None if peak is None or release is None else 0.5 * (peak + release)


def _pitch_rate(points: np.ndarray, last: int, rate: float) -> np.ndarray:
    """The foot's pitch rate (F,) rad/s from low-passed heel and toe ``points`` (2, F, 3) m:
    how fast the marker that left the floor first rises over the one that left last (index
    ``last``), as the elevation angle of the line between them; > 0 while the foot rolls over
    its forefoot."""
    rolling = points[1 - last] - points[last]
    pitch = np.arctan2(rolling[:, 2], np.linalg.norm(rolling[:, :2], axis=1))
    return np.gradient(pitch) * rate if len(pitch) > 1 else 0.0 * pitch


def _release_time(pitch_rate: np.ndarray, lo: int, hi: int) -> float | None:
    """When the pitch rate (F,) rad/s, past its push-off peak in ``[lo, hi)`` (frames), has
    fallen to :data:`TOE_OFF_PITCH_FRACTION` of that peak (frames, sub-frame by linear
    interpolation); None without a positive peak or a crossing before ``hi``."""
    window = pitch_rate[lo:hi]
    if window.size == 0 or not np.isfinite(window).any():
        return None
    peak = lo + int(np.nanargmax(window))
    level = TOE_OFF_PITCH_FRACTION * pitch_rate[peak]
    if not pitch_rate[peak] > 0:
        return None
    below = np.flatnonzero(~(pitch_rate[peak:hi] > level))
    if not below.size:
        return None
    i = peak + int(below[0])
    if not np.isfinite(pitch_rate[i]):
        return None
    return (i - 1) + (pitch_rate[i - 1] - level) / (pitch_rate[i - 1] - pitch_rate[i])


def _lift_time(upward: np.ndarray, peak: float, rate: float) -> float:
    """When a point's low-passed upward velocity ``upward`` (F,) m/s rises fastest (frames),
    from 0.1 s before to 0.05 s after the foot centre's upward-velocity ``peak`` (frames)."""
    reach = round(0.1 * rate)
    lift = _peak_time(np.gradient(upward), max(0, int(peak) - reach), int(peak) + reach // 2)
    return peak if lift is None else lift


def _arrival_time(speed, top, end, hi, window, rise=0.3) -> float | None:
    """When a contact point stops: the knot where its speed ceases to fall (mirror image)."""
    peak = top + int(np.nanargmax(speed[top:end + 1]))
    rest = peak + int(np.nanargmin(speed[peak:hi]))
    lo = rest - int(np.argmax(speed[peak:rest + 1][::-1] > rise * speed[peak]))
    return _knot(speed, lo, min(hi, lo + window + 1))


def _knot(signal: np.ndarray, lo: int, hi: int, step: float = 0.05) -> float | None:
    """Sub-frame knot (frames) of the best continuous two-line fit to ``signal[lo:hi]`` whose
    slope increases at the knot (a speed starting to rise, or ceasing to fall); None if the
    window is too short or holds missing samples."""
    hi = min(hi, len(signal))
    y = signal[lo:hi]
    if len(y) < 5 or not np.isfinite(y).all():
        return None
    x = np.arange(lo, hi, dtype=np.float64)
    knots = np.arange(lo + 1, hi - 2 + step / 2, step)
    design = np.stack([np.ones((len(knots), len(x))), x - knots[:, None],
                       np.maximum(x - knots[:, None], 0.0)], axis=2)         # (K, n, 3)
    gram = design.transpose(0, 2, 1) @ design
    coef = np.linalg.solve(gram, (design.transpose(0, 2, 1) @ y)[:, :, None])  # (K, 3, 1)
    cost = np.sum(((design @ coef)[:, :, 0] - y) ** 2, axis=1)
    coef = coef[:, :, 0]
    cost[coef[:, 2] <= 0] = np.inf
    best = int(np.argmin(cost))
    return float(knots[best]) if np.isfinite(cost[best]) else None


def _kink(values: np.ndarray, centre: float, half: int, step: float = 0.05) -> float | None:
    """Sub-frame time (frames) of the best kink in ``values`` (F,) or (F, C) near ``centre``.

    Fits, over ``centre ± half`` frames of the *unfiltered* samples, a curve that is quadratic
    on each side of a knot and continuous there (so its velocity and acceleration may jump), for
    every knot on a ``step`` grid within ``centre ± half/2``, and returns the knot of least
    squared error: where a foot point's velocity jumps (lift-off or landing of a rigid foot) or,
    for smooth data, where its acceleration changes most.
    """
    values = values.reshape(len(values), -1)
    lo = max(0, int(np.floor(centre - half / 2)) - half // 2)
    hi = min(len(values), int(np.ceil(centre)) + half + 1)
    y = values[lo:hi]
    if hi - lo < 2 * half // 2 + 6 or not np.isfinite(y).all():
        return None
    x = np.arange(lo, hi, dtype=np.float64)
    knots = np.arange(max(centre - half / 2, lo + 2), min(centre + half / 2, hi - 3) + step / 2,
                      step)
    if knots.size == 0:
        return None
    d = x - knots[:, None]                                                   # (K, n)
    after = np.maximum(d, 0.0)
    design = np.stack([np.ones_like(d), d, d * d, after, after * after], axis=2)  # (K, n, 5)
    gram = design.transpose(0, 2, 1) @ design
    coef = np.linalg.solve(gram, design.transpose(0, 2, 1) @ y)             # (K, 5, C)
    cost = np.sum((design @ coef - y) ** 2, axis=(1, 2))
    return float(knots[int(np.argmin(cost))])


def _refined(values: np.ndarray, coarse: float, half: int, rounds: int = 4) -> float:
    """``coarse`` (frames) moved to the kink of the unfiltered ``values``: the search window is
    re-centred on each kink found until it stays put (at most ``rounds`` times)."""
    time = coarse
    for _ in range(rounds):
        fine = _kink(values, time, half)
        if fine is None or abs(fine - time) < 0.5:
            return time if fine is None else fine
        time = fine
    return time


def _median_kink(raw: np.ndarray, point: int, coarse: float, half: int) -> float:
    """Median of the refined times (frames) from ``raw[point]`` (F, 3), its height, and both
    points together; ``raw`` is (2, F, 3) unfiltered heel and toe."""
    return float(np.median([_refined(signal, coarse, half) for signal in
                            (raw[point], raw[point, :, 2], raw.transpose(1, 0, 2))]))


def _event(side: str, kind: str, time_s: float, measured: np.ndarray, rate: float) -> GaitEvent:
    frame = int(np.clip(round(time_s * rate), 0, len(measured) - 1))
    half = max(1, round(0.05 * rate))
    quality = float(measured[max(0, frame - half):frame + half + 1].mean())
    return GaitEvent(side, kind, float(time_s), frame, quality)


#: Labels of lab-recorded events (C3D EVENT group: Vicon, Qualisys, our synthetic captures) and
#: the event kind each marks; the side is the context's first letter (Left/Right), else the
#: label's (LTO).
LAB_EVENT_KINDS = {"Foot Off": "toe_off", "Foot Strike": "heel_strike",
                   "LTO": "toe_off", "RTO": "toe_off", "LHS": "heel_strike", "RHS": "heel_strike"}


def event_differences(detected, reference, /, *, kind: str, start_time: float = 0.0,
                      max_s: float = 0.1) -> np.ndarray:
    """Detected minus reference time (s) of each reference event of ``kind``, shape (R,).

    ``detected`` are :class:`GaitEvent` (seconds from the first frame), ``reference`` the
    trial's lab events (:class:`mocaplib.trial.Event`, on the lab clock whose first frame is at
    ``start_time``). Each reference event is paired with the nearest detected event of the
    same side and kind; NaN where there is none within ``max_s`` (e.g. at the capture's edges).
    """
    out = []
    for lab in reference:
        if LAB_EVENT_KINDS.get(lab.label) != kind:
            continue
        letter = next((text[:1].upper() for text in (lab.context, lab.label)
                       if text[:1].upper() in ("L", "R")), None)
        if letter is None:
            continue
        side = "left" if letter == "L" else "right"
        found = [e.time_s + start_time - lab.time_s for e in detected
                 if e.side == side and e.kind == kind]
        nearest = min(found, key=abs, default=np.inf)
        out.append(nearest if abs(nearest) <= max_s else np.nan)
    return np.array(out, dtype=np.float64)


#: Landmarks used as each foot's heel and toe point, the toe by preference order.
FOOT_LANDMARKS = {"left": ("L_HEEL", ("L_TOE", "L_MT1", "L_MT5", "L_TOE2")),
                  "right": ("R_HEEL", ("R_TOE", "R_MT1", "R_MT5", "R_TOE2"))}


def feet_of(trial, match, /, *, motion=None
            ) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, np.ndarray]]:
    """The feet of a trial's protocol-matched markers, and where they were measured.

    Returns ``{"left": (heel, toe), "right": ...}`` (F, 3) m and ``{"left": (F,) bool, ...}``,
    the frames where the capture measured both (pass it as :func:`detect_events`'s
    ``measured``). ``match`` is a :class:`mocaplib.markersets.matching.ProtocolMatch`; the toe is the
    first present of :data:`FOOT_LANDMARKS`. With a fitted ``motion``
    (:class:`mocaplib.Motion`), samples where a marker is missing are taken from the fitted
    skeleton's position of that marker, except in frames the fit flagged as failed and before
    the marker's first measured sample or after its last (they stay missing: nothing measured
    supports an event there), and the labelling errors the fit undid (``motion.repairs``: a
    LHEE/RHEE swap, a marker left out) are undone here too, as the fit read them. Raises
    :class:`EventError` naming
    the landmark the capture has no label for (and the labels the protocol gives for it), or
    the marker the fit left out in every frame.
    """
    present = match.present_landmarks
    modelled = motion.model_markers() if motion is not None else None

    def track(side, label):
        measured = match.marker(trial, label)
        if motion is not None:
            measured = motion.repaired_track(label, lambda other: match.marker(trial, other))
        points = measured
        if modelled is not None and label in motion.marker_labels:
            model_points = modelled[:, motion.marker_labels.index(label)]
            usable = (np.isnan(measured) & ~np.asarray(motion.failed, dtype=bool)[:, None]
                      & _between_samples(np.isfinite(measured).all(axis=1))[:, None])
            points = np.where(usable, model_points, measured)
        if np.isnan(points[:, 2]).all():        # the match takes only labels seen somewhere
            raise EventError(f"{side} foot marker {label} was left out by the fit in every "
                             "frame: it stays far from where the calibrated skeleton puts it",
                             path=trial.source,
                             hint="check its label and its placement: the fit's warnings name "
                                  "the markers it left out")
        return points, np.isfinite(measured).all(axis=1)

    feet, measured = {}, {}
    for side, (heel, toes) in FOOT_LANDMARKS.items():
        toe = next((name for name in toes if name in present), None)
        if heel not in present:
            _no_foot_marker(trial, match, f"{side} heel", (heel,))
        if toe is None:
            _no_foot_marker(trial, match, f"{side} toe", toes)
        (heel_points, heel_seen), (toe_points, toe_seen) = (track(side, present[heel]),
                                                            track(side, present[toe]))
        feet[side] = (heel_points, toe_points)
        measured[side] = heel_seen & toe_seen
    return feet, measured


def _between_samples(seen: np.ndarray) -> np.ndarray:
    """The frames (F,) bool from the first ``True`` of ``seen`` (F,) bool to its last."""
    frames = np.flatnonzero(seen)
    inside = np.zeros(len(seen), dtype=bool)
    if len(frames):
        inside[frames[0]:frames[-1] + 1] = True
    return inside


def _no_foot_marker(trial, match, what: str, landmarks: tuple[str, ...]) -> None:
    """Raise the :class:`EventError` for a capture without a ``what`` marker (any of
    ``landmarks``), blaming the capture's labels or, when it has none, the protocol."""
    protocol = match.protocol
    labels = [key for m in protocol.markers if m.landmark.name in landmarks
              for key in (m.label, *m.aliases)]
    named = f"{what} ({'/'.join(landmarks)})"
    need = "gait events need a heel and a toe marker on each foot"
    if not labels:
        raise EventError(f"protocol {protocol.name!r} has no {named} marker", path=trial.source,
                         hint=f"{need}: pass --protocol with a protocol that has one, or add "
                              "one to this protocol")
    raise EventError(f"the capture has no {named} marker: none of the labels protocol "
                     f"{protocol.name!r} gives for it ({', '.join(labels)}) is in the file",
                     path=trial.source,
                     hint=f"{need}: rename the capture's {what} label to one of those, add it "
                          "to the protocol as an alias, or pass --protocol (`mocaplib inspect` "
                          "lists the capture's labels and their gaps: a label missing in every "
                          "frame counts as absent)")
