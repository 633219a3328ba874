"""Quality control of a fitted capture's cycles: the QC metrics of each cycle (names and units of
:data:`mocaplib.gait.qc.QC_LIMITS`) and the choice of the cycle a capture contributes."""


from __future__ import annotations

import math

import numpy as np

from ..model.filtering import WALKING_CUTOFF, lowpass, resample, shortest_run
from ..skeleton import JOINT_ANGLES, ROOT_X, ROOT_Y, TRANSLATION
from .criteria import closure, internal_power, jerk_rms, segment_energies, third_derivative


def qc_series(motion, ground: np.ndarray | None = None) -> dict:
    """The capture-wide series the QC of its cycles reads: ``q`` the coordinates (F, D),
    rotations unwrapped; ``third`` the third time derivative (F, J) rad/s^3 of the joint angles
    (:data:`mocaplib.skeleton.JOINT_ANGLES`) and ``energies`` each body segment's energy (F, B)
    J/kg (:func:`mocaplib.gait.criteria.segment_energies`, positions relative to the floor moving at
    ``ground`` m/s), both from the coordinates low-passed at
    :data:`mocaplib.model.filtering.WALKING_CUTOFF` (None when the capture is too short to be
    filtered): derivatives of unfiltered angles would measure fit noise only."""

    q = motion.q.copy()
    q[:, ~TRANSLATION] = np.unwrap(q[:, ~TRANSLATION], axis=0)
    if ground is not None:
        q[:, [ROOT_X, ROOT_Y]] -= np.outer(np.arange(len(q)) / motion.rate, ground[:2])
    if motion.n_frames < shortest_run(motion.rate, WALKING_CUTOFF) \
            or motion.rate <= 2 * WALKING_CUTOFF:
        return {"q": q, "third": None, "energies": None}
    smooth = lowpass(q, motion.rate, WALKING_CUTOFF)
    return {"q": q, "third": third_derivative(smooth[:, JOINT_ANGLES], motion.rate),
            "energies": segment_energies(motion.skeleton, smooth, motion.rate)}


def inside_cycle(cycle, motion) -> np.ndarray:
    """The frames (F,) bool of ``motion`` from the cycle's start to its end."""
    frames = np.arange(motion.n_frames) / motion.rate
    return (frames >= cycle.start_s) & (frames <= cycle.end_s)


def named_failures(cycle, motion, qc: dict, thresholds: dict) -> list[str]:
    """The cycle's QC failures (:func:`mocaplib.gait.qc.qc_failures` of its metrics ``qc``),
    those of the marker metrics naming their marker: for ``marker_max_m`` the trusted marker
    with the largest residual and when ("RPSIS at 3.58 s", from the capture's first frame), for
    ``marker_rms_m`` the one of largest RMS over the cycle."""
    failures = qc_failures(qc, thresholds)
    if not any(f.split()[0] in ("marker_max_m", "marker_rms_m") for f in failures):
        return failures
    inside = np.flatnonzero(inside_cycle(cycle, motion))
    trusted = np.flatnonzero(motion.trusted())
    residuals = motion.residuals[np.ix_(inside, trusted)]
    if not np.isfinite(residuals).any():
        return failures
    labels = [motion.marker_labels[m] for m in trusted]
    frame, worst = np.unravel_index(np.nanargmax(residuals), residuals.shape)
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nanmean(residuals ** 2, axis=0))
    culprits = {"marker_max_m": f"{labels[worst]} at {inside[frame] / motion.rate:.2f} s",
                "marker_rms_m": labels[int(np.nanargmax(rms))]}
    return [f"{f} ({culprits[f.split()[0]]})" if f.split()[0] in culprits else f
            for f in failures]


def cycle_qc(cycle, motion, series: dict | None = None) -> dict:
    """QC metrics of one cycle (names and units of :data:`mocaplib.gait.qc.QC_LIMITS`).

    marker RMS / max: fit residuals of the frames in the cycle (m), of the markers the fit
    follows (:meth:`mocaplib.model.motion.Motion.trusted`); gap fraction: missing marker samples
    among them; event quality: the cycle's; Fourier RMS: the worst rotational
    DOF's reconstruction RMS (rad); closure (C2): norm of the joint-angle change from start to
    end (rad, :func:`mocaplib.gait.criteria.closure`); jerk (C1): RMS over the cycle's frames and the
    joint angles of their third time derivative (rad/s^3); internal power (C3): the absolute
    energy changes of every body segment between the cycle's consecutive frames over their
    span, W/kg (:func:`mocaplib.gait.criteria.internal_power`); jerk and power are None when the
    capture is too short to be filtered. ``series``: the capture's :func:`qc_series`, when
    already computed.
    """

    series = qc_series(motion) if series is None else series
    inside = inside_cycle(cycle, motion)
    residuals = motion.residuals[inside][:, motion.trusted()]
    ends = resample(series["q"], motion.rate, np.array([cycle.start_s, cycle.end_s]))
    third, energies = series["third"], series["energies"]
    spanned = (np.count_nonzero(inside) - 1) / motion.rate
    with np.errstate(invalid="ignore"):
        return {
            "marker_rms_m": float(np.sqrt(np.nanmean(residuals ** 2))),
            "marker_max_m": float(np.nanmax(residuals)),
            "gap_fraction": float(np.isnan(residuals).mean()),
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
