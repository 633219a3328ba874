"""Planted feet: every motion mocaplib writes from a library (``mocaplib query``, ``mocaplib
retarget``, the path follower) holds each foot on the floor through its stance.

**Feet.** Each foot is rigid: its ankle centre (the foot segment's origin) and the heel and toe
tip of :meth:`mocaplib.skeleton.Skeleton.sole`, on the sole. The floor is the plane z = 0 of the
world frame.

**Stance** (:func:`stance_frames`). A library entry stores its toe-offs (the left one at phase
0, ``right_toe_off_s``), not its foot strikes, and a blend stores neither; the stance of each
foot is read from the motion itself: the frames where the slower of its heel and toe moves
horizontally at most :data:`CONTACT_SPEED` and the lower of them is within :data:`CONTACT_RISE`
of the foot's standing level (the median height of that lower point over the frames where the
foot is still, below :data:`STILL_SPEED`), gaps of up to :data:`STANCE_GAP_S` bridged, in runs
of at least :data:`MIN_STANCE_S`. Two such runs are one stance where the foot stays as slow
between them, its lower point within :data:`ROLL_RISE` of the level, and one of its heel and toe
ends within :data:`ROLL_SHIFT` of where it was: a rigid sole pitched off the real foot's lifts
its lower point off the floor while rolling from heel to toe, and the toe alone holds the floor
after push-off (on the real entries without it, four stances split in two: a toe stance apart,
the foot sliding between them). A motion planted at less than :data:`STANCE_RATE` has its
stances read at that rate (:func:`plant_cycles`). A foot whose standing level is above
:data:`MAX_LEVEL` has no stance (on the shared files' ``running_c5`` the feet stay 142 mm or
more above the floor: it is not planted, its body not lowered). On the samples these stances end
-0.011 to 0.079 s after the entries' toe-offs (events from foot-marker kinematics), the latest
where a side-stepping or turning foot pivots on its toe (tests/test_planting.py).

**Planting** (:func:`plant_feet`):

1. The whole body is lowered by the height at which the feet stand (:func:`standing_level`):
   the median, over the stance runs, of the sole's mean height at the run's flattest frame (the
   fitted ankle centre sits higher above the floor than the skeleton's ``ankle_height``: 17-18
   mm on the samples; the real entries' feet stand from 9 mm below to 30 mm above the floor).
   The flat foot sets it, not the lowest sole point of every stance frame: the rigid toe tip
   dips into the floor at push-off where a real foot bends its toes.
2. Each stance run is locked at its flattest frame (the frame where the higher of heel and toe
   is lowest): the foot's heading there and the horizontal position of its heel (and of its toe,
   the sole's length ahead). Through the run the foot loses its roll and rolls on the floor:
   about the locked heel while its toes point up, about the locked toe while its heel is up (the
   two coincide when the foot is flat, so the pivot changes without a jump). It keeps its own
   pitch where that changes the knee's flexion by at most :data:`~.foot_targets.KNEE_GAP`, and
   beyond twice that takes the pitch that keeps the ankle as far from the hip as the motion's is
   (the leg's length: the knee keeps its flexion and the hip turns the leg). A foot that comes
   within :data:`~.foot_targets.FLAT_RISE` of lying flat in the run is laid flat where it lies
   flattest, its pitch there taken off the run's, less by a smoothstep towards the run's ends
   (a runner's foot that lands nearly flat stands flat once). Nor does it move
   the knee further in a frame than the motion's knee moves at most in that stance: outwards
   from the frame where the foot lies flattest (kept, so that the foot still lies flat), a
   pitch that would is replaced by one that moves the knee that far. A real foot rolls over the
   ball of the foot at push-off (half its length ahead of the ankle on the real entries, where
   the rigid toe tip is three quarters), so the rigid toe tip locked on the floor costs a
   steeper or flatter foot, not a raised ankle: near a straight knee, as in late stance, each
   millimetre the ankle rises bends the knee by degrees.
3. Outside stance the foot follows the motion; within :data:`~.foot_targets.BLEND_S` of a run
   the correction of the run's first (last) frame, a turn about the ankle and a shift, fades in
   (out) by a smoothstep (the foot stays rigid). A correction that changes the knee's flexion by
   more than that allows without moving the knee faster than the motion's fastest fades over
   more frames (as many as the neighbouring run leaves free), the smoothstep running through
   them in proportion to how much slower the motion's knee moves there than at its fastest, and
   over enough of them to spend :data:`~.foot_targets.FADE_MARGIN` times the change. The foot
   comes down to (rises from) the floor at :data:`~.foot_targets.APPROACH_SPEED` at least near
   it, and a swing foot stays :data:`~.foot_targets.SWING_CLEARANCE` above it (reached at that
   speed from the stance's edge); a swing foot whose toe (heel) would be lower turns about its
   ankle to lift it (the rigid toe that dips into the floor at push-off), no further than to
   lay its sole level, and rises as a whole by what is still missing.
4. Both legs (hip, knee, ankle DOFs) and the pelvis height are solved for the three foot points of
   each foot per frame, all frames at once, by damped Gauss-Newton steps
   (:data:`~.legs.IK_ITERATIONS` at most, until no pelvis height moves by
   :data:`~.legs.STEP_TOLERANCE`: only the heights are kept from this solve) that stay near the
   motion: every DOF is pulled to its own value with weight :data:`~.legs.PRIOR`, the pelvis
   height with :data:`~.legs.PELVIS_PRIOR` (it moves only where a leg cannot reach); the DOFs are
   kept within their joint limits and the knees at 0 or more (never hyperextended). Each step
   poses only the legs below the motion's pelvis (:class:`~mocaplib.library.legs.LegChains`: both
   legs, all frames at once) and solves each frame's normal equations with the pelvis height
   eliminated, the two legs' blocks apart. The pelvis height's correction is then smoothed
   (:data:`PELVIS_SMOOTHING_S`: no jolt) and the legs solved again under it (until no DOF moves by
   :data:`~.legs.STEP_TOLERANCE`), for the targets of the motion with that pelvis (a swing foot
   goes up and down with the body, and a stance foot's pitch keeps the knee for the hip where it
   is; the first targets where the correction is at most :data:`PELVIS_TARGETS_TOLERANCE`). The
   Levenberg damping (:data:`~.legs.DAMPING`) is small, so that the DOFs that move the feet
   least converge too: on the sample entries the first solve takes 4-12 steps (median 7), the
   second 2-4 (one entry 10). A periodic motion sampled at a whole number of frames a cycle is
   solved on one cycle (:func:`plant_feet`'s ``period``).

:func:`contact_measures` measures the result: slide, penetration, flat-foot hover and the
pelvis's vertical acceleration (:class:`ContactMeasures`). On the samples planted at 100 Hz
the knee's largest change in a frame is the motion's own, to the solve's tolerance
(tests/test_planting.py).

**On real entries** (tests/test_planting_real.py, the shared files' library, each entry on its
own skeleton): before planting the feet slide 20-30 mm, the rigid toe goes 33-67 mm below the
floor at push-off and the feet hover up to 47 mm; planted, all 14 meet every target: no foot
slides (0.00 mm, also over the stances found again on the planted motion), goes more than 0.01
mm below the floor or hovers more than 1.3 mm. Planting changes a knee by up to 25.9 deg and a
hip's flexion by up to 13.2 deg; the joint limits force up to 12.3 deg of it, planting chooses
up to 14.9 and 13.2 deg (target 5 deg, not met): 07_01_c0's left leg, whose knee the motion
hyperextends, the stance's target keeping the motion's leg length (the knee bent as far as the
motion hyperextends it: held straight, the foot ends 14 mm from its target); a left foot whose
fitted sole stands pitched 6.8 deg toes up, laid flat about its heel
(PiG_Motion-FlatFoot-Full_c1, 11.4 deg; HC030A22_c3's right foot likewise, 9.5 deg); BTS_c0's
left toe, 55 mm below the floor after toe-off, turned the :data:`~.foot_targets.MAX_TOE_TURN` it
may and raised (9.2 deg); HC030A05_c0's stance knee kept bent :data:`~.foot_targets.STANCE_KNEE`
where its ankle lies beyond the straight leg (7.4 deg). It lowers no body by more than its
feet's hover in stance (at most 30 mm). There the knee's largest change in a frame is up to 1.8
times the motion's own (BTS_c0).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d

from ..gait.fourier import RootDrift, fit_series, synthesize
from ..skeleton import ROOT_Z, Skeleton
from .foot_targets import BLEND_S, flattest, foot_axes, foot_targets, mask_runs
from .legs import LEG_DOFS, LEGS, SOLVED, LegChains, solve_feet

#: Stance: the slower sole point moves at most CONTACT_SPEED horizontally (m/s), the lower is
#: within CONTACT_RISE (m) of the foot's standing level, for at least MIN_STANCE_S (s); a foot
#: is still below STILL_SPEED (m/s). Gaps of at most STANCE_GAP_S (s) within a stance are
#: bridged (a foot rolling from heel to toe may move faster than CONTACT_SPEED for a frame).
CONTACT_SPEED, CONTACT_RISE, MIN_STANCE_S, STILL_SPEED, STANCE_GAP_S = 0.3, 0.008, 0.1, 0.1, 0.03
#: Contact runs of a foot that stays slow, its lower sole point within ROLL_RISE (m) of its
#: standing level, between them, and one of its sole points within ROLL_SHIFT (m) of where it
#: was, are one stance: a rigid sole pitched off the real foot's lifts its lower point off the
#: floor while it rolls from heel to toe (by up to 24 mm for a 20 cm sole pitched 7 deg, as
#: real entries' fitted soles stand) and as the toe alone holds the floor after push-off.
ROLL_RISE, ROLL_SHIFT = 0.025, 0.02
#: A foot whose standing level is higher than this above the floor (m) has no stance: it never
#: comes near the floor (a run in flight, a floor not at z = 0), and the body is not lowered.
MAX_LEVEL = 0.05
#: The pelvis height's correction (where a leg cannot reach) is spread over this (s): the
#: lowest correction within it, smoothed by a Gaussian of half its width. A correction of at
#: most PELVIS_TARGETS_TOLERANCE (m) everywhere keeps the targets of the motion before it (on
#: the samples its largest is 0.045 mm at the median entry; the planted series change by at
#: most 0.0024 rad for it, the feet's measures not at all: benchmarks/character.py).
PELVIS_SMOOTHING_S, PELVIS_TARGETS_TOLERANCE = 0.12, 1e-4
#: :func:`plant_cycles` reads the stances from the motion sampled at this rate (Hz) at least:
#: the contact rule's speeds and standing level need it (sampled at 30 Hz, a real entry's
#: landing was found 0.15 s late).
STANCE_RATE = 100.0
#: Harmonics and sampling rate (Hz) of :func:`planted_series`.
SERIES_ORDER, SERIES_RATE = 15, 30.0
#: A sole point within this (m) of the floor touches it (:func:`contact_measures`).
TOUCH = 0.001


@dataclass(frozen=True)
class ContactMeasures:
    """How a motion's feet meet the floor (:func:`contact_measures`), metres and m/s².

    ``slide_m``: the largest horizontal travel of a sole point (heel or toe) while it touches
    the floor (within :data:`TOUCH`) in one stance; ``penetration_m``: the deepest a sole point
    goes below the floor; ``hover_m``: the largest, over the stances seen whole (not cut by the
    motion's ends), of the lowest height the higher of heel and toe reaches (0 when the foot
    lies flat on the floor once in each stance);
    ``pelvis_acceleration_m_s2``: the largest vertical acceleration of the pelvis (second
    differences); ``stances``: the stance runs measured, both feet.
    """

    slide_m: float
    penetration_m: float
    hover_m: float
    pelvis_acceleration_m_s2: float
    stances: int

    def as_dict(self) -> dict:
        return {"slide_m": self.slide_m, "penetration_m": self.penetration_m,
                "hover_m": self.hover_m,
                "pelvis_acceleration_m_s2": self.pelvis_acceleration_m_s2,
                "stances": self.stances}


@dataclass(frozen=True)
class Planted:
    """A motion with its feet planted (:func:`plant_feet`): ``motion`` (P, D) the world poses
    at ``rate`` Hz before planting, ``planted`` (P, D) after, ``stances`` (P, 2) bool the frames
    where each foot (left, right) stands, and the frames [start, stop) ``window`` of them that
    count: :attr:`q`, :attr:`stance`, and the :class:`ContactMeasures` :attr:`before` and
    :attr:`after` (over the window, its stances whole; computed when first read).
    ``fine_stances``: where the stances were read at :data:`STANCE_RATE`, above ``rate``
    (:func:`plant_cycles`), the times (K,) s from the window's start and the stance (K, 2)
    bool at them; else None."""

    skeleton: Skeleton
    motion: np.ndarray
    planted: np.ndarray
    stances: np.ndarray
    rate: float
    window: tuple[int, int]
    fine_stances: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def q(self) -> np.ndarray:
        """The planted poses (F, D) of the window's frames."""
        return self.planted[slice(*self.window)]

    @property
    def stance(self) -> np.ndarray:
        """The stance frames (F, 2) bool of the window's frames."""
        return self.stances[slice(*self.window)]

    @cached_property
    def before(self) -> ContactMeasures:
        return contact_measures(self.skeleton, self.motion, self.rate, self.stances,
                                window=self.window)

    @cached_property
    def after(self) -> ContactMeasures:
        return contact_measures(self.skeleton, self.planted, self.rate, self.stances,
                                window=self.window)


