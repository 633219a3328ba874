"""Joint-angle fitting: batched, robust, bounded Levenberg–Marquardt over many frames at once.

Per frame ``f`` the fit minimises

    Σ_m ρ(||x_fm − p_m(q_f)||) + μ² ||q_f − q̄_f||²

where ``p_m(q)`` is marker ``m`` of the calibrated model (:mod:`mocaplib.model.calibration`), ρ the
soft-L1 loss ``2c²(√(1 + (d/c)²) − 1)`` (quadratic below the scale c = 20 mm, linear above, so
one bad marker cannot drag the pose), ``q̄_f`` the mean of the neighbouring frames' current
solution (a weak continuity term; μ is small so it only steadies poorly seen DOFs) and ``q`` is
kept within :meth:`mocaplib.skeleton.Skeleton.bounds` (projected steps; a DOF on a bound whose
gradient points outwards leaves the step). Missing markers (NaN) drop out.

All frames of a chunk are solved together: the (F, D, D) Gauss–Newton normal equations of the
analytic Jacobian come from per-DOF sums of marker moments (:func:`_normal_equations`, no
(F, M, 3, D) Jacobian is formed) and are solved as one batched ``numpy.linalg.solve``;
each frame keeps its own damping and stops when its cost stops falling or its next step is
below a tolerance (taken without a trial). :func:`fit` first solves :func:`keyframes` (4 to 32
frames apart, closer where markers move less straight) from per-segment rigid fits (Kabsch on
the segment's markers and its joint centre, decomposed into the joint's DOFs); every other
frame starts from the Gauss–Newton step its markers ask of its two keyframes' linearisation,
and where that leaves a step below the tolerance it stops without its own normal equations
(:func:`_predict_between`; still and slow stretches cost one evaluation a frame). Samples of
a trajectory that jumps away from the model (mislabelled, swapped in, glitching) are removed
and counted (:func:`jumping_runs`, :data:`OUTLIER_LIMIT`). Before that, labelling errors are
undone (:func:`find_repairs`): two markers whose labels are exchanged, for the whole capture
or a stretch of it, are exchanged back, and a marker that stays far from its place is left
out; each repair is reported (:attr:`Motion.repairs`).

Units: metres and radians. Arrays: time on axis 0.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from ..errors import FitError
from ..markersets.protocols import label_match
from ..numeric import distinct, median, nanmedian
from ..runs import valid_runs
from ..skeleton import (DOF_NAMES, DOFS, LEVELS, MOVES, ROOT_HEADING, SEGMENT_NAMES, SEGMENTS,
                        SHIFTS, Skeleton, cross_rows, elementary_rotations, twist_jacobian, twists)
from .filtering import resample
from .motion import Motion, Repair, apply_repairs

if TYPE_CHECKING:
    from ..trial import Trial
    from .subject import SubjectModel

#: Soft-L1 scale c, metres: residuals above it count linearly (soft tissue moves markers 5-20 mm).
ROBUST_SCALE = 0.02
#: Continuity weight μ, metres per radian (per metre for translations).
SMOOTHING = 0.01
#: A frame with fewer markers on the pelvis, or in all, is flagged as failed. Three place the
#: root segment by its own markers, as a six-DOF segment needs; with two, its turn about the
#: line through them rests on the legs' and trunk's soft tissue (the real walks entering the
#: volume: pelvis tilt at its -45° limit or 10-15° above the frames beside them).
MIN_PELVIS_MARKERS = 3
MIN_MARKERS = 6
#: Frames with a marker RMS above this many times the median are re-solved from neighbours.
RESTART_FACTOR = 3.0
#: Outlying samples (a mislabelled, swapped-in or jumping trajectory). A marker's residual in a
#: frame is suspect above ``max(SUSPECT_FLOOR, median + OUTLIER_MADS x 1.4826 MAD)`` of that
#: marker's residuals over the capture, or above OUTLIER_LIMIT (the robust fit may have
#: absorbed part of its error); the frame is fitted again without its suspects, and a suspect
#: still more than OUTLIER_LIMIT from the refitted pose is removed (gapped: residual NaN,
#: counted in ``Motion.rejected``); the others are put back. OUTLIER_LIMIT is OpenSim's
#: best-practice bound on a marker error (40 mm): soft tissue and noise leave skin markers
#: within ~20 mm, and joints the skeleton lacks (toes, scapula) within ~35 mm.
SUSPECT_FLOOR = 0.015
OUTLIER_MADS = 8.0
OUTLIER_LIMIT = 0.04
#: Only a trajectory that jumps is removed: a run of suspect frames whose residual vector
#: changes by more than this (m) between two frames near its start or end (or that starts or
#: ends at a gap or the capture's edge). A marker the skeleton cannot follow (a toe marker in
#: push-off) drifts away smoothly and is kept, however large its residual.
JUMP = 0.01
#: Exchanged labels (:func:`find_repairs`): in a frame where two markers are both suspect, each
#: lies nearer the other's model position than its own, the two distances summed, by this
#: factor at least, after a fit without the two; a swap is reported for a stretch of at least
#: SWAP_MIN_FRAMES such frames (holes of up to SWAP_BRIDGE frames bridged); at most SWAP_PAIRS
#: pairs are fitted again, those whose exchange looks best in the most frames first.
SWAP_RATIO = 0.5
SWAP_MIN_FRAMES = 3
SWAP_BRIDGE = 3
SWAP_PAIRS = 12
#: A marker whose median residual stays above OUTLIER_LIMIT (after swaps are undone) over at
#: least SWAP_MIN_FRAMES frames is left out of the fit (a label on the wrong marker).
#: Keyframes (:func:`keyframes`) are solved first, from rigid fits; the others start from
#: predictions made from them, so they need fewer iterations. Keyframes are LONGEST_STRIDE apart,
#: or down to STRIDE where a marker strays more than KEY_TOLERANCE (m) from the straight line
#: between its keyframe positions (so a still subject needs few keyframes, a fast one many).
STRIDE = 4
#: Longest interval between keyframes, frames (used where markers move along straight lines).
LONGEST_STRIDE = 32
#: Largest distance (m) a marker may stray from the straight line between keyframes.
KEY_TOLERANCE = 0.005
#: Largest change (rad or m) the keyframes' linearisation may make to an interpolated start.
PREDICTION_LIMIT = 0.1
#: A frame whose last step moved a DOF by less than this many step tolerances checks its next
#: step with that step's matrix before forming new normal equations (:func:`solve_poses`):
#: below it, 35-100 % of such checks stopped the frame in the fits of the samples and of the
#: real files; above, 0-60 %, and a check that fails costs a gradient and a solve.
REUSE_BELOW = 40
#: Frames solved together; bounds memory to ~chunk × D² × 8 bytes per normal-matrix array.
CHUNK = 1000
#: The stopping rule of :func:`fit_filtered`'s raw pass, which only finds the outlying samples
#: and starts the filtered fit: it removed the same samples and flagged the same frames as
#: the default rule on the 17 real files and the samples, in 10-40 % less time.
OUTLIER_PASS = {"tol": 1e-3, "step_tol": 2e-3}

_LOWER, _UPPER = Skeleton.bounds()
_ROOT = SEGMENT_NAMES.index("pelvis")
#: (D, D) for :func:`_normal_equations`: 1 where DOF i moves the segment of DOF j (j's markers
#: are a subset of i's). Parents' DOFs come first, so above the diagonal it holds every pair
#: that shares markers.
_ANCESTOR = MOVES[[SEGMENT_NAMES.index(d.segment) for d in DOFS]].T.astype(np.float64)
assert (np.tril(_ANCESTOR, -1) <= _ANCESTOR.T).all(), "a DOF listed before its parent's"
#: :data:`_ANCESTOR` above the diagonal, halved on it: ``B + Bᵀ`` of ``B = A * _HALF_UPPER`` is
#: the symmetric matrix of A's upper triangle, to the bit (halving and doubling are exact).
_HALF_UPPER = np.triu(_ANCESTOR) - 0.5 * np.diag(np.diag(_ANCESTOR))
#: index pairs of the 6 distinct entries of a symmetric 3x3 moment (xx, yy, zz, xy, xz, yz)
_QI, _QJ = np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2])


@dataclass
class PoseFit:
    """Result of :func:`solve_poses` for F frames and M markers.

    q (F, D); residuals (F, M) metres, NaN where missing; converged (F,) bool;
    iterations run (int).
    """

    q: np.ndarray
    residuals: np.ndarray
    converged: np.ndarray
    iterations: int


def solve_poses(skeleton: Skeleton, markers: np.ndarray, segments: np.ndarray,
                offsets: np.ndarray, /, *, q0: np.ndarray | None = None,
                free: np.ndarray | None = None, weights: np.ndarray | None = None,
                robust_scale: float = ROBUST_SCALE, smoothing: float = SMOOTHING,
                max_iter: int = 40, tol: float = 1e-4, step_tol: float = 5e-4,
                step_metric: tuple[np.ndarray, np.ndarray] | None = None) -> PoseFit:
    """Fit joint coordinates to markers for every frame at once.

    Parameters
    ----------
    markers : ndarray, shape (F, M, 3), metres, NaN where missing.
    segments, offsets : shapes (M,), (M, 3): each marker's segment index and position in it.
    q0 : ndarray, shape (F, D), optional. Start; default :func:`initial_pose`.
    free : bool ndarray, shape (D,), optional. DOFs to fit; the others stay at ``q0`` (default
        all free).
    weights : ndarray, shape (M,) or (F, M), optional. Marker weights (default 1).
    robust_scale : soft-L1 scale c, metres (``np.inf`` for plain least squares).
    smoothing : continuity weight μ (0 switches it off).
    max_iter, tol, step_tol : iteration limit; a frame has converged when its cost falls by
        less than ``tol`` (relative) or its largest step is below ``step_tol`` (rad or m).
    step_metric : (inverses (K, D, D), owner (F,) int), optional. Inverse normal matrices of
        solved poses near ``q0`` and the one each frame may use (-1: none), as
        :func:`_predict_between` gives them: a frame whose first step by its matrix is below
        ``step_tol`` takes that step without forming its own normal equations.
    """
    markers = np.asarray(markers, dtype=np.float64)
    n_frames, n_markers = markers.shape[:2]
    segments = np.asarray(segments, dtype=int)
    offsets = np.asarray(offsets, dtype=np.float64)
    free = np.ones(len(DOF_NAMES), bool) if free is None else np.asarray(free, bool)
    valid = _seen(markers)
    target = np.where(valid[:, None], markers.transpose(0, 2, 1), 0.0)          # (F, 3, M)
    w_marker = np.ones((n_frames, n_markers)) if weights is None else np.broadcast_to(
        np.asarray(weights, float), (n_frames, n_markers))
    w_marker = np.where(valid, w_marker, 0.0)
    q = initial_pose(skeleton, markers, segments, offsets) if q0 is None else np.array(q0, float)
    q = np.clip(q, _LOWER, _UPPER)
    n_dofs = len(DOF_NAMES)
    diagonal = (slice(None), np.arange(n_dofs), np.arange(n_dofs))
    lam = np.full(n_frames, 1e-5)
    active = np.ones(n_frames, dtype=bool)
    # the damped normal matrix of each frame's last accepted step, and that step's size (inf:
    # none in the last iteration)
    last_matrix = np.empty((n_frames, n_dofs, n_dofs))
    last_step = np.full(n_frames, np.inf)
    rough = np.zeros(n_frames, dtype=bool)      # stopped after an untried step over step_tol
    mu2 = smoothing ** 2
    marker_map = _marker_map(segments, offsets)
    moved = MOVES[segments].astype(np.float64)                   # (M, D): DOF d moves marker m

    def objective(d, rows, q_rows, q_ref):
        """Cost (n,) of frames ``rows`` at poses q_rows whose markers lie ``d`` (n, M) m off."""
        return (w_marker[rows] * _soft_l1(d, robust_scale)).sum(axis=1) + mu2 * (
            ((q_rows - q_ref) * free) ** 2).sum(axis=1)

    def descent(twist, about, r, w, q_rows, q_ref):
        """The cost's descent direction JᵀWr − μ²(q_rows − q_ref) (n, D), 0 on held DOFs."""
        g = _gradient(twist, about, moved, r, w)
        g -= mu2 * (q_rows - q_ref)
        g[:, ~free] = 0.0
        return g

    def cost(q_rows, rows, q_ref):
        """Cost (n,) of poses q_rows for frames ``rows``, their kinematic chain and markers."""
        chain = skeleton.chain(q_rows)
        pts = _points(chain[0], marker_map)
        return objective(_norm3(target[rows] - pts), rows, q_rows, q_ref), chain, pts

    chains = list(skeleton.chain(q))        # transforms, DOF axes and pivots at the current q
    pts = _points(chains[0], marker_map)    # (F, 3, M), markers at the current q
    inverse, owner = step_metric if step_metric is not None else (None, np.full(n_frames, -1))
    rows = np.flatnonzero((owner >= 0) & _interior(q, free))
    if rows.size:
        every = rows.size == n_frames                # then no copies of the big arrays
        twist, origin = twists(chains if every else tuple(c[rows] for c in chains))
        about = (pts if every else pts[rows]) - origin[:, :, None]
        r = (target if every else target[rows]) - (pts if every else pts[rows])
        g = descent(twist, about, r, w_marker[rows] * _soft_l1_weight(_norm3(r), robust_scale),
                    q[rows], _neighbour_mean(q)[rows])
        step = _projected(q[rows], _by_owner(inverse, owner[rows], g))
        _take_steps(q, pts, active, rows, step, np.abs(step).max(axis=1) < step_tol, twist,
                    about, moved, every=every)

    iterations = 0
    for iterations in range(1, max_iter + 1):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        every = rows.size == n_frames                # then no copies of the big arrays
        q_ref = _neighbour_mean(q)[rows]
        qa = q[rows]
        r = (target if every else target[rows]) - (pts if every else pts[rows])
        d = _norm3(r)
        w = w_marker[rows] * _soft_l1_weight(d, robust_scale)              # IRLS weights
        twist, origin = twists(chains if every else tuple(c[rows] for c in chains))
        about = (pts if every else pts[rows]) - origin[:, :, None]
        # a frame that has just taken a step of less than REUSE_BELOW step_tols first measures
        # its next step by that step's matrix (as the step metric above; the matrix changes
        # little over a converging step): a step below step_tol, or one whose predicted cost
        # decrease gᵀs is below tol (relative), it takes untried and stops, without forming
        # its own normal equations
        check = np.flatnonzero((last_step[rows] < REUSE_BELOW * step_tol)
                               & _interior(qa, free))
        last_step[rows] = np.inf
        if check.size:
            g = descent(twist[check], about[check], r[check], w[check], qa[check], q_ref[check])
            step = _projected(qa[check], np.linalg.solve(last_matrix[rows[check]],
                                                         g[..., None])[..., 0])
            c0 = objective(d[check], rows[check], qa[check], q_ref[check])
            small = np.abs(step).max(axis=1) < step_tol
            there = small | ((g * step).sum(axis=1) <= tol * np.maximum(c0, 1e-12))
            _take_steps(q, pts, active, rows[check], step, there, twist[check], about[check],
                        moved)
            rough[rows[check[there & ~small]]] = True
            if there.all() and check.size == rows.size:
                continue
            if there.any():
                keep = np.ones(rows.size, dtype=bool)
                keep[check[there]] = False
                rows, q_ref, qa, r, d, w, twist, about = (
                    x[keep] for x in (rows, q_ref, qa, r, d, w, twist, about))
        A, g = _normal_equations(twist, about, moved, r, w)
        g -= mu2 * (qa - q_ref)
        # the continuity term's curvature counted twice: the step also stays near the current
        # pose (a proximal term, no change to the minimum). Every frame moves towards its
        # neighbours' mean while they move towards its own: with the curvature counted once,
        # a DOF the markers hardly see (ankle inversion on a heel-toe foot) jumps back and
        # forth between two frames without end; twice, it settles.
        A[diagonal] += 2 * mu2
        # locked DOFs, and DOFs on a bound whose gradient points outwards, leave the step
        held = (~free | ((qa <= _LOWER + 1e-12) & (g < 0)) | ((qa >= _UPPER - 1e-12) & (g > 0)))
        some = np.flatnonzero(held.any(axis=1))
        if some.size:
            h = held[some]
            A[some] *= ~h[:, :, None] & ~h[:, None, :]
            A[some[:, None], diagonal[1], diagonal[2]] += h
            g[held] = 0.0
        diag = A[diagonal].copy()
        c0 = objective(d, rows, qa, q_ref)
        # a few damping trials per iteration: frames whose step fails raise their damping
        todo = np.ones(rows.size, dtype=bool)
        for attempt in range(4):
            k = np.flatnonzero(todo)
            if k.size == 0:
                break
            Ak = A if k.size == rows.size else A[k]            # (A itself on the first trial)
            Ak[diagonal] = diag[k] + lam[rows[k], None] * (diag[k] + 1e-9)
            step = np.linalg.solve(Ak, g[k][..., None])[..., 0]
            trial_q = np.clip(qa[k] + step, _LOWER, _UPPER)
            # a frame whose next (undamped enough) step is below step_tol is at its minimum:
            # it takes the step untried, its markers moved to first order (error ~ step² x
            # lever, < 1 µm)
            there = (np.abs(trial_q - qa[k]).max(axis=1) < step_tol) & (attempt == 0)
            in_Ak = np.arange(k.size)
            if there.any():
                last, f = k[there], rows[k[there]]
                pts[f] += _first_order_move(twist[last], about[last], moved,
                                            trial_q[there] - qa[last])
                q[f] = trial_q[there]
                active[f] = False
                todo[last] = False
                k, trial_q, in_Ak = k[~there], trial_q[~there], in_Ak[~there]
                if k.size == 0:
                    break
            c1, trial_chain, trial_pts = cost(trial_q, rows[k], q_ref[k])
            better = c1 <= c0[k]
            good = k[better]
            moved_by = np.abs(trial_q[better] - qa[good]).max(axis=1)
            q[rows[good]] = trial_q[better]
            for cached, new in zip(chains, trial_chain):
                cached[rows[good]] = new[better]
            pts[rows[good]] = trial_pts[better]
            lam[rows[good]] = np.maximum(lam[rows[good]] / 3.0, 1e-9)
            last_matrix[rows[good]] = Ak[in_Ak[better]]
            last_step[rows[good]] = moved_by
            done = ((c0[good] - c1[better] <= tol * np.maximum(c0[good], 1e-12))
                    | (moved_by < step_tol))
            active[rows[good[done]]] = False
            worse = k[~better]
            lam[rows[worse]] *= 4.0
            todo[good] = False
            # no descent left (a damped step below step_tol, or damping exhausted): at a minimum
            stuck = worse[(np.abs(trial_q[~better] - qa[worse]).max(axis=1) < step_tol)
                          | (lam[rows[worse]] > 1e8)]
            active[rows[stuck]] = False
            todo[stuck] = False
    if rough.any():                             # their markers placed exactly
        pts[rough] = _points(skeleton.chain(q[rough])[0], marker_map)
    residuals = _norm3(markers.transpose(0, 2, 1) - pts)
    return PoseFit(q, residuals, ~active, iterations)


