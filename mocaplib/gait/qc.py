"""Quality control of a fitted capture's cycles: the QC metrics of each cycle (names and units of
:data:`mocaplib.gait.qc.QC_LIMITS`), and the messages that name a failure's marker, its likely
cause and what to do (:func:`named_failures`, :data:`LIKELY_CAUSES`).

**Outliers are samples, not cycles.** A marker sample the fit removed as an outlier
(:attr:`mocaplib.model.motion.Motion.rejected`) or a spike of the residual — at most
:data:`SPIKE_FRAMES` consecutive samples of one marker standing more than :data:`SPIKE_RISE`
above the running median of its residual (:func:`outlier_samples`) — is left out of the
cycle's marker metrics: one bad sample is an outlier to remove, not a reason to reject a
cycle. Outliers are rare: a marker whose removed samples and spikes are more than
:data:`SPIKE_SHARE` of its samples is noisy throughout, and they count (its spikes in the
marker metrics, its removed samples as gaps). What a technician
rejects (a marker off for several frames, a poor or noisy fit throughout) still fails.
"""


from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..model.filtering import WALKING_CUTOFF, lowpass, resample, shortest_run
from ..runs import frames_within
from ..skeleton import JOINT_ANGLES, ROOT_X, ROOT_Y, TRANSLATION
from .criteria import closure, internal_power, jerk_rms, segment_energies, third_derivative


def qc_series(motion, ground: np.ndarray | None = None) -> dict:
    """The capture-wide series the QC of its cycles reads: ``q`` the coordinates (F, D),
    rotations unwrapped; ``third`` the third time derivative (F, J) rad/s^3 of the joint angles
    (:data:`mocaplib.skeleton.JOINT_ANGLES`) and ``energies`` each body segment's energy (F, B)
    J/kg (:func:`mocaplib.gait.criteria.segment_energies`, positions relative to the floor moving at
    ``ground`` m/s), both from the coordinates low-passed at
    :data:`mocaplib.model.filtering.WALKING_CUTOFF` (None when the capture is too short to be
    filtered): derivatives of unfiltered angles would measure fit noise only; ``outliers`` the
    marker samples (F, M) bool the marker metrics leave out (:func:`outlier_samples`)."""

    q = motion.q.copy()
    q[:, ~TRANSLATION] = np.unwrap(q[:, ~TRANSLATION], axis=0)
    if ground is not None:
        q[:, [ROOT_X, ROOT_Y]] -= np.outer(np.arange(len(q)) / motion.rate, ground[:2])
    if motion.n_frames < shortest_run(motion.rate, WALKING_CUTOFF) \
            or motion.rate <= 2 * WALKING_CUTOFF:
        return {"q": q, "third": None, "energies": None, "outliers": outlier_samples(motion)}
    smooth = lowpass(q, motion.rate, WALKING_CUTOFF)
    return {"q": q, "third": third_derivative(smooth[:, JOINT_ANGLES], motion.rate),
            "energies": segment_energies(motion.skeleton, smooth, motion.rate),
            "outliers": outlier_samples(motion)}


def inside_cycle(cycle, motion) -> slice:
    """The frames of ``motion`` from the cycle's start to its end (a slice of the frame axis:
    :func:`mocaplib.runs.frames_within`)."""
    return frames_within(cycle.start_s, cycle.end_s, motion.rate, motion.n_frames)


#: The longest run of samples (frames) of one marker a residual spike spans: a longer excursion
#: is the marker's, and the metrics count it.
SPIKE_FRAMES = 2
#: How far (m) a spike stands above the running median (over 2·SPIKE_FRAMES + 1 frames) of its
#: marker's residual: the jump the fit's repairs call a marker's own
#: (:data:`mocaplib.model.repairs.JUMP`, 0.01 m), ten times the samples' marker noise.
SPIKE_RISE = 0.01
#: The largest share of a marker's samples that may be outliers (removed or spikes) for them to
#: be left out: beyond it the marker is noisy throughout (25 mm of noise on every coordinate
#: spikes about a third of the samples; a lab capture's bad sample or two is well under 1 %).
SPIKE_SHARE = 0.02


def outlier_samples(motion) -> np.ndarray:
    """The marker samples (F, M) bool the QC metrics leave out: those the fit removed as
    outliers (:attr:`~mocaplib.model.motion.Motion.rejected`) and the residual spikes (module
    docstring), over the whole capture, but for markers with more of them than
    :data:`SPIKE_SHARE` of their samples."""
    residuals = motion.residuals
    half = SPIKE_FRAMES
    padded = np.pad(residuals, ((half, half), (0, 0)), mode="edge")
    windows = sliding_window_view(padded, 2 * half + 1, axis=0)      # (F, M, 2h+1)
    baseline = np.empty(residuals.shape)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # a window without a sample: NaN
        for start in range(0, len(residuals), OUTLIER_BLOCK):   # a long take's, a block at a time
            rows = slice(start, start + OUTLIER_BLOCK)
            baseline[rows] = np.nanmedian(windows[rows], axis=2)
        outliers = (residuals - baseline > SPIKE_RISE) | motion.rejected
    return outliers & (outliers.mean(axis=0) <= SPIKE_SHARE)        # rare ones only, per marker


