"""Calibrate and fit one capture, as every command does (:func:`fit_capture`): the protocol
matched, the markers low-passed, the subject calibrated on a static or on the capture, every
frame fitted. ``mocaplib fit`` needs only this, not the library's modules.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from ..errors import CalibrationError
from ..io.c3d import read_c3d
from ..markersets.matching import ProtocolMatch, label_match, match_trial
from ..skeleton import SEGMENT_NAMES, SEGMENTS
from ..statics import static_names
from ..trial import Trial, require_markers
from .calibration import calibrate
from .calibration_checks import MIN_PRESENCE, check_static, choose_static
from .filtering import filter_trial
from .ik import fit_filtered, fit_quality, model_markers
from .joint_centres import register_offsets
from .motion import Motion, apply_repairs
from .solver import solve_poses
from .subject import SubjectModel


class StageClock:
    """Times named stages and remembers the one running (to blame it when it fails)."""

    def __init__(self):
        self.times: dict[str, float] = {}
        self.current: str | None = None

    @contextmanager
    def stage(self, name: str):
        self.current = name
        start = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - start
        self.current = None


@dataclass
class FittedCapture:
    """One capture calibrated and fitted (:func:`fit_capture`).

    Attributes
    ----------
    match : ProtocolMatch
        The capture's labels matched with its protocol (:func:`mocaplib.markersets.matching.match_trial`).
    cutoff : float or None
        Hz the markers were low-passed at (None: not filtered).
    model : SubjectModel
        The subject model; its ``source`` names the static trial used.
    motion : Motion
        The fitted joint angles.
    static : int or None
        Index of the static trial used among those given (None: calibrated from the capture).
    warnings : list[str]
        What the user should know about the calibration and the fit, one sentence each.
    """

    match: ProtocolMatch
    cutoff: float | None
    model: SubjectModel
    motion: Motion
    static: int | None
    warnings: list[str]

    @property
    def joint_centres_from_motion(self) -> bool:
        """Whether joint centres, flexion axes and zero poses no landmark gives were assumed
        from the capture's motion: a cluster set calibrated without a static."""
        return self.static is None and _is_cluster_set(self.model)

    def fitted_markers(self, trial: Trial, /) -> Trial:
        """The markers the fit followed, as a trial of the model's markers (labels in model
        order, F frames of ``trial``, the capture this was fitted to): the labelling errors
        the fit found undone, the samples it rejected gapped (NaN), low-passed at
        :attr:`cutoff` (:func:`mocaplib.model.filtering.filter_trial`); what OpenSim's tools
        are given to solve the same problem (``mocaplib fit --trc``)."""


        labels = list(self.model.labels)
        markers = apply_repairs(model_markers(trial, self.model), labels, self.motion.repairs)
        markers[self.motion.rejected] = float("nan")
        chosen = replace(trial, markers=markers, labels=labels, warnings=list(trial.warnings))
        return chosen if self.cutoff is None else filter_trial(chosen, cutoff=self.cutoff)[0]


