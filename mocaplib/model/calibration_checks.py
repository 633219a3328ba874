"""Checks of a calibration's input, each raising :class:`~mocaplib.errors.CalibrationError` that
names the trial and says what to do: the pelvis is marked and above the feet, the body is
upright and its left and right labels are not exchanged, a static shows the same subject with
the same markers as the motion (:func:`check_same_subject`), and which of several statics shows
a capture's subject (:func:`choose_static`).

Markers are ``(F, M, 3)`` arrays in metres, Z up.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from ..errors import CalibrationError
from ..markersets.matching import label_match
from ..markersets.protocols import Protocol
from ..markersets.sides import forward_cues
from ..numeric import median, nanmedian
from ..skeleton import SEGMENT_NAMES
from ..statics import static_names
from ..trial import Trial
from .ik import MIN_PELVIS_MARKERS
from .joint_centres import segment_distances
from .subject import SubjectModel

#: Largest median difference (m) of within-segment marker distances between a static trial and
#: the motion it calibrates (step 0): 2.5x the largest measured within one real session
#: (2.0 mm), under a third of the smallest measured between two people (17 mm).
SAME_SUBJECT_LIMIT = 0.005


#: Marker pairs closer than this (m) are not compared in step 0 (their ratio is noisy).
MIN_PAIR_DISTANCE = 0.05


#: Step 0 needs at least this many marker pairs seen in both trials; with fewer it is skipped.
MIN_PAIRS = 3


# ----------------------------------------------------------------------------- pieces
def refuse_unmarked_pelvis(cal: Trial, proto: Protocol, n_seen: int) -> None:
    """Raise the error for a trial with fewer than 3 usable pelvis markers, saying whether
    they are not labelled or labelled but missing in most frames."""
    labelled = [label for label in proto.labelled_in(cal)
                if proto.marker(label).landmark.segment == "pelvis"]
    if len(labelled) >= 3:
        raise CalibrationError(
            f"pelvis markers {', '.join(labelled)} are labelled but only {n_seen} of them are "
            f"seen in at least {MIN_PRESENCE:.0%} of the {cal.n_frames} frames; 3 are needed "
            "to place the pelvis", path=cal.source,
            hint="the capture is too short or those markers are missing in most frames: "
                 "check its gaps with `mocaplib inspect`")
    raise CalibrationError(
        f"only {n_seen} pelvis marker(s) of protocol {proto.name!r} are in the trial; "
        "3 are needed to place the pelvis", path=cal.source,
        hint="check the labels against the protocol, or pass --protocol")


def check_upright(X: np.ndarray, segments: np.ndarray, cal: Trial) -> None:
    """Raise :class:`CalibrationError` naming ``cal`` when the pelvis markers of the
    calibration frames ``X`` (F, M, 3) (``segments`` (M,)) lie below the feet's in most frames:
    the file's vertical axis points down (a skeleton fitted upside down turns every joint)."""
    feet = np.isin(segments, [SEGMENT_NAMES.index("foot_l"), SEGMENT_NAMES.index("foot_r")])
    pelvis = segments == SEGMENT_NAMES.index("pelvis")
    if not feet.any() or not len(X):
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # frames without feet: NaN
        height = nanmedian(np.nanmean(X[:, pelvis, 2], axis=1) - np.nanmean(X[:, feet, 2], axis=1))
    if height < 0:
        raise CalibrationError(
            f"the pelvis markers lie {-height * 1000:.0f} mm below the feet's: the "
            "file's vertical axis points down", path=cal.source,
            hint="export the capture with the vertical axis pointing up (Z or Y up)")