#: Frames whose residual medians :func:`outlier_samples` takes at once: the median's work
#: arrays stay near 10 MB whatever the capture's length (each window's median is the same).
OUTLIER_BLOCK = 4096


@dataclass(frozen=True)
class Failure:
    """One QC failure of a cycle, as :func:`named_failures` describes it: the metric, its
    value and limit (SI units), the cycle, the fitted motion, and ``facts`` the caller knows
    about the capture (``static``: the static's file name or None when calibrated from the
    capture itself; ``protocol``: the marker set's name; more keys may be added)."""

    metric: str
    value: float | None
    limit: float
    cycle: object
    motion: object
    facts: dict


#: Likely causes of QC failures: functions of a :class:`Failure` giving ``(cause, action)``, or
#: None when they do not apply. The first that applies is added to the failure's message
#: (:func:`named_failures`); more specific ones (a marker set, a calibration) go first:
#: ``LIKELY_CAUSES.insert(0, hint)``.
LIKELY_CAUSES: list[Callable[[Failure], tuple[str, str] | None]] = []


def _joints_from_motion(failure: Failure):
    if failure.facts.get("joint_centres") != "the motion":
        return None
    return ("a cluster set without a static: the joint centres, the flexion axes and the "
            "segments' zero poses no landmark gives are assumed from the capture's motion (the "
            "calibration warning names each)", "record a static standing trial with the knee, "
            "ankle and elbow markers on and pass it with --static, or check the angles and keep "
            "the cycle with --qc waive")


def _self_calibrated(failure: Failure):
    if failure.metric not in ("marker_max_m", "marker_rms_m") or "static" not in failure.facts \
            or failure.facts["static"] is not None:
        return None
    return ("calibrated from the capture itself: the marker offsets and segment lengths are "
            "fitted to the motion", "give the session's static with --static or a session.toml")


def _marker_off(failure: Failure):
    if failure.metric not in ("marker_max_m", "marker_rms_m"):
        return None
    return ("a marker off its segment for several frames (moved on the skin, knocked, or "
            "mislabelled), not a single sample", "check the named marker's label and "
            "trajectory there, or leave the cycle out (drop_cycles in session.toml)")


def _not_periodic(failure: Failure):
    if failure.metric not in ("fourier_rms_rad", "cycle_closure_rad"):
        return None
    return ("the cycle is not periodic: the person starts, stops or changes what they do "
            "within it", "trim the capture to one activity (trim in session.toml) or choose "
            "another cycle (cycles)")


def _filled_events(failure: Failure):
    if failure.metric not in ("event_quality", "gap_fraction"):
        return None
    return ("the foot markers are missing (out of view) around the cycle's events"
            if failure.metric == "event_quality" else "markers out of view for much of the cycle",
            "fill the gaps in the capture, or choose another cycle (cycles in session.toml)")


LIKELY_CAUSES += [_joints_from_motion, _self_calibrated, _marker_off, _not_periodic,
                  _filled_events]


def named_failures(cycle, motion, qc: dict, thresholds: dict, *, facts: dict | None = None
                   ) -> list[str]:
    """The cycle's QC failures (:func:`mocaplib.gait.qc.qc_failures` of its metrics ``qc``),
    those of the marker metrics naming their marker — for ``marker_max_m`` the trusted marker
    with the largest residual and when ("RPSIS at 3.58 s", from the capture's first frame),
    for ``marker_rms_m`` the one of largest RMS over the cycle, outlier samples left out
    (:func:`outlier_samples`) — each followed by its likely cause and what to do (the first of
    :data:`LIKELY_CAUSES` that applies; ``facts`` as :class:`Failure` says)."""
    failures = qc_failures(qc, thresholds)
    culprits = {}
    if any(f.split()[0] in ("marker_max_m", "marker_rms_m") for f in failures):
        span = inside_cycle(cycle, motion)
        inside = np.arange(span.start, span.stop)
        trusted = np.flatnonzero(motion.trusted())
        residuals = np.where(outlier_samples(motion), np.nan,
                             motion.residuals)[np.ix_(inside, trusted)]
        if np.isfinite(residuals).any():
            labels = [motion.marker_labels[m] for m in trusted]
            frame, worst = np.unravel_index(np.nanargmax(residuals), residuals.shape)
            with np.errstate(invalid="ignore"):
                rms = np.sqrt(np.nanmean(residuals ** 2, axis=0))
            culprits = {"marker_max_m": f"{labels[worst]} at {inside[frame] / motion.rate:.2f} s",
                        "marker_rms_m": labels[int(np.nanargmax(rms))]}
    named = []
    for text in failures:
        metric = text.split()[0]
        if metric in culprits:
            text = f"{text} ({culprits[metric]})"
        failure = Failure(metric, qc.get(metric), thresholds.get(metric), cycle, motion,
                          facts or {})
        hint = next((h for h in (cause(failure) for cause in LIKELY_CAUSES) if h), None)
        named.append(text if hint is None else f"{text}: likely {hint[0]}; {hint[1]}")
    return named


