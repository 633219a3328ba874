"""The floor under the feet: its height from the feet's low samples, the ground's velocity on a
treadmill (the belt's, shared by both feet in stance), and the frames a foot stands flat on it.
The gait events (:mod:`mocaplib.gait.events`) and the foot's zero in calibration
(:func:`mocaplib.model.anatomy.flat_soles`) read them.

Foot points are ``(F, 3)`` arrays in metres, Z up; velocities m/s.
"""

from __future__ import annotations

import numpy as np

from ..numeric import median, nanpercentile
from ..runs import valid_runs


def floor_height(points: np.ndarray, velocity: np.ndarray, rate: float, *,
                 still_speed: float = 0.2, min_extent: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Heights (2, F) of heel and toe above the floor they stand on (m), and the floor's
    horizontal velocity (3,) (m/s: zero overground, the belt's on a treadmill); ``points``
    and their ``velocity`` (2, F, 3), ``rate`` Hz.

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
    A foot that stands still further than :data:`FLOOR_STEP` off that plane in some stance,
    or a plane steeper than :data:`MAX_RAMP_DEG`, shows other floors (a stair's treads, a
    curb): the heights are then taken above the level tread of the stance nearest in time
    (:func:`_treads`).
    """
    z = points[:, :, 2]
    rough = z - nanpercentile(z, 5, axis=1)[:, None]
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
            still = rough < nanpercentile(rough, 10, axis=1)[:, None]
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
    heights = z - floor
    speeds = np.linalg.norm(velocity - ground, axis=2)
    if (np.abs(_treads(heights, speeds, rate)).max() > FLOOR_STEP
            or np.linalg.norm(coef[len(points):]) > np.tan(np.radians(MAX_RAMP_DEG))):
        # stances on other floors (a stair): their treads are level, whatever slope the
        # plane took through them, so the heights are taken above each stance's tread, each
        # point moved onto the first's scale by their difference where both stand still
        with np.errstate(invalid="ignore"):
            flat = (speeds < FLAT_SPEED).all(axis=0) & np.isfinite(z).all(axis=0)
        level = z - (median(z[:, flat] - z[0, flat], axis=1) if flat.any()
                     else coef[:len(points)] - coef[0])[:, None]
        heights = level - _treads(level, speeds, rate)[None]
    return heights, ground


#: A foot stands flat on the floor where its heel and toe (or forefoot) points are both within
#: this height of the floor (m)...
FLAT_CLEARANCE = 0.01
#: ...and both move slower than this relative to the ground (m/s).
FLAT_SPEED = 0.1


#: A foot stands on another floor than the plane through its other stances when it stands
#: still this far above or below the plane (m): a stair's tread or a curb (15-20 cm, 10 cm),
#: not a floor's unevenness nor a tilt the plane follows.
FLOOR_STEP = 0.03
#: Steepest floor (degrees) taken for one plane: a ramp for walking is 5° at most (1:12); a
#: steeper plane through the stances is a stair's (a uniform stair lies on one: 30° or so).
MAX_RAMP_DEG = 8.0
#: Shortest time (s) a foot stands still (heel and toe slower than :data:`FLAT_SPEED`) to
#: show a floor: longer than the pause at the top of a step in place (the foot's speed passes
#: through zero there for some 40 ms).
MIN_STANCE_S = 0.15


def _treads(heights: np.ndarray, speeds: np.ndarray, rate: float) -> np.ndarray:
    """The floor under a foot (F,), m, on the scale of its heel and toe ``heights`` (2, F),
    from those and their ``speeds`` (2, F) m/s relative to the ground: each run of at least
    :data:`MIN_STANCE_S` in which the heel or the toe stands still (slower than
    :data:`FLAT_SPEED`; 3 frames within that time of the capture's start or end, which cut the
    stance) shows the level of the floor under the foot (the median height of the points
    standing still there), and each frame takes the level of the stance nearest in time: it
    changes halfway between two stances, in the swing from one tread to the next, where the
    foot is above both. Zeros for a foot never standing still."""
    n = heights.shape[1]
    with np.errstate(invalid="ignore"):
        still = (speeds < FLAT_SPEED) & np.isfinite(heights)
    shortest = MIN_STANCE_S * rate
    runs = [(a, b) for a, b in valid_runs(still.any(axis=0)).tolist()
            if b - a >= shortest or (b - a >= 3 and (a < shortest or b > n - shortest))]
    if not runs:
        return np.zeros(n)
    levels = np.array([median(heights[:, a:b][still[:, a:b]]) for a, b in runs])
    middles = [0.5 * (b0 - 1 + a1) for (_, b0), (a1, _) in zip(runs, runs[1:])]
    return levels[np.searchsorted(middles, np.arange(n))]


def foot_flat_frames(heel: np.ndarray, toe: np.ndarray, rate: float) -> np.ndarray:
    """The frames (F,) bool in which a foot stands flat on the floor: its ``heel`` and ``toe``
    (or forefoot) points (F, 3), metres, both within :data:`FLAT_CLEARANCE` of the floor
    (:func:`floor_height`) and both slower than :data:`FLAT_SPEED` relative to the ground;
    ``rate`` Hz. In walking, the middle of each stance: the heel is not yet rising and the
    forefoot has come down. False where a point is missing."""
    if len(heel) < 2:
        return np.zeros(len(heel), dtype=bool)
    points = np.stack([heel, toe])
    velocity = np.gradient(points, axis=1) * rate
    heights, ground = floor_height(points, velocity, rate)
    with np.errstate(invalid="ignore"):
        return ((heights < FLAT_CLEARANCE).all(axis=0)
                & (np.linalg.norm(velocity - ground, axis=2) < FLAT_SPEED).all(axis=0))


def _shared_velocity(velocity: np.ndarray, radius: float, /) -> np.ndarray:
    """The horizontal velocity (2,) m/s most of ``velocity`` (N, 2) share: of 256 evenly
    spaced samples, the one with the most of 4096 evenly spaced samples within ``radius``/2;
    then, twice, the median of the samples within ``radius`` of it, along that velocity and
    across it (:func:`_median_along`).

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
        shared = _median_along(velocity[np.linalg.norm(velocity - shared, axis=1) < radius],
                               shared)
    return shared


def _median_along(velocity: np.ndarray, direction: np.ndarray, /) -> np.ndarray:
    """The median (2,) of ``velocity`` (N, 2) taken along ``direction`` (2,) and across it:
    the same whichever way the lab's horizontal axes point, as a median of x and of y is not
    (along x when ``direction`` is zero)."""
    length = np.hypot(*direction)
    along = direction / length if length > 1e-9 else np.array([1.0, 0.0])
    frame = np.array([along, [-along[1], along[0]]])                   # rows: along, across
    return frame.T @ median(velocity @ frame.T, axis=0)


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