def sole_points(skeleton: Skeleton, q: np.ndarray, /) -> np.ndarray:
    """Heel and toe of both feet in poses ``q`` (F, D): (F, 2, 2, 3) m (frames, left/right,
    heel/toe, xyz), posed down the legs alone (:class:`~mocaplib.library.legs.LegChains`)."""
    q = np.asarray(q, dtype=np.float64)
    return LegChains(skeleton, q).points(q[:, LEG_DOFS], q[:, ROOT_Z])[:, :, 1:]


def stance_frames(skeleton: Skeleton, q: np.ndarray, rate: float, /) -> np.ndarray:
    """The frames (F, 2) bool in which each foot (left, right) stands on the floor, in world
    poses ``q`` (F, D) at ``rate`` Hz (module docstring)."""
    return _stance(sole_points(skeleton, q), rate)


def _stance(sole: np.ndarray, rate: float) -> np.ndarray:
    """:func:`stance_frames` of the heel and toe points ``sole`` (F, 2, 2, 3) m of
    :func:`sole_points`."""
    low = sole[..., 2].min(axis=2)                                            # (F, 2)
    speed = np.linalg.norm(np.gradient(sole[..., :2], axis=0) * rate, axis=-1).min(axis=2)
    out = np.zeros(low.shape, dtype=bool)
    shortest = max(1, round(MIN_STANCE_S * rate))
    bridge = max(1, round(STANCE_GAP_S * rate))
    for side in (0, 1):
        still = speed[:, side] < STILL_SPEED
        if not still.any():
            continue
        level = np.median(low[still, side])
        if level > MAX_LEVEL:
            continue
        slow = speed[:, side] <= CONTACT_SPEED
        contact = slow & (low[:, side] <= level + CONTACT_RISE)
        near = slow & (low[:, side] <= level + ROLL_RISE)
        for mask in (contact, near):
            for start, stop in mask_runs(~mask):
                if 0 < start and stop < len(mask) and stop - start <= bridge:
                    mask[start:stop] = True
        for start, stop in mask_runs(near):
            runs: list[list[int]] = []
            for a, b in mask_runs(contact[start:stop]):
                a, b = start + a, start + b
                if runs and _stays(sole[[runs[-1][1] - 1, a], side]):
                    runs[-1][1] = b
                    continue
                runs.append([a, b])
            for a, b in runs:
                out[a:b, side] = b - a >= shortest
    return out


