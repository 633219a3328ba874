"""One foot's gait events (:class:`GaitEvent`): when, within one swing of the foot, its toe-off
and its heel-strike happen: the release of the last marker to leave the floor, the lift, the
arrival, each refined to sub-frame precision from the kink of the foot's trajectory.

Foot points are ``(F, 3)`` arrays in metres, Z up; times in seconds or frames as named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runs import valid_runs


def swing_spans(contact: np.ndarray, clearance: np.ndarray, min_frames: int) -> list[tuple[int, int]]:
    """[start, end) of each run of at least ``min_frames`` measured frames out of contact; a
    run cut short by either end of the capture needs only 3 (its one visible event is seen)."""
    runs = valid_runs(~contact & np.isfinite(clearance)).tolist()
    return [(s, e) for s, e in runs
            if e - s >= min_frames or ((s == 0 or e == len(contact)) and e - s >= 3)]


def peak_time(signal: np.ndarray, lo: int, hi: int) -> float | None:
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


#: Peaks within this share of the highest are near-equal: they share the crest
#: (:func:`crest_time`). Two bumps of a push's upward velocity 50 ms apart, equal to 1e-3
#: (CMU 07_01's left foot at 2.2 s), took turns as the maximum when the capture was stored as
#: integers or sampled at half its rate, moving the toe-off by 25 ms.
CREST_SHARE = 0.05


def crest_time(signal: np.ndarray, lo: int, hi: int) -> float | None:
    """Sub-frame time (frames) of the crest of ``signal[lo:hi]``: the mean of the times
    (:func:`peak_time`) of its peaks within :data:`CREST_SHARE` of the highest, each weighted
    by how far it rises above that level; the highest peak's own time when it alone is there,
    so that near-equal peaks share the time rather than take turns with the noise, and a peak
    rising towards the level moves it continuously; None if none."""
    window = signal[lo:hi]
    if window.size == 0 or not np.isfinite(window).any():
        return None
    level = np.nanmax(window) * (1.0 - CREST_SHARE)
    rises = np.r_[True, window[1:] >= window[:-1]]       # the window's ends count as peaks
    falls = np.r_[window[:-1] > window[1:], True]
    peaks = np.union1d(np.flatnonzero(rises & falls), np.nanargmax(window))
    weights = window[peaks] - level
    above = weights > 0
    if not above.any():                  # a maximum of zero or less: no share of it to take
        return peak_time(signal, lo, hi)
    times = [peak_time(signal, lo + i, lo + i + 1) for i in peaks[above]]
    return float(np.dot(weights[above], times) / weights[above].sum())


def toe_off_signals(foot: FootTrack, last: int, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """What the default toe-off of a walking foot is read from, when the marker of index
    ``last`` is the one that leaves the floor last: the upward velocity (F,) m/s of the point
    :data:`TOE_OFF_WEIGHT` of the way from the other marker to it, and the foot's pitch rate
    (F,) rad/s (:func:`_pitch_rate`). Computed once per foot for all its toe-offs."""
    velocity = foot.velocity[:, :, 2]
    push = TOE_OFF_WEIGHT * velocity[last] + (1.0 - TOE_OFF_WEIGHT) * velocity[1 - last]
    return push, _pitch_rate(foot.points, last, rate)


def toe_off_time(signals: tuple[np.ndarray, np.ndarray], lo: int, hi: int
                 ) -> tuple[float | None, float]:
    """The default toe-off (frames) of a walking foot in ``[lo, hi)`` (frames), from its
    :func:`toe_off_signals`, and how far apart (frames) the two marks it is the mean of lie:
    the push point's upward-velocity peak (its :func:`crest_time`), sought while the foot
    still rolls (:func:`_roll_end`: a foot lifted later in the swing, onto a stair's tread,
    may rise faster), and the time the foot's pitch rate falls to
    :data:`TOE_OFF_PITCH_FRACTION` of its push-off peak (:mod:`mocaplib.gait.events`); (None,
    0) when either is not found."""
    peak, release = toe_off_marks(signals, lo, hi)
    if peak is None or release is None:
        return None, 0.0
    return 0.5 * (peak + release), abs(release - peak)


def toe_off_marks(signals: tuple[np.ndarray, np.ndarray], lo: int, hi: int
                  ) -> tuple[float | None, float | None]:
    """The two marks (frames, None where not found) the default toe-off in ``[lo, hi)``
    (frames) is the mean of (:func:`toe_off_time`): the push point's upward-velocity peak
    while the foot rolls, and the end of the roll."""
    push, pitch_rate = signals
    return (crest_time(push, lo, _roll_end(pitch_rate, lo, hi)),
            _release_time(pitch_rate, lo, hi))


def _roll_end(pitch_rate: np.ndarray, lo: int, hi: int) -> int:
    """The end (exclusive, frames) of the push-off in ``[lo, hi)``: one past the first frame,
    after the pitch rate's (F,) rad/s push-off peak, where it is no longer positive (the foot
    has stopped rolling over its forefoot between that frame and the one before); ``hi`` if
    it never stops there."""
    window = pitch_rate[lo:hi]
    if window.size == 0 or not np.isfinite(window).any():
        return hi
    peak = lo + int(np.nanargmax(window))
    stopped = np.flatnonzero(~(pitch_rate[peak:hi] > 0))
    return min(hi, peak + int(stopped[0]) + 1) if stopped.size else hi


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


def lift_time(rise: np.ndarray, peak: float, rate: float) -> float:
    """When a point's low-passed upward velocity rises fastest (frames), from 0.1 s before to
    0.05 s after the foot centre's upward-velocity ``peak`` (frames); ``rise`` (F,) m/s per
    frame: ``np.gradient`` of that velocity, computed once per foot for all its toe-offs."""
    reach = round(0.1 * rate)
    lift = peak_time(rise, max(0, int(peak) - reach), int(peak) + reach // 2)
    return peak if lift is None else lift


def arrival_time(speed, top, end, hi, window, rise=0.3) -> float | None:
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
    lo = max(0, int(np.floor(centre - half / 2)) - half // 2)
    hi = min(len(values), int(np.ceil(centre)) + half + 1)
    if hi - lo < 2 * half // 2 + 6:
        return None
    y = values[lo:hi].reshape(hi - lo, -1)         # the window only: reshaping all F copies
    if not np.isfinite(y).all():
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


def median_kink(raw: np.ndarray, point: int, coarse: float, half: int) -> float:
    """Median of the refined times (frames) from ``raw[point]`` (F, 3), its height, and both
    points together; ``raw`` is (2, F, 3) unfiltered heel and toe."""
    return float(np.median([_refined(signal, coarse, half) for signal in
                            (raw[point], raw[point, :, 2], raw.transpose(1, 0, 2))]))


def nearest_frame(time_s: float, rate: float, n_frames: int) -> int:
    """The frame (0-based) nearest ``time_s`` (s) at ``rate`` Hz, within ``n_frames``."""
    return int(np.clip(round(time_s * rate), 0, n_frames - 1))


def gait_event(side: str, kind: str, time_s: float, measured: np.ndarray, rate: float, *,
               spread_s: float = 0.0) -> GaitEvent:
    frame = nearest_frame(time_s, rate, len(measured))
    half = max(1, round(0.05 * rate))
    quality = float(measured[max(0, frame - half):frame + half + 1].mean())
    return GaitEvent(side, kind, float(time_s), frame, quality, spread_s=spread_s)


def unplaced_event(side: str, kind: str, window: tuple[float, float], rate: float, n_frames: int,
                   reason: str) -> GaitEvent:
    """An event the foot shows happened within ``window`` (frames: start, end) but that cannot
    be placed there with confidence, for ``reason``: at the window's middle, quality 0."""
    start, end = (float(np.clip(w, 0, n_frames - 1)) / rate for w in window)
    middle = 0.5 * (start + end)
    return GaitEvent(side, kind, middle, nearest_frame(middle, rate, n_frames),
                     0.0, window=(start, end), reason=reason)