def fit_capture(trial: Trial, /, *, protocol="auto", static=None,
                static_pose: str = "free", cutoff: float | str | None = "auto",
                heading_offsets=None, measurements: dict | None = None,
                static_window: tuple[float, float] | None = None, fallback: bool = False,
                neutral_model=None, clock: StageClock | None = None,
                knee_turns: dict[str, float] | None = None) -> FittedCapture:
    """Calibrate and fit one capture, as every command does: ``protocol`` matched on the
    capture, markers low-passed at ``cutoff`` (Hz, "auto" or None,
    :func:`mocaplib.model.filtering.filter_trial`), the subject model calibrated
    (:func:`mocaplib.model.calibration.calibrate`) on the static that shows the capture's subject or
    on the capture itself, then :func:`mocaplib.model.ik.fit_filtered`.

    Parameters
    ----------
    trial : Trial
        The capture (not modified).
    protocol : ProtocolMatch, Protocol, str or os.PathLike
        A :class:`~mocaplib.markersets.matching.ProtocolMatch` of this trial, or what
        :func:`mocaplib.markersets.matching.match_trial` takes (a Protocol, shipped name, TOML
        path or "auto"; resolved on the capture whatever the static's labels).
    static : Trial, list of Trial or None
        A static trial or one per subject or session; the one that shows this capture's
        subject is used (:func:`mocaplib.model.calibration_checks.choose_static`). None: calibrate
        from the capture itself.
    static_pose : {"free", "neutral"}
        The pose of the static trials.
    cutoff : float, "auto", "none" or None
        Marker low-pass cutoff, Hz (:func:`mocaplib.model.filtering.filter_trial`).
    heading_offsets : sequence of float, optional
        Per static, the heading correction of a forward reference, radians
        (:func:`mocaplib.build.forward.forward_offsets`; the static in the neutral pose).
    measurements : dict, optional
        Subject measurements (metres) overriding the calibration file's.
    static_window : (float, float), optional
        The (start, end) seconds of the static to calibrate on
        (:func:`mocaplib.statics.standing_part`).
    fallback : bool
        When no static shows the subject: calibrate from the capture itself and say so
        (True), or raise (False).
    neutral_model : callable, optional
        ``neutral_model(i)``: the model of static ``i`` in the neutral pose, when the caller
        keeps them (a build calibrates each once per process); None calibrates it here.
    clock : StageClock, optional
        Times the stages "protocol", "filter", "calibrate" and "fit".
    knee_turns : dict, optional
        As :func:`mocaplib.model.calibration.calibrate` takes it (None: functional knee axes).

    Returns
    -------
    FittedCapture
        The protocol match, the cutoff used, the subject model, the fitted motion, the index of
        the static used and the warnings.

    Raises
    ------
    CalibrationError
        No static shows the capture's subject and ``fallback`` is False, or the calibration
        fails (the message names the file and what to do).
    FitError
        The markers cannot be filtered or fitted.
    """

    clock = clock or StageClock()
    statics = static_trials(static)
    for given in statics:
        require_markers(given)
    warnings: list[str] = []
    with clock.stage("protocol"):
        match = protocol if isinstance(protocol, ProtocolMatch) else match_trial(trial, protocol)
    with clock.stage("filter"):
        # the protocol's markers only: the cutoff is judged on them, and they are filtered
        filtered, used = filter_trial(trial, cutoff=cutoff, keep=match.columns)
    with clock.stage("calibrate"):
        try:
            chosen = choose_static(filtered, statics, match.protocol, check_one=fallback)
            if chosen is not None and static_pose == "neutral" and neutral_model is not None:
                model = neutral_model(chosen)
                check_static(filtered, statics[chosen], model)
            else:
                model = calibrate(filtered, protocol=match.protocol,
                                  static=None if chosen is None else statics[chosen],
                                  static_pose=static_pose,
                                  heading_offset=0.0 if heading_offsets is None or chosen is None
                                  else heading_offsets[chosen],
                                  measurements=measurements, static_window=static_window,
                                  knee_turns=knee_turns)
        except CalibrationError as exc:
            if not (fallback and statics):
                raise
            warnings.append(f"calibrated from the capture itself: no static shows its subject "
                            f"({exc.message})")
            chosen, model = None, calibrate(filtered, protocol=match.protocol,
                                            measurements=measurements, knee_turns=knee_turns)
    if chosen is not None:
        name = static_names([s.source or f"static {i + 1}" for i, s in enumerate(statics)])[chosen]
        window = model.static_window_s
        if window != (0.0, statics[chosen].duration):
            warnings.append(f"static {name}: calibrated on its stretch {window[0]:.2f}-"
                            f"{window[1]:.2f} s (of {statics[chosen].duration:.2f} s)")
        warnings.extend(model.swap_warnings)     # without a static the fit reports the swaps
        model, added = with_motion_markers(model, filtered)
        if added:
            warnings.append(f"static {name} does not show {', '.join(added)} (seen in under "
                            f"{MIN_PRESENCE:.0%} of its frames): placed on "
                            f"{'their segments' if len(added) > 1 else 'its segment'} from "
                            "the capture's own frames")
    else:
        warnings.append(_foot_zero_warning(model))
        if _is_cluster_set(model):
            warnings.append(_cluster_warning(model))
    with clock.stage("fit"):
        motion, _ = fit_filtered(trial, model, cutoff=used)
    warnings.extend(_fit_warnings(model, motion))
    return FittedCapture(match, used, model, motion, chosen, warnings)