def _stays(ends: np.ndarray) -> bool:
    """Whether a foot whose heel and toe are at ``ends`` (2, 2, 3) m in two frames kept one of
    them within :data:`ROLL_SHIFT` of its place (horizontally)."""
    return bool(np.linalg.norm(ends[1, :, :2] - ends[0, :, :2], axis=-1).min() <= ROLL_SHIFT)


def standing_level(sole: np.ndarray, stance: np.ndarray, /) -> float:
    """The height (m) at which the feet stand: the median, over the stance runs of ``stance``
    (F, 2) bool, of the sole's mean height at the run's flattest frame (where the higher of
    heel and toe is lowest); ``sole`` (F, 2, 2, 3) m as :func:`sole_points` gives it."""
    heights = [sole[start:stop, side, :, 2] for side in (0, 1)
               for start, stop in mask_runs(stance[:, side])]
    return float(np.median([run[flattest(run)].mean() for run in heights]))


def plant_feet(skeleton: Skeleton, q: np.ndarray, rate: float, /, *,
               stance: np.ndarray | None = None, window: tuple[int, int] | None = None,
               period: int | None = None) -> Planted:
    """Plant the feet of world poses ``q`` (F, D) at ``rate`` Hz (module docstring).

    ``stance``: the frames (F, 2) bool of each foot's stance; default :func:`stance_frames`.
    ``window``: the frames [start, stop) that count (:class:`Planted`); default all.
    ``period``: frames after which ``q`` repeats itself moved on the floor (a periodic motion
    sampled at a whole number of frames a cycle, its path a line or an arc: the same in the
    path frame; the window as long as the motion's ends need to see each stance whole): each
    solve then poses the window's first period of frames only, the others repeat its
    solution (the pelvis height's correction spread around the cycle).
    Returns the :class:`Planted` motion.
    """
    q = np.array(q, dtype=np.float64)
    motion = q.copy()
    window = (0, len(q)) if window is None else window
    sole = sole_points(skeleton, q)
    stance = _stance(sole, rate) if stance is None else np.asarray(stance, bool)
    if stance.any():
        q[:, ROOT_Z] -= standing_level(sole, stance)
    solved = np.arange(len(q)) if period is None else window[0] + np.arange(period)
    cyclic = (np.arange(len(q)) - window[0]) % period if period else slice(None)
    targets = foot_targets(skeleton, q, stance, rate)[solved]
    reached = solve_feet(skeleton, q[solved], targets, SOLVED)
    drop = reached[:, ROOT_Z] - q[solved, ROOT_Z]
    spread, mode = max(1, round(PELVIS_SMOOTHING_S * rate)), "nearest" if period is None \
        else "wrap"
    lowered = gaussian_filter1d(minimum_filter1d(drop, 2 * spread + 1, mode=mode), spread / 2,
                                mode=mode)
    q[:, ROOT_Z] += lowered[cyclic]
    if np.abs(lowered).max() > PELVIS_TARGETS_TOLERANCE:
        targets = foot_targets(skeleton, q, stance, rate)[solved]
    out = q.copy()
    out[:, list(SOLVED)] = solve_feet(skeleton, q[solved], targets, LEGS,
                                      initial=reached)[cyclic][:, list(SOLVED)]
    return Planted(skeleton, motion, out, stance, rate, window)


