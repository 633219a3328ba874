"""Locomotion cycles: cut at consecutive left toe-offs, measured, encoded, and one chosen.

A cycle runs from a left toe-off to the next left toe-off (DESIGN.md). For each complete cycle
this module measures the pattern and velocities (:mod:`mocaplib.gait.patterns`), optionally encodes
the joint coordinates (:mod:`mocaplib.gait.fourier`), and rates how steady it is.

**Choice of one cycle per activity segment (documented rule).** Each cycle has an activity
(:mod:`mocaplib.gait.activity`: standing, stepping in place, turning on the spot, walking
forwards, backwards or sideways, running, stairs or slopes); consecutive cycles of one
activity, each starting where the one before ends, form an *activity segment*
(:func:`activity_segments`), and a capture contributes one cycle per segment, so a mixed take
gives its forward walk, its backward walk and its turn as separate entries. Within a segment
the choice is the steadiest cycle. A steady cycle repeats itself: its two
halves (about one step each) have the same speed and turn rate. The *unsteadiness* of a cycle is

    |v₂ − v₁| + r·|ω₂ − ω₁|       (m/s),  r = 0.2 m (about half a shoulder width)

where v₁, v₂ are the mean horizontal speeds of the shoulder midpoint (chord / (T/2)) over the
first and second half of the cycle and ω₁, ω₂ the mean rates of θ_S; ``r·Δω`` is the speed
difference the shoulders feel from a change of turn rate. Gait initiation and termination,
stumbles and turns that start mid-cycle all raise it. The chosen cycle is the one with the
lowest unsteadiness among cycles whose bounding toe-offs have event quality >= 0.5 (all cycles
if none qualifies); ties go to the earlier cycle. The candidates are first narrowed to the
cycles that pass the library's QC, when any of the segment's does, so a segment whose steadiest
cycle fails QC contributes its steadiest good one. The choice is made once, by
:func:`qc_and_choice` (what ``mocaplib cycles`` and ``mocaplib build`` run), after the QC:
:func:`analyse_cycles` measures and rates the cycles and chooses none. A session's per-capture
choice (``cycles``, ``drop_cycles``, ``trim`` in ``session.toml``) replaces the rule: the cycles
it leaves out carry the reason in ``left_out``. Every cycle is returned, so callers keep all of
them on request (``--all-cycles``).

**Partial visibility (documented rule).** A cycle is not cut across a gap longer than
``max_gap_s`` (:data:`MAX_GAP_S`, 0.25 s): a run of frames the fit could not solve (too few
markers: :attr:`mocaplib.model.motion.Motion.failed`), whose joint angles are interpolated; nor
into such a run at the capture's start or end, whose angles are held from the one solved frame
beside it (a walker leaving the volume would stop there). When no
cycle from left toe-off to left toe-off is left (fewer than two left toe-offs visible, or
every such cycle spans a longer gap), the protocol's ``fallback_starts``
(:attr:`mocaplib.markersets.protocols.Protocol.fallback_starts`) are tried in order: a cycle from one
event of that side and kind to the next, kept only when it holds the other three events of one
stride, each once, in the order of walking (left toe-off, left heel-strike, right toe-off,
right heel-strike) or of running (left toe-off, right heel-strike, right toe-off, left
heel-strike), so the left toe-off inside it is known (``left_toe_off``) and the cycle can be
expressed from it (:func:`mocaplib.library.phase.from_left_toe_off`). A jump, whose feet leave and
land together, holds them in neither order and gives no such cycle.

**Rest.** A capture with no gait event at all (standing) gives one rest entry: v̂ = ω̂ = v̂_l =
v̂_f = 0, pattern ``point``, nominal period :data:`REST_PERIOD` (1.0 s, about the stride time
of normal walking, so rest blends with slow walking on a comparable time base), starting at the
capture's first frame; its Fourier encoding is order 0 (the mean posture over that second).
A capture shorter than that second (a fragment of walking has no gait event either) is an
error, not a rest entry.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import EventError, NoCycleError
from ..model.filtering import WALKING_CUTOFF, lowpass, resample, shortest_run
from ..runs import frames_within, valid_runs
from ..skeleton import DOF_NAMES, ROOT_X, ROOT_Y, ROOT_Z, SEGMENT_NAMES, TRANSLATION
from ..statics import STANDING_EXTENT, STATIC_WINDOW_S, moved_extent, quietest_stretch
from ..trial import CYCLE_STARTS
from .events import EventSettings
from .foot_events import GaitEvent
from .fourier import ANGLE_TOLERANCE, LENGTH_TOLERANCE, CycleEncoding, encode_cycle
from .patterns import (CycleVelocities, Pattern, cycle_samples, cycle_times, path_velocities,
                       sample_shoulders)
from .qc import QC_LIMITS, cycle_qc, qc_failures, qc_series

#: Nominal period of the rest entry, seconds.
REST_PERIOD = 1.0
#: Lever arm converting a turn-rate difference into a shoulder speed difference, metres.
STEADINESS_RADIUS = 0.2
#: Cycles bounded by toe-offs of lower quality are chosen only when no other qualifies: the
#: library's QC limit on event quality.
MIN_EVENT_QUALITY = QC_LIMITS["event_quality"][0]
#: Longest gap (s) a cycle may span: frames the fit interpolated (module docstring); the same
#: limit as the gait events' linear fill of the foot markers.
MAX_GAP_S = EventSettings.max_gap_s
#: One stride's events, ``<side>_<kind>`` names: the left toe-off and the library's
#: ``cycle_start`` values.
STRIDE_EVENTS = ("left_toe_off", *CYCLE_STARTS)
#: The orders of one stride's events from the left toe-off: walking (the left foot swings, then
#: the right) and running (each toe-off followed by a flight and the other foot's strike).
GAIT_ORDERS = {"walking": ("left_toe_off", "left_heel_strike", "right_toe_off",
                           "right_heel_strike"),
               "running": ("left_toe_off", "right_heel_strike", "right_toe_off",
                           "left_heel_strike")}
#: What a standard cycle starts at.
LEFT_TOE_OFF = STRIDE_EVENTS[0]
#: Steps in a cycle (a stride): its rise per step is half its height change.
STEPS_PER_CYCLE = 2


@dataclass
class Cycle:
    """One locomotion cycle (or the rest entry) of a capture.

    Attributes
    ----------
    index : int
        Position among the capture's cycles (0-based).
    start_s, end_s : float
        Bounds, seconds from the capture's first frame (the two left toe-offs).
    velocities : CycleVelocities
        Pattern, v̂ (m/s), ω̂ (rad/s), v̂_l, v̂_f (m/s).
    unsteadiness : float
        See the module docstring, m/s (0 for rest).
    event_quality : float
        Smaller quality of the two bounding toe-offs (1 for rest).
    encoding : CycleEncoding or None
        Fourier encoding of the joint coordinates, when they were given.
    rest : bool
        True for the rest entry of a standing capture.
    chosen : bool
        True for the cycle chosen for the library.
    right_toe_off : float or None
        The first right toe-off inside the cycle, seconds from its start (0 for a cycle that
        starts at one; None when none was detected, and for rest): where its mirror image
        starts (:mod:`mocaplib.library.mirror`).
    start_event : str
        The event the cycle starts and ends at (:data:`STRIDE_EVENTS`): ``"left_toe_off"``
        unless the protocol's fallback cut it (module docstring).
    left_toe_off : float or None
        For a cycle starting at another event, the left toe-off inside it, seconds from its
        start; None for a cycle that starts at a left toe-off.
    unplaced : tuple[str, ...]
        One sentence per event the detector could not place (:attr:`GaitEvent.warning`) among
        its bounds or inside it: a bound not placed gives the cycle ``event_quality`` 0.
    uncertain : tuple[str, ...]
        One sentence per toe-off among its bounds or inside it placed midway between two marks
        that disagree (:attr:`GaitEvent.uncertain`); the cycle keeps its ``event_quality``.
    bound_plates : (int or None, int or None)
        The force plates (1-based) that timed the events the cycle starts and ends at
        (:mod:`mocaplib.gait.plate_events`), None for an event the markers timed.
    bound_shifts : (float, float)
        How far (s) the force plates moved those two events from the markers' times
        (:attr:`GaitEvent.plate_shift_s`), 0 where they did not.
    rise_per_step : float or None
        How far the pelvis rises (> 0) or drops per step over the cycle, m: half its height
        change from start to end (a cycle is two steps); 0 for rest, None without the joint
        coordinates. Stairs and slopes (:mod:`mocaplib.gait.activity`).
    activity : str
        What the person does (:data:`mocaplib.gait.activity.ACTIVITIES`); "" until set
        (:func:`mocaplib.gait.activity.set_activities`).
    left_out : str or None
        Why a session's per-capture choice leaves the cycle out (None: a candidate).
    """

    index: int
    start_s: float
    end_s: float
    velocities: CycleVelocities
    unsteadiness: float
    event_quality: float
    encoding: CycleEncoding | None = None
    rest: bool = False
    chosen: bool = False
    right_toe_off: float | None = None
    start_event: str = LEFT_TOE_OFF
    left_toe_off: float | None = None
    unplaced: tuple[str, ...] = ()
    uncertain: tuple[str, ...] = ()
    bound_plates: tuple[int | None, int | None] = (None, None)
    bound_shifts: tuple[float, float] = (0.0, 0.0)
    rise_per_step: float | None = None
    activity: str = ""
    left_out: str | None = None

    @property
    def period(self) -> float:
        """T, seconds."""
        return self.end_s - self.start_s

    def to_dict(self) -> dict:
        """JSON-ready summary (SI units; ``fourier_rms_deg`` in degrees)."""
        vel = self.velocities
        out = {"index": self.index, "start_s": self.start_s, "end_s": self.end_s,
               "T": self.period, "pattern": vel.pattern.to_dict(), "v": vel.v,
               "omega": vel.omega, "v_l": vel.v_l, "v_f": vel.v_f,
               "fourier_n": None, "fourier_rms_deg": None, "fourier_worst_dof": None,
               "unsteadiness": self.unsteadiness, "event_quality": self.event_quality,
               "rest": self.rest, "chosen": self.chosen, "right_toe_off_s": self.right_toe_off,
               "start_event": self.start_event, "left_toe_off_s": self.left_toe_off,
               "unplaced_events": list(self.unplaced), "uncertain_events": list(self.uncertain),
               "bound_plates": list(self.bound_plates),
               "bound_plate_shifts_s": list(self.bound_shifts),
               "rise_per_step_m": self.rise_per_step,
               "activity": self.activity, "left_out": self.left_out}
        if self.encoding is not None:
            out.update(fourier_n=self.encoding.order, fourier_rms_deg=self.encoding.rms_deg,
                       fourier_worst_dof=self.encoding.worst_dof)
        return out


def shoulder_centres(motion, /) -> tuple[np.ndarray, np.ndarray]:
    """Left and right shoulder joint centres (F, 3) m of a fitted :class:`~mocaplib.Motion`.

    The humerus origins of the fitted skeleton: on the synthetic captures they give v̂_l about
    twice as close to the truth as the acromion markers (whose placement error yaws the
    shoulder line), see docs/results/velocity_accuracy.md.
    """

    frames = motion.skeleton.forward(motion.q, segments=[SEGMENT_NAMES.index("humerus_l"),
                                                         SEGMENT_NAMES.index("humerus_r")])
    return frames[:, 0, :3, 3], frames[:, 1, :3, 3]


def motion_cycles(events: list[GaitEvent], motion, /, *, ground: np.ndarray | None = None,
                  shoulders: tuple[np.ndarray, np.ndarray] | None = None,
                  fallback_starts: tuple[str, ...] = (), max_gap_s: float = MAX_GAP_S,
                  source: str | os.PathLike | None = None) -> list[Cycle]:
    """:func:`analyse_cycles` of a fitted :class:`~mocaplib.Motion`: its shoulder joint centres
    (:func:`shoulder_centres`, or ``shoulders`` when already computed), joint coordinates and
    the frames it could not solve (``filled``); what ``mocaplib cycles`` and ``mocaplib build``
    run. ``events`` and ``ground`` as :func:`mocaplib.gait.events.capture_events` gives them."""
    left, right = shoulder_centres(motion) if shoulders is None else shoulders
    return analyse_cycles(events, left, right, motion.rate, q=motion.q, ground=ground,
                          filled=motion.failed, fallback_starts=fallback_starts,
                          max_gap_s=max_gap_s, source=source)


def event_name(event: GaitEvent, /) -> str:
    """``<side>_<kind>``, as :data:`STRIDE_EVENTS` and protocols name events."""
    return f"{event.side}_{event.kind}"


def cycle_bounds(events: list[GaitEvent], /, *, start: str = LEFT_TOE_OFF
                 ) -> list[tuple[GaitEvent, GaitEvent]]:
    """Pairs of consecutive events named ``start`` (:data:`STRIDE_EVENTS`), in time order;
    for another start than the left toe-off, only the pairs holding the other three events of
    one stride, each once, in a gait order (:data:`GAIT_ORDERS`, module docstring)."""
    ordered = sorted(events, key=lambda e: e.time_s)
    named = [e for e in ordered if event_name(e) == start]
    pairs = list(zip(named[:-1], named[1:]))
    if start == LEFT_TOE_OFF:
        return pairs
    orders = [order[order.index(start) + 1:] + order[:order.index(start)]
              for order in GAIT_ORDERS.values()]
    return [(first, last) for first, last in pairs
            if tuple(event_name(e) for e in ordered
                     if first.time_s < e.time_s < last.time_s) in orders]


def longest_gap(filled: np.ndarray | None, rate: float, start_s: float, end_s: float) -> float:
    """Longest run (s) of ``filled`` (F,) bool frames inside [start_s, end_s]: a run of n
    frames spans (n + 1) / rate between the solved frames around it; 0 when none. A run at the
    capture's first or last frame has a solved frame on one side only (its angles are held
    from it, not interpolated): inf when the window reaches into one."""
    if filled is None:
        return 0.0
    filled = np.asarray(filled, dtype=bool)
    inside = frames_within(start_s, end_s, rate, len(filled))
    longest = 0.0
    for first, stop in valid_runs(filled[inside]).tolist():
        from_start = first == 0 and filled[:inside.start].all()
        to_end = inside.start + stop >= inside.stop and filled[inside.stop:].all()
        if from_start or to_end:
            return float("inf")
        longest = max(longest, (stop - first + 1) / rate)
    return longest


def analyse_cycles(events: list[GaitEvent], left_shoulder: np.ndarray,
                   right_shoulder: np.ndarray, rate: float, /, *, q: np.ndarray | None = None,
                   ground: np.ndarray | None = None, filled: np.ndarray | None = None,
                   fallback_starts: tuple[str, ...] = (), max_gap_s: float = MAX_GAP_S,
                   tol_angle: float = ANGLE_TOLERANCE, tol_length: float = LENGTH_TOLERANCE,
                   point_radius: float = 0.05, min_arc_angle: float = np.deg2rad(10.0),
                   source: str | os.PathLike | None = None) -> list[Cycle]:
    """Every complete cycle of a capture, measured and rated, one of them ``chosen``.

    Parameters
    ----------
    events
        The capture's gait events (:func:`mocaplib.gait.events.detect_events`).
    left_shoulder, right_shoulder
        (F, 3) metres, Z up, NaN where missing.
    rate
        Frame rate, Hz.
    q
        Optional joint coordinates (F, D) in :data:`mocaplib.skeleton.DOF_NAMES` order; when
        given each cycle gets its Fourier encoding (tolerances ``tol_angle`` rad, raised to
        each angle's noise floor, and ``tol_length`` m: :func:`mocaplib.gait.fourier.encode_cycle`).
    ground
        The floor's velocity (3,) m/s, from :func:`mocaplib.gait.events.ground_velocity`: on a
        treadmill, paths, velocities and the root's drift are measured relative to the belt.
    filled
        Frames (F,) bool whose samples were interpolated (the fit could not solve them); a
        cycle spanning a run of them longer than ``max_gap_s`` (s) is not cut.
    fallback_starts
        Events (:data:`STRIDE_EVENTS` names) a cycle may start at, in order, when no cycle
        from left toe-off to left toe-off is left (module docstring); the protocol's.
    point_radius, min_arc_angle
        Pattern choice, see :func:`mocaplib.gait.patterns.fit_pattern`.

    Returns
    -------
    list of Cycle
        The cycles in time order, each with its velocities, unsteadiness, event quality and
        (with ``q``) Fourier encoding and rise per step; none is ``chosen`` yet
        (:func:`qc_and_choice` chooses). A capture without events gives one rest entry,
        chosen.

    Raises
    ------
    EventError
        :class:`~mocaplib.errors.NoCycleError` when there are events but no complete cycle
        (fewer than two left toe-offs, and no fallback cycle; or every cycle spans too long a
        gap): its message says which.
    """
    n_frames = len(np.asarray(left_shoulder))
    if q is not None:
        q = _unwrapped(np.asarray(q, dtype=np.float64), n_frames, source)
        if ground is not None:
            q[:, [ROOT_X, ROOT_Y]] -= np.outer(np.arange(n_frames) / rate, ground[:2])
        never = ~np.isfinite(q).any(axis=0)
    if not events:
        return [_rest_entry(left_shoulder, right_shoulder, rate, q, n_frames, source,
                            tol_angle, tol_length)]
    start_event, pairs = _cut(events, rate, filled=filled, fallback_starts=fallback_starts,
                              max_gap_s=max_gap_s, shoulders=(left_shoulder, right_shoulder),
                              source=source)
    smooth = None if q is None else _smoothed(q, rate)
    between = _events_between(events)
    cycles = []
    for index, (first, last) in enumerate(pairs):
        start, end = first.time_s, last.time_s
        near = between(start, end)
        times, mid, heading = cycle_samples(left_shoulder, right_shoulder, rate, start, end,
                                            ground=ground, source=source)
        velocities = path_velocities(times, mid, heading, point_radius=point_radius,
                                     min_arc_angle=min_arc_angle)
        encoding = rise = None
        if q is not None:
            samples = _interpolate(q, rate, times, never, source)
            noise = None if smooth is None else np.sqrt(np.nanmean(
                (samples - resample(smooth, rate, times))[:-1] ** 2, axis=0))
            encoding = encode_cycle(samples[:-1], times[:-1] - start, end - start, samples[-1],
                                    tol_angle=tol_angle, tol_length=tol_length, noise=noise)
            rise = float(samples[-1, ROOT_Z] - samples[0, ROOT_Z]) / STEPS_PER_CYCLE
        cycles.append(Cycle(index, start, end, velocities, _unsteadiness(times, mid, heading),
                            min(first.quality, last.quality), encoding,
                            right_toe_off=0.0 if start_event == "right_toe_off"
                            else _first_inside(near, "right", start, end),
                            start_event=start_event,
                            left_toe_off=None if start_event == LEFT_TOE_OFF
                            else _first_inside(near, "left", start, end),
                            unplaced=tuple(e.warning for e in near if not e.placed),
                            uncertain=tuple(e.warning for e in near if e.uncertain),
                            bound_plates=(first.plate, last.plate),
                            bound_shifts=(first.plate_shift_s, last.plate_shift_s),
                            rise_per_step=rise))
    return cycles


def _cut(events: list[GaitEvent], rate: float, /, *, filled, fallback_starts, max_gap_s,
         shoulders, source) -> tuple[str, list[tuple[GaitEvent, GaitEvent]]]:
    """The event the cycles start at and their bounding events: left toe-offs, else the first
    of ``fallback_starts`` that gives a cycle, each cycle spanning no gap longer than
    ``max_gap_s`` (:func:`longest_gap` of ``filled``); :class:`NoCycleError` saying why there
    is none (``shoulders``: left and right (F, 3) m, for the hint)."""
    too_long = []
    for start in (LEFT_TOE_OFF, *fallback_starts):
        pairs = []
        for first, last in cycle_bounds(events, start=start):
            gap = longest_gap(filled, rate, first.time_s, last.time_s)
            if gap > max_gap_s:
                too_long.append(f"{first.time_s:.2f}-{last.time_s:.2f} s ({start}) " + (
                    f"spans {gap:.2f} s the fit could not solve" if np.isfinite(gap) else
                    "reaches into the frames the fit could not solve at the capture's start "
                    "or end (held, not interpolated: no max_gap_s admits them)"))
            else:
                pairs.append((first, last))
        if pairs:
            return start, pairs
    why = "fewer than two left toe-offs were found"
    if fallback_starts:
        why += (f", and no cycle from {' or '.join(fallback_starts)} holds one stride's events "
                "in gait order")
    hint = _no_cycle_hint(*shoulders, rate, filled)
    if too_long:
        why = (f"every cycle spans a gap longer than max_gap_s {max_gap_s:g} s: "
               + "; ".join(too_long))
        hint = ("the markers are missing there (out of view?): fill the capture's gaps, or "
                "raise max_gap_s (--max-gap) if interpolating that long is acceptable")
    elif not fallback_starts:
        hint += ("; or let cycles start at other events: fallback_starts in the protocol's "
                 "[cycles] table (docs/guide/events-cycles.md)")
    raise NoCycleError(f"no complete cycle: {why}", path=source, hint=hint)


def _no_cycle_hint(left: np.ndarray, right: np.ndarray, rate: float,
                   filled: np.ndarray | None = None) -> str:
    """What to do about a capture without two left toe-offs: a capture seen (not ``filled``,
    (F,) bool) for less than half its frames is out of view most of the time; one whose
    shoulders stand still (:data:`mocaplib.statics.STANDING_EXTENT`) for a second or more,
    half of it at least, is a static with a step; otherwise it holds too few strides, or a
    wrong rate."""

    mid = 0.5 * (np.asarray(left, dtype=float) + np.asarray(right, dtype=float))[:, None]
    seen = np.ones(len(mid), dtype=bool) if filled is None else ~np.asarray(filled, dtype=bool)
    if seen.mean() < 0.5:
        frames = np.flatnonzero(seen)
        span = (f"{frames[0] / rate:.2f}-{frames[-1] / rate:.2f} s" if len(frames)
                else "no frame")
        return (f"the fit sees the subject in {seen.sum() / rate:.2f} s of the capture's "
                f"{len(mid) / rate:.2f} s ({span}): out of the capture volume the rest of "
                "the time; a cycle needs one stride in view (from a left toe-off to the next, "
                "or between the protocol's fallback_starts)")
    length = int(round(STATIC_WINDOW_S * rate)) + 1
    if len(mid) > length:
        start = quietest_stretch(mid, length)
        still = [moved_extent(mid[start:start + k]) <= STANDING_EXTENT
                 for k in (length, len(mid) // 2)]
        if all(still):
            return ("the subject stands still for most of it: a static trial (a step in or out "
                    "around it)? Give it with --static, which uses its quietest second (or "
                    "--static-window START:END)")
    return ("a cycle runs from one left toe-off to the next; capture at least two full "
            "strides, or, if it has them, check its frame rate (POINT:RATE): a wrong rate "
            "makes the swings seem too short or too slow to count")


def choose_cycle(cycles: list[Cycle], /, *, eligible: set[int] | None = None) -> Cycle:
    """Mark and return the steadiest of ``cycles`` (module docstring's rule); clears the other
    marks among them.

    ``eligible``: indices of the cycles that may be chosen (those passing the library's QC,
    :func:`mocaplib.gait.cycles.qc_and_choice`); every cycle when None or when none is eligible.
    """
    if not cycles:
        raise EventError("no cycle to choose from")
    pool = [c for c in cycles if eligible is None or c.index in eligible] or cycles
    good = [c for c in pool if c.event_quality >= MIN_EVENT_QUALITY] or pool
    best = min(good, key=lambda c: (c.unsteadiness, c.index))
    for cycle in cycles:
        cycle.chosen = cycle is best
    return best


def activity_segments(cycles: list[Cycle], /) -> list[list[Cycle]]:
    """The activity segments of a capture's candidate cycles (``left_out`` None), in time
    order: runs of consecutive cycles of one ``activity``, each starting where the one before
    ends (module docstring)."""
    segments: list[list[Cycle]] = []
    for cycle in (c for c in cycles if c.left_out is None):
        last = segments[-1][-1] if segments else None
        if last is not None and last.activity == cycle.activity \
                and cycle.start_s == last.end_s:     # the same bounding event
            segments[-1].append(cycle)
        else:
            segments.append([cycle])
    return segments


def choose_cycles(cycles: list[Cycle], /, *, eligible: set[int] | None = None,
                  picked: tuple[int, ...] | None = None) -> list[Cycle]:
    """Mark and return the cycles a capture contributes: the steadiest of each activity
    segment (:func:`activity_segments`, :func:`choose_cycle` with ``eligible``), or the cycles
    whose indices a session ``picked``; cycles ``left_out`` are never chosen."""
    for cycle in cycles:
        cycle.chosen = False
    if picked is not None:
        for cycle in cycles:
            cycle.chosen = cycle.index in picked and cycle.left_out is None
        return [c for c in cycles if c.chosen]
    return [choose_cycle(segment, eligible=eligible) for segment in activity_segments(cycles)]


def _events_between(events: list[GaitEvent], /):
    """A function ``(start, end)`` -> the ``events`` whose time lies in [start, end] (s), in
    their order in the list: a binary search in the events sorted once by time, so a long
    take's every cycle does not scan all of its events."""
    order = sorted((i for i, e in enumerate(events) if np.isfinite(e.time_s)),
                   key=lambda i: events[i].time_s)
    times = np.array([events[i].time_s for i in order], dtype=np.float64)

    def between(start: float, end: float) -> list[GaitEvent]:
        lo, hi = np.searchsorted(times, start, "left"), np.searchsorted(times, end, "right")
        return [events[i] for i in sorted(order[lo:hi])]
    return between


def _first_inside(events: list[GaitEvent], side: str, start: float, end: float
                  ) -> float | None:
    """Seconds from ``start`` to the first toe-off of ``side`` strictly between ``start`` and
    ``end`` (s), or None."""
    inside = [e.time_s for e in events
              if e.side == side and e.kind == "toe_off" and start < e.time_s < end]
    return min(inside) - start if inside else None


def _unsteadiness(times: np.ndarray, mid: np.ndarray, heading: np.ndarray) -> float:
    """Module docstring's measure (m/s) from a cycle's :func:`~mocaplib.gait.patterns.cycle_samples`."""
    half = int(np.argmin(np.abs(times - 0.5 * (times[0] + times[-1]))))
    v1 = np.hypot(*(mid[half, :2] - mid[0, :2])) / (times[half] - times[0])
    v2 = np.hypot(*(mid[-1, :2] - mid[half, :2])) / (times[-1] - times[half])
    w1 = (heading[half] - heading[0]) / (times[half] - times[0])
    w2 = (heading[-1] - heading[half]) / (times[-1] - times[half])
    return float(abs(v2 - v1) + STEADINESS_RADIUS * abs(w2 - w1))


def check_rest_duration(n_frames: int, rate: float, /, *,
                        source: str | os.PathLike | None = None) -> None:
    """Raise :class:`~mocaplib.errors.NoCycleError` (an :class:`EventError`) when a capture of
    ``n_frames`` at ``rate`` Hz without a gait
    event is too short to be rest: it spans (first to last frame) less than
    :data:`REST_PERIOD`, so it may as well be a fragment of walking."""
    duration = (n_frames - 1) / rate if n_frames else 0.0
    if duration < REST_PERIOD:
        raise NoCycleError(f"a capture of {n_frames} frame(s) cannot be a rest entry: "
                         f"{duration:.3g} s without a gait event, shorter than the "
                         f"{REST_PERIOD:g} s a rest entry spans", path=source,
                         hint="capture at least a second of standing, or two full strides")


def _rest_entry(left, right, rate, q, n_frames, source, tol_angle, tol_length) -> Cycle:
    check_rest_duration(n_frames, rate, source=source)
    times = cycle_times(0.0, REST_PERIOD, rate)
    mid, _ = sample_shoulders(left, right, rate, times, source=source)
    pattern = Pattern("point", {"point": mid[:, :2].mean(axis=0)})
    velocities = CycleVelocities(pattern, REST_PERIOD, 0.0, 0.0, 0.0, 0.0)
    encoding = None
    if q is not None:
        samples = _interpolate(q, rate, times, ~np.isfinite(q).any(axis=0), source)
        inside = times < REST_PERIOD
        encoding = encode_cycle(samples[inside], times[inside], REST_PERIOD, samples[0],
                                tol_angle=tol_angle, tol_length=tol_length, max_order=0)
    return Cycle(0, 0.0, REST_PERIOD, velocities, 0.0, 1.0, encoding, rest=True, chosen=True,
                 rise_per_step=0.0)


def _unwrapped(q: np.ndarray, n_frames: int, source) -> np.ndarray:
    if q.ndim != 2 or len(q) != n_frames or q.shape[1] != len(TRANSLATION):
        raise EventError(f"q must have shape ({n_frames}, {len(TRANSLATION)}), got {q.shape}",
                         path=source)
    out = q.copy()
    rotations = ~TRANSLATION
    for d in np.flatnonzero(rotations):
        valid = np.isfinite(q[:, d])
        out[valid, d] = np.unwrap(q[valid, d])
    return out


def _smoothed(q: np.ndarray, rate: float) -> np.ndarray | None:
    """The coordinates (F, D) low-passed at :data:`mocaplib.model.filtering.WALKING_CUTOFF`, from
    which each cycle's noise floor is measured (:mod:`mocaplib.gait.fourier`); None when the capture
    is too short or too slowly sampled to be filtered there."""

    if len(q) < shortest_run(rate, WALKING_CUTOFF) or rate <= 2 * WALKING_CUTOFF:
        return None
    return lowpass(q, rate, WALKING_CUTOFF)


def _interpolate(q: np.ndarray, rate: float, times: np.ndarray, never: np.ndarray,
                 source=None) -> np.ndarray:
    """Joint coordinates (n, D) at ``times`` (s), linear between frames, over NaN gaps too;
    EventError when a DOF is ``never`` (D,) bool finite (found once per capture: a long take's
    every cycle does not scan all of ``q``)."""

    if never.any():
        name = DOF_NAMES[int(np.argmax(never))]
        raise EventError(f"joint coordinate {name} is missing in every frame", path=source,
                         hint="check the fit: this DOF was never fitted")
    return resample(q, rate, times)


def qc_and_choice(cycles, motion, thresholds: dict, *, ground: np.ndarray | None = None,
                  picked: tuple[int, ...] | None = None) -> dict[int, dict]:
    """QC metrics (:func:`cycle_qc`) of every cycle of a fitted capture, by cycle index, and the
    choice of the cycles it contributes (:func:`choose_cycles`: per activity segment, among
    those that pass ``thresholds`` when any does, or the session's ``picked`` indices). What
    ``mocaplib build`` and ``mocaplib cycles`` run, once the cycles' activities are set
    (:func:`mocaplib.gait.activity.set_activities`). ``ground``: the floor's velocity (3,) m/s
    on a treadmill (:func:`mocaplib.gait.events.capture_events`), for the internal power."""
    series = qc_series(motion, ground)
    qcs = {c.index: cycle_qc(c, motion, series) for c in cycles}
    if not (len(cycles) == 1 and cycles[0].rest):
        choose_cycles(cycles, eligible={i for i, qc in qcs.items()
                                        if not qc_failures(qc, thresholds)}, picked=picked)
    return qcs
