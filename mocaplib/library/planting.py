"""Planted feet: every motion mocaplib writes from a library (``mocaplib query``, ``mocaplib
retarget``, the path follower) holds each foot on the floor through its stance.

**Feet.** Each foot is rigid: its ankle centre (the foot segment's origin) and the heel and toe
tip of :meth:`mocaplib.skeleton.Skeleton.sole`, on the sole. The floor is the plane z = 0 of the
world frame.

**Stance** (:func:`stance_frames`). A library entry stores its toe-offs (the left one at phase
0, ``right_toe_off_s``), not its foot strikes, and a blend stores neither; the stance of each
foot is read from the motion itself: the frames where the slower of its heel and toe moves
horizontally at most :data:`CONTACT_SPEED` and the lower of them is within
:data:`CONTACT_RISE` of the foot's standing level (the median height of that lower point over
the frames where the foot is still, below :data:`STILL_SPEED`), gaps of up to
:data:`STANCE_GAP_S` bridged, in runs of at least :data:`MIN_STANCE_S`. A foot whose standing
level is above :data:`MAX_LEVEL` has no stance (on the shared files' ``running_c5`` the feet
stay 142 mm or more above the floor: it is not planted, its body not lowered). On the samples these stances end -0.011 to 0.079 s after the entries' toe-offs (events
from foot-marker kinematics), the latest where a side-stepping or turning foot pivots on its
toe (tests/test_planting.py).

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
   pitch where that changes the knee's flexion by at most :data:`KNEE_GAP`, and beyond twice
   that takes the pitch that keeps the ankle as far from the hip as the motion's is (the leg's
   length: the knee keeps its flexion and the hip turns the leg). A real foot rolls over the
   ball of the foot at push-off (half its length ahead of the ankle on the real entries, where
   the rigid toe tip is three quarters), so the rigid toe tip locked on the floor costs a
   steeper or flatter foot, not a raised ankle: near a straight knee, as in late stance, each
   millimetre the ankle rises bends the knee by degrees.
3. Outside stance the foot follows the motion; within :data:`BLEND_S` of a run the correction of
   the run's first (last) frame, a turn about the ankle and a shift, fades in (out) by a
   smoothstep (the foot stays rigid), the foot coming down to (rising from) the floor at
   :data:`APPROACH_SPEED` at least near it; a swing foot whose toe (heel) would be lower turns
   about its ankle to lift it (the rigid toe that dips into the floor at push-off), no further
   than to lay its sole level, and rises as a whole by what is still missing.
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
   is; the first targets where the correction is at most :data:`PELVIS_TARGETS_TOLERANCE`). The Levenberg damping (:data:`~.legs.DAMPING`) is small, so that the DOFs that move the
   feet least converge too: on the sample entries the first solve takes 4-12 steps (median 7), the
   second 2-4 (one entry 10). A periodic motion sampled at a whole number of frames a cycle is
   solved on one cycle (:func:`plant_feet`'s ``period``).

:func:`contact_measures` measures the result: slide, penetration, flat-foot hover and the
pelvis's vertical acceleration (:class:`ContactMeasures`).

**On real entries** (tests/test_planting_real.py, the shared files' library, each entry on its
own skeleton): before planting the feet slide 20-30 mm, the rigid toe goes 33-67 mm below the
floor at push-off and the feet hover up to 47 mm. Planting changes a knee by up to 13.4 deg and
a hip's flexion by up to 7.0 deg; the joint limits force up to 12.3 deg of it (07_01_c0's
hyperextended knee held at 0), planting chooses up to 13.4 and 7.0 deg (target 5 deg, not met):
HC030A22_c3's right leg in the swing between a stance and a short stance on its toe (the heel
20 mm up), found apart and locked at its own first frame; two left feet whose fitted soles
stand pitched 4.2 and 6.8 deg toes up, the heel 14-18 mm below the floor, laid flat about their
heel (07_01_c0 12.3, PiG_Motion-FlatFoot-Full_c1 11.4 deg in stance); BTS_c0's left toe, 55 mm
below the floor after toe-off, turned the :data:`MAX_TOE_TURN` it may and raised (9.3 deg);
HC030A05_c0's right foot, pitched 2.5 deg toes up, laid flat (8.6 deg). It lowers no body by
more than its feet's hover in stance (at most 30 mm).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d
from scipy.spatial.transform import Rotation

from ..gait.fourier import RootDrift, fit_series, synthesize
from ..skeleton import ROOT_Z, Skeleton
from .legs import KNEES, LEG_DOFS, LEGS, SOLVED, LegChains, level_frames, solve_feet

#: Stance: the slower sole point moves at most CONTACT_SPEED horizontally (m/s), the lower is
#: within CONTACT_RISE (m) of the foot's standing level, for at least MIN_STANCE_S (s); a foot
#: is still below STILL_SPEED (m/s). Gaps of at most STANCE_GAP_S (s) within a stance are
#: bridged (a foot rolling from heel to toe may move faster than CONTACT_SPEED for a frame).
CONTACT_SPEED, CONTACT_RISE, MIN_STANCE_S, STILL_SPEED, STANCE_GAP_S = 0.3, 0.008, 0.1, 0.1, 0.03
#: A foot whose standing level is higher than this above the floor (m) has no stance: it never
#: comes near the floor (a run in flight, a floor not at z = 0), and the body is not lowered.
MAX_LEVEL = 0.05
#: Time (s) over which a run's correction fades in before it and out after it; within it a foot
#: stays above the floor by APPROACH_SPEED (m/s) times the time to the stance (times the share
#: of the window still ahead: nothing at its far end).
BLEND_S, APPROACH_SPEED = 0.1, 0.2
#: A stance foot keeps its own pitch where that changes its knee's flexion by at most KNEE_GAP
#: (rad), and beyond twice that takes the pitch that keeps the knee's flexion (within the 5 deg
#: a knee may change: a foot tilted to save less hovers, on the samples' runs by 3.9 mm at 1 deg).
KNEE_GAP = np.deg2rad(4.0)
#: The largest turn (rad) about the ankle that lifts a swing foot's toe or heel off the floor.
MAX_TOE_TURN = np.deg2rad(30.0)
#: The pelvis height's correction (where a leg cannot reach) is spread over this (s): the
#: lowest correction within it, smoothed by a Gaussian of half its width. A correction of at
#: most PELVIS_TARGETS_TOLERANCE (m) everywhere keeps the targets of the motion before it (on
#: the samples its largest is 0.045 mm at the median entry; the planted series change by at
#: most 0.0024 rad for it, the feet's measures not at all: benchmarks/character.py).
PELVIS_SMOOTHING_S, PELVIS_TARGETS_TOLERANCE = 0.12, 1e-4
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
    :attr:`after` (over the window, its stances whole; computed when first read)."""

    skeleton: Skeleton
    motion: np.ndarray
    planted: np.ndarray
    stances: np.ndarray
    rate: float
    window: tuple[int, int]

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
        contact = (speed[:, side] <= CONTACT_SPEED) & (low[:, side] <= level + CONTACT_RISE)
        for start, stop in _runs(~contact):
            if 0 < start and stop < len(contact) and stop - start <= bridge:
                contact[start:stop] = True
        for start, stop in _runs(contact):
            out[start:stop, side] = stop - start >= shortest
    return out