#: Frames of the capture :func:`with_motion_markers` places a marker the static lacks on.
MOTION_MARKER_FRAMES = 60


def with_motion_markers(model: SubjectModel, trial: Trial) -> tuple[SubjectModel, list[str]]:
    """``model`` (calibrated on a static) with the protocol's markers it lacks that ``trial``
    shows in at least :data:`MIN_PRESENCE` of its frames (a marker the static hid, or put on
    after it), and their labels. Each is placed on its segment where the model's poses, fitted
    to the model's markers in up to :data:`MOTION_MARKER_FRAMES` frames that show it, put it
    on average; the model's own markers, frames and DOFs are unchanged."""
    proto = model.protocol
    X = label_match(trial, proto).markers(trial)                              # (F, P, 3)
    seen = np.isfinite(X[..., 0])
    extra = [j for j, label in enumerate(proto.labels)
             if label not in model.labels and seen[:, j].mean() >= MIN_PRESENCE]
    if not extra:
        return model, []
    showing = np.flatnonzero(seen[:, extra].any(axis=1))
    frames = showing[np.linspace(0, len(showing) - 1, min(len(showing), MOTION_MARKER_FRAMES)
                                 ).round().astype(int)]
    poses = solve_poses(model.skeleton, model_markers(trial, model)[frames],
                        model.marker_segments, model.marker_offsets, free=model.free).q
    segments = np.array([SEGMENT_NAMES.index(proto.markers[j].landmark.segment) for j in extra])
    offsets = register_offsets(model.skeleton, poses, X[frames][:, extra], segments,
                               nominal=np.full((len(extra), 3), np.nan), align=())
    placed = np.isfinite(offsets).all(axis=1)
    labels = [proto.labels[j] for j, ok in zip(extra, placed) if ok]
    return replace(model, labels=model.labels + labels,
                   marker_segments=np.concatenate([model.marker_segments, segments[placed]]),
                   marker_offsets=np.vstack([model.marker_offsets, offsets[placed]])), labels


def _foot_zero_warning(model: SubjectModel) -> str:
    """Where a model calibrated without a static takes each foot's zero (ankle dorsiflexion
    0) from, one sentence (:func:`mocaplib.model.anatomy.flat_soles`)."""
    sides = [f"{name} {model.centre_methods[f'sole_{side}']}"
             for side, name in (("l", "left"), ("r", "right"))
             if f"sole_{side}" in model.centre_methods]
    return ("no static: each foot's zero (ankle dorsiflexion 0) is the foot along its sole, "
            + ("; ".join(sides) if sides else "no foot markers"))


#: The likely cause of a QC failure of a cluster set fitted without a static, and what to do.
def _is_cluster_set(model: SubjectModel) -> bool:
    """Whether the model follows tracking markers (clusters) on a limb."""
    tracking = {m.label for m in model.protocol.markers if m.tracking}
    return any(label in tracking for label in model.labels)