def _interior(q: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Frames (n,) bool of poses ``q`` (n, D) whose ``free`` (D,) DOFs are all off their
    joint bounds."""
    return (((q > _LOWER + 1e-12) & (q < _UPPER - 1e-12)) | ~free).all(axis=1)


def _projected(q: np.ndarray, step: np.ndarray) -> np.ndarray:
    """``step`` (n, D) from poses ``q`` (n, D) cut to the joint bounds."""
    return np.clip(q + step, _LOWER, _UPPER) - q


def _take_steps(q: np.ndarray, pts: np.ndarray, active: np.ndarray, rows: np.ndarray,
                step: np.ndarray, take: np.ndarray, twist: np.ndarray, about: np.ndarray,
                moved: np.ndarray, *, every: bool = False) -> None:
    """Take the steps (n, D) of frames ``rows`` (n,) where ``take`` (n,) bool, untried: ``q``
    (F, D) moved, their markers ``pts`` (F, 3, M) moved to first order
    (:func:`_first_order_move`, from ``twist`` (n, 6, D) and ``about`` (n, 3, M)) and their
    ``active`` (F,) cleared, in place; ``every``: ``rows`` are all frames."""
    # (moving every row, by zero where not taken, copies less than selecting)
    step = np.where(take[:, None], step, 0.0)
    if every:
        pts += _first_order_move(twist, about, moved, step)
    else:
        pts[rows] += _first_order_move(twist, about, moved, step)
    q[rows] += step
    active[rows[take]] = False


def _by_owner(matrices: np.ndarray, owner: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``matrices[owner[f]] @ vectors[f]`` for every row f, shape (F, D): matrices (K, D, D),
    owner (F,) indices into them in any order, vectors (F, D). One product per run of equal
    consecutive owners (owners are keyframes, so runs are long) instead of gathering
    (F, D, D) matrices."""
    out = np.empty_like(vectors)
    edges = np.r_[0, np.flatnonzero(np.diff(owner)) + 1, len(owner)]
    for start, stop in zip(edges[:-1], edges[1:]):
        out[start:stop] = vectors[start:stop] @ matrices[owner[start]].T
    return out


def _marker_map(segments: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(4S, M) matrix taking the rows ``[R | t]`` of every segment transform to the points
    fixed at ``offsets`` (M, 3) in ``segments`` (M,): see :func:`_points`."""
    n = len(segments)
    out = np.zeros((len(SEGMENTS), 4, n))
    out[segments, :3, np.arange(n)] = offsets
    out[segments, 3, np.arange(n)] = 1.0
    return out.reshape(-1, n)


def _points(transforms: np.ndarray, marker_map: np.ndarray) -> np.ndarray:
    """Points (F, 3, M) (coordinates on axis 1) from the segment transforms (F, S, 4, 4) of
    :meth:`~mocaplib.skeleton.Skeleton.chain` and :func:`_marker_map`: one matrix product."""
    n, s = transforms.shape[:2]
    rows = transforms[:, :, :3, :].transpose(0, 2, 1, 3).reshape(n * 3, s * 4)
    return (rows @ marker_map).reshape(n, 3, marker_map.shape[1])


def _seen(points: np.ndarray) -> np.ndarray:
    """Points (..., 3) whose three coordinates are finite, bool (...): as
    ``np.isfinite(points).all(axis=-1)``, without its slow reduction over a short axis."""
    return np.isfinite(points[..., 0]) & np.isfinite(points[..., 1]) & np.isfinite(points[..., 2])


def _norm3(v: np.ndarray) -> np.ndarray:
    """Lengths (F, M) of vectors (F, 3, M)."""
    return np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2 + v[:, 2] ** 2)


def _normal_equations(twist: np.ndarray, p: np.ndarray, moved: np.ndarray, r: np.ndarray,
                      w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Newton normal equations ``JᵀWJ`` (F, D, D) and ``JᵀWr`` (F, D) without the
    (F, M, 3, D) Jacobian.

    ``twist`` (F, 6, D): :func:`~mocaplib.skeleton.twists` at the current poses; ``p``
    (F, 3, M) the markers there, about the twists' origin; ``moved`` (M, D) 1 where DOF d moves
    marker m; ``r`` (F, 3, M) marker minus model; ``w`` (F, M) weights (0 for missing markers).

    DOF ``i`` moves a point ``p`` at the velocity ``ωᵢ × p + vᵢ`` (its twist: ``ω`` its world
    axis and ``v = c × ω`` about its pivot ``c`` for a rotation; ``ω = 0``, ``v`` its axis for a
    translation). So ``(JᵀWJ)ᵢⱼ = sᵢ · Hⱼ sⱼ`` whenever every marker DOF ``j`` moves is moved by
    ``i`` too, with ``Hⱼ`` the 6×6 weighted second moment of the markers ``j`` moves (as in the
    composite-rigid-body algorithm), and ``(JᵀWr)ᵢ = sᵢ · Σ w (p × r, r)`` over the markers
    ``i`` moves: per-DOF sums of 16 marker moments, two matrix products for all of them.
    """
    n, m = w.shape
    moments = np.empty((n, 10, m))                                              # (F, 10, M)
    moments[:, 0] = w
    wp = np.multiply(w[:, None], p, out=moments[:, 1:4])
    np.multiply(np.take(wp, _QI, axis=1), np.take(p, _QJ, axis=1), out=moments[:, 4:10])
    total = (moments.reshape(n * 10, m) @ moved).reshape(n, 10, moved.shape[1])  # (F, 10, D)
    W, P, Q = total[:, 0], total[:, 1:4], total[:, 4:10].swapaxes(0, 1)
    qxx, qyy, qzz, qxy, qxz, qyz = Q
    omega, v = twist[:, :3], twist[:, 3:]
    ox, oy, oz = omega[:, 0], omega[:, 1], omega[:, 2]
    trace = qxx + qyy + qzz
    H_s = np.empty_like(twist)                              # H_j s_j for every DOF j
    H_s[:, 0] = trace * ox - (qxx * ox + qxy * oy + qxz * oz)
    H_s[:, 1] = trace * oy - (qxy * ox + qyy * oy + qyz * oz)
    H_s[:, 2] = trace * oz - (qxz * ox + qyz * oy + qzz * oz)
    H_s[:, :3] += cross_rows(P, v)
    H_s[:, 3:] = W[:, None] * v + cross_rows(omega, P)
    A = twist.transpose(0, 2, 1) @ H_s
    A *= _HALF_UPPER                        # right on and above the diagonal: mirror it below
    A += A.transpose(0, 2, 1)              # numpy buffers the overlap
    return A, _gradient(twist, p, moved, r, w)


def _gradient(twist: np.ndarray, p: np.ndarray, moved: np.ndarray, r: np.ndarray,
              w: np.ndarray) -> np.ndarray:
    """``JᵀWr`` (F, D) from the twists (F, 6, D) and the markers ``p`` (F, 3, M) about their
    origin, ``r`` (F, 3, M) and ``w`` (F, M) as in :func:`_normal_equations`."""
    n, m = w.shape
    moments = np.empty((n, 6, m))
    wr = np.multiply(w[:, None], r, out=moments[:, 3:])
    moments[:, :3] = cross_rows(p, wr)
    total = (moments.reshape(n * 6, m) @ moved).reshape(n, 6, moved.shape[1])
    return (twist * total).sum(axis=1)


def _first_order_move(twist: np.ndarray, p: np.ndarray, moved: np.ndarray,
                      step: np.ndarray) -> np.ndarray:
    """Displacements (F, 3, M) of markers ``p`` (F, 3, M, about the twists' origin) for a small
    change ``step`` (F, D) of the poses, to first order: ``J step`` from the twists (F, 6, D)."""
    n = len(step)
    total = (twist * step[:, None]).reshape(n * 6, moved.shape[1]) @ moved.T
    total = total.reshape(n, 6, len(moved))
    return cross_rows(total[:, :3], p) + total[:, 3:]


def _soft_l1(d: np.ndarray, c: float) -> np.ndarray:
    """Soft-L1 loss of distances d (metres): d² for d ≪ c, ≈ 2c·d for d ≫ c."""
    if not np.isfinite(c):
        return d ** 2
    return 2.0 * c ** 2 * (np.sqrt(1.0 + (d / c) ** 2) - 1.0)


def _soft_l1_weight(d: np.ndarray, c: float) -> np.ndarray:
    """IRLS weight ρ'(d) / (2d) of the soft-L1 loss, in (0, 1]."""
    if not np.isfinite(c):
        return np.ones_like(d)
    return 1.0 / np.sqrt(1.0 + (d / c) ** 2)


def _neighbour_mean(q: np.ndarray) -> np.ndarray:
    """Mean of each frame's previous and next frame (one neighbour at the ends), shape (F, D)."""
    if len(q) < 2:
        return q.copy()
    out = np.empty_like(q)
    out[1:-1] = 0.5 * (q[:-2] + q[2:])
    out[0], out[-1] = q[1], q[-2]
    return out


# ----------------------------------------------------------------------------- initial pose
def initial_pose(skeleton: Skeleton, markers: np.ndarray, segments: np.ndarray,
                 offsets: np.ndarray) -> np.ndarray:
    """Start pose from per-segment rigid fits, shape (F, D).

    Segments are visited root first, those of one depth together (:data:`LEVELS`). Each
    segment's rotation is the weighted Kabsch fit of its markers (model offsets → measured)
    plus its joint centre placed by the parent; the rotation relative to the parent is
    decomposed into the joint's DOFs. Frames or segments with fewer than three points get the
    value interpolated over time (0 when never seen). The heading is unwrapped over time.
    """
    n_frames = markers.shape[0]
    q = np.zeros((n_frames, len(DOF_NAMES) + 1))       # the last column: LEVELS' padding slot
    joint = skeleton.joint_offsets()
    rot = np.empty((n_frames, len(SEGMENTS), 3, 3))         # segment-to-world, built root first
    pos = np.empty((n_frames, len(SEGMENTS), 3))
    unseen = np.concatenate([markers, np.full((n_frames, 1, 3), np.nan)], axis=1)
    for (segs, parents, spins, *_), euler, dofs in zip(LEVELS, _EULER, _LEVEL_DOFS):
        # each segment's markers (index -1: the unseen column) and a last slot for its centre
        own = [np.flatnonzero(segments == s) for s in segs]
        index = np.full((len(segs), max(map(len, own)) + 1), -1)
        local = np.zeros(index.shape + (3,))
        for row, m in enumerate(own):
            index[row, :len(m)] = m
            local[row, :len(m)] = offsets[m]
        world = unseen[:, index]                                          # (F, k, N, 3)
        if parents is None:
            R_parent = np.broadcast_to(np.eye(3), (n_frames, len(segs), 3, 3))
            R, t, ok = _kabsch(local, world)
            rel = R
            q[:, SHIFTS] = t[:, 0]
        else:
            R_parent = rot[:, parents]
            centre = (R_parent @ joint[segs, :, None])[..., 0] + pos[:, parents]
            world[:, :, -1] = centre                          # its local position: zero
            R, _, ok = _kabsch(local, world)
            rel = np.swapaxes(R_parent, -1, -2) @ R
        q[:, spins] = _joint_angles(rel, *euler)
        for row in np.flatnonzero(~ok.all(axis=0)):
            q[np.ix_(~ok[:, row], dofs[row])] = np.nan
        cols = np.concatenate(dofs)
        q[:, cols] = _fill_gaps(q[:, cols])
        local_rot = elementary_rotations(q[:, :-1])
        R = R_parent
        for j in spins.T:
            R = R @ local_rot[:, j]
        rot[:, segs] = R
        pos[:, segs] = q[:, None, SHIFTS] if parents is None else centre
    q = q[:, :-1]
    q[:, ROOT_HEADING] = np.unwrap(q[:, ROOT_HEADING])
    return np.clip(q, _LOWER, _UPPER)


def _kabsch(local: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rigid fits ``world ≈ R @ local + t`` per frame (and per set) over the finite points.

    local (..., N, 3); world (F, ..., N, 3) with NaN where missing. Returns R (F, ..., 3, 3),
    t (F, ..., 3) and ok (F, ...): at least three points and a non-degenerate spread.
    """
    valid = _seen(world)
    w = valid.astype(float)
    count = w.sum(axis=-1)
    Y = np.where(valid[..., None], world, 0.0)
    safe = np.maximum(count, 1.0)[..., None]
    cp = (w[..., None, :] @ local)[..., 0, :] / safe
    cy = (w[..., None, :] @ Y)[..., 0, :] / safe
    P = (local - cp[..., None, :]) * w[..., None]
    H = np.swapaxes(P, -1, -2) @ (Y - cy[..., None, :])
    U, S, Vt = np.linalg.svd(H)
    V, Ut = np.swapaxes(Vt, -1, -2), np.swapaxes(U, -1, -2)
    sign = np.sign(np.linalg.det(V @ Ut))
    sign[sign == 0] = 1.0
    V = V.copy()
    V[..., 2] *= sign[..., None]                          # V diag(1, 1, sign)
    R = V @ Ut
    t = cy - (R @ cp[..., None])[..., 0]
    ok = (count >= 3) & (S[..., 1] > 1e-6)
    return R, t, ok


def _euler_table(spins: np.ndarray) -> tuple[np.ndarray, ...]:
    """For :func:`_joint_angles`: per row of ``spins`` (k, 3) (a joint's rotation DOFs, padded
    with D), the Tait-Bryan letters i, j, k (k,) over its axes' letters (completed with the
    unused ones), e (k,) = +1 for a cyclic order (XYZ, YZX, ZXY) else -1, and the axes'
    signs (k, 3) (1 for padding)."""
    letters, signs = np.zeros((len(spins), 3), dtype=int), np.ones((len(spins), 3))
    for row, dofs in enumerate(spins):
        axes = [DOFS[c].axis for c in dofs if c < len(DOFS)]
        used = [int(np.argmax(np.abs(axis))) for axis in axes]
        letters[row] = used + [c for c in range(3) if c not in used][:3 - len(used)]
        signs[row, :len(axes)] = [float(np.sign(axis[k])) for axis, k in zip(axes, used)]
    i, j, k = letters.T
    return i, j, k, np.where((j - i) % 3 == 1, 1.0, -1.0), signs


def _joint_angles(R: np.ndarray, i: np.ndarray, j: np.ndarray, k: np.ndarray, e: np.ndarray,
                  signs: np.ndarray) -> np.ndarray:
    """Angles (F, n, 3) about each joint's signed unit axes (±X/±Y/±Z, intrinsic order)
    closest to its rotation R (F, n, 3, 3), with :func:`_euler_table`'s letters, e and signs.

    R is read as the Tait-Bryan sequence R_i(a) R_j(b) R_k(c): b = asin(e R_ik),
    a = atan2(-e R_jk, R_kk), c = atan2(-e R_ij, R_ii); a joint with fewer axes uses the
    first angles.
    """
    n = np.arange(R.shape[1])
    b = np.arcsin(np.clip(e * R[:, n, i, k], -1.0, 1.0))
    a = np.arctan2(-e * R[:, n, j, k], R[:, n, k, k])
    c = np.arctan2(-e * R[:, n, i, j], R[:, n, i, i])
    return np.stack([a, b, c], axis=-1) * signs


#: per level of LEVELS: :func:`_euler_table` of its joints, and each segment's DOFs
_EULER = [_euler_table(spins) for _, _, spins, *_ in LEVELS]
_LEVEL_DOFS = [[np.array([DOF_NAMES.index(n) for n in SEGMENTS[s].dofs]) for s in segs]
               for segs, *_ in LEVELS]


def _bracket(keys: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """For every frame of ``range(n_frames)``, the index (F,) in ``keys`` (K,) (sorted, from 0 to
    n_frames - 1) of the key after it (the one before for the last) and its position (F,) from
    the key before (0) to that one (1)."""
    frames = np.arange(n_frames)
    after = np.clip(np.searchsorted(keys, frames, side="right"), 1, len(keys) - 1)
    return after, (frames - keys[after - 1]) / np.maximum(keys[after] - keys[after - 1], 1)


def _fill_gaps(values: np.ndarray) -> np.ndarray:
    """Linearly interpolate NaN rows over time per column (0 where a column is all NaN)."""
    if not np.isnan(values).any():
        return values.copy()
    return np.nan_to_num(resample(values, 1.0, np.arange(len(values))), nan=0.0)


# ----------------------------------------------------------------------------- the fit
def fit(trial: "Trial", model: "SubjectModel", /, *, robust_scale: float = ROBUST_SCALE,
        smoothing: float = SMOOTHING, max_iter: int = 40, tol: float = 1e-4,
        step_tol: float = 5e-4, chunk: int = CHUNK, q0: np.ndarray | None = None) -> Motion:
    """Fit the calibrated model's joint angles to every frame of ``trial``.

    Frames are solved together (but those whose markers cannot pose the model,
    :func:`_poseable`), from keyframes solved from per-segment rigid fits; frames left
    with an outlying marker RMS are re-solved from their neighbours' poses, and outlying
    samples are removed (:data:`OUTLIER_LIMIT`): fitted again without them, kept out if still
    further than that, reported in ``Motion.rejected`` (F, M) bool with NaN residuals.

    Parameters
    ----------
    trial : Trial with the model's protocol labels (matched as :func:`mocaplib.markersets.protocols.label_match` does).
    model : SubjectModel from :func:`mocaplib.model.calibration.calibrate`.
    robust_scale : soft-L1 scale, metres; ``np.inf`` for plain least squares.
    smoothing : continuity weight μ (metres per radian); 0 switches it off.
    max_iter, tol, step_tol : LM iterations per chunk of frames; a frame stops when its cost
        falls by less than ``tol`` (relative) or its largest step is below ``step_tol`` (rad
        or m), as :func:`solve_poses`.
    chunk : frames solved together.
    q0 : (F, D) start poses (a previous fit of the same frames); default: the coarse-to-fine
        start described above.

    Returns
    -------
    Motion with angles (F, D), residuals (F, M) metres, ``failed`` frames (fewer than
    :data:`MIN_PELVIS_MARKERS` pelvis markers or :data:`MIN_MARKERS` markers, or no
    convergence) whose angles are interpolated from their neighbours and whose residuals are
    NaN, the removed samples, the labelling errors undone (:func:`find_repairs`,
    :func:`far_markers`; ``Motion.repairs``) and the model's locked DOFs (held at 0).
    """
    markers = model_markers(trial, model)
    n_frames = trial.n_frames
    if n_frames == 0:
        raise FitError("the trial has no frames", path=trial.source)
    free = model.free
    q = np.zeros((n_frames, len(DOF_NAMES)))
    residuals = np.full((n_frames, len(model.labels)), np.nan)
    converged = np.zeros(n_frames, dtype=bool)
    rejected = np.zeros((n_frames, len(model.labels)), dtype=bool)
    repairs: list[Repair] = []
    # frames whose markers cannot pose the model fail whatever their pose: solved, their free
    # poses would take the solver's full iterations and pull their neighbours through the
    # continuity term, so each chunk solves the others only, as if they were consecutive
    poseable = _poseable(_seen(markers), model)
    for start in range(0, n_frames, chunk):
        part = start + np.flatnonzero(poseable[start:start + chunk])
        if part.size == 0:
            continue
        settings = dict(free=free, robust_scale=robust_scale, smoothing=smoothing,
                        max_iter=max_iter, tol=tol, step_tol=step_tol,
                        weights=model.marker_weights)
        # coarse to fine in time: keyframes from rigid-fit starts, then all frames from their
        # predictions (a warm start, as frame-by-frame solvers use)
        solve = partial(solve_poses, model.skeleton, markers[part], model.marker_segments,
                        model.marker_offsets, **settings)
        start_q, metric = (_coarse_start(model, markers[part], settings) if q0 is None
                           else _warm_start(model, markers[part], settings, q0[part]))
        res = _restart_outliers(solve, solve(q0=start_q, step_metric=metric))
        res, markers[part], found = _undo_labelling_errors(
            lambda x, q: solve_poses(model.skeleton, x, model.marker_segments,
                                     model.marker_offsets, q0=q, **settings),
            res, markers[part], model, settings)
        repairs += [replace(r, start=int(part[r.start]), stop=int(part[r.stop - 1]) + 1)
                    for r in found]
        rejected[part] = _reject_outliers(res, markers[part], model, **settings)
        q[part], residuals[part], converged[part] = res.q, res.residuals, res.converged
    failed = ~_poseable(np.isfinite(markers[..., 0]) & ~rejected, model) | ~converged
    if failed.all():
        raise FitError(f"no frame could be fitted (each has fewer than {MIN_PELVIS_MARKERS} "
                       f"pelvis markers or {MIN_MARKERS} markers in all)", path=trial.source,
                       hint="check the protocol matches the labels")
    if failed.any():
        residuals[failed] = np.nan
        q[failed] = np.nan
        q = _fill_gaps(q)
        q[:, ~free] = 0.0
    rejected &= ~failed[:, None]
    return Motion(q, model.skeleton, trial.rate,
                  marker_labels=list(model.labels), residuals=residuals, failed=failed,
                  rejected=rejected,
                  locked_dofs=list(model.locked_dofs), unobservable=dict(model.unobservable),
                  marker_weights=model.marker_weights,
                  marker_segments=np.array(model.marker_segments),
                  marker_offsets=np.array(model.marker_offsets),
                  repairs=repairs, source=trial.source)


def _poseable(seen: np.ndarray, model: "SubjectModel") -> np.ndarray:
    """Frames (F,) bool whose seen markers (F, M) can pose the model: at least
    :data:`MIN_PELVIS_MARKERS` on the pelvis and :data:`MIN_MARKERS` in all."""
    return ((seen[:, model.marker_segments == _ROOT].sum(axis=1) >= MIN_PELVIS_MARKERS)
            & (seen.sum(axis=1) >= MIN_MARKERS))


def _coarse_start(model: "SubjectModel", markers: np.ndarray, settings: dict
                  ) -> tuple[np.ndarray, tuple]:
    """Start poses (F, D) for markers (F, M, 3) and their ``step_metric``: the
    :func:`keyframes` solved from per-segment rigid fits, the other frames predicted from them
    (:func:`_predict_between`)."""
    keys = keyframes(markers)
    q0 = initial_pose(model.skeleton, markers[keys], model.marker_segments,
                      model.marker_offsets)
    q0[:, ~settings["free"]] = 0.0
    first = solve_poses(model.skeleton, markers[keys], model.marker_segments,
                        model.marker_offsets, q0=q0, **settings)
    return _predict_between(model, markers, keys, first.q, settings)


def _warm_start(model: "SubjectModel", markers: np.ndarray, settings: dict, q0: np.ndarray
                ) -> tuple[np.ndarray, tuple | None]:
    """Start poses (F, D) for markers (F, M, 3) near poses ``q0`` (F, D) (a previous fit of the
    same frames, such as :func:`fit_filtered`'s raw pass), and their ``step_metric``.

    Where :func:`keyframes` lie more than :data:`STRIDE` frames apart (markers moving along
    straight lines: a still or slow stretch), the keyframes bounding those spans are solved from
    ``q0`` and the frames between start from their predictions (:func:`_predict_between`), which
    stop most of them after one check; every other frame starts from ``q0``.
    """
    keys = keyframes(markers)
    sparse = np.flatnonzero(np.diff(keys) > LONGEST_STRIDE // 2)
    if sparse.size == 0:
        return q0, None
    ends = distinct(np.r_[keys[sparse], keys[sparse + 1]])
    solved = solve_poses(model.skeleton, markers[ends], model.marker_segments,
                         model.marker_offsets, q0=q0[ends], **settings)
    start, (inverse, owner) = _predict_between(model, markers, ends, solved.q, settings)
    inside = np.zeros(len(markers) + 1, dtype=int)
    np.add.at(inside, keys[sparse], 1)
    np.add.at(inside, keys[sparse + 1] + 1, -1)
    outside = np.cumsum(inside)[:-1] == 0
    start[outside] = q0[outside]
    owner[outside] = -1
    return start, (inverse, owner)


def _predict_between(model: "SubjectModel", markers: np.ndarray, keys: np.ndarray,
                     q_keys: np.ndarray, settings: dict) -> tuple[np.ndarray, tuple]:
    """Poses (F, D) for markers (F, M, 3) from solved keyframes ``keys`` (K,) with poses
    ``q_keys`` (K, D): each frame's pose is the Gauss–Newton step its markers ask of each of its
    two keyframes (their normal equations, solved once), blended linearly in time; and the
    ``step_metric`` of :func:`solve_poses` for them (the keyframes' inverse normal matrices).

    Exact where the model is linear between keyframes (a still or slow subject), so such frames
    start at their minimum and stop after one check; where a prediction strays more than
    :data:`PREDICTION_LIMIT` from the plain interpolation of the keyframe poses, that is used.
    """
    skeleton, segments = model.skeleton, model.marker_segments
    n = len(markers)
    free = settings["free"]
    chain = skeleton.chain(q_keys)
    twist, origin = twists(chain)
    about = _points(chain[0], _marker_map(segments, model.marker_offsets)) - origin[:, :, None]
    valid = _seen(markers)
    target = np.where(valid[:, None], markers.transpose(0, 2, 1), 0.0)
    moved = MOVES[segments].astype(np.float64)
    r = target[keys] - about - origin[:, :, None]
    w = valid[keys] * settings["weights"] * _soft_l1_weight(_norm3(r), settings["robust_scale"])
    A = _normal_equations(twist, about, moved, r, w)[0]
    A[:, np.arange(len(free)), np.arange(len(free))] += settings["smoothing"] ** 2 + 1e-9
    A[:, ~free] = A[:, :, ~free] = 0.0
    A[:, ~free, ~free] = 1.0
    inverse = np.linalg.inv(A)
    jacobian = twist_jacobian(twist, about, moved).reshape(len(keys), -1, len(free))  # (K, 3M, D)
    jacobian[..., ~free] = 0.0
    at_key = about + origin[:, :, None]
    after, alpha = _bracket(keys, n)
    plain = (1.0 - alpha)[:, None] * q_keys[after - 1] + alpha[:, None] * q_keys[after]
    q = np.zeros_like(plain)
    edges = np.r_[0, np.flatnonzero(np.diff(after)) + 1, n]
    for start, stop in zip(edges[:-1], edges[1:]):          # the frames between two keyframes
        span = slice(start, stop)
        for key, share in ((after[start] - 1, 1.0 - alpha[span]), (after[start], alpha[span])):
            wr = (target[span] - at_key[key]) * np.where(valid[span], w[key], 0.0)[:, None]
            step = (wr.reshape(stop - start, -1) @ jacobian[key]) @ inverse[key].T
            q[span] += share[:, None] * (q_keys[key] + step)
    stray = np.abs(q - plain).max(axis=1) > PREDICTION_LIMIT
    q[stray] = plain[stray]
    # the nearest keyframe's matrix measures a frame's next step if it sees the same markers
    owner = np.where(alpha < 0.5, after - 1, after)
    owner[stray | (valid != valid[keys[owner]]).any(axis=1)] = -1
    return np.clip(q, _LOWER, _UPPER), (inverse, owner)


def keyframes(markers: np.ndarray, *, longest: int = LONGEST_STRIDE,
              shortest: int = STRIDE, tolerance: float = KEY_TOLERANCE) -> np.ndarray:
    """Frames (K,) to solve first: every ``longest``-th frame and the last, with intervals
    halved down to ``shortest`` frames while a marker between their ends leaves the straight
    line between its positions there by more than ``tolerance`` metres (or is seen there but
    not at an end). Markers (F, M, 3), NaN where missing."""
    n = len(markers)
    keys = distinct(np.r_[np.arange(0, n, longest), n - 1])
    gap = longest
    seen = np.isfinite(markers[:, :, 0])
    while gap > shortest and len(keys) < n:
        after, alpha = _bracket(keys, n)
        alpha = alpha[:, None, None]
        line = (1 - alpha) * markers[keys[after - 1]] + alpha * markers[keys[after]]
        d = markers - line
        off = d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2   # NaN if unseen here or at an end
        split = np.zeros(len(keys), dtype=bool)
        split[after[(seen & ~(off <= tolerance ** 2)).any(axis=1)]] = True
        if not split.any():                    # the same lines again at the next level
            break
        mid = (keys[:-1] + keys[1:]) // 2
        keys = distinct(np.r_[keys, mid[split[1:] & (keys[1:] - keys[:-1] > 1)]])
        gap //= 2
    return keys


def find_repairs(skeleton: Skeleton, markers: np.ndarray, segments: np.ndarray,
                 offsets: np.ndarray, labels: list[str], fitted: PoseFit, **settings
                 ) -> list[Repair]:
    """The exchanged labels in a fit of markers (F, M, 3) (``labels`` (M,), the model's
    ``segments`` (M,) and ``offsets`` (M, 3), ``fitted`` its poses and residuals), as
    :class:`Repair` s of kind ``"swap"``.

    Any two markers (left/right, front/back, neighbours on one segment) are candidates when
    both are suspect (:func:`suspect_threshold`) in the same frames and exchanging them would
    bring them nearer their model positions (a hint only: two exchanged markers drag the pose
    of their segment); those frames are fitted again without the two, and the swap is kept
    where each then lies nearer the other's place (:data:`SWAP_RATIO`), in stretches of
    :data:`SWAP_MIN_FRAMES` frames or more, each grown while the two trajectories keep to
    their own paths (:func:`_whole_swap`). A pair is only judged when, without it, each of its
    segments keeps two markers on it or below it (otherwise the fit cannot place them: the
    two wrist markers of Plug-in Gait's forearm, which turn with its twist).
    ``settings`` go to :func:`solve_poses`.
    """
    r = fitted.residuals
    suspect = r > suspect_threshold(r)
    if suspect.sum() < 2 * SWAP_MIN_FRAMES:
        return []
    model = skeleton.points(fitted.q, segments, offsets)
    together = suspect.T.astype(np.int64) @ suspect.astype(np.int64)
    candidates = []
    first, second = np.nonzero(np.triu((together >= SWAP_MIN_FRAMES)
                                       & _placed_without(segments), 1))
    frames = np.flatnonzero(suspect.any(axis=1))
    x, at, rf = markers[frames], model[frames], r[frames]
    # (frames, pairs): both suspect, and each nearer the other's place (the pose may be
    # dragged: a hint)
    hint = (suspect[frames][:, first] & suspect[frames][:, second]
            & (_norm_rows(x[:, first] - at[:, second]) + _norm_rows(x[:, second] - at[:, first])
               < rf[:, first] + rf[:, second]))
    for p in np.flatnonzero(hint.sum(axis=0) >= SWAP_MIN_FRAMES):
        rows = frames[hint[:, p]]
        candidates.append((len(rows), first[p], second[p], rows))
    out: list[Repair] = []
    taken = np.zeros_like(suspect)
    for _, i, j, rows in sorted(candidates, key=lambda c: -c[0])[:SWAP_PAIRS]:
        rows = rows[~taken[rows, i] & ~taken[rows, j]]
        if len(rows) < SWAP_MIN_FRAMES:
            continue
        without = markers[rows].copy()
        without[:, [i, j]] = np.nan
        again = skeleton.points(solve_poses(skeleton, without, segments, offsets,
                                            q0=fitted.q[rows], **settings).q, segments, offsets)
        own = (_norm_rows(markers[rows, i] - again[:, i])
               + _norm_rows(markers[rows, j] - again[:, j]))
        other = (_norm_rows(markers[rows, i] - again[:, j])
                 + _norm_rows(markers[rows, j] - again[:, i]))
        swapped = np.zeros(len(r), dtype=bool)
        swapped[rows[other < SWAP_RATIO * own]] = True
        stretches = []
        for start, stop in _bridged_runs(swapped, SWAP_BRIDGE):
            inside = (rows >= start) & (rows < stop) & (other < SWAP_RATIO * own)
            if inside.sum() >= SWAP_MIN_FRAMES:
                stretches.append((*_whole_swap(markers[:, i], markers[:, j], start, stop),
                                  inside))
        for start, stop, inside in _merged(stretches):
            taken[start:stop, [i, j]] = True
            out.append(Repair("swap", (labels[i], labels[j]), int(start), int(stop),
                              f"each lay {500 * median(own[inside]):.0f} mm from its model "
                              f"place and {500 * median(other[inside]):.0f} mm from the "
                              f"other's (median of {int(inside.sum())} frames)"))
    return out


def _placed_without(segments: np.ndarray) -> np.ndarray:
    """(M, M) bool, True at (i, j) when the segments of markers ``i`` and ``j`` (``segments``
    (M,)) each keep two other markers on them or below them: a fit without the two still
    places them."""
    first = [DOF_NAMES.index(SEGMENTS[s].dofs[0]) for s in segments]
    below = MOVES[segments][:, first]          # (M, M): marker m on or below marker k's segment
    # markers on or below i's segment other than i and j (i's own always counts)
    left = (below.sum(axis=0) - 1)[:, None] - below.T
    np.fill_diagonal(left, 0)
    return (left >= 2) & (left.T >= 2)


def _whole_swap(a: np.ndarray, b: np.ndarray, start: int, stop: int) -> tuple[int, int]:
    """The stretch ``[start, stop)`` where trajectories ``a`` and ``b`` (F, 3) are found
    exchanged, grown frame by frame while each trajectory continues its own path better than
    the other's (a label exchange begins and ends where they cross over; frames where the fit
    cannot tell, a segment's other markers missing, are taken with it)."""
    def grows(frame, ref_a, ref_b):
        pairs = [(p, own, other) for p, own, other in ((a[frame], ref_a, ref_b),
                                                        (b[frame], ref_b, ref_a))
                 if np.isfinite(p).all()]
        straight = sum(np.linalg.norm(p - own) for p, own, _ in pairs)
        crossed = sum(np.linalg.norm(p - other) for p, _, other in pairs)
        return not pairs or straight < crossed

    for step, edge in ((-1, start), (1, stop - 1)):
        ref_a, ref_b = a[edge], b[edge]
        frame = edge + step
        while 0 <= frame < len(a) and np.isfinite(ref_a).all() and np.isfinite(ref_b).all() \
                and grows(frame, ref_a, ref_b):
            ref_a = a[frame] if np.isfinite(a[frame]).all() else ref_a
            ref_b = b[frame] if np.isfinite(b[frame]).all() else ref_b
            frame += step
        if step < 0:
            start = frame + 1
        else:
            stop = frame
    seen = np.flatnonzero(np.isfinite(a[start:stop, 0]) | np.isfinite(b[start:stop, 0]))
    return start + int(seen[0]), start + int(seen[-1]) + 1


def _merged(stretches: list) -> list:
    """(start, stop, inside) stretches with those that overlap merged (``inside`` or-ed)."""
    out: list = []
    for start, stop, inside in sorted(stretches, key=lambda x: x[0]):
        if out and start <= out[-1][1]:
            out[-1] = (out[-1][0], max(stop, out[-1][1]), out[-1][2] | inside)
        else:
            out.append((start, stop, inside))
    return out


def _norm_rows(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of ``v`` (N, 3); NaN where a coordinate is."""
    return np.sqrt((v ** 2).sum(axis=-1))


def _bridged_runs(mask: np.ndarray, bridge: int) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in ``mask`` (F,), holes of up to ``bridge`` frames
    between two runs filled."""
    runs: list[list[int]] = []
    for start, stop in valid_runs(mask):
        if runs and start - runs[-1][1] <= bridge:
            runs[-1][1] = stop
        else:
            runs.append([start, stop])
    return [(a, b) for a, b in runs]


def far_markers(residuals: np.ndarray, labels: list[str]) -> list[Repair]:
    """Markers whose median residual (F, M) stays above :data:`OUTLIER_LIMIT` over at least
    :data:`SWAP_MIN_FRAMES` frames, as :class:`Repair` s of kind ``"drop"`` over the frames."""
    out = []
    seen = np.isfinite(residuals)
    typical = nanmedian(residuals, axis=0)
    for m in np.flatnonzero((typical > OUTLIER_LIMIT) & (seen.sum(axis=0) >= SWAP_MIN_FRAMES)):
        frames = np.flatnonzero(seen[:, m])
        out.append(Repair("drop", (labels[m],), int(frames[0]), int(frames[-1]) + 1,
                          f"it stays {1000 * typical[m]:.0f} mm from its model place (median of "
                          f"{len(frames)} frames)"))
    return out


def _undo_labelling_errors(solve, res: PoseFit, markers: np.ndarray, model: "SubjectModel",
                           settings: dict) -> tuple[PoseFit, np.ndarray, list[Repair]]:
    """Find exchanged labels (:func:`find_repairs`), then markers far from their place
    (:func:`far_markers`), in a fit ``res`` of ``markers`` (F, M, 3); undo them and fit again
    (``solve(markers, q0)``). Returns the fit, the repaired markers and the repairs."""
    repairs = find_repairs(model.skeleton, markers, model.marker_segments,
                           model.marker_offsets, model.labels, res, **settings)
    if repairs:
        markers = apply_repairs(markers, model.labels, repairs)
        res = solve(markers, res.q)
    dropped = far_markers(res.residuals, model.labels)
    if dropped:
        markers = apply_repairs(markers, model.labels, dropped)
        res = solve(markers, res.q)
    return res, markers, repairs + dropped


def fit_filtered(trial: "Trial", model: "SubjectModel", /, *, cutoff: float | str | None,
                 **options) -> tuple[Motion, float | None]:
    """Fit ``trial``'s markers low-passed at ``cutoff`` (Hz, "auto" or None), outliers first.

    A low-pass filter turns a jumping trajectory into a ramp the jump rule cannot see, so
    labelling errors and outlying samples are found on the raw markers (a :func:`fit` of
    ``trial``, stopped by :data:`OUTLIER_PASS`'s looser rule unless ``options`` give one),
    undone and gapped, and the model's markers are filtered
    (:func:`mocaplib.model.filtering.filter_trial`, gap-aware; "auto" judges the cutoff on them) and
    fitted again, starting from the raw fit's poses low-passed at the same cutoff. The motion's
    ``rejected`` holds the samples removed by either fit, its ``repairs`` those of both. Returns
    the motion and the cutoff used (None: unfiltered, one fit). ``options`` go to :func:`fit`.
    """
    from .filtering import filter_trial, lowpass

    if cutoff is None or cutoff == "none":
        return fit(trial, model, **options), None
    raw = fit(trial, model, **{**OUTLIER_PASS, **options})
    # only the model's markers are filtered and fitted again (the filter treats each marker
    # on its own): a file's other points (virtual points, other subjects) cost nothing
    columns = _trial_columns(trial, model)
    found = columns >= 0
    labels = [label for label, f in zip(model.labels, found) if f]
    markers = apply_repairs(trial.markers[:, columns[found]], labels, raw.repairs)
    frames, m = np.nonzero(raw.rejected[:, found])
    markers[frames, m] = np.nan
    cleaned, used = filter_trial(replace(trial, markers=markers, labels=[
        trial.labels[c] for c in columns[found]], warnings=list(trial.warnings)), cutoff=cutoff)
    # the raw fit low-passed like the markers is the warm start: closer to the filtered poses
    start = raw.q if used is None else lowpass(np.unwrap(raw.q, axis=0), trial.rate, used)
    motion = fit(cleaned, model, q0=start, **options)
    motion.rejected |= raw.rejected & ~motion.failed[:, None]
    motion.residuals[motion.rejected] = np.nan
    motion.repairs = raw.repairs + motion.repairs
    return motion, used


def _trial_columns(trial: "Trial", model: "SubjectModel") -> np.ndarray:
    """The trial's marker column (M,) of each model marker (-1 when absent), as
    :func:`model_markers` reads them."""
    match = label_match(trial, model.protocol)   # the fit repairs swaps
    return np.array([match.indices[model.protocol.labels.index(label)]
                     for label in model.labels], dtype=int)


def suspect_threshold(residuals: np.ndarray) -> np.ndarray:
    """Per-marker residual (M,) above which a sample is suspect, metres: median +
    :data:`OUTLIER_MADS` robust standard deviations (1.4826 MAD) of that marker's residuals
    (F, M) over the frames where it is seen, at least :data:`SUSPECT_FLOOR` and at most
    :data:`OUTLIER_LIMIT`."""
    typical = nanmedian(residuals, axis=0)
    limit = typical + OUTLIER_MADS * 1.4826 * nanmedian(np.abs(residuals - typical), axis=0)
    return np.clip(np.where(np.isfinite(limit), limit, SUSPECT_FLOOR), SUSPECT_FLOOR,
                   OUTLIER_LIMIT)


def _reject_outliers(res: PoseFit, markers: np.ndarray, model: "SubjectModel",
                     **settings) -> np.ndarray:
    """Remove outlying samples from a fit (updated in place); returns the removed (F, M).

    Suspect samples (residual above :func:`suspect_threshold`) in runs that jump
    (:func:`jumping_runs`) are taken out and their frames fitted again; a suspect still beyond
    :data:`OUTLIER_LIMIT` from that pose is removed, the others are put back and the frame
    fitted once more with them if any was.
    """
    limit = OUTLIER_LIMIT
    suspect = res.residuals > suspect_threshold(res.residuals)
    if suspect.any():
        error = markers - model.skeleton.points(res.q, model.marker_segments,
                                                model.marker_offsets)
        suspect = jumping_runs(error, suspect)
    if not suspect.any():
        return suspect
    removed = suspect.copy()
    for _ in range(2):
        rows = np.flatnonzero(suspect.any(axis=1))
        kept = np.where(removed[rows, :, None], np.nan, markers[rows])
        again = solve_poses(model.skeleton, kept, model.marker_segments, model.marker_offsets,
                            q0=res.q[rows], **settings)
        distance = np.linalg.norm(markers[rows] - model.skeleton.points(
            again.q, model.marker_segments, model.marker_offsets), axis=2)
        res.q[rows], res.converged[rows] = again.q, again.converged
        res.residuals[rows] = np.where(removed[rows], np.nan, distance)
        back = removed[rows] & ~(distance > limit)
        if not back.any():
            break
        removed[rows] &= ~back          # put back what was only off because of the pose
        suspect = np.zeros_like(suspect)
        suspect[rows] = back
    return removed


def jumping_runs(error: np.ndarray, suspect: np.ndarray) -> np.ndarray:
    """The runs of ``suspect`` (F, M) bool that begin or end with a jump, (F, M) bool.

    ``error`` (F, M, 3): marker minus model position, NaN where missing. A run of consecutive
    suspect frames of one marker is kept when its residual vector changes by more than
    :data:`JUMP` between two consecutive frames within 2 frames of its start or end, or when
    it starts or ends at a gap or the capture's edge (its onset is unseen). A marker suspect in
    half of the frames where it is seen or more is not an outlier but misplaced or misfitted
    (a calibration matter): its samples are all kept.
    """
    step = np.linalg.norm(np.diff(error, axis=0), axis=2)        # (F-1, M); NaN at gaps
    jump = np.where(np.isnan(step), np.inf, step) > JUMP
    n = len(suspect)
    out = np.zeros_like(suspect)
    seen = np.isfinite(error[..., 0]).sum(axis=0)
    for m in np.flatnonzero((suspect.sum(axis=0) > 0) & (suspect.sum(axis=0) < 0.5 * seen)):
        for start, stop in valid_runs(suspect[:, m]):
            near = np.r_[max(start - 3, 0):min(start + 2, n - 1),
                         max(stop - 3, 0):min(stop + 2, n - 1)]
            if start == 0 or stop == n or jump[near, m].any():
                out[start:stop, m] = True
    return out


def _restart_outliers(solve, first: PoseFit) -> PoseFit:
    """Re-solve frames stuck in a wrong minimum, starting from their neighbours' solution.

    A frame whose marker RMS exceeds :data:`RESTART_FACTOR` times the median (and 15 mm) gets
    the pose interpolated from the other frames as a new start; each frame keeps whichever
    solution has the smaller marker RMS.
    """
    rms = _frame_rms(first.residuals)
    suspect = rms > max(RESTART_FACTOR * nanmedian(rms), 0.015)
    if not suspect.any() or suspect.all():
        return first
    start = first.q.copy()
    start[suspect] = np.nan
    second = solve(q0=_fill_gaps(start))
    better = _frame_rms(second.residuals) < rms
    for name in ("q", "residuals", "converged"):
        getattr(first, name)[better] = getattr(second, name)[better]
    return first


def _frame_rms(residuals: np.ndarray) -> np.ndarray:
    """RMS of each row of residuals (F, M) over its seen entries, shape (F,); +inf if none."""
    seen = np.isfinite(residuals)
    total = np.where(seen, residuals, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(seen.any(axis=1), np.sqrt(total.sum(axis=1) / seen.sum(axis=1)), np.inf)


def fit_quality(motion: Motion) -> dict:
    """Fit quality in millimetres, as the CLI prints it.

    ``marker_rms_mm``: mean over frames of each frame's marker RMS (OpenSim's "marker error
    RMS", averaged); ``max_marker_error_mm``: the largest residual of any marker in any frame;
    ``per_marker_rms_mm``: each marker's RMS over the capture; ``locked_dofs``;
    ``held_dofs``: those the markers cannot see (:attr:`Motion.unobservable`) with the
    standard deviation they would have had, degrees; ``at_limit``: the share of frames each
    DOF that reaches a joint limit spends there;
    ``failed_frames``: indices of frames that could not be fitted; ``rejected_samples``:
    samples removed as outliers (not in the residual figures), ``rejected_per_marker``: their
    count per marker label (markers with any); ``repairs``: the labelling errors undone
    (:meth:`mocaplib.model.motion.Repair.as_dict`).
    """
    frame_rms = _frame_rms(motion.residuals)
    marker_rms = _frame_rms(motion.residuals.T)
    marker_rms[np.isinf(marker_rms)] = np.nan
    return {
        "marker_rms_mm": float(np.mean(frame_rms[np.isfinite(frame_rms)]) * 1000),
        "max_marker_error_mm": float(np.nanmax(motion.residuals) * 1000),
        "per_marker_rms_mm": {label: float(v * 1000)
                              for label, v in zip(motion.marker_labels, marker_rms)},
        "locked_dofs": list(motion.locked_dofs),
        "held_dofs": {k: float(np.degrees(v)) for k, v in motion.unobservable.items()},
        "at_limit": motion.limit_shares(),
        "failed_frames": np.flatnonzero(motion.failed).tolist(),
        "rejected_samples": int(motion.rejected.sum()),
        "repairs": [r.as_dict(motion.rate) for r in motion.repairs],
        "rejected_per_marker": {label: int(n) for label, n in
                                zip(motion.marker_labels, motion.rejected.sum(axis=0)) if n},
    }


def model_markers(trial: "Trial", model: "SubjectModel") -> np.ndarray:
    """The trial's markers in the model's order, shape (F, M, 3), NaN where absent (as
    labelled: :func:`fit` undoes the labelling errors it finds)."""
    match = label_match(trial, model.protocol)   # the fit repairs swaps
    order = [model.protocol.labels.index(label) for label in model.labels]
    found = sum(match.indices[j] >= 0 for j in order)
    if found == 0:
        raise FitError(f"none of the model's markers ({', '.join(model.labels[:8])}...) is in "
                       "the trial", path=trial.source,
                       hint=f"calibrate with the trial's protocol, not {model.protocol.name!r}")
    return match.markers(trial)[:, order]
