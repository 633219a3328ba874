"""Where planted feet go (:func:`foot_targets`, :mod:`mocaplib.library.planting` steps 2-3): each
stance run's foot locked on the floor and rolling on it, no faster for the knee than the motion;
each run's correction faded in before it and out after it; a swing foot kept off the floor. Feet
are their ankle, heel and toe points in the world, m, both feet of every frame at once; the
floor is the plane z = 0."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial.transform import Rotation

from ..skeleton import ROOT_Z, Skeleton
from .legs import KNEES, LEG_DOFS, LegChains, level_frames

#: Time (s) over which a run's correction fades in before it and out after it; within it a foot
#: stays above the floor by APPROACH_SPEED (m/s) times the time to the stance (times the share
#: of the window still ahead: nothing at its far end).
BLEND_S, APPROACH_SPEED = 0.1, 0.2
#: A stance foot keeps its own pitch where that changes its knee's flexion by at most KNEE_GAP
#: (rad), and beyond twice that takes the pitch that keeps the knee's flexion (within the 5 deg
#: a knee may change: a foot tilted to save less hovers, on the samples' runs by 3.9 mm at 1 deg).
KNEE_GAP = np.deg2rad(4.0)
#: A stance foot's pitch keeps its knee bent this much (rad) at least: where the ankle would lie
#: further from the hip, the pitch nearest the motion's that puts it there (near the straight
#: knee the solve's Jacobian vanishes and it falls short: real walks' toes slid 5 mm, their knee
#: targets at 1.1 deg).
STANCE_KNEE = np.deg2rad(2.0)
#: A fade spends this many times the knee change it makes (the smoothstep's steepest slope is
#: 1.5 times its mean; the knee follows the foot's correction only nearly in proportion).
FADE_MARGIN = 2.0
#: A stance foot whose heel and toe come within FLAT_RISE (m) of the same height is laid flat
#: where they come nearest (twice the 3 mm flat-foot hover target: a runner's foot that lands
#: nearly flat, 2.8 mm on the samples' runs; a foot that stays on its toes stays so).
FLAT_RISE = 0.006
#: A swing foot's sole stays this high (m) above the floor at least, reached at APPROACH_SPEED
#: from its stances' edges: the rigid toe that dips into the floor after push-off, raised onto
#: it, would scrape along it (a walk's minimum toe clearance is about 13 mm, Winter 1992).
SWING_CLEARANCE = 0.005
#: The largest turn (rad) about the ankle that lifts a swing foot's toe or heel off the floor.
MAX_TOE_TURN = np.deg2rad(30.0)


def mask_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The [start, stop) frame ranges where ``mask`` (F,) bool is True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def flattest(heights: np.ndarray) -> int:
    """The frame where a foot lies flattest: where the higher of its heel and toe, ``heights``
    (n, 2) m over a stance's n frames, is lowest."""
    return int(np.argmin(heights.max(axis=1)))


