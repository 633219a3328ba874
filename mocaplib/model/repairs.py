"""Labelling errors and outliers found while fitting: two markers whose labels are exchanged
(for the whole capture or a stretch of it) exchanged back, a marker that stays far from its
place left out (:func:`find_repairs`), and samples of a trajectory that jumps away from the
model removed (:func:`jumping_runs`).

Markers are ``(F, M, 3)`` arrays in metres (NaN where unseen), model marker positions the
same shape; residuals ``(F, M)`` metres.
"""

from __future__ import annotations

import numpy as np

from ..numeric import median, nanmedian
from ..runs import valid_runs
from ..skeleton import DOF_NAMES, MOVES, SEGMENTS, Skeleton
from .motion import Repair, apply_repairs
from .solver import RESTART_FACTOR, PoseFit, fill_gaps, frame_rms, solve_poses
from .subject import SubjectModel

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


def undo_labelling_errors(solve, res: PoseFit, markers: np.ndarray, model: "SubjectModel",
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


def suspect_threshold(residuals: np.ndarray) -> np.ndarray:
    """Per-marker residual (M,) above which a sample is suspect, metres: median +
    :data:`OUTLIER_MADS` robust standard deviations (1.4826 MAD) of that marker's residuals
    (F, M) over the frames where it is seen, at least :data:`SUSPECT_FLOOR` and at most
    :data:`OUTLIER_LIMIT`."""
    typical = nanmedian(residuals, axis=0)
    limit = typical + OUTLIER_MADS * 1.4826 * nanmedian(np.abs(residuals - typical), axis=0)
    return np.clip(np.where(np.isfinite(limit), limit, SUSPECT_FLOOR), SUSPECT_FLOOR,
                   OUTLIER_LIMIT)


def reject_outliers(res: PoseFit, markers: np.ndarray, model: "SubjectModel",
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


def restart_outliers(solve, first: PoseFit) -> PoseFit:
    """Re-solve frames stuck in a wrong minimum, starting from their neighbours' solution.

    A frame whose marker RMS exceeds :data:`RESTART_FACTOR` times the median (and 15 mm) gets
    the pose interpolated from the other frames as a new start; each frame keeps whichever
    solution has the smaller marker RMS.
    """
    rms = frame_rms(first.residuals)
    suspect = rms > max(RESTART_FACTOR * nanmedian(rms), 0.015)
    if not suspect.any() or suspect.all():
        return first
    start = first.q.copy()
    start[suspect] = np.nan
    second = solve(q0=fill_gaps(start))
    better = frame_rms(second.residuals) < rms
    for name in ("q", "residuals", "converged"):
        getattr(first, name)[better] = getattr(second, name)[better]
    return first