def _cluster_warning(model: SubjectModel) -> str:
    """What a cluster set calibrated without a static assumes, one sentence: how each knee,
    ankle and elbow was placed (:func:`mocaplib.model.joint_centres.joint_centres`) and where
    the limbs' zero poses come from."""
    joints = [f"{joint} {side}: {model.centre_methods[f'{joint}_{side[0]}']}"
              for joint in ("knee", "ankle", "elbow") for side in ("left", "right")
              if f"{joint}_{side[0]}" in model.centre_methods]
    return ("cluster set without a static: segment zero poses are assumed from the joint "
            "centres (knee flexion 0 with the hip, knee and ankle centres in line, elbow flexion "
            "0 with the shoulder, elbow and wrist centres in line, hip rotation 0 with the "
            "knee's flexion axis along the pelvis's); " + "; ".join(joints))


def _fit_warnings(model: SubjectModel, motion: Motion) -> list[str]:
    """What a user should know about a fit: the labelling repairs, DOFs held at 0 and why,
    DOFs at a joint limit, frames not fitted, samples removed."""

    quality = fit_quality(motion)
    notes = motion.repair_warnings()
    if model.left_out:
        notes.append(f"no markers on {', '.join(model.left_out)}; their DOFs are held at 0")
    left_out = {dof for seg in SEGMENTS if seg.name in model.left_out for dof in seg.dofs}
    unseen = [dof for dof in motion.locked_dofs if dof not in left_out]
    if unseen:
        notes.append(f"the markers of protocol {model.protocol.name!r} cannot see "
                     f"{', '.join(unseen)}; held at 0")
    notes.extend(motion.limit_warnings())
    if quality["failed_frames"]:
        notes.append(f"{len(quality['failed_frames'])} frames could not be fitted (interpolated)")
    if quality["rejected_samples"]:
        notes.append(f"{quality['rejected_samples']} marker samples removed as outliers "
                     f"({', '.join(f'{k} {v}' for k, v in quality['rejected_per_marker'].items())})")
    return notes


def fit(capture, /, *, protocol="auto", static=None, static_pose: str = "free",
        cutoff: float | str | None = "auto", static_window: tuple[float, float] | None = None,
        measurements: dict | None = None, heading_offsets=None) -> Motion:
    """The joint angles ``mocaplib fit`` writes for a capture, with the same options.

    Parameters
    ----------
    capture : str, os.PathLike or Trial
        The capture: a C3D file (read with :func:`mocaplib.io.c3d.read_c3d`) or a trial.
    protocol : ProtocolMatch, Protocol, str or "auto"
        The marker set (``--protocol``): a shipped name, a TOML path, or detected.
    static : path, Trial or a list of them, optional
        The static trial(s) (``--static``); the one that shows the capture's subject is used.
        None calibrates the subject from the capture itself.
    static_pose : {"free", "neutral"}
        The static's pose (``--static-pose``).
    cutoff : float, "auto" or None
        The markers' low-pass cutoff in Hz (``--cutoff``).
    static_window : (start, end) seconds, optional
        The stretch of the static to calibrate on (``--static-window``).
    measurements : dict, optional
        Subject measurements in metres and kilograms (``--subject``).
    heading_offsets : sequence of float, optional
        Per static, the heading correction in radians a forward reference measures
        (:func:`mocaplib.build.forward.forward_offsets`).

    Returns
    -------
    Motion
        The fitted motion: ``motion.q`` (F, D) in :data:`mocaplib.skeleton.DOF_NAMES` order,
        radians (the pelvis translations in metres), ``motion.time`` (F,) seconds.
    """
    trial = capture if isinstance(capture, Trial) else read_c3d(capture)
    return fit_capture(trial, protocol=protocol, static=static, static_pose=static_pose,
                       cutoff=cutoff, static_window=static_window, measurements=measurements,
                       heading_offsets=heading_offsets).motion


def static_trials(static) -> list[Trial]:
    """The static trials ``static`` gives: None, one, or a list of them, each a :class:`Trial`
    or a C3D file (read with :func:`mocaplib.io.c3d.read_c3d`)."""
    given = [] if static is None else list(static) if isinstance(static, (list, tuple)) \
        else [static]
    return [s if isinstance(s, Trial) else read_c3d(s) for s in given]