def foot_axes(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pitch (toes up > 0) and heading (rad) of feet with orientations ``R`` (..., 3, 3)."""
    x = R[..., :, 0]
    return np.arctan2(x[..., 2], np.hypot(x[..., 0], x[..., 1])), np.arctan2(x[..., 1], x[..., 0])


def foot_targets(skeleton: Skeleton, q: np.ndarray, stance: np.ndarray, rate: float) -> np.ndarray:
    """Where the ankle, heel and toe of each foot go, (F, 2, 3, 3) m, in world poses ``q`` (F, D)
    at ``rate`` Hz whose feet stand in the frames ``stance`` (F, 2) bool
    (:mod:`~mocaplib.library.planting`, steps 2-3)."""
    points, orientation, hips = LegChains(skeleton, q).frames(q[:, LEG_DOFS], q[:, ROOT_Z])
    local = np.vstack([np.zeros(3), skeleton.sole()])                     # ankle, heel, toe
    targets = points.copy()
    runs = [(side, start, stop) for side in (0, 1) for start, stop in mask_runs(stance[:, side])]
    if not runs:
        return targets
    pitch, heading = foot_axes(orientation)
    length = local[2, 0] - local[1, 0]
    frame, side, heel, psi = [], [], [], []
    for s, start, stop in runs:                # each run locked at its flattest frame
        flat = start + flattest(points[start:stop, s, 1:, 2])
        frame.append(np.arange(start, stop))
        side.append(np.full(stop - start, s))
        heel.append(np.tile([*points[flat, s, 1, :2], 0.0], (stop - start, 1)))
        psi.append(np.full(stop - start, heading[flat, s]))
    frame, side, heel, psi = (np.concatenate(x) for x in (frame, side, heel, psi))
    forward = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=-1)
    toe = heel + length * forward
    leg = (skeleton.lengths["thigh"], skeleton.lengths["shank"])
    theta = _stance_pitch(points[frame, side, 0], hips[frame, side],
                          q[frame, np.array(KNEES)[side]], pitch[frame, side], heel, toe,
                          forward, local, leg,
                          np.array([stop - start for _, start, stop in runs]))
    placed = np.einsum("nij,pj->npi", level_frames(theta, psi), local)
    pivot = np.where((theta >= 0)[:, None], heel - placed[:, 1], toe - placed[:, 2])
    targets[frame, side] = placed + pivot[:, None]
    clearance = _fade(targets, points, runs, max(1, round(BLEND_S * rate)), rate,
                      _knee_flexion(targets[..., 0, :], hips, leg)
                      - _knee_flexion(points[..., 0, :], hips, leg), q[:, list(KNEES)])
    swing = ~stance
    clearance = np.maximum(clearance, np.minimum(
        SWING_CLEARANCE, APPROACH_SPEED * _frames_from(stance) / rate))
    targets[swing] = _cleared(targets[swing], clearance[swing])
    return targets


def _frames_from(stance: np.ndarray) -> np.ndarray:
    """How many frames (F, 2) each frame lies from its foot's nearest stance frame in
    ``stance`` (F, 2) bool (0 in stance; infinite for a foot with none)."""
    out = np.full(stance.shape, np.inf)
    for side in (0, 1):
        if stance[:, side].any():
            out[:, side] = distance_transform_edt(~stance[:, side])
    return out


def _stance_pitch(ankle: np.ndarray, hip: np.ndarray, flexion: np.ndarray, pitch: np.ndarray,
                  heel: np.ndarray, toe: np.ndarray, forward: np.ndarray, local: np.ndarray,
                  leg: tuple[float, float], lengths: np.ndarray) -> np.ndarray:
    """The pitch (n,) rad of a foot rolling on the floor about its locked ``heel`` (n, 3) m (toes
    up, pitch >= 0) or ``toe`` (n, 3) m (heel up, pitch < 0), its heading the horizontal unit
    vector ``forward`` (n, 3), through consecutive stance runs of ``lengths`` frames: the
    motion's ``pitch`` (n,) rad where that changes the knee's flexion by at most
    :data:`KNEE_GAP`, beyond twice that the pitch that keeps the ankle as far from the ``hip``
    (n, 3) m as the motion's ``ankle`` (n, 3) m is (the knee's flexion kept; the solution
    nearest the motion's pitch, or the one that comes nearest where none keeps it), a linear
    blend between; then, outwards from the run's flattest frame, wherever that would move the
    knee further in a frame than the motion's knee moves at most in the run, the pitch that
    moves it that far (:func:`_rate_limited`); last, where the ankle would lie further from the
    hip than the knee bent :data:`STANCE_KNEE` reaches, the pitch that puts it there. The
    knee's ``flexion`` (n,) rad in the motion; ``local``: ankle, heel, toe in the foot frame
    (3, 3) m; ``leg``: thigh and shank lengths, m
    (the knee's flexion follows the law of cosines, its constant term fitted to the motion's
    flexion, which takes the joints' shifts in; an ankle beyond the straight leg's reach counts
    as a knee bent less than straight, as far as the law continued past 0 puts it)."""
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
        """Knee flexion (rad) of a leg whose ankle is length2 (m²) from its hip; beyond the
        straight leg's reach negative, as far as the law's continuation past 0 puts it (so that
        a foot out of reach counts as a change of the knee)."""
        x = (length2 - constant) / twice
        beyond = np.sqrt(2.0 * np.maximum(x - 1.0, 0.0))       # arccos(x) ~ sqrt(2 (1 - x))
        return np.where(x <= 1.0, np.arccos(np.clip(x, -1.0, 1.0)), -beyond)

    def length2(theta: np.ndarray) -> np.ndarray:
        """|ankle - hip|² (n,) m² at pitch ``theta`` (n,) rad, about the pivot its sign picks."""
        about = {}
        for sign in (1.0, -1.0):
            rest, arm, offset, square = reach(sign)
            about[sign] = square + arm ** 2 + 2 * arm * (offset[:, 0] * np.cos(rest + theta)
                                                         + offset[:, 1] * np.sin(rest + theta))
        return np.where(theta >= 0, about[1.0], about[-1.0])

    def nearest(length2_wanted: np.ndarray) -> np.ndarray:
        """The pitch (n,) rad nearest the motion's whose ankle is ``length2_wanted`` (n,) m² from
        the hip (or that comes nearest)."""
        best, miss = np.zeros(len(pitch)), np.full(len(pitch), np.inf)
        for sign in (1.0, -1.0):
            rest, arm, offset, square = reach(sign)
            span = np.maximum(2 * arm * np.hypot(*offset.T), 1e-12)
            cosine = np.clip((length2_wanted - square - arm ** 2) / span, -1.0, 1.0)
            direction = np.arctan2(offset[:, 1], offset[:, 0])
            for root in (np.arccos(cosine), -np.arccos(cosine)):
                theta = np.angle(np.exp(1j * (direction + root - rest)))
                theta = sign * np.maximum(sign * theta, 0.0)
                away = np.abs(theta - pitch)
                better = away < miss
                best[better], miss[better] = theta[better], away[better]
        return best

    own = np.abs(flexion)
    change = knee(length2(pitch)) - own
    share = np.clip(np.abs(change) / KNEE_GAP - 1.0, 0.0, 1.0)
    ruled = _laid_flat(pitch + share * (nearest(wanted) - pitch), lengths,
                       local[2, 0] - local[1, 0])
    kept = knee(length2(ruled)) - own
    limited = _rate_limited(own + kept, lengths, ruled, own) - own
    moved = np.abs(limited - kept) > 1e-9
    out = ruled.copy()
    if moved.any():
        out[moved] = nearest(constant + twice * np.cos(np.maximum(own + limited, 0.0)))[moved]
    beyond = knee(length2(out)) < STANCE_KNEE
    if beyond.any():
        out[beyond] = nearest(constant + twice * np.cos(STANCE_KNEE))[beyond]
    return out


def _nearest_level(pitch: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The index (runs,) of the frame of least absolute ``pitch`` (n,) in each of the
    consecutive runs of ``lengths`` frames."""
    return np.lexsort((np.abs(pitch), np.repeat(np.arange(len(lengths)), lengths)))[
        np.cumsum(lengths) - lengths]


def _laid_flat(pitch: np.ndarray, lengths: np.ndarray, sole: float) -> np.ndarray:
    """Stance pitches (n,) rad of consecutive runs of ``lengths`` frames, each run whose foot (a
    sole ``sole`` m long) comes within :data:`FLAT_RISE` of lying flat laid flat where it lies
    flattest: its pitch there taken off, less by a smoothstep towards the run's ends."""
    first = np.cumsum(lengths) - lengths
    anchor = _nearest_level(pitch, lengths)
    offset = pitch[anchor] * (np.abs(np.sin(pitch[anchor])) * sole <= FLAT_RISE)
    run = np.repeat(np.arange(len(lengths)), lengths)
    away = np.arange(len(pitch)) - anchor[run]
    reach = np.where(away < 0, (anchor - first + 1)[run], (first + lengths - anchor)[run])
    w = 1.0 - np.abs(away) / reach
    return pitch - offset[run] * w * w * (3 - 2 * w)


def _rate_limited(values: np.ndarray, lengths: np.ndarray, tilt: np.ndarray,
                  reference: np.ndarray) -> np.ndarray:
    """``values`` (n,) of consecutive runs of ``lengths`` frames each, changed to move by at most
    as far in a frame as ``reference`` (n,) moves at most in the run: kept where ``tilt`` (n,)
    is nearest 0 in the run, each frame away from there clipped to that step from the one before
    it on the way out."""
    first = np.cumsum(lengths) - lengths
    anchor = _nearest_level(tilt, lengths)
    steps = np.abs(np.diff(reference, prepend=reference[:1]))
    steps[first] = 0.0
    step = np.maximum.reduceat(steps, first)                        # (runs,)
    moves = np.abs(np.diff(values, prepend=values[:1]))
    moves[first] = 0.0
    faster = np.maximum.reduceat(moves, first) > step               # the runs to change
    out = values.copy()
    for way in (1, -1):
        at = anchor.copy()
        going = faster.copy()
        while True:
            going &= (at + way >= first) & (at + way < first + lengths)
            if not going.any():
                break
            was = at[going]
            at[going] += way
            now = at[going]
            out[now] = np.clip(values[now], out[was] - step[going], out[was] + step[going])
    return out


def _knee_flexion(ankle: np.ndarray, hip: np.ndarray, leg: tuple[float, float]) -> np.ndarray:
    """The knee flexion (...) rad of legs of thigh and shank lengths ``leg`` (m) whose
    ``ankle`` (..., 3) m is where it is from the ``hip`` (..., 3) m (law of cosines)."""
    length2 = np.sum((ankle - hip) ** 2, axis=-1)
    return np.arccos(np.clip((length2 - leg[0] ** 2 - leg[1] ** 2) / (2 * leg[0] * leg[1]),
                             -1.0, 1.0))


def _fade(targets: np.ndarray, points: np.ndarray, runs: list[tuple[int, int, int]], fade: int,
          rate: float, knee_change: np.ndarray, knee: np.ndarray) -> np.ndarray:
    """Fade each stance run's correction in before it and out after it, over the frames of its
    foot beyond each of its edges that the foot's neighbouring run and that run's own fade
    leave free (runs in order, each fading out, then the next in): the rigid correction that
    moves the motion's foot to its target at the edge (a turn about the ankle, then a shift),
    weighted by a smoothstep from 1 at the edge to 0 over ``fade`` frames at least, more where
    the correction changes the knee's flexion by ``knee_change`` (F, 2) rad at the edge: the
    smoothstep runs through the frames in proportion to how much slower the motion's knee
    ``knee`` (F, 2) rad moves there than at its fastest, and over as many as leave the knee
    never faster than that. ``targets`` (set in place), ``points``: (F, 2, 3, 3) m, ankle,
    heel, toe; ``runs``: (side, start, stop) each, by foot and in order. Returns how high
    (F, 2) m the lower sole point must stay in the frames faded
    (:mod:`~mocaplib.library.planting`, step 3)."""
    side, start, stop = np.asarray(runs, dtype=int).reshape(-1, 3).T
    after_own = np.r_[side[1:] == side[:-1], False]          # the foot's next run follows
    before_own = np.r_[False, after_own[:-1]]
    gap_after = np.where(after_own, np.r_[start[1:], 0] - stop, len(targets) - stop)
    edge, edge_side = np.r_[start, stop - 1], np.r_[side, side]
    direction = np.r_[-np.ones_like(start), np.ones_like(stop)]
    reach = int(np.r_[gap_after, start].max(initial=0)) + 1
    k = np.arange(1, reach + 1)
    frame = np.clip(edge[:, None] + direction[:, None] * k, 0, len(targets) - 1)
    fastest = np.abs(np.diff(knee, axis=0)).max(initial=0.0)
    spare = np.maximum(fastest - np.abs(knee[frame, edge_side[:, None]]
                                        - knee[np.clip(frame - direction[:, None], 0,
                                                       len(targets) - 1), edge_side[:, None]]),
                       0.0) + 1e-12                                  # (E, reach)
    spent = np.cumsum(spare, axis=1)
    need = FADE_MARGIN * np.abs(knee_change[edge, edge_side])
    length = np.maximum(fade, 1 + np.argmax(np.c_[spent >= need[:, None],
                                                  np.ones(len(edge), bool)], axis=1))
    fading_out = np.minimum(length[len(start):], gap_after + 1) - 1
    free_before = np.where(before_own, start - np.r_[0, stop[:-1]] - np.r_[0, fading_out[:-1]],
                           start)
    length = np.r_[np.minimum(length[:len(start)], free_before + 1), fading_out + 1]
    count = length - 1
    turn = _aligning_turns(targets[edge, edge_side] - targets[edge, edge_side, :1],
                           points[edge, edge_side] - points[edge, edge_side, :1])
    shift = targets[edge, edge_side, 0] - points[edge, edge_side, 0]
    which = np.repeat(np.arange(len(edge)), count)
    k = np.arange(len(which)) - np.repeat(np.cumsum(count) - count, count) + 1
    frame, foot = edge[which] + direction[which] * k, edge_side[which]
    s = np.where((length > fade)[which], spent[which, k - 1] / spent[which, length[which] - 1],
                 k / length[which])
    s = 1.0 - s
    s = s * s * (3 - 2 * s)
    ankle = points[frame, foot, :1]
    angle = np.linalg.norm(turn[which], axis=1)
    axis = turn[which] / np.maximum(angle, 1e-300)[:, None]
    targets[frame, foot] = (ankle + s[:, None, None] * shift[which, None]
                            + _turned(points[frame, foot] - ankle, axis, s * angle))
    clearance = np.zeros(targets.shape[:2])
    clearance[frame, foot] = APPROACH_SPEED * k / rate * (1 - k / length[which])
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
        across = np.cross(axis[low], r)[:, 2]      # z of u × r: z(φ) = r_z cos φ + c sin φ
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