def plant_cycles(skeleton: Skeleton, angles: Callable[[np.ndarray], np.ndarray],
                 drift: RootDrift, period: float, rate: float, frames: int, /) -> Planted:
    """:func:`plant_feet` on ``frames`` frames at ``rate`` Hz from t = 0 of a periodic motion:
    ``angles(t)`` (F, D), the joint coordinates at times ``t`` (F,) s in the path frame that
    ``drift`` moves along, periodic in ``period`` s. The motion is planted with one period more
    on each side, so that a stance across the clip's ends is locked as a whole and a clip of
    whole cycles loops; a clip of whole cycles of a whole number of frames each is solved on
    one cycle (``plant_feet``'s ``period``). Below :data:`STANCE_RATE` the stances are read
    from the motion sampled at that rate."""
    q, window = _padded(angles, drift, period, rate, frames)
    steps = round(period * rate)
    whole = abs(period * rate - steps) < 1e-9 * steps and frames % steps == 0
    if rate >= STANCE_RATE:
        return plant_feet(skeleton, q, rate, window=window, period=steps if whole else None)
    stance, fine = _fine_stance(skeleton, angles, drift, period,
                                (np.arange(len(q)) - window[0]) / rate)
    planted = plant_feet(skeleton, q, rate, stance=stance, window=window,
                         period=steps if whole else None)
    return replace(planted, fine_stances=fine)