#: Where the default toe-off's velocity-peak point lies between a foot's two markers: this
#: share of the way from the one that left the floor first to the one that left last.
TOE_OFF_WEIGHT = 0.6


#: Share of its push-off peak the foot's pitch rate has fallen to at the default toe-off's
#: end-of-roll mark (half: the peak's half-maximum on its falling side).
TOE_OFF_PITCH_FRACTION = 0.5
#: A default toe-off whose two marks lie farther apart (s) is :attr:`GaitEvent.uncertain`: one
#: of them has missed the release, and nothing tells which. The samples' lie at most 25 ms
#: apart (docs/guide/events-cycles.md).
MARKS_APART_S = 0.030


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
        the heel and the toe (not filled in, linearly or from a fitted model); 0 for an event
        not placed, 1 for one a force plate timed.
    window : (float, float) or None
        None for an event placed at ``time_s``. Else the event is known to have happened
        within these seconds (the foot left the floor, or came down, between them) but could
        not be placed with confidence, for ``reason``; ``time_s`` is the window's middle, so
        the cycle it bounds is still cut there, and carries the quality 0.
    reason : str
        Why an event was not placed ("" for a placed one).
    plate : int or None
        The force plate (1-based) whose loading or unloading timed the event
        (:mod:`mocaplib.gait.plate_events`; its ``quality`` is then 1), None for an event
        timed by the foot markers.
    spread_s : float
        For a default toe-off the foot markers placed, how far apart (s) the two marks it is
        the mean of lie (:func:`toe_off_marks`); over :data:`MARKS_APART_S` it is uncertain by
        half of it and says so (:attr:`warning`). 0 for the other events.
    plate_shift_s : float
        For a toe-off the foot markers placed in a capture whose force plates timed others:
        how far (s) it was moved, as the plates measured the markers' toe-offs
        (:mod:`mocaplib.gait.plate_events`, step 5); 0 for the other events.
    """

    side: str
    kind: str
    time_s: float
    frame: int
    quality: float
    window: tuple[float, float] | None = None
    reason: str = ""
    plate: int | None = None
    spread_s: float = 0.0
    plate_shift_s: float = 0.0

    @property
    def placed(self) -> bool:
        """Whether the detector placed the event (else only its ``window`` is known)."""
        return self.window is None

    @property
    def uncertain(self) -> bool:
        """Whether the event is placed but its two marks lie over :data:`MARKS_APART_S`
        apart."""
        return self.placed and self.spread_s > MARKS_APART_S

    @property
    def warning(self) -> str:
        """One sentence for the user about an event not placed or :attr:`uncertain` ("" for
        the others)."""
        if self.uncertain:
            return (f"{self.side} {self.kind.replace('_', '-')} at {self.time_s:.2f} s uncertain "
                    f"by ±{500 * self.spread_s:.0f} ms: its two marks (the push's "
                    f"upward-velocity peak, the end of the foot's roll) lie "
                    f"{1000 * self.spread_s:.0f} ms apart; placed midway")
        if self.placed:
            return ""
        return (f"{self.side} {self.kind.replace('_', '-')} not placed: it happened between "
                f"{self.window[0]:.2f} and {self.window[1]:.2f} s, but {self.reason}")


@dataclass(frozen=True)
class FootTrack:
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