def cycle_qc(cycle, motion, series: dict | None = None) -> dict:
    """QC metrics of one cycle (names and units of :data:`mocaplib.gait.qc.QC_LIMITS`).

    marker RMS / max: fit residuals of the frames in the cycle (m), of the markers the fit
    follows (:meth:`mocaplib.model.motion.Motion.trusted`), outlier samples left out (module
    docstring); gap fraction: missing marker samples among them (outliers are not gaps); event
    quality: the cycle's; Fourier RMS: the worst rotational DOF's reconstruction RMS (rad);
    closure (C2): norm of the joint-angle change from start to end (rad,
    :func:`mocaplib.gait.criteria.closure`); jerk (C1): RMS over the cycle's frames and the
    joint angles of their third time derivative (rad/s^3); internal power (C3): the absolute
    energy changes of every body segment between the cycle's consecutive frames over their span,
    W/kg (:func:`mocaplib.gait.criteria.internal_power`); jerk and power are None when the
    capture is too short to be filtered. ``series``: the capture's :func:`qc_series`, when
    already computed.
    """

    series = qc_series(motion) if series is None else series
    inside = inside_cycle(cycle, motion)
    residuals = motion.residuals[inside][:, motion.trusted()]
    outliers = series["outliers"][inside][:, motion.trusted()]
    measured = np.where(outliers, np.nan, residuals)
    ends = resample(series["q"], motion.rate, np.array([cycle.start_s, cycle.end_s]))
    third, energies = series["third"], series["energies"]
    spanned = (max(inside.stop - inside.start, 0) - 1) / motion.rate
    with np.errstate(invalid="ignore"):
        return {
            "marker_rms_m": float(np.sqrt(np.nanmean(measured ** 2))),
            "marker_max_m": float(np.nanmax(measured)),
            "gap_fraction": float((np.isnan(residuals) & ~outliers).mean()),
            "event_quality": float(cycle.event_quality),
            "fourier_rms_rad": float(cycle.encoding.series.rms[~TRANSLATION].max()),
            "cycle_closure_rad": closure(ends[0], ends[1]),
            "jerk_rms_rad_s3": None if third is None else jerk_rms(third[inside]),
            "internal_power_w_kg": None if energies is None or spanned <= 0
            else internal_power(energies[inside], spanned),
        }


#: QC metric name -> (threshold, "max" if the value must not exceed it, "min" if not fall below).
#: Marker limits are OpenSim's IK best practice. Event quality below 0.5 means most foot samples
#: around a bounding toe-off were gap-filled, not measured. The Fourier limit is twice the encoding
#: target of 0.5 deg (Skejø 2021): the RMS is measured against the fitted angles, whose
#: frame-to-frame noise on poorly observed DOFs (ankle inversion, shoulder rotation) is about
#: 0.5 deg itself, so 1 deg flags cycles that are not periodic or not followed, not fit noise.
#: A threshold of None means the metric is reported, not checked.
QC_LIMITS: dict[str, tuple[float | None, str]] = {
    "marker_rms_m": (0.02, "max"),
    "marker_max_m": (0.04, "max"),
    "gap_fraction": (0.5, "max"),
    "event_quality": (0.5, "min"),   # also mocaplib.gait.cycles.MIN_EVENT_QUALITY (the choice)
    # the loosest encoding tolerance, mocaplib.gait.fourier.MAX_ANGLE_TOLERANCE: see docs
    "fourier_rms_rad": (math.radians(1.0), "max"),
    "cycle_closure_rad": (None, "max"),
    "jerk_rms_rad_s3": (None, "max"),
    "internal_power_w_kg": (None, "max"),   # C3, mocaplib.gait.criteria; absent in older files
}


QC_NAMES = tuple(QC_LIMITS)


DEFAULT_QC_THRESHOLDS = {name: limit for name, (limit, _) in QC_LIMITS.items()}


# --------------------------------------------------------------------------- building
def qc_failures(qc: dict, thresholds: dict, waived: dict | None = None) -> list[str]:
    """Human-readable QC metrics outside their threshold and not waived (empty when all pass)."""
    failures = []
    for name, value in qc.items():
        limit = thresholds.get(name)
        if limit is None or (waived and name in waived):
            continue
        if value is None or not math.isfinite(value):
            failures.append(f"{name} is not finite")
            continue
        if QC_LIMITS[name][1] == "max" and value > limit:
            failures.append(f"{name} {value:.4g} > {limit:.4g}")
        elif QC_LIMITS[name][1] == "min" and value < limit:
            failures.append(f"{name} {value:.4g} < {limit:.4g}")
    return failures
