"""One capture through the stages, the same for the Python API, every command and the build:
read, match the protocol, calibrate and fit (:func:`mocaplib.model.fitting.fit_capture`), detect
the gait events, cut the cycles and measure them, check each cycle's quality and choose the
one the library keeps (:func:`process`).

SI units throughout: metres, seconds, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gait.activity import set_activities
from ..gait.cycles import Cycle, motion_cycles, qc_and_choice, shoulder_centres
from ..gait.events import EventSettings, capture_events
from ..gait.foot_events import GaitEvent
from ..gait.qc import DEFAULT_QC_THRESHOLDS
from ..io.c3d import read_c3d
from ..markersets.matching import ProtocolMatch, match_trial, missing_landmarks_error
from ..model.fitting import FittedCapture, StageClock, fit_capture
from ..model.motion import Motion
from ..model.subject import SubjectModel
from ..trial import Trial


@dataclass
class ProcessedCapture:
    """One capture taken through every stage (:func:`process`).

    Attributes
    ----------
    trial : Trial
        The capture as read.
    fitted : FittedCapture
        The protocol match, the cutoff, the subject model, the motion, the static used and
        the calibration's and fit's warnings.
    events : list[GaitEvent]
        The gait events, in time order.
    ground : ndarray (3,) or None
        The floor's velocity, m/s (a treadmill's belt; zero overground).
    shoulders : (ndarray, ndarray)
        The fitted left and right shoulder joint centres (F, 3), metres.
    cycles : list[Cycle]
        Every complete cycle, its pattern, velocities, Fourier encoding and activity;
        ``chosen`` marks those the library keeps (one per activity segment), ``left_out``
        those a session's choice leaves out.
    qc : dict[int, dict]
        Each cycle's QC metrics by cycle index (names of :data:`mocaplib.gait.qc.QC_LIMITS`).
    """

    trial: Trial
    fitted: FittedCapture
    events: list[GaitEvent]
    ground: np.ndarray | None
    shoulders: tuple[np.ndarray, np.ndarray]
    cycles: list[Cycle]
    qc: dict[int, dict]

    @property
    def match(self) -> ProtocolMatch:
        return self.fitted.match

    @property
    def model(self) -> SubjectModel:
        return self.fitted.model

    @property
    def motion(self) -> Motion:
        return self.fitted.motion

    @property
    def chosen(self) -> Cycle | None:
        """The first cycle the library keeps (None when the capture has none); a take of
        several activities keeps one per activity segment: the cycles with ``chosen`` set."""
        return next((c for c in self.cycles if c.chosen), None)


def process(capture, /, *, protocol="auto", static=None, static_pose: str = "free",
            cutoff: float | str | None = "auto",
            static_window: tuple[float, float] | None = None,
            measurements: dict | None = None, heading_offsets=None,
            toe_off: str = EventSettings.toe_off, max_gap_s: float = EventSettings.max_gap_s,
            qc_thresholds: dict | None = None, fallback: bool = False, neutral_model=None,
            clock: StageClock | None = None) -> ProcessedCapture:
    """Take one capture through every stage, as ``mocaplib cycles`` and ``mocaplib build`` do:
    :func:`fit_events`, then :func:`cut_cycles`.

    Parameters
    ----------
    capture : str, os.PathLike or Trial
        A C3D file, or a trial already read.
    protocol, static, static_pose, cutoff, static_window, measurements, heading_offsets
        As :func:`mocaplib.model.fitting.fit` (the options of ``mocaplib fit``).
    toe_off : str
        How toe-off is placed (:data:`mocaplib.gait.events.TOE_OFF_DEFINITIONS`).
    max_gap_s : float
        The longest stretch of filled foot-marker samples an event or a cycle may span, s.
    qc_thresholds : dict, optional
        QC thresholds by metric name (default :data:`mocaplib.gait.qc.DEFAULT_QC_THRESHOLDS`):
        the chosen cycle is the steadiest one that passes them, if any does.
    fallback, neutral_model, clock
        As :func:`mocaplib.model.fitting.fit_capture`.

    Returns
    -------
    ProcessedCapture
        The trial, the fit, the events, the cycles with the chosen one, and their QC.

    Raises
    ------
    MocapError
        Naming the file and the stage: a capture that cannot be read, matched, calibrated or
        fitted; :class:`~mocaplib.errors.NoCycleError` when it holds no complete cycle.
    """
    fitted = fit_events(capture, protocol=protocol, static=static, static_pose=static_pose,
                        cutoff=cutoff, static_window=static_window, measurements=measurements,
                        heading_offsets=heading_offsets, toe_off=toe_off, max_gap_s=max_gap_s,
                        fallback=fallback, neutral_model=neutral_model, clock=clock)
    return cut_cycles(fitted, max_gap_s=max_gap_s, qc_thresholds=qc_thresholds, clock=clock)


def fit_events(capture, /, *, protocol="auto", static=None, static_pose: str = "free",
               cutoff: float | str | None = "auto",
               static_window: tuple[float, float] | None = None,
               measurements: dict | None = None, heading_offsets=None,
               toe_off: str = EventSettings.toe_off,
               max_gap_s: float = EventSettings.max_gap_s, fallback: bool = False,
               neutral_model=None, clock: StageClock | None = None) -> ProcessedCapture:
    """The first stages of :func:`process` (same parameters): read, match, calibrate, fit and
    detect the gait events; the result has no cycles yet (:func:`cut_cycles` cuts them)."""
    clock = clock or StageClock()
    if isinstance(capture, Trial):
        trial = capture
    else:
        with clock.stage("import"):
            trial = read_c3d(capture)
    with clock.stage("protocol"):
        match = protocol if isinstance(protocol, ProtocolMatch) else match_trial(trial, protocol)
        missing = missing_landmarks_error(match, trial.source)
        if missing is not None:
            raise missing
    fitted = fit_capture(trial, protocol=match, static=static, static_pose=static_pose,
                         cutoff=cutoff, static_window=static_window, measurements=measurements,
                         heading_offsets=heading_offsets, fallback=fallback,
                         neutral_model=neutral_model, clock=clock)
    with clock.stage("events"):
        events, ground = capture_events(trial, match, motion=fitted.motion, toe_off=toe_off,
                                        max_gap_s=max_gap_s)
        shoulders = shoulder_centres(fitted.motion)
    return ProcessedCapture(trial, fitted, events, ground, shoulders, [], {})


def cut_cycles(capture: ProcessedCapture, /, *, max_gap_s: float = EventSettings.max_gap_s,
               qc_thresholds: dict | None = None, clock: StageClock | None = None,
               trim: tuple[tuple[float, float], ...] | None = None,
               picked: tuple[int, ...] | None = None, dropped: tuple[int, ...] = ()
               ) -> ProcessedCapture:
    """The last stages of :func:`process` on a capture :func:`fit_events` gives: its cycles
    (pattern, velocities, Fourier encoding, activity), their QC and the chosen ones, set on
    ``capture`` and returned. A session's choice (``session.toml``,
    :mod:`mocaplib.build.sessions`): ``trim`` the (start, end) windows, s from the capture's
    first frame, a candidate cycle lies inside; ``picked`` the indices of the cycles to keep
    instead of the rule's; ``dropped`` those never to keep."""
    clock = clock or StageClock()
    motion = capture.motion
    with clock.stage("cycles"):
        capture.cycles = motion_cycles(capture.events, motion, ground=capture.ground,
                                       shoulders=capture.shoulders,
                                       fallback_starts=capture.match.protocol.fallback_starts,
                                       max_gap_s=max_gap_s, source=capture.trial.source)
        set_activities(capture.cycles, capture.events)
        leave_out(capture.cycles, trim=trim, dropped=dropped)
    with clock.stage("entries"):
        capture.qc = qc_and_choice(capture.cycles, motion, DEFAULT_QC_THRESHOLDS
                                   if qc_thresholds is None else qc_thresholds,
                                   ground=capture.ground, picked=picked)
    return capture


def leave_out(cycles: list[Cycle], /, *, trim: tuple[tuple[float, float], ...] | None = None,
              dropped: tuple[int, ...] = ()) -> None:
    """Set ``left_out`` on the cycles outside every ``trim`` window ((start, end) s) and on
    those whose index is ``dropped``, saying why."""
    for cycle in cycles:
        if cycle.index in dropped:
            cycle.left_out = "dropped by the session (drop_cycles)"
        elif trim is not None and not any(start <= cycle.start_s and cycle.end_s <= end
                                          for start, end in trim):
            cycle.left_out = ("outside the session's trim windows " + ", ".join(
                f"{start:g}-{end:g} s" for start, end in trim))