def check_sides(X: np.ndarray, landmarks: list[str], cal: Trial) -> None:
    """Raise :class:`CalibrationError` naming ``cal`` when, by every front/back cue its
    landmarks give (two at least: :func:`mocaplib.markersets.sides.forward_cues`, which an exchange
    of sides leaves, Z up), most of its left/right landmark pairs (``landmarks`` (M,) names of
    the calibration frames ``X`` (F, M, 3)) have the left one on the subject's right: the left
    and right labels are exchanged throughout, and a mirrored body would be fitted. One cue
    alone is not trusted: a single exchange of a front and a back label turns it."""
    at = {name: X[:, i] for i, name in enumerate(landmarks)}
    pairs = [(name, "R" + name[1:]) for name in at
             if name.startswith("L_") and "R" + name[1:] in at]
    cues = forward_cues(at, len(X))
    if len(pairs) < 3 or len(cues) < 2:
        return
    counts = []
    for forward in cues:
        left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)         # up x forward
        lateral = np.array([nanmedian(((at[a][:, :2] - at[b][:, :2]) * left).sum(axis=1))
                            for a, b in pairs])
        counts.append(int((lateral < 0).sum()))
    if min(counts) > len(pairs) / 2:
        raise CalibrationError(
            f"{min(counts)} of the {len(pairs)} left markers that have a right one lie on the "
            "subject's right of it (facing from the back of the body to its front): the left "
            "and right labels are exchanged", path=cal.source,
            hint="relabel the capture's left and right markers, or check the protocol's sides")


def check_static(trial: Trial, static: Trial, model: SubjectModel) -> None:
    """Step 0 of :func:`calibrate` for a ``model`` calibrated on ``static`` with
    ``static_pose="neutral"`` (which depends on the static and protocol alone, so a batch of
    one session calibrates once): raises :class:`CalibrationError` when the motion ``trial``
    never shows the model's pelvis markers together or shows another subject or marker
    placement, naming both files."""
    used = np.array([model.protocol.labels.index(label) for label in model.labels], dtype=int)
    X_static = label_match(static, model.protocol).markers(static)[:, used]
    check_static_markers(X_static, trial, model.protocol, used, model.marker_segments, model.labels,
                  static)


def check_static_markers(X_static: np.ndarray, trial: Trial, proto: Protocol, used: np.ndarray,
                  segments: np.ndarray, labels: list[str], static: Trial) -> np.ndarray:
    """The checks of :func:`check_static` on the static's ``used`` protocol markers
    ``X_static`` (F_s, M, 3); returns the motion's (F, M, 3)."""
    X_motion = label_match(trial, proto).markers(trial)[:, used]
    _check_motion_markers(X_motion, segments, labels, proto, static=static, trial=trial)
    check_same_subject(X_static, X_motion, segments, labels, static=static, trial=trial)
    return X_motion


def _check_motion_markers(X_motion: np.ndarray, segments: np.ndarray, labels: list[str],
                          proto: Protocol, *, static: Trial, trial: Trial) -> None:
    """Refuse a static whose pelvis markers the motion trial (F, M, 3) never shows together:
    no frame of it could be fitted with the static's model (a static of another marker set)."""
    pelvis = segments == SEGMENT_NAMES.index("pelvis")
    most = int(np.isfinite(X_motion[:, pelvis, 0]).sum(axis=1).max(initial=0))
    if most >= MIN_PELVIS_MARKERS:
        return
    names = np.array(labels)[pelvis]
    present = set(proto.labelled_in(trial))
    shows = (f"never shows {MIN_PELVIS_MARKERS} of the static's pelvis markers "
             f"({', '.join(names)}, protocol {proto.name!r}) in one frame")
    if sum(name in present for name in names) >= MIN_PELVIS_MARKERS:
        raise CalibrationError(f"this motion trial {shows}: they are missing in its frames",
                               path=trial.source, hint="check its gaps with `mocaplib inspect`")
    raise CalibrationError(f"the motion trial {trial.source} {shows}: the static is of another "
                           "marker set", path=static.source,
                           hint="give the static of this capture's session, or pass --protocol")


