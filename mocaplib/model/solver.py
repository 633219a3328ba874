"""The pose solver: batched, robust, bounded Levenberg–Marquardt over many frames at once
(:func:`solve_poses`), and the starting poses from rigid fits of each segment's markers
(:func:`initial_pose`). The objective and the method are described in :mod:`mocaplib.model.ik`.

Arrays: poses ``q`` (F, D) radians and metres in :data:`mocaplib.skeleton.DOF_NAMES` order,
markers ``(F, M, 3)`` metres (NaN where unseen).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..skeleton import (DOF_NAMES, DOFS, LEVELS, MOVES, ROOT_HEADING, SEGMENT_NAMES, SEGMENTS,
                        SHIFTS, Skeleton, cross_rows, elementary_rotations, twists)
from .filtering import resample

#: Soft-L1 scale c, metres: residuals above it count linearly (soft tissue moves markers 5-20 mm).
ROBUST_SCALE = 0.02


#: Continuity weight μ, metres per radian (per metre for translations).
SMOOTHING = 0.01


#: Frames with a marker RMS above this many times the median are re-solved from neighbours.
RESTART_FACTOR = 3.0


LOWER, UPPER = Skeleton.bounds()


ROOT_SEGMENT = SEGMENT_NAMES.index("pelvis")


#: (D, D) for :func:`normal_equations`: 1 where DOF i moves the segment of DOF j (j's markers
#: are a subset of i's). Parents' DOFs come first, so above the diagonal it holds every pair
#: that shares markers.
ANCESTOR = MOVES[[SEGMENT_NAMES.index(d.segment) for d in DOFS]].T.astype(np.float64)


#: :data:`ANCESTOR` above the diagonal, halved on it: ``B + Bᵀ`` of ``B = A * _HALF_UPPER`` is
#: the symmetric matrix of A's upper triangle, to the bit (halving and doubling are exact).
_HALF_UPPER = np.triu(ANCESTOR) - 0.5 * np.diag(np.diag(ANCESTOR))


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
    valid = seen_points(markers)
    target = np.where(valid[:, None], markers.transpose(0, 2, 1), 0.0)          # (F, 3, M)
    w_marker = np.ones((n_frames, n_markers)) if weights is None else np.broadcast_to(
        np.asarray(weights, float), (n_frames, n_markers))
    w_marker = np.where(valid, w_marker, 0.0)
    q = initial_pose(skeleton, markers, segments, offsets) if q0 is None else np.array(q0, float)
    q = np.clip(q, LOWER, UPPER)
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
    marker_map = marker_matrix(segments, offsets)
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
        pts = marker_points(chain[0], marker_map)
        return objective(vector_lengths(target[rows] - pts), rows, q_rows, q_ref), chain, pts

    chains = list(skeleton.chain(q))        # transforms, DOF axes and pivots at the current q
    pts = marker_points(chains[0], marker_map)    # (F, 3, M), markers at the current q
    inverse, owner = step_metric if step_metric is not None else (None, np.full(n_frames, -1))
    rows = np.flatnonzero((owner >= 0) & _interior(q, free))
    if rows.size:
        every = rows.size == n_frames                # then no copies of the big arrays
        twist, origin = twists(chains if every else tuple(c[rows] for c in chains))
        about = (pts if every else pts[rows]) - origin[:, :, None]
        r = (target if every else target[rows]) - (pts if every else pts[rows])
        g = descent(twist, about, r, w_marker[rows] * soft_l1_weight(vector_lengths(r), robust_scale),
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
        d = vector_lengths(r)
        w = w_marker[rows] * soft_l1_weight(d, robust_scale)              # IRLS weights
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
        A, g = normal_equations(twist, about, moved, r, w)
        g -= mu2 * (qa - q_ref)
        # the continuity term's curvature counted twice: the step also stays near the current
        # pose (a proximal term, no change to the minimum). Every frame moves towards its
        # neighbours' mean while they move towards its own: with the curvature counted once,
        # a DOF the markers hardly see (ankle inversion on a heel-toe foot) jumps back and
        # forth between two frames without end; twice, it settles.
        A[diagonal] += 2 * mu2
        # locked DOFs, and DOFs on a bound whose gradient points outwards, leave the step
        held = (~free | ((qa <= LOWER + 1e-12) & (g < 0)) | ((qa >= UPPER - 1e-12) & (g > 0)))
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
            trial_q = np.clip(qa[k] + step, LOWER, UPPER)
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
        pts[rough] = marker_points(skeleton.chain(q[rough])[0], marker_map)
    residuals = vector_lengths(markers.transpose(0, 2, 1) - pts)
    return PoseFit(q, residuals, ~active, iterations)


def _interior(q: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Frames (n,) bool of poses ``q`` (n, D) whose ``free`` (D,) DOFs are all off their
    joint bounds."""
    return (((q > LOWER + 1e-12) & (q < UPPER - 1e-12)) | ~free).all(axis=1)