def standing_level(sole: np.ndarray, stance: np.ndarray, /) -> float:
    """The height (m) at which the feet stand: the median, over the stance runs of ``stance``
    (F, 2) bool, of the sole's mean height at the run's flattest frame (where the higher of
    heel and toe is lowest); ``sole`` (F, 2, 2, 3) m as :func:`sole_points` gives it."""
    heights = [sole[start:stop, side, :, 2] for side in (0, 1)
               for start, stop in _runs(stance[:, side])]
    return float(np.median([run[np.argmin(run.max(axis=1))].mean() for run in heights]))


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
    targets = _targets(skeleton, q, stance, rate)[solved]
    reached = solve_feet(skeleton, q[solved], targets, SOLVED)
    drop = reached[:, ROOT_Z] - q[solved, ROOT_Z]
    spread, mode = max(1, round(PELVIS_SMOOTHING_S * rate)), "nearest" if period is None \
        else "wrap"
    lowered = gaussian_filter1d(minimum_filter1d(drop, 2 * spread + 1, mode=mode), spread / 2,
                                mode=mode)
    q[:, ROOT_Z] += lowered[cyclic]
    if np.abs(lowered).max() > PELVIS_TARGETS_TOLERANCE:
        targets = _targets(skeleton, q, stance, rate)[solved]
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
    one cycle (``plant_feet``'s ``period``)."""
    q, window = _padded(angles, drift, period, rate, frames)
    steps = round(period * rate)
    whole = abs(period * rate - steps) < 1e-9 * steps and frames % steps == 0
    return plant_feet(skeleton, q, rate, window=window, period=steps if whole else None)


def planted_series(skeleton: Skeleton, a: np.ndarray, b: np.ndarray, period: float,
                   drift: RootDrift, /, *, order: int = SERIES_ORDER,
                   rate: float = SERIES_RATE) -> tuple[np.ndarray, np.ndarray]:
    """A cycle's Fourier coefficients ``a``, ``b`` (D, N+1) (path frame, period ``period`` s,
    moving along ``drift``) with its feet planted on ``skeleton``: the cycle sampled at about
    ``rate`` Hz, planted (:func:`plant_cycles`) and the DOFs planting solves (:data:`SOLVED`)
    fitted again with ``order`` harmonics; (D, max(N, order)+1) each, the other DOFs' rows
    ``a``'s and ``b``'s own padded with zeros. For animations that pose the skeleton from a
    series (the report's viewer); on the sample entries at the defaults the refitted feet slide
    up to 3.7 mm, go up to 2.0 mm below the floor and hover up to 3.2 mm
    (docs/results/character.md). The sampling rate sets it more than the harmonics: on the
    synthetic walks the planted 30 Hz frames joined by lines slide 2.6 mm, by a periodic cubic
    3.3 mm (the series 3.3 mm); 100 Hz with 30 harmonics slides 2.0 mm."""
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
    return out_a, out_b


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
        for start, stop in _runs(stance[:, side]):
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


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The [start, stop) frame ranges where ``mask`` (F,) bool is True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def _foot_axes(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pitch (toes up > 0) and heading (rad) of feet with orientations ``R`` (..., 3, 3)."""
    x = R[..., :, 0]
    return np.arctan2(x[..., 2], np.hypot(x[..., 0], x[..., 1])), np.arctan2(x[..., 1], x[..., 0])


def _targets(skeleton: Skeleton, q: np.ndarray, stance: np.ndarray, rate: float) -> np.ndarray:
    """Where the ankle, heel and toe of each foot go: (F, 2, 3, 3) m (module docstring, 2-3)."""
    points, orientation, hips = LegChains(skeleton, q).frames(q[:, LEG_DOFS], q[:, ROOT_Z])
    local = np.vstack([np.zeros(3), skeleton.sole()])                     # ankle, heel, toe
    targets = points.copy()
    runs = [(side, start, stop) for side in (0, 1) for start, stop in _runs(stance[:, side])]
    if not runs:
        return targets
    pitch, heading = _foot_axes(orientation)
    length = local[2, 0] - local[1, 0]
    frame, side, heel, psi = [], [], [], []
    for s, start, stop in runs:                # each run locked at its flattest frame
        flat = start + int(np.argmin(points[start:stop, s, 1:, 2].max(axis=1)))
        frame.append(np.arange(start, stop))
        side.append(np.full(stop - start, s))
        heel.append(np.tile([*points[flat, s, 1, :2], 0.0], (stop - start, 1)))
        psi.append(np.full(stop - start, heading[flat, s]))
    frame, side, heel, psi = (np.concatenate(x) for x in (frame, side, heel, psi))
    forward = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=-1)
    toe = heel + length * forward
    theta = _stance_pitch(points[frame, side, 0], hips[frame, side], q[frame, np.array(KNEES)[side]],
                          pitch[frame, side], heel, toe, forward, local,
                          (skeleton.lengths["thigh"], skeleton.lengths["shank"]))
    placed = np.einsum("nij,pj->npi", level_frames(theta, psi), local)
    pivot = np.where((theta >= 0)[:, None], heel - placed[:, 1], toe - placed[:, 2])
    targets[frame, side] = placed + pivot[:, None]
    clearance = _fade(targets, points, runs, max(1, round(BLEND_S * rate)), rate)
    swing = ~stance
    targets[swing] = _cleared(targets[swing], clearance[swing])
    return targets


def _stance_pitch(ankle: np.ndarray, hip: np.ndarray, flexion: np.ndarray, pitch: np.ndarray,
                  heel: np.ndarray, toe: np.ndarray, forward: np.ndarray, local: np.ndarray,
                  leg: tuple[float, float]) -> np.ndarray:
    """The pitch (n,) rad of a foot rolling on the floor about its locked ``heel`` (n, 3) m (toes
    up, pitch >= 0) or ``toe`` (n, 3) m (heel up, pitch < 0), its heading the horizontal unit
    vector ``forward`` (n, 3): the motion's ``pitch``
    (n,) rad where that changes the knee's flexion by at most :data:`KNEE_GAP`, beyond twice
    that the pitch that keeps the ankle as far from the ``hip`` (n, 3) m as the motion's
    ``ankle`` (n, 3) m is (the knee's flexion kept; the solution nearest the motion's pitch,
    or the one that comes nearest where none keeps it), a linear blend between. The knee's
    ``flexion`` (n,) rad in the motion; ``local``: ankle, heel, toe in the foot frame (3, 3) m;
    ``leg``: thigh and shank lengths, m (the knee's flexion follows the law of cosines, its
    constant term fitted to the motion's flexion, which takes the joints' shifts in)."""
    wanted = np.sum((ankle - hip) ** 2, axis=1)                 # the leg's length², m²
    pivots = {1.0: (heel, local[1]), -1.0: (toe, local[2])}

    def reach(sign: float) -> tuple[float, float, np.ndarray, np.ndarray]:
        """Rest angle and arm of the ankle about the pivot, and the pivot's offset from the hip
        along and above the foot's heading, |pivot - hip|² (n,): |ankle - hip|² = offset² +
        arm² + 2 arm |offset| cos(rest + pitch - direction)."""
        pivot, point = pivots[sign]
        d = pivot - hip
        return (np.arctan2(-point[2], -point[0]), np.hypot(point[0], point[2]),
                np.stack([np.sum(d * forward, axis=1), d[:, 2]], axis=-1), np.sum(d * d, axis=1))

    twice = 2 * leg[0] * leg[1]
    constant = wanted - twice * np.cos(flexion)

    def knee(length2: np.ndarray) -> np.ndarray:
        """Knee flexion (rad, 0 or more) of a leg whose ankle is length2 (m²) from its hip."""
        return np.arccos(np.clip((length2 - constant) / twice, -1.0, 1.0))

    def length2(theta: np.ndarray) -> np.ndarray:
        """|ankle - hip|² (n,) m² at pitch ``theta`` (n,) rad, about the pivot its sign picks."""
        about = {}
        for sign in (1.0, -1.0):
            rest, arm, offset, square = reach(sign)
            about[sign] = square + arm ** 2 + 2 * arm * (offset[:, 0] * np.cos(rest + theta)
                                                         + offset[:, 1] * np.sin(rest + theta))
        return np.where(theta >= 0, about[1.0], about[-1.0])

    best, miss = np.zeros(len(pitch)), np.full(len(pitch), np.inf)
    for sign in (1.0, -1.0):
        rest, arm, offset, square = reach(sign)
        span = np.maximum(2 * arm * np.hypot(*offset.T), 1e-12)
        cosine = np.clip((wanted - square - arm ** 2) / span, -1.0, 1.0)
        direction = np.arctan2(offset[:, 1], offset[:, 0])
        for root in (np.arccos(cosine), -np.arccos(cosine)):
            theta = np.angle(np.exp(1j * (direction + root - rest)))
            theta = sign * np.maximum(sign * theta, 0.0)
            away = np.abs(theta - pitch)
            better = away < miss
            best[better], miss[better] = theta[better], away[better]
    change = np.abs(knee(length2(pitch)) - np.abs(flexion))
    share = np.clip(change / KNEE_GAP - 1.0, 0.0, 1.0)
    return pitch + share * (best - pitch)


def _fade(targets: np.ndarray, points: np.ndarray, runs: list[tuple[int, int, int]], fade: int,
          rate: float) -> np.ndarray:
    """Fade each stance run's correction in before it and out after it: up to ``fade`` - 1
    frames of its foot beyond each of its edges, as far as the foot's neighbouring run and that
    run's own fade (taken first: runs in order, each fading in, then out) leave free, take the
    rigid correction that moves the motion's foot to its target at the edge (a turn about the
    ankle, then a shift), weighted by a smoothstep from 1 at the edge to 0. ``targets`` (set
    in place), ``points``: (F, 2, 3, 3) m, ankle, heel, toe; ``runs``: (side, start, stop)
    each, by foot and in order. Returns how high (F, 2) m the lower sole point must stay in the
    frames faded (module docstring, 3)."""
    side, start, stop = np.asarray(runs, dtype=int).reshape(-1, 3).T
    longest = fade - 1
    after_own = np.r_[side[1:] == side[:-1], False]          # the foot's next run follows
    before_own = np.r_[False, after_own[:-1]]
    fading_out = np.minimum(longest, np.where(after_own, np.r_[start[1:], 0] - stop,
                                              len(targets) - stop))
    free_before = np.where(before_own, start - np.r_[0, stop[:-1]] - np.r_[0, fading_out[:-1]],
                           start)
    edge = np.r_[start, stop - 1]
    direction, count = np.r_[-np.ones_like(start), np.ones_like(stop)], \
        np.r_[np.minimum(longest, free_before), fading_out]
    edge_side = np.r_[side, side]
    turn = _aligning_turns(targets[edge, edge_side] - targets[edge, edge_side, :1],
                           points[edge, edge_side] - points[edge, edge_side, :1])
    shift = targets[edge, edge_side, 0] - points[edge, edge_side, 0]
    which = np.repeat(np.arange(len(edge)), count)
    k = np.arange(len(which)) - np.repeat(np.cumsum(count) - count, count) + 1
    frame, foot = edge[which] + direction[which] * k, edge_side[which]
    s = 1.0 - k / fade
    s = s * s * (3 - 2 * s)
    ankle = points[frame, foot, :1]
    angle = np.linalg.norm(turn[which], axis=1)
    axis = turn[which] / np.maximum(angle, 1e-300)[:, None]
    targets[frame, foot] = (ankle + s[:, None, None] * shift[which, None]
                            + _turned(points[frame, foot] - ankle, axis, s * angle))
    clearance = np.zeros(targets.shape[:2])
    clearance[frame, foot] = APPROACH_SPEED * k / rate * (1 - k / fade)
    return clearance


def _aligning_turns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vectors (n, 3) rad of the rotations R that take the points ``b`` (n, P, 3) nearest
    to ``a`` (n, P, 3) (least squares, Kabsch: Σ |a - R b|² least, det R = 1)."""
    u, _, vt = np.linalg.svd(np.einsum("npi,npj->nij", b, a))
    d = np.sign(np.linalg.det(vt.transpose(0, 2, 1) @ u.transpose(0, 2, 1)))
    vt[:, 2] *= d[:, None]
    return Rotation.from_matrix(vt.transpose(0, 2, 1) @ u.transpose(0, 2, 1)).as_rotvec()



def _cleared(feet: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Feet (n, 3, 3) (ankle, heel, toe) with heel and toe at least ``height`` (n,) m above the
    floor: a foot with only its toe (heel) too low turns about its ankle, in its vertical plane,
    by the least angle that lifts it, up to :data:`MAX_TOE_TURN` and, turning towards level, no
    further than to lay its sole level (beyond, the other end would go down faster than this one
    rises), then the whole foot rises by what is still missing."""
    feet = feet.copy()
    ankle, heel, toe = feet[:, 0], feet[:, 1], feet[:, 2]
    axis = np.cross(toe - heel, [0.0, 0.0, 1.0])                    # a turn by φ > 0: toes up
    axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
    level = -np.arctan2(toe[:, 2] - heel[:, 2], np.linalg.norm((toe - heel)[:, :2], axis=1))
    for point, other in ((2, 1), (1, 2)):
        low = (feet[:, point, 2] < height) & (feet[:, other, 2] >= height)
        if not low.any():
            continue
        r = feet[low, point] - ankle[low]
        across = np.cross(axis[low], r)[:, 2]                 # z of u × r: z(φ) = r_z cos φ + c sin φ
        reach = np.hypot(r[:, 2], across)
        delta = np.arctan2(across, r[:, 2])
        cosine = np.clip((height[low] - ankle[low, 2]) / np.maximum(reach, 1e-12), -1.0, 1.0)
        turns = np.stack([delta - np.arccos(cosine), delta + np.arccos(cosine)])
        turns = np.angle(np.exp(1j * turns))
        phi = np.clip(np.take_along_axis(turns, np.argmin(np.abs(turns), axis=0)[None], 0)[0],
                      -MAX_TOE_TURN, MAX_TOE_TURN)
        past = phi * level[low] > level[low] ** 2                # turned beyond level
        phi[past] = level[low][past]
        feet[low] = ankle[low, None] + _turned(feet[low] - ankle[low, None], axis[low], phi)
    short = np.maximum(0.0, height - feet[:, 1:, 2].min(axis=1))
    feet[..., 2] += short[:, None]
    return feet


def _turned(vectors: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``vectors`` (n, k, 3) turned about unit ``axis`` (n, 3) by ``angle`` (n,) rad
    (Rodrigues)."""
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    u = axis[:, None, :]
    return (vectors * c + np.cross(u, vectors) * s
            + u * np.sum(u * vectors, axis=-1, keepdims=True) * (1 - c))