def check_same_subject(X_static: np.ndarray, X_motion: np.ndarray, segments: np.ndarray,
                       labels: list[str], *, static: Trial, trial: Trial,
                       limit: float = SAME_SUBJECT_LIMIT) -> float:
    """Step 0: does the static trial show the motion's subject with the same markers on?

    ``X_static`` (F_s, M, 3) and ``X_motion`` (F_m, M, 3) the same M markers (``labels``) of the
    two trials (``static``, ``trial``: named in the error), ``segments`` (M,). Compares the
    within-segment distances (:func:`segment_distances`) of pairs at least
    :data:`MIN_PAIR_DISTANCE` apart seen in both. Returns the median |d_motion − d_static| (m),
    NaN when fewer than :data:`MIN_PAIRS` pairs can be compared (nothing is checked); raises
    :class:`CalibrationError` when it exceeds ``limit``, naming both files and the pairs that
    differ most.
    """
    d_static, pairs = segment_distances(X_static, segments)
    d_motion, _ = segment_distances(X_motion, segments)
    usable = np.isfinite(d_static) & np.isfinite(d_motion) & (d_static >= MIN_PAIR_DISTANCE)
    if usable.sum() < MIN_PAIRS:
        return float("nan")
    diff = d_motion[usable] - d_static[usable]
    difference = float(median(np.abs(diff)))
    if difference > limit:
        worst = np.argsort(-np.abs(diff))[:3]
        pairs_used = pairs[usable]
        examples = ", ".join(f"{labels[pairs_used[k, 0]]}-{labels[pairs_used[k, 1]]} "
                             f"{1000 * d_static[usable][k]:.0f} mm in the static, "
                             f"{1000 * d_motion[usable][k]:.0f} mm in the motion" for k in worst)
        scale = float(np.exp(median(np.log(d_motion[usable] / d_static[usable]))))
        raise CalibrationError(
            f"this static trial does not match the motion trial {trial.source or '(unnamed)'}: "
            f"distances between markers on one segment differ by "
            f"{1000 * difference:.1f} mm (median of {int(usable.sum())} pairs; one subject with "
            f"the same markers stays within {1000 * limit:.0f} mm; motion/static size ratio "
            f"{scale:.3f}); e.g. {examples}", path=static.source,
            hint="use the static recorded with this subject in this session (markers not moved "
                 "since), or calibrate from the motion itself (leave out --static)")
    return difference


def choose_static(trial: Trial, statics: Sequence[Trial], protocol: Protocol, *,
                  check_one: bool = False) -> int | None:
    """Index of the static in ``statics`` that shows ``trial``'s subject, for a batch of
    several subjects or sessions: the least step-0 difference (:func:`check_same_subject`
    over the within-segment marker pairs of ``protocol``), if within
    :data:`SAME_SUBJECT_LIMIT`. Raises :class:`CalibrationError` naming the trial and each
    static with its difference when none is within the limit or none can be compared. With
    one static, 0 (:func:`calibrate` checks it in step 0) unless ``check_one``; with none,
    None."""
    if len(statics) < 2 and not (check_one and statics):
        return 0 if statics else None
    segments = np.array([SEGMENT_NAMES.index(m.landmark.segment) for m in protocol.markers])
    X_motion = label_match(trial, protocol).markers(trial)
    gaps = np.array([check_same_subject(
        label_match(static, protocol).markers(static), X_motion,
        segments, protocol.labels, static=static, trial=trial, limit=np.inf)
        for static in statics])
    if np.isfinite(gaps).any() and np.nanmin(gaps) <= SAME_SUBJECT_LIMIT:
        return int(np.nanargmin(gaps))
    names = static_names([static.source or f"static {i + 1}" for i, static in enumerate(statics)])
    listing = "; ".join(
        f"{name} " + ("shares too few marker pairs with it (another marker set?)"
                      if np.isnan(gap) else f"{1000 * gap:.1f} mm")
        for name, gap in zip(names, gaps))
    which = (f"none of the {len(statics)} static trials shows" if len(statics) > 1
             else "the static trial does not show")
    raise CalibrationError(
        f"{which} this capture's subject with the same "
        f"markers (median difference of the distances between markers on one segment; one "
        f"subject stays within {1000 * SAME_SUBJECT_LIMIT:.0f} mm): {listing}",
        path=trial.source, hint="add the static recorded with this subject in this session, "
                                "or build this capture without --static")


#: Markers seen in fewer than this fraction of frames are not used.
MIN_PRESENCE = 0.10