def _projected(q: np.ndarray, step: np.ndarray) -> np.ndarray:
    """``step`` (n, D) from poses ``q`` (n, D) cut to the joint bounds."""
    return np.clip(q + step, LOWER, UPPER) - q


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


def marker_matrix(segments: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(4S, M) matrix taking the rows ``[R | t]`` of every segment transform to the points
    fixed at ``offsets`` (M, 3) in ``segments`` (M,): see :func:`marker_points`."""
    n = len(segments)
    out = np.zeros((len(SEGMENTS), 4, n))
    out[segments, :3, np.arange(n)] = offsets
    out[segments, 3, np.arange(n)] = 1.0
    return out.reshape(-1, n)


def marker_points(transforms: np.ndarray, marker_map: np.ndarray) -> np.ndarray:
    """Points (F, 3, M) (coordinates on axis 1) from the segment transforms (F, S, 4, 4) of
    :meth:`~mocaplib.skeleton.Skeleton.chain` and :func:`marker_matrix`: one matrix product."""
    n, s = transforms.shape[:2]
    rows = transforms[:, :, :3, :].transpose(0, 2, 1, 3).reshape(n * 3, s * 4)
    return (rows @ marker_map).reshape(n, 3, marker_map.shape[1])


def seen_points(points: np.ndarray) -> np.ndarray:
    """Points (..., 3) whose three coordinates are finite, bool (...): as
    ``np.isfinite(points).all(axis=-1)``, without its slow reduction over a short axis."""
    return np.isfinite(points[..., 0]) & np.isfinite(points[..., 1]) & np.isfinite(points[..., 2])


def vector_lengths(v: np.ndarray) -> np.ndarray:
    """Lengths (F, M) of vectors (F, 3, M)."""
    return np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2 + v[:, 2] ** 2)


def normal_equations(twist: np.ndarray, p: np.ndarray, moved: np.ndarray, r: np.ndarray,
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
    origin, ``r`` (F, 3, M) and ``w`` (F, M) as in :func:`normal_equations`."""
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


def soft_l1_weight(d: np.ndarray, c: float) -> np.ndarray:
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
            R, t, ok = rigid_fits(local, world)
            rel = R
            q[:, SHIFTS] = t[:, 0]
        else:
            R_parent = rot[:, parents]
            centre = (R_parent @ joint[segs, :, None])[..., 0] + pos[:, parents]
            world[:, :, -1] = centre                          # its local position: zero
            R, _, ok = rigid_fits(local, world)
            rel = np.swapaxes(R_parent, -1, -2) @ R
        q[:, spins] = _joint_angles(rel, *euler)
        for row in np.flatnonzero(~ok.all(axis=0)):
            q[np.ix_(~ok[:, row], dofs[row])] = np.nan
        cols = np.concatenate(dofs)
        q[:, cols] = fill_gaps(q[:, cols])
        local_rot = elementary_rotations(q[:, :-1])
        R = R_parent
        for j in spins.T:
            R = R @ local_rot[:, j]
        rot[:, segs] = R
        pos[:, segs] = q[:, None, SHIFTS] if parents is None else centre
    q = q[:, :-1]
    q[:, ROOT_HEADING] = np.unwrap(q[:, ROOT_HEADING])
    return np.clip(q, LOWER, UPPER)


def rigid_fits(local: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rigid fits ``world ≈ R @ local + t`` per frame (and per set) over the finite points.

    local (..., N, 3); world (F, ..., N, 3) with NaN where missing. Returns R (F, ..., 3, 3),
    t (F, ..., 3) and ok (F, ...): at least three points and a non-degenerate spread.
    """
    valid = seen_points(world)
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


def bracket_keys(keys: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """For every frame of ``range(n_frames)``, the index (F,) in ``keys`` (K,) (sorted, from 0 to
    n_frames - 1) of the key after it (the one before for the last) and its position (F,) from
    the key before (0) to that one (1)."""
    frames = np.arange(n_frames)
    after = np.clip(np.searchsorted(keys, frames, side="right"), 1, len(keys) - 1)
    return after, (frames - keys[after - 1]) / np.maximum(keys[after] - keys[after - 1], 1)


def fill_gaps(values: np.ndarray) -> np.ndarray:
    """Linearly interpolate NaN rows over time per column (0 where a column is all NaN)."""
    if not np.isnan(values).any():
        return values.copy()
    return np.nan_to_num(resample(values, 1.0, np.arange(len(values))), nan=0.0)


def frame_rms(residuals: np.ndarray) -> np.ndarray:
    """RMS of each row of residuals (F, M) over its seen entries, shape (F,); +inf if none."""
    seen = np.isfinite(residuals)
    total = np.where(seen, residuals, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(seen.any(axis=1), np.sqrt(total.sum(axis=1) / seen.sum(axis=1)), np.inf)


#: A frame whose last step moved a DOF by less than this many step tolerances checks its next
#: step with that step's matrix before forming new normal equations (:func:`solve_poses`):
#: below it, 35-100 % of such checks stopped the frame in the fits of the samples and of the
#: real files; above, 0-60 %, and a check that fails costs a gradient and a solve.
REUSE_BELOW = 40
