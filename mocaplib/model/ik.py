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
analytic Jacobian come from per-DOF sums of marker moments
(:func:`mocaplib.model.solver.normal_equations`, no (F, M, 3, D) Jacobian is formed) and are
solved as one batched ``numpy.linalg.solve``;
each frame keeps its own damping and stops when its cost stops falling or its next step is
below a tolerance (taken without a trial). :func:`fit` first solves :func:`keyframes` (4 to 32
frames apart, closer where markers move less straight) from per-segment rigid fits (Kabsch on
the segment's markers and its joint centre, decomposed into the joint's DOFs); every other
frame starts from the Gauss–Newton step its markers ask of its two keyframes' linearisation,
and where that leaves a step below the tolerance it stops without its own normal equations
(:func:`_predict_between`; still and slow stretches cost one evaluation a frame). Samples of
a trajectory that jumps away from the model (mislabelled, swapped in, glitching) are removed
and counted (:func:`mocaplib.model.repairs.jumping_runs`,
:data:`~mocaplib.model.repairs.OUTLIER_LIMIT`). Before that, labelling errors are undone
(:func:`mocaplib.model.repairs.find_repairs`): two markers whose labels are exchanged, for
the whole capture or a stretch of it, are exchanged back, and a marker that stays far from
its place is left out; each repair is reported (:attr:`Motion.repairs`).

Units: metres and radians. Arrays: time on axis 0.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from ..errors import FitError
from ..markersets.matching import label_match
from ..numeric import distinct
from ..skeleton import DOF_NAMES, MOVES, twist_jacobian, twists
from .filtering import filter_trial, lowpass
from .motion import Motion, Repair, apply_repairs
from .repairs import reject_outliers, restart_outliers, undo_labelling_errors
from .solver import (ANCESTOR, LOWER, ROBUST_SCALE, ROOT_SEGMENT, SMOOTHING, UPPER, bracket_keys,
                     fill_gaps, frame_rms, initial_pose, marker_matrix, marker_points,
                     normal_equations, seen_points, soft_l1_weight, solve_poses, vector_lengths)

if TYPE_CHECKING:
    from ..trial import Trial
    from .subject import SubjectModel

#: A frame with fewer markers on the pelvis, or in all, is flagged as failed. Three place the
#: root segment by its own markers, as a six-DOF segment needs; with two, its turn about the
#: line through them rests on the legs' and trunk's soft tissue (the real walks entering the
#: volume: pelvis tilt at its -45° limit or 10-15° above the frames beside them).
MIN_PELVIS_MARKERS = 3
MIN_MARKERS = 6
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
#: Frames solved together; bounds memory to ~chunk × D² × 8 bytes per normal-matrix array.
CHUNK = 1000
#: The stopping rule of :func:`fit_filtered`'s raw pass, which only finds the outlying samples
#: and starts the filtered fit: it removed the same samples and flagged the same frames as
#: the default rule on the 17 real files and the samples, in 10-40 % less time.
OUTLIER_PASS = {"tol": 1e-3, "step_tol": 2e-3}

assert (np.tril(ANCESTOR, -1) <= ANCESTOR.T).all(), "a DOF listed before its parent's"


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
    trial : Trial with the model's protocol labels (matched as :func:`mocaplib.markersets.matching.label_match` does).
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
    poseable = _poseable(seen_points(markers), model)
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
        res = restart_outliers(solve, solve(q0=start_q, step_metric=metric))
        res, markers[part], found = undo_labelling_errors(
            lambda x, q: solve_poses(model.skeleton, x, model.marker_segments,
                                     model.marker_offsets, q0=q, **settings),
            res, markers[part], model, settings)
        repairs += [replace(r, start=int(part[r.start]), stop=int(part[r.stop - 1]) + 1)
                    for r in found]
        rejected[part] = reject_outliers(res, markers[part], model, **settings)
        q[part], residuals[part], converged[part] = res.q, res.residuals, res.converged
    failed = ~_poseable(np.isfinite(markers[..., 0]) & ~rejected, model) | ~converged
    if failed.all():
        raise FitError(f"no frame could be fitted (each has fewer than {MIN_PELVIS_MARKERS} "
                       f"pelvis markers or {MIN_MARKERS} markers in all)", path=trial.source,
                       hint="check the protocol matches the labels")
    if failed.any():
        residuals[failed] = np.nan
        q[failed] = np.nan
        q = fill_gaps(q)
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
    return ((seen[:, model.marker_segments == ROOT_SEGMENT].sum(axis=1) >= MIN_PELVIS_MARKERS)
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
    about = marker_points(chain[0], marker_matrix(segments, model.marker_offsets)) - origin[:, :, None]
    valid = seen_points(markers)
    target = np.where(valid[:, None], markers.transpose(0, 2, 1), 0.0)
    moved = MOVES[segments].astype(np.float64)
    r = target[keys] - about - origin[:, :, None]
    w = valid[keys] * settings["weights"] * soft_l1_weight(vector_lengths(r), settings["robust_scale"])
    A = normal_equations(twist, about, moved, r, w)[0]
    A[:, np.arange(len(free)), np.arange(len(free))] += settings["smoothing"] ** 2 + 1e-9
    A[:, ~free] = A[:, :, ~free] = 0.0
    A[:, ~free, ~free] = 1.0
    inverse = np.linalg.inv(A)
    jacobian = twist_jacobian(twist, about, moved).reshape(len(keys), -1, len(free))  # (K, 3M, D)
    jacobian[..., ~free] = 0.0
    at_key = about + origin[:, :, None]
    after, alpha = bracket_keys(keys, n)
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
    return np.clip(q, LOWER, UPPER), (inverse, owner)


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
        after, alpha = bracket_keys(keys, n)
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
    per_frame = frame_rms(motion.residuals)
    marker_rms = frame_rms(motion.residuals.T)
    marker_rms[np.isinf(marker_rms)] = np.nan
    return {
        "marker_rms_mm": float(np.mean(per_frame[np.isfinite(per_frame)]) * 1000),
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