def _fine_stance(skeleton: Skeleton, angles: Callable[[np.ndarray], np.ndarray],
                 drift: RootDrift, period: float, times: np.ndarray
                 ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """:func:`stance_frames` (F, 2) bool at ``times`` (F,) s of the periodic motion of
    :func:`plant_cycles`, read at :data:`STANCE_RATE` or a little more (a whole number of
    samples a cycle: the soles posed over one cycle in the path frame, then moved along
    ``drift``), each time taking its nearest sample's; and the samples' own times (K,) s and
    stance (K, 2) bool (:attr:`Planted.fine_stances`)."""
    count = int(np.ceil(period * STANCE_RATE))
    rate = count / period
    first = int(np.floor(times[0] * rate))
    k = np.arange(first, int(np.ceil(times[-1] * rate)) + 1)
    local = sole_points(skeleton, angles(np.arange(count) / rate))[k % count]  # (K, 2, 2, 3)
    x, y, psi = drift.frame(k / rate)
    c, s = np.cos(psi)[:, None, None], np.sin(psi)[:, None, None]
    world = local.copy()
    world[..., 0] = x[:, None, None] + c * local[..., 0] - s * local[..., 1]
    world[..., 1] = y[:, None, None] + s * local[..., 0] + c * local[..., 1]
    fine = _stance(world, rate)
    return fine[np.round(times * rate).astype(int) - first], (k / rate, fine)


@dataclass(frozen=True)
class PlantedSeries:
    """A cycle with its feet planted, for animations that pose the skeleton from a series
    (:func:`planted_series`): Fourier ``a``, ``b`` (D, N+1) in the path frame, and ``locks``
    (L, 6), each stance of the planted cycle within :data:`~.foot_targets.BLEND_S` of [0, T):
    the foot (0 left, 1 right), the times (s from the cycle's start) of its first and last
    stance samples, its heel's x and y (m) and its heading (rad) where it lies flattest, in the
    path frame at t = 0."""

    a: np.ndarray
    b: np.ndarray
    locks: np.ndarray


def planted_series(skeleton: Skeleton, a: np.ndarray, b: np.ndarray, period: float,
                   drift: RootDrift, /, *, order: int = SERIES_ORDER,
                   rate: float = SERIES_RATE) -> PlantedSeries:
    """A cycle's Fourier coefficients ``a``, ``b`` (D, N+1) (path frame, period ``period`` s,
    moving along ``drift``) with its feet planted on ``skeleton``: the cycle sampled at about
    ``rate`` Hz, planted (:func:`plant_cycles`) and the DOFs planting solves (:data:`SOLVED`)
    fitted again with ``order`` harmonics; (D, max(N, order)+1) each, the other DOFs' rows
    ``a``'s and ``b``'s own padded with zeros; and the stances' locks (:class:`PlantedSeries`).
    The series alone rounds the stance off: on the sample entries at the defaults its feet
    slide up to 3.8 mm and go up to 2.0 mm below the floor (docs/results/character.md; the
    sampling rate sets it more than the harmonics: 100 Hz with 40 harmonics slides 1.7 mm at
    1.85 times the cost). The report's viewer poses each frame from the series and then moves
    each leg to its foot's lock (templates/motion.js, ``plantedPose``): nothing slides."""
    steps = max(round(period * rate), 2 * order + 1)
    planted = plant_cycles(skeleton, lambda t: synthesize(a, b, period, t), drift, period,
                           steps / period, steps)
    t = np.arange(steps) * period / steps
    series = fit_series(drift.remove(planted.q, t), t, period, order)
    width = max(a.shape[1], order + 1)
    out_a, out_b = np.zeros((len(a), width)), np.zeros((len(a), width))
    out_a[:, :a.shape[1]], out_b[:, :b.shape[1]] = a, b
    rows = list(SOLVED)
    out_a[rows], out_b[rows] = 0.0, 0.0
    out_a[rows, :order + 1], out_b[rows, :order + 1] = series.a[rows], series.b[rows]
    return PlantedSeries(out_a, out_b, _locks(planted, period / steps))


def _locks(planted: Planted, step: float) -> np.ndarray:
    """The :class:`PlantedSeries` locks (L, 6) of ``planted``, a cycle planted with one period
    more on each side, sampled every ``step`` s from its window's start."""
    start, stop = planted.window
    runs = [(side, first, last) for side in (0, 1)
            for first, last in mask_runs(planted.stances[:, side])
            if (last - 1 - start) * step >= -BLEND_S
            and (first - start) * step <= (stop - start) * step + BLEND_S]
    if not runs:
        return np.zeros((0, 6))
    rows = np.unique(np.concatenate([np.arange(first, last) for _, first, last in runs]))
    q = planted.planted[rows]
    points, orientation, _ = LegChains(planted.skeleton, q).frames(q[:, LEG_DOFS], q[:, ROOT_Z])
    _, heading = foot_axes(orientation)
    locks = []
    for side, first, last in runs:
        at = np.searchsorted(rows, np.arange(first, last))
        flat = at[flattest(points[at, side, 1:, 2])]
        end = (last - 1 - start) * step
        begin = _stance_start(planted, side, (first - start) * step, end)
        locks.append([side, begin, end, *points[flat, side, 1, :2], heading[flat, side]])
    return np.array(locks, dtype=np.float64).reshape(-1, 6)


def _stance_start(planted: Planted, side: int, begin: float, end: float) -> float:
    """When (s from the window's start) the stance of the foot ``side`` whose frames run from
    ``begin`` to ``end`` (s) starts: at the first sample of the stance read at
    :data:`STANCE_RATE` that holds them (:attr:`Planted.fine_stances`; a frame takes its
    nearest fine sample's stance, so the frames' run may start up to a frame after the foot
    comes down, the foot then posed from the series alone, above the floor), else ``begin``.
    Its end stays the last frame's: the frames after it are not planted, and a lock held
    past them holds the heel where the foot rolls over its toe."""
    if planted.fine_stances is None:
        return begin
    times, stance = planted.fine_stances
    for lo, hi in mask_runs(stance[:, side]):
        if times[lo] <= end and times[hi - 1] >= begin:
            return min(begin, float(times[lo]))
    return begin


def cycle_contact(skeleton: Skeleton, angles: Callable[[np.ndarray], np.ndarray],
                  drift: RootDrift, period: float, rate: float, frames: int, /
                  ) -> ContactMeasures:
    """The :class:`ContactMeasures` of the periodic motion :func:`plant_cycles` takes, as it
    is (its stances whole, from one period more on each side)."""
    q, window = _padded(angles, drift, period, rate, frames)
    return contact_measures(skeleton, q, rate, stance_frames(skeleton, q, rate), window=window)


def _padded(angles, drift: RootDrift, period: float, rate: float, frames: int
            ) -> tuple[np.ndarray, tuple[int, int]]:
    """World poses (P + frames + P, D) of the periodic motion of :func:`plant_cycles` from
    t = -P / rate on, P the frames of one period, and the window [P, P + frames)."""
    pad = int(np.ceil(period * rate))
    t = np.arange(-pad, frames + pad) / rate
    return drift.restore(angles(t), t), (pad, pad + frames)


def plant_blend(blend, skeleton: Skeleton, /, i: int = 0, *, rate: float, cycles: int
                ) -> Planted:
    """Blend ``i`` of a :class:`~mocaplib.library.controlspace.Blend` as
    :meth:`~mocaplib.library.controlspace.Blend.world` samples it (``cycles`` cycles at
    ``rate`` Hz from t = 0) on ``skeleton``, its feet planted (:func:`plant_cycles`)."""
    period = float(blend.T[i])
    drift = RootDrift(0.0, 0.0, 0.0, *(0.0, 0.0, 0.0) if blend.drift is None
                      else (float(v) for v in blend.drift[i]))
    frames = blend.frames(i, rate=rate, cycles=cycles)
    return plant_cycles(skeleton, lambda t: synthesize(blend.a[i], blend.b[i], period, t),
                        drift, period, rate, frames)


def contact_measures(skeleton: Skeleton, q: np.ndarray, rate: float, stance: np.ndarray, /, *,
                     window: tuple[int, int] | None = None) -> ContactMeasures:
    """The :class:`ContactMeasures` of world poses ``q`` (F, D) at ``rate`` Hz, the stances
    ``stance`` (F, 2) bool, over the frames [start, stop) of ``window`` (default all): the
    stances that overlap it, whole, and its frames' penetration and acceleration."""
    first, last = (0, len(q)) if window is None else window
    sole = sole_points(skeleton, q)
    slide, hover, count = 0.0, 0.0, 0
    for side in (0, 1):
        for start, stop in mask_runs(stance[:, side]):
            if stop <= first or start >= last:
                continue
            count += 1
            run = sole[start:stop, side]                                   # (n, 2, 3)
            if 0 < start and stop < len(q):                  # seen whole
                hover = max(hover, float(run[..., 2].max(axis=1).min()))
            for point in (0, 1):
                touching = run[run[:, point, 2] <= TOUCH, point, :2]
                if len(touching):
                    slide = max(slide, float(np.linalg.norm(
                        touching - touching[0], axis=1).max()))
    z = q[max(first - 1, 0):last + 1, ROOT_Z]
    acceleration = np.abs(np.diff(z, 2)) * rate ** 2 if len(z) > 2 else np.zeros(1)
    return ContactMeasures(slide, float(max(0.0, -sole[first:last, ..., 2].min())), hover,
                           float(acceleration.max()), count)
