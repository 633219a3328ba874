"""The batch pipeline: from C3D captures to a motion library, in parallel, cached, resumable.

:func:`process_capture` takes one capture through every stage (import, protocol detection,
calibration, fit, events, cycles, pattern and velocities, Fourier, library entries). It is a
pure, picklable function of the file's content and the settings: it never raises for a bad
capture but returns a :class:`CaptureResult` carrying the error (file, stage, reason).

:func:`build` runs it over many captures — serially, in worker processes (``jobs``,
:mod:`mocaplib.workers`: a dead worker fails only its capture) or on a Dask cluster
(``scheduler``) — caches each capture's result (JSON, keyed by the SHA-256 of the file, the
settings, the tool version and the code, verified by the hash of its content when read), and
assembles the :class:`~mocaplib.library.Library` and the per-capture diagnostics the HTML report
reads, written as one unit (see ``docs/library-format.md`` and ``docs/reliability.md``).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import sys
import time
import warnings
from collections import Counter
from collections.abc import Callable, Iterable
from contextlib import contextmanager
from functools import lru_cache
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

from . import __version__
from .errors import LibraryError, MocapError, NoCycleError
from .events import TOE_OFF_DEFINITIONS
from .io import fs_text, open_regular, read_regular, unique_paths
from .io.atomic import atomic_write_files, atomic_write_text
from .io.jsonvalues import canonical_sha256, parse_json
from .sessions import plan_captures
from .workers import pinned, run_tasks
import numpy as np

from .library import (DEFAULT_QC_THRESHOLDS, DIAGNOSTICS_FORMAT, Library, assemble_library,
                      json_text, make_entry, qc_failures, to_json_data)

DIAGNOSTICS_VERSION = 1
#: Long series in the diagnostics are downsampled to at most this many points.
MAX_SERIES_POINTS = 300
#: The chosen cycle's angles are downsampled to at most this many points per DOF.
MAX_CYCLE_POINTS = 100
#: The chosen cycle's measured ankle paths are downsampled to at most this many points.
MAX_POULAINE_POINTS = 60
#: Significant digits of the diagnostics' numbers (plots need no more).
DIAGNOSTICS_DIGITS = 6
#: Seconds to wait for a Dask scheduler to answer.
SCHEDULER_TIMEOUT_S = 20
#: A forward reference whose subject faces further than this (degrees) from the direction of
#: travel is refused: that is a side-step or a diagonal (the paper's diagonals start at 60°),
#: not a forward walk. Measured uncorrected: 0.23° on the samples (placement error alone), up
#: to 7.7° on lab walks with their static taken as neutral (docs/guide/patterns.md).
FORWARD_LIMIT_DEG = 15.0
#: A forward reference's cycles slower than this (m/s) show no direction of travel.
MIN_FORWARD_SPEED = 0.3
#: The QC metrics a forward reference's cycles must pass (at the build's thresholds): the
#: marker fit, the gaps and the events, which speak for the shoulder line and the cycle. The
#: marker maximum and the Fourier metrics judge the encoding and would leave out every lab walk
#: at hand with its static taken as neutral (non-periodic arms, one marker 52-60 mm off).
FORWARD_QC = ("marker_rms_m", "gap_fraction", "event_quality")
#: A forward reference's heading correction is repeated until the reference faces its path
#: within this (degrees), at most FORWARD_PASSES times.
FORWARD_TOLERANCE_DEG = 0.01
FORWARD_PASSES = 4


@dataclass(frozen=True)
class BuildSettings:
    """Everything besides the captures that decides a library's content.

    protocol : ``"auto"`` or a protocol name / TOML path (see :mod:`mocaplib.protocols`).
    static : a static calibration capture, several (one per subject or session: each capture
        is calibrated with the one showing its subject, :func:`mocaplib.calibration.choose_static`;
        one that none shows is calibrated from itself, with a warning), or None to calibrate
        from each motion capture. :func:`build` adds the standing files among its inputs and
        takes a folder's ``session.toml`` for the captures beside it (:mod:`mocaplib.sessions`).
    static_window : (start, end) seconds of each static to calibrate on, or None: the whole
        static when it stands still, else its quietest second
        (:func:`mocaplib.calibration.standing_part`).
    require_static : a capture that no static shows fails instead of being calibrated from
        itself.
    static_pose : ``"free"`` or ``"neutral"`` (the static subject stands with every joint
        angle 0; see :func:`mocaplib.calibration.calibrate`).
    forward_reference : one or several captures in which the subject walks forwards (straight
        or curving, not side-stepping), or None: each turns the heading of the neutral static
        that shows its subject (see :func:`forward_offsets`).
    heading_offsets : per static, the heading correction (radians) the forward references
        measured; None: not measured (:func:`build` measures it when references are given).
    cutoff : marker low-pass before calibration and fit (:mod:`mocaplib.filtering`): Hz,
        ``"auto"`` (Winter's residual analysis per capture) or None (unfiltered).
    toe_off : the toe-off definition that cuts the cycles, ``"foot_velocity"`` (real feet) or
        ``"lift"`` (rigid feet); see :mod:`mocaplib.events`.
    all_cycles : keep every complete cycle, not only the one chosen per capture.
    mirror : also add each capture's left-right mirror image (:func:`mirror_entries`).
    qc_policy : ``"drop"`` leaves cycles failing a QC threshold out of the library (with a
        warning); ``"waive"`` keeps them and records the waiver and its reason in the entry.
    qc_thresholds : QC metric -> limit (None = reported only); see
        :data:`mocaplib.library.QC_LIMITS`.
    measurements : subject measurements (metres, kilograms) overriding those each
        calibration file stores (see :func:`mocaplib.calibration.calibrate`).
    """

    protocol: str = "auto"
    static: str | tuple[str, ...] | None = None
    static_pose: str = "free"
    static_window: tuple[float, float] | None = None
    require_static: bool = False
    forward_reference: str | tuple[str, ...] | None = None
    heading_offsets: tuple[float, ...] | None = None
    cutoff: float | str | None = "auto"
    toe_off: str = "foot_velocity"
    all_cycles: bool = False
    mirror: bool = False
    qc_policy: str = "drop"
    qc_thresholds: dict = field(default_factory=lambda: dict(DEFAULT_QC_THRESHOLDS))
    measurements: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("static", "forward_reference"):
            object.__setattr__(self, name, _files(getattr(self, name)))
        if self.static_window is not None:
            window = tuple(map(float, self.static_window))
            if len(window) != 2 or not 0 <= window[0] <= window[1]:
                raise MocapError(f"static_window must be (start, end) seconds with 0 <= start "
                                 f"<= end, got {self.static_window!r}")
            object.__setattr__(self, "static_window", window)
        if self.heading_offsets is not None:
            object.__setattr__(self, "heading_offsets", tuple(map(float, self.heading_offsets)))
            if len(self.heading_offsets) != len(self.statics):
                raise MocapError(f"heading_offsets needs one angle per static "
                                 f"({len(self.statics)}), got {len(self.heading_offsets)}")
        if ((self.forward_reference is not None or self.heading_offsets is not None)
                and (not self.statics or self.static_pose != "neutral")):
            raise MocapError("a forward reference turns the heading of a static in the neutral "
                             "pose: give the static, with static_pose 'neutral'")
        if self.toe_off not in TOE_OFF_DEFINITIONS:
            raise MocapError(f"toe_off must be one of {', '.join(TOE_OFF_DEFINITIONS)}, "
                             f"got {self.toe_off!r}")
        if self.qc_policy not in ("drop", "waive"):
            raise MocapError(f"qc_policy must be 'drop' or 'waive', got {self.qc_policy!r}")

    @property
    def statics(self) -> tuple[str, ...]:
        """The static trials given: none, one, or one per subject or session."""
        return (self.static,) if isinstance(self.static, str) else self.static or ()

    @property
    def forward_references(self) -> tuple[str, ...]:
        """The forward references given (none, one or several)."""
        return ((self.forward_reference,) if isinstance(self.forward_reference, str)
                else self.forward_reference or ())

    def heading_offset(self, static: int) -> float:
        """The heading correction (radians) of static number ``static``; 0 when unmeasured."""
        return 0.0 if self.heading_offsets is None else self.heading_offsets[static]

    def to_dict(self) -> dict:
        """The settings as JSON data, as stored in the library (static files and forward
        references by name only: one name, a list of names when several were given, or None)."""
        data = asdict(self)
        from .calibration import static_names

        for key, paths in (("static", self.statics),
                           ("forward_reference", self.forward_references)):
            names = static_names(paths)
            data[key] = names if len(names) > 1 else names[0] if names else None
        return to_json_data(data)


def _files(given) -> str | tuple[str, ...] | None:
    """One path, several (each file once: :func:`mocaplib.io.unique_paths`), or None for none
    or an empty one."""
    if given is None or isinstance(given, (str, os.PathLike)):
        given = () if given is None else (given,)
    paths = tuple(unique_paths(given))
    return paths[0] if len(paths) == 1 else paths or None


@dataclass
class CaptureResult:
    """What one capture gave: library entries and diagnostics, or the error that stopped it.

    Attributes
    ----------
    source : str
        The capture's path as given.
    sha256 : str
        SHA-256 of the file's bytes ("" when unreadable).
    ok : bool
    error, stage : str or None
        Why and in which stage the capture failed (None when ok).
    entries : list[dict]
        Library entries (see :func:`mocaplib.library.make_entry`).
    diagnostics : dict
        This capture's record of the diagnostics sidecar (see ``docs/library-format.md``).
    warnings : list[str]
    stage_times : dict[str, float]
        Seconds spent in each stage.
    n_frames : int
    n_cycles : int
        Complete cycles found (entries may be fewer: one chosen, QC drops).
    from_cache : bool
    static : str or None
        File name of the static trial the capture was calibrated with (None: none).
    no_entry : str or None
        Why a capture that did not fail gave no library entry (None when it gave some, or
        failed): no complete cycle, every cycle left out by QC, or a static trial that cannot
        be a rest entry.
    """

    source: str
    sha256: str = ""
    ok: bool = True
    error: str | None = None
    stage: str | None = None
    entries: list = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    stage_times: dict = field(default_factory=dict)
    n_frames: int = 0
    n_cycles: int = 0
    from_cache: bool = False
    static: str | None = None
    no_entry: str | None = None

    @property
    def file(self) -> str:
        """The capture's file name as text (:func:`mocaplib.io.fs_text`)."""
        return fs_text(Path(self.source).name)

    def to_dict(self) -> dict:
        return to_json_data({f.name: getattr(self, f.name) for f in fields(self)})

    @classmethod
    def from_dict(cls, data: dict) -> "CaptureResult":
        return cls(**{f.name: data[f.name] for f in fields(cls) if f.name in data})


# --------------------------------------------------------------------------- one capture
class _Clock:
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


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes; OSError for anything but a regular file (a pipe or
    device could block or never end: :func:`mocaplib.io.open_regular`)."""
    digest = hashlib.sha256()
    with open_regular(path) as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def process_capture(path: str | os.PathLike, settings: BuildSettings) -> CaptureResult:
    """Take one capture through every stage; never raises for a bad capture.

    Returns a :class:`CaptureResult`: entries and diagnostics when it worked, otherwise
    ``ok=False`` with ``stage`` and ``error`` (the error names the file). A capture that holds
    no complete cycle (:class:`~mocaplib.errors.NoCycleError`), or whose cycles QC leaves out,
    is not a failure: it gives no entry and ``no_entry`` says why. Nor is a static trial of the
    settings (:attr:`BuildSettings.statics`) processed as a capture: whatever stops it,
    ``no_entry`` says so.
    """
    result = CaptureResult(source=os.fspath(path))
    if result.file != Path(path).name:
        result.warnings.append(f"the file name is not valid UTF-8: its entries name it "
                               f"{result.file!r} (the bytes read as Latin-1)")
    clock = _Clock()
    is_static = os.path.realpath(path) in {os.path.realpath(s) for s in settings.statics}
    try:
        with clock.stage("read"):
            result.sha256 = file_sha256(path)
        _run_stages(Path(path), settings, result, clock)
    except NoCycleError as exc:
        result.no_entry = f"{exc.message} ({exc.hint})" if exc.hint else exc.message
    except MocapError as exc:
        _fail(result, clock.current, str(exc) if exc.path else f"{path}: {exc}")
    except OSError as exc:
        _fail(result, clock.current, f"{path}: cannot read: {exc.strerror or exc}")
    except Exception as exc:  # a bug on an odd capture must not stop a whole build
        _fail(result, clock.current, f"{path}: internal error in stage {clock.current}: "
                                     f"{type(exc).__name__}: {exc}")
    if is_static and not result.ok:
        why = (result.error or "").removeprefix(f"{path}: ")
        result.ok, result.error, result.no_entry = True, None, \
            f"a static trial: used to calibrate, no entry of its own ({result.stage}: {why})"
        result.stage = None
    elif result.ok and not result.entries and result.no_entry is None:
        result.no_entry = "every complete cycle was left out by QC (see the warnings)"
    elif is_static and result.no_entry:
        result.no_entry = f"a static trial: used to calibrate, no entry of its own " \
                          f"({result.no_entry})"
    result.stage_times = clock.times
    return result


def _run_stages(path: Path, settings: BuildSettings, result: CaptureResult, clock: _Clock):
    """:func:`_cut_capture`, then the entries (and with ``settings.mirror`` those of the mirror
    image, :func:`mirror_entries`); fills ``result`` (raises MocapError for a bad capture)."""
    trial, motion, cycles, events, ground = _cut_capture(path, settings, result, clock)
    with clock.stage("entries"):
        result.n_cycles = sum(not c.rest for c in cycles)
        qcs = qc_and_choice(cycles, motion, settings.qc_thresholds, ground=ground)
        kept = [c for c in cycles if c.chosen or settings.all_cycles]
    with clock.stage("poulaines"):
        shapes = {c.index: cycle_shape(motion, c) for c in kept}
    with clock.stage("entries"):
        result.entries = _entries(path, result, kept, qcs, settings, motion, trial.first_frame,
                                  shapes)
        result.diagnostics.update(_cycle_diagnostics(
            motion, cycles, {e["cycle_index"]: e["id"] for e in result.entries}, shapes))
    if settings.mirror and result.entries:
        with clock.stage("mirror"):
            images, entries = mirror_entries(path, result, cycles, motion, events, ground,
                                             settings, trial.first_frame)
            result.entries += entries
            ids = {e["cycle_index"]: e["id"] for e in entries}
            result.diagnostics["mirror_cycles"] = to_json_data(
                [{**c.to_dict(), "entry_id": ids.get(c.index)} for c in images],
                DIAGNOSTICS_DIGITS)


def _cut_capture(path: Path, settings: BuildSettings, result: CaptureResult, clock: _Clock):
    """import -> protocol -> calibrate -> fit -> events -> cycles (patterns, velocities,
    Fourier); returns the trial, its :class:`~mocaplib.motion.Motion`, its cycles, its gait
    events and the ground's velocity (3,) m/s (:func:`mocaplib.events.capture_events`), and puts
    the warnings, the static used and the capture's diagnostic series in ``result``.

    The stages are chained as ``mocaplib cycles`` chains them (:func:`mocaplib.ik.fit_capture`
    spelled out, so each stage is timed; then the same :func:`mocaplib.events.capture_events`
    and :func:`mocaplib.cycles.motion_cycles`), so both give the same cycles. Settings with a
    forward reference must carry its measured ``heading_offsets`` (:func:`build` measures
    them).
    """
    if settings.forward_reference is not None and settings.heading_offsets is None:
        raise MocapError("the forward reference's heading offsets are not measured: build with "
                         "pipeline.build, or set heading_offsets=forward_offsets(settings)")
    from .calibration import calibrate, choose_static, static_names
    from .errors import CalibrationError
    from .cycles import motion_cycles, shoulder_centres
    from .filtering import filter_trial
    from .events import capture_events
    from .ik import fit_filtered
    from .io.c3d import read_c3d
    from .protocols import match_trial, missing_landmarks_error

    with clock.stage("import"):
        trial = read_c3d(path)
        statics = [(static, _static_sha256(static)) for static in settings.statics]
        static_trials = [_read_static(*key) for key in statics]
    result.n_frames = trial.n_frames
    result.warnings.extend(trial.warnings)
    with clock.stage("protocol"):
        match = match_trial(trial, settings.protocol)
        missing = missing_landmarks_error(match, path)
        if missing is not None:
            raise missing
    with clock.stage("filter"):
        filtered, cutoff = filter_trial(trial, cutoff=settings.cutoff)
    with clock.stage("calibrate"):
        try:
            chosen = choose_static(filtered, static_trials, match.protocol, check_one=True)
            model = _static_model(filtered, match.protocol, settings, statics, static_trials,
                                  chosen)
        except CalibrationError as exc:
            if not static_trials or settings.require_static:
                raise
            result.warnings.append(f"calibrated from the capture itself: no static shows its "
                                   f"subject ({exc.message})")
            chosen, model = None, calibrate(filtered, protocol=match.protocol,
                                            measurements=settings.measurements)
        if chosen is not None:
            result.static = static_names(settings.statics)[chosen]
            window = model.static_window_s
            result.diagnostics["static_window_s"] = list(window)
            if window != (0.0, static_trials[chosen].duration):
                result.warnings.append(f"static {result.static}: calibrated on its stretch "
                                       f"{window[0]:.2f}-{window[1]:.2f} s (of "
                                       f"{static_trials[chosen].duration:.2f} s)")
    if chosen is not None:                       # without one the fit reports the swaps
        result.warnings.extend(model.swap_warnings)
    with clock.stage("fit"):
        motion, _ = fit_filtered(trial, model, cutoff=cutoff)
    result.warnings.extend(motion.repair_warnings())
    if motion.locked_dofs:
        result.warnings.append(f"protocol {match.protocol.name!r} cannot see "
                               f"{len(motion.locked_dofs)} DOFs, held at 0: "
                               f"{', '.join(motion.locked_dofs)}")
    result.warnings.extend(motion.limit_warnings())
    if motion.failed.any():
        result.warnings.append(f"{int(motion.failed.sum())} frames could not be fitted "
                               "(interpolated)")
    if motion.rejected.any():
        result.warnings.append(f"{int(motion.rejected.sum())} marker samples removed as "
                               "outliers (jumping or mislabelled trajectories)")
    with clock.stage("events"):
        events, ground = capture_events(trial, match, motion=motion, toe_off=settings.toe_off)
        shoulders = shoulder_centres(motion)
        result.diagnostics.update(_series(trial, motion, shoulders, events, cutoff))
    with clock.stage("cycles"):
        cycles = motion_cycles(events, motion, ground=ground, shoulders=shoulders, source=path)
    return trial, motion, cycles, events, ground


def _static_model(filtered, protocol, settings: BuildSettings, statics, static_trials,
                  chosen: int | None):
    """The subject model of a capture (its markers ``filtered``) from static number ``chosen``
    (None: from the capture itself); ``statics`` (path, SHA-256) and ``static_trials`` the
    build's. Raises :class:`~mocaplib.errors.CalibrationError` when the static cannot serve
    (:func:`mocaplib.calibration.calibrate`, :func:`mocaplib.calibration.check_static`), or
    when ``settings.require_static`` and there is none."""
    from .calibration import calibrate, check_static
    from .errors import CalibrationError

    if chosen is None and settings.require_static:
        raise CalibrationError("no static trial given, and the build requires one "
                               "(require_static)", path=filtered.source,
                               hint="give the subject's static with --static or a "
                                    "session.toml, or leave --require-static out")
    static = None if chosen is None else static_trials[chosen]
    if static is not None and settings.static_pose == "neutral":
        model = _neutral_model(*statics[chosen], protocol, settings.heading_offset(chosen),
                               tuple(sorted(settings.measurements.items())),
                               settings.static_window)
        check_static(filtered, static, model)
        return model
    return calibrate(filtered, protocol=protocol, static=static,
                     static_pose=settings.static_pose, measurements=settings.measurements,
                     static_window=settings.static_window)


def _static_sha256(path: str) -> str:
    """SHA-256 of a static trial's file; one that cannot be read is named (C3DError)."""
    from .errors import C3DError

    try:
        return file_sha256(path)
    except OSError as exc:
        raise C3DError(f"cannot read the static trial: {exc.strerror or exc}", path=path,
                       hint="check the --static path") from None


@lru_cache(maxsize=None)
def _read_static(path: str, sha256: str):
    """The static trial, read once per worker process for each content (``sha256``)."""
    from .io.c3d import read_c3d
    return read_c3d(path)


@lru_cache(maxsize=None)
def _neutral_model(path: str, sha256: str, protocol, heading_offset: float,
                   measurements: tuple = (), window: tuple[float, float] | None = None):
    """The model calibrated on the neutral-pose static ``path`` with its heading turned by
    ``heading_offset`` (radians), once per worker process for each content, protocol and
    offset and measurements ((name, value) pairs) and static ``window``: it depends on nothing
    else, so each
    capture only checks that it shows the same subject
    (:func:`mocaplib.calibration.check_static`)."""
    from .calibration import calibrate
    static = _read_static(path, sha256)
    return calibrate(static, protocol=protocol, static=static, static_pose="neutral",
                     heading_offset=heading_offset, measurements=dict(measurements),
                     static_window=window)


def forward_offsets(settings: BuildSettings) -> tuple[float, ...]:
    """Per static of ``settings``, the heading correction (radians) that its forward references
    measure; 0 for a static that none shows.

    A neutral static fixes the heading of every segment frame by fitting the root to all
    markers at their catalogue positions, so the placement error turns it by a fraction of a
    degree, and v̂_l of every capture is off by about −v̂ times that angle
    (docs/guide/patterns.md). A forward reference — a capture in which the subject walks
    forwards — measures the angle: it is taken through the build's stages with the static that
    shows its subject (:func:`_cut_capture`), and the mean of atan2(v̂_l, v̂_f) over its cycles
    (:func:`_facing_angles`) is how far the static's heading must turn for the subject to
    face where they walk. Several references of one static are averaged. The turn is repeated
    on the turned static until each reference faces its path within
    :data:`FORWARD_TOLERANCE_DEG` (one turn leaves 4 % on the samples, 5 % on a lab walk,
    whose poses are further from the static's); the offset is the sum of the turns.
    Raises :class:`~mocaplib.errors.CalibrationError` naming a reference that cannot be
    processed, shows no walking cycle, or faces further than :data:`FORWARD_LIMIT_DEG` from
    its path, or the references when :data:`FORWARD_PASSES` turns do not settle it.
    """
    from .calibration import static_names
    from .errors import CalibrationError

    offsets = tuple(0.0 for _ in settings.statics)
    for _ in range(FORWARD_PASSES):
        residuals = _facing_angles(replace(settings, heading_offsets=offsets))
        offsets = tuple(offset + residual for offset, residual in zip(offsets, residuals))
        if max(map(abs, residuals)) < np.deg2rad(FORWARD_TOLERANCE_DEG):
            return offsets
    unsettled = ", ".join(f"{name} {np.rad2deg(r):+.3f}°" for name, r in
                          zip(static_names(settings.statics), residuals)
                          if abs(r) >= np.deg2rad(FORWARD_TOLERANCE_DEG))
    raise CalibrationError(f"the forward references do not settle the heading of the static: "
                           f"turn {FORWARD_PASSES} of {FORWARD_PASSES} was still {unsettled} "
                           f"(the turns stop below {FORWARD_TOLERANCE_DEG:g}°)",
                           path=", ".join(settings.forward_references),
                           hint="give references whose cycles pass QC steadily (more cycles, "
                                "a better fit), or build without --forward-reference")


def _facing_angles(settings: BuildSettings) -> tuple[float, ...]:
    """Per static, the mean over its forward references of where the subject moves relative
    to where they face (radians, to the left; 0 for a static without a reference): the mean
    atan2(v̂_l, v̂_f) of each reference's complete cycles that are at least
    :data:`MIN_FORWARD_SPEED` fast and pass the build's QC of :data:`FORWARD_QC`. A reference
    is calibrated with the static that shows its subject, never from itself
    (``require_static``)."""
    from .calibration import static_names
    from .errors import CalibrationError

    names = static_names(settings.statics)
    found: list[list[float]] = [[] for _ in names]
    hint = "give a capture in which the subject walks forwards, straight or curving"
    limits = {name: settings.qc_thresholds.get(name) for name in FORWARD_QC}
    for reference in settings.forward_references:
        result = CaptureResult(source=reference)
        try:
            _, motion, cycles, _, ground = _cut_capture(
                Path(reference), replace(settings, require_static=True), result, _Clock())
        except OSError as exc:
            raise CalibrationError(f"cannot read the forward reference: {exc.strerror or exc}",
                                   path=reference, hint="check the path") from None
        except MocapError as exc:
            where = "" if exc.path in (None, reference) else f"{exc.path}: "
            own = ("give a forward walk of a subject whose static you pass with --static"
                   if isinstance(exc, CalibrationError) else exc.hint)
            raise CalibrationError(f"the forward reference cannot be processed: "
                                   f"{where}{exc.message}", path=reference,
                                   hint=own or hint) from None
        qcs = qc_and_choice(cycles, motion, settings.qc_thresholds, ground=ground)
        walking = [c for c in cycles if not c.rest and c.velocities.v >= MIN_FORWARD_SPEED]
        failures = {c.index: qc_failures({name: qcs[c.index][name] for name in FORWARD_QC},
                                         limits) for c in walking}
        moving = [c.velocities for c in walking if not failures[c.index]]
        if not moving:
            why = "; ".join(f"cycle {i}: {', '.join(f)}" for i, f in failures.items())
            raise CalibrationError(
                f"the forward reference has no complete gait cycle at {MIN_FORWARD_SPEED} m/s "
                f"or faster that passes QC" + (f" ({why})" if why else ""), path=reference,
                hint="the fit of its markers must pass QC: check the static is this subject's "
                     "and the labels" if why else hint)
        angle = float(np.mean([np.arctan2(c.v_l, c.v_f) for c in moving]))
        if abs(np.rad2deg(angle)) > FORWARD_LIMIT_DEG:
            raise CalibrationError(
                f"in the forward reference the subject moves {abs(np.rad2deg(angle)):.1f}° to "
                f"the {'left' if angle > 0 else 'right'} of where they face (limit "
                f"{FORWARD_LIMIT_DEG:g}°): a side-step or a diagonal, not a forward walk",
                path=reference, hint=hint)
        found[names.index(result.static)].append(angle)
    return tuple(float(np.mean(angles)) if angles else 0.0 for angles in found)


def qc_and_choice(cycles, motion, thresholds: dict, *, ground: np.ndarray | None = None
                  ) -> dict[int, dict]:
    """QC metrics (:func:`cycle_qc`) of every cycle of a fitted capture, by cycle index, and the
    chosen cycle re-chosen among those that pass ``thresholds`` when any does
    (:func:`mocaplib.cycles.choose_cycle`): a capture whose steadiest cycle fails QC
    contributes its steadiest good one. What ``mocaplib build`` and ``mocaplib cycles`` run.
    ``ground``: the floor's velocity (3,) m/s on a treadmill
    (:func:`mocaplib.events.capture_events`), for the internal power."""
    from .cycles import choose_cycle

    series = _qc_series(motion, ground)
    qcs = {c.index: cycle_qc(c, motion, series) for c in cycles}
    if len(cycles) > 1:
        choose_cycle(cycles, eligible={i for i, qc in qcs.items()
                                       if not qc_failures(qc, thresholds)})
    return qcs


def _entries(path: Path, result: CaptureResult, cycles, qcs: dict[int, dict],
             settings: BuildSettings, motion, first_frame: int, shapes: dict, *,
             mirror_of: dict[int, str] | None = None):
    """Library entries of the kept cycles of the fitted ``motion``; cycles failing QC are
    dropped or waived. ``qcs``: QC metrics by cycle index (:func:`qc_and_choice`);
    ``first_frame``: the capture's first C3D frame number (``start_s`` counts from it);
    ``shapes``: :func:`cycle_shape` by cycle index; ``mirror_of``: for the cycles of a mirror
    image (``motion`` mirrored), the id of the entry each one mirrors, by cycle index."""
    from .mirror import MIRROR_TAG

    entries = []
    for cycle in cycles:
        qc = qcs[cycle.index]
        failures = qc_failures(qc, settings.qc_thresholds)
        image_of = None if mirror_of is None else mirror_of[cycle.index]
        where = (f"{'mirror image ' if image_of else ''}cycle {cycle.index} "
                 f"({cycle.start_s:.2f}-{cycle.end_s:.2f} s)")
        waived = {}
        if failures and settings.qc_policy == "drop":
            result.warnings.append(f"{where} left out of the library: {'; '.join(failures)}")
            continue
        if failures:
            waived = {f.split()[0]: f"accepted by build setting qc_policy=waive ({f})"
                      for f in failures}
            result.warnings.append(f"{where} kept with QC waived: {'; '.join(failures)}")
        vel, enc = cycle.velocities, cycle.encoding
        entries.append(make_entry(
            id=f"{fs_text(path.stem)}{MIRROR_TAG if image_of else ''}_c{cycle.index}",
            source_file=fs_text(path.name),
            source_sha256=result.sha256, cycle_index=cycle.index, chosen=cycle.chosen,
            start_s=cycle.start_s, end_s=cycle.end_s, T=cycle.period,
            pattern=vel.pattern.to_dict(), v=vel.v, omega=vel.omega, v_l=vel.v_l, v_f=vel.v_f,
            a=enc.series.a, b=enc.series.b, root_drift=_drift(enc.drift),
            qc=qc, qc_waived=waived, locomotion_class=locomotion_class(path, cycle.rest),
            segment_lengths_m=motion.skeleton.lengths, rate_hz=motion.rate,
            first_frame=first_frame, joint_shifts_m=motion.skeleton.shifts,
            held_dofs=motion.unobservable,
            dofs_at_limit=motion.limit_shares(inside_cycle(cycle, motion)),
            right_toe_off_s=cycle.right_toe_off,
            mirror_of=image_of, mirror_method=None if image_of is None else "capture",
            poulaine=None if cycle.rest else shapes[cycle.index]["poulaine"].to_dict(),
            ramp=enc.ramp))
    return entries


def cycle_shape(motion, cycle) -> dict:
    """A cycle's samples: ``phase`` (n,) t/T in [0, 1), ``q`` its coordinates (n, D) in its
    path frame (root as the library stores it), and, unless it is rest, its ``poulaine``
    (:class:`mocaplib.poulaine.Poulaine`) and the ``measured`` ankle centres (n, 2, 3) m it
    models (:func:`mocaplib.poulaine.cycle_poulaine`)."""
    from .filtering import resample
    from .patterns import cycle_times
    from .poulaine import cycle_poulaine

    times = cycle_times(cycle.start_s, cycle.end_s, motion.rate)[:-1]
    q = resample(np.unwrap(motion.q, axis=0), motion.rate, times)
    shape = {"phase": (times - cycle.start_s) / cycle.period,
             "q": cycle.encoding.drift.remove(q, times - cycle.start_s)}
    if not cycle.rest:
        shape["poulaine"], shape["measured"] = cycle_poulaine(
            motion.skeleton, shape["q"], shape["phase"], cycle.encoding.drift)
    return shape


def mirror_entries(path: Path, result: CaptureResult, cycles, motion, events, ground,
                   settings: BuildSettings, first_frame: int) -> tuple[list, list[dict]]:
    """The capture's mirror image, cut and measured as a capture: its cycles (all of them,
    :class:`~mocaplib.cycles.Cycle`) and the entries they give.

    The fitted ``motion`` is reflected (world y -> -y, :func:`mocaplib.mirror.mirror_motion`)
    and its gait events exchange sides, so its cycles run between the capture's *right*
    toe-offs; patterns, velocities, Fourier series and QC are measured on them as on any
    capture (:func:`mocaplib.cycles.motion_cycles`, :func:`cycle_qc`). Each names in
    ``mirror_of`` the capture's entry (in ``result.entries``) whose cycle overlaps it most in
    time (the nearest when none overlaps). Which become entries: the image of the capture's
    chosen cycle, the one overlapping it most (chosen when its source is in the library), or
    with ``settings.all_cycles`` every image. QC failures are dropped or waived as for the
    capture's own cycles; an image within :data:`mocaplib.mirror.SYMMETRIC_DISTANCE` of its
    source in the control space is left out (the cycle is its own mirror image: straight
    walks, runs, rest). What is left out is said in ``result.warnings``.
    """
    from .cycles import motion_cycles
    from .mirror import (REFLECTION, SYMMETRIC_DISTANCE, image_distance, mirror_events,
                         mirror_motion)

    mirrored = mirror_motion(motion)
    try:
        images = motion_cycles(mirror_events(events), mirrored,
                               ground=None if ground is None else REFLECTION @ ground,
                               source=path)
    except MocapError as exc:  # fewer than two right toe-offs: the capture's own entries stay
        result.warnings.append(f"no mirror image: {exc.message}")
        return [], []
    sources = {e["cycle_index"]: e for e in result.entries}
    chosen = next(c for c in cycles if c.chosen)
    partner = _nearest(chosen, images)
    for image in images:
        image.chosen = image is partner and chosen.index in sources
    kept = images if settings.all_cycles else [partner]
    own = [c for c in cycles if c.index in sources]
    mirror_of = {image.index: sources[_nearest(image, own).index]["id"] for image in kept}
    series = _qc_series(mirrored, None if ground is None else REFLECTION @ ground)
    qcs = {image.index: cycle_qc(image, mirrored, series) for image in kept}
    shapes = {image.index: cycle_shape(mirrored, image) for image in kept}
    entries = []
    for entry in _entries(path, result, kept, qcs, settings, mirrored, first_frame, shapes,
                          mirror_of=mirror_of):
        source = next(e for e in result.entries if e["id"] == entry["mirror_of"])
        distance = image_distance(source, entry)
        if distance < SYMMETRIC_DISTANCE:
            result.warnings.append(f"mirror image cycle {entry['cycle_index']} left out: it "
                                   f"lies {distance:.3f} (normalised) from {source['id']} in "
                                   f"the control space, within {SYMMETRIC_DISTANCE}: that "
                                   "cycle is its own mirror image")
        else:
            entries.append(entry)
    return images, entries


def _nearest(cycle, others):
    """The cycle of ``others`` (not empty) overlapping ``cycle`` longest in time, or nearest
    to it when none overlaps (the earlier of equals)."""
    def overlap(other):
        return min(cycle.end_s, other.end_s) - max(cycle.start_s, other.start_s)
    return max(others, key=lambda other: (overlap(other), -other.start_s))


def _drift(drift) -> dict:
    """The moving frame's velocities (its displacement per cycle follows: ``make_entry``)."""
    return {"u_f_m_s": drift.u_f, "u_l_m_s": drift.u_l, "omega_rad_s": drift.omega}


def _qc_series(motion, ground: np.ndarray | None = None) -> dict:
    """The capture-wide series the QC of its cycles reads: ``q`` the coordinates (F, D),
    rotations unwrapped; ``third`` the third time derivative (F, J) rad/s^3 of the joint angles
    (:data:`mocaplib.skeleton.JOINT_ANGLES`) and ``energies`` each body segment's energy (F, B)
    J/kg (:func:`mocaplib.criteria.segment_energies`, positions relative to the floor moving at
    ``ground`` m/s), both from the coordinates low-passed at
    :data:`mocaplib.filtering.WALKING_CUTOFF` (None when the capture is too short to be
    filtered): derivatives of unfiltered angles would measure fit noise only."""
    from .criteria import segment_energies, third_derivative
    from .filtering import WALKING_CUTOFF, lowpass, shortest_run
    from .fourier import ROOT_X, ROOT_Y
    from .skeleton import JOINT_ANGLES, TRANSLATION

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


def cycle_qc(cycle, motion, series: dict | None = None) -> dict:
    """QC metrics of one cycle (names and units of :data:`mocaplib.library.QC_LIMITS`).

    marker RMS / max: fit residuals of the frames in the cycle (m), of the markers the fit
    follows (:meth:`mocaplib.motion.Motion.trusted`); gap fraction: missing marker samples
    among them; event quality: the cycle's; Fourier RMS: the worst rotational
    DOF's reconstruction RMS (rad); closure (C2): norm of the joint-angle change from start to
    end (rad, :func:`mocaplib.criteria.closure`); jerk (C1): RMS over the cycle's frames and the
    joint angles of their third time derivative (rad/s^3); internal power (C3): the absolute
    energy changes of every body segment between the cycle's consecutive frames over their
    span, W/kg (:func:`mocaplib.criteria.internal_power`); jerk and power are None when the
    capture is too short to be filtered. ``series``: the capture's :func:`_qc_series`, when
    already computed.
    """
    from .criteria import closure, internal_power, jerk_rms
    from .filtering import resample
    from .skeleton import TRANSLATION

    series = _qc_series(motion) if series is None else series
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


def _series(trial, motion, shoulders, events, cutoff_hz) -> dict:
    """The diagnostics known once events are detected (kept when a later stage fails)."""
    every = downsample(trial.n_frames)
    with warnings.catch_warnings():  # frames without any marker have no RMS: NaN, said so
        warnings.simplefilter("ignore", RuntimeWarning)
        frame_rms = motion.frame_rms()
    mid = 0.5 * (shoulders[0] + shoulders[1])
    return to_json_data({
        "rate_hz": trial.rate,
        "marker_cutoff_hz": cutoff_hz,
        "time_s": trial.time[every],
        "shoulder_mid_xy": mid[every, :2],
        "frame_rms_m": frame_rms[every],
        "events": [{"side": e.side, "kind": e.kind, "time_s": e.time_s} for e in events],
        "repairs": [r.as_dict(trial.rate) for r in motion.repairs],
    }, DIAGNOSTICS_DIGITS)


def _cycle_diagnostics(motion, cycles, entry_ids, shapes: dict) -> dict:
    """Every cycle's summary, the chosen cycle's angles (root in the moving frame) and its
    measured ankle paths (``shapes``: :func:`cycle_shape` by cycle index)."""
    chosen = next(c for c in cycles if c.chosen)
    shape = shapes[chosen.index]
    pick = downsample(len(shape["phase"]), MAX_CYCLE_POINTS)
    angles = {"time_s": shape["phase"][pick] * chosen.period}
    angles.update({name: shape["q"][pick, d] for d, name in enumerate(motion.angles.columns)})
    poulaine = None
    if "measured" in shape:
        pick = downsample(len(shape["phase"]), MAX_POULAINE_POINTS)
        poulaine = {"phase": shape["phase"][pick], "left_m": shape["measured"][pick, 0],
                    "right_m": shape["measured"][pick, 1]}
    return to_json_data({
        "cycles": [{**c.to_dict(), "entry_id": entry_ids.get(c.index)} for c in cycles],
        "angles": angles, "poulaine": poulaine,
    }, DIAGNOSTICS_DIGITS)


def locomotion_class(path: Path, rest: bool) -> str | None:
    """The capture's locomotion class, if known, else None.

    In order: the ``class`` of its truth sidecar ``<stem>.truth.json`` (written by
    :mod:`mocaplib.synth`); the class of the capture named like the file in a shipped capture
    plan (``protocols/*plan*.toml``); ``"rest"`` for a standing capture.
    """
    truth = path.with_name(f"{path.stem}.truth.json")
    if truth.is_file():
        try:
            found = json.loads(truth.read_text(encoding="utf-8")).get("class")
        except (OSError, ValueError, AttributeError):
            found = None
        if isinstance(found, str) and found:
            return found
    planned = _planned_classes().get(path.stem)
    if planned:
        return planned
    return "rest" if rest else None


@lru_cache(maxsize=1)
def _planned_classes() -> dict[str, str]:
    """Capture name -> class over the shipped capture plans."""
    from .protocols import capture_plans
    from .synth.plan import load_plan

    classes: dict[str, str] = {}
    for plan_path in capture_plans():
        try:
            plan = load_plan(plan_path)
        except MocapError:
            continue  # a broken plan does not stop a build; `mocaplib synth` reports it
        for capture in plan.captures:
            classes.setdefault(capture.name, capture.cls)
    return classes


def _fail(result: CaptureResult, stage: str | None, reason: str) -> None:
    result.ok, result.stage, result.error = False, stage, reason
    result.entries = []


# --------------------------------------------------------------------------- many captures
@dataclass
class BuildResult:
    """A finished build: the library, every capture's result (input order) and a summary;
    ``notes`` are the build's own warnings (e.g. a cache it could not write)."""

    library: Library
    captures: list[CaptureResult]
    settings: BuildSettings
    seconds: float = 0.0
    notes: list = field(default_factory=list)

    @property
    def failures(self) -> list[CaptureResult]:
        return [c for c in self.captures if not c.ok]

    @property
    def ok(self) -> bool:
        return not self.failures

    def summary(self) -> dict:
        """Counts, failures (file, stage, reason) and warnings, as JSON data."""
        return {
            "captures": len(self.captures),
            "succeeded": sum(c.ok for c in self.captures),
            "failed": len(self.failures),
            "from_cache": sum(c.from_cache for c in self.captures),
            "cycles": sum(c.n_cycles for c in self.captures),
            "entries": len(self.library),
            "seconds": round(self.seconds, 3),
            "failures": [{"file": c.source, "stage": c.stage, "reason": c.error}
                         for c in self.failures],
            "no_entry": [{"file": c.source, "reason": c.no_entry} for c in self.captures
                         if c.no_entry],
            "warnings": [{"file": c.source, "warning": w} for c in self.captures
                         for w in c.warnings],
            "statics": dict(Counter(c.static for c in self.captures if c.static)),
            "notes": list(self.notes),
        }

    def summary_text(self) -> str:
        """The summary as a short table for people."""
        s = self.summary()
        lines = [f"captures {s['captures']}  ok {s['succeeded']}  failed {s['failed']}  "
                 f"cached {s['from_cache']}  cycles {s['cycles']}  entries {s['entries']}  "
                 f"({s['seconds']:.1f} s)"]
        from .calibration import static_names

        names = static_names(self.settings.statics)
        if len(names) > 1:
            lines.append("captures per static: " + ", ".join(
                f"{name} {s['statics'].get(name, 0)}" for name in names))
        if self.settings.forward_reference is not None:
            lines.append("heading turned by the forward reference: " + ", ".join(
                f"{name} {np.rad2deg(offset):+.3f}°"
                for name, offset in zip(names, self.settings.heading_offsets)))
        if s["failures"]:
            lines.append("failures:")
            lines += [f"  {f['file']} [{f['stage']}]: "
                      f"{(f['reason'] or '').removeprefix(f['file'] + ': ')}"
                      for f in s["failures"]]
        if s["no_entry"]:
            lines.append("no entry:")
            lines += [f"  {Path(n['file']).name}: {n['reason']}" for n in s["no_entry"]]
        lines += [f"note: {note}" for note in s["notes"]]
        if s["warnings"]:
            lines.append(f"warnings ({len(s['warnings'])}):")
            lines += [f"  {Path(w['file']).name}: {w['warning']}" for w in s["warnings"]]
        return "\n".join(lines)

    def diagnostics(self, library_name: str = "library.json", *,
                    library_sha256: str | None = None) -> dict:
        """The diagnostics sidecar's content (see ``docs/library-format.md``);
        ``library_sha256``: the SHA-256 of the library file's bytes it belongs to."""
        records = []
        for c in self.captures:
            record = {key: None for key in ("rate_hz",)}
            record.update({"time_s": [], "shoulder_mid_xy": [], "frame_rms_m": [],
                           "events": [], "cycles": [], "angles": {}, "poulaine": None})
            record.update(c.diagnostics)
            record.update({"source": c.file, "ok": c.ok, "error": c.error, "stage": c.stage,
                           "static": c.static, "no_entry": c.no_entry,
                           "warnings": list(c.warnings)})
            records.append(record)
        return to_json_data({"format": DIAGNOSTICS_FORMAT, "version": DIAGNOSTICS_VERSION,
                             "library": library_name, "library_sha256": library_sha256,
                             "captures": records}, DIAGNOSTICS_DIGITS)

    def write(self, path: str | os.PathLike) -> tuple[Path, Path]:
        """Write the library and ``<stem>.diagnostics.json`` beside it, as one unit: both are
        written to temporaries first (a full disk or an error leaves both old files as they
        were), then the library is renamed into place and the sidecar last. The sidecar names
        the SHA-256 of the library's bytes, so a reader tells a sidecar left from an earlier
        build (a kill between the two renames) from the library's own and does not use it
        (see ``docs/reliability.md``).

        Raises :class:`LibraryError` and writes nothing when the library has no entry (every
        capture failed, or no cycle was kept): an empty library never replaces one.
        """
        path = Path(path)
        if not len(self.library):
            why = ("every capture failed" if not any(c.ok for c in self.captures) else
                   "no capture gave a library entry (see the warnings)")
            raise LibraryError(f"nothing written: {why}", path=path,
                               hint="fix what the summary names and build again; a library "
                                    "already there is left as it was")
        sidecar = diagnostics_path(path)
        library = self.library.to_json().encode("utf-8")
        diagnostics = self.diagnostics(path.name,
                                       library_sha256=hashlib.sha256(library).hexdigest())
        atomic_write_files([(path, library), (sidecar, json_text(diagnostics).encode("utf-8"))])
        return path, sidecar


def diagnostics_path(library_path: str | os.PathLike) -> Path:
    """Where the diagnostics sidecar of a library file goes: ``<stem>.diagnostics.json``."""
    path = Path(library_path)
    return path.with_name(f"{path.stem}.diagnostics.json")


def find_captures(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """C3D files named directly, plus the ``*.c3d`` entries found recursively (sorted) in
    folders.

    In a folder, every entry named ``*.c3d`` that is not a folder is a capture: a pipe, a
    device, a dangling link or a link loop too, which then fails alone, saying why, when it is
    read. Links to folders are not followed (a link loop cannot trap the search). The same file
    named twice is processed once. Raises :class:`MocapError` for a path that does not exist.
    """
    found: dict[str, Path] = {}
    for item in inputs:
        path = Path(item)
        if path.is_dir():  # a folder or pipe named like a capture is not one
            candidates = _c3d_entries(path)
        elif os.path.lexists(path):  # reading a pipe or a broken link fails and says why
            candidates = [path]
        else:
            raise MocapError("no such file or folder", path=path,
                             hint="check the path; folders are searched for *.c3d")
        for candidate in candidates:
            found.setdefault(os.path.realpath(candidate), candidate)
    return list(found.values())


def _c3d_entries(folder: Path) -> list[Path]:
    """Entries named ``*.c3d`` (any case) in ``folder`` and its subfolders that are not
    folders, sorted; links to folders are neither taken nor followed."""
    entries = []
    for root, _, names in os.walk(folder):
        entries += [Path(root, name) for name in names if Path(name).suffix.lower() == ".c3d"]
    return sorted(entries)


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 of mocaplib's own code and data (``*.py``, protocols, schema), read once.

    Part of every cache key: a result cached by different code (a development checkout, a
    patched install) is never reused, even when the version number did not change.
    """
    root = Path(__file__).resolve().parent
    files = [Path(folder, name) for folder, _, names in os.walk(root, followlinks=True)
             for name in names if name.endswith((".py", ".toml", ".json"))]
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def cache_key(path: Path, sha256: str, settings: BuildSettings) -> str:
    """Hex key of a capture's cached result: file name and content, settings, tool version.

    The static trial's content, the capture's truth sidecar (which names its locomotion
    class), :func:`code_fingerprint` and the users' protocol folders
    (:func:`mocaplib.protocols.user_fingerprint`) are part of the key, so editing any of them
    invalidates the cache.
    """
    from .protocols import user_fingerprint

    parts = {"file": path.name, "sha256": sha256, "settings": settings.to_dict(),
             "tool": __version__, "code": code_fingerprint(), "protocols": user_fingerprint()}
    if settings.statics:
        shas = [_static_sha256(static) for static in settings.statics]
        parts["static_sha256"] = shas if len(shas) > 1 else shas[0]
    truth = path.with_name(f"{path.stem}.truth.json")
    if truth.is_file():
        parts["truth_sha256"] = file_sha256(truth)
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def build(inputs: Iterable[str | os.PathLike], settings: BuildSettings | None = None, *,
          jobs: int = 1, scheduler: str | None = None, cache_dir: str | os.PathLike | None = None,
          progress: bool = True,
          process: Callable[[str, BuildSettings], CaptureResult] | None = None
          ) -> BuildResult:
    """Process every capture and assemble the library.

    Parameters
    ----------
    inputs
        C3D files and folders (searched recursively for ``*.c3d``).
    settings
        :class:`BuildSettings` (defaults when None). Each capture is processed with the
        settings :func:`mocaplib.sessions.plan_captures` gives it: a ``session.toml``'s beside
        it, or these with the standing files among the captures added to the statics.
        Forward references are measured first (:func:`forward_offsets`; its CalibrationError
        is raised, nothing is processed).
    jobs
        Worker processes (1 = in this process).
    scheduler
        Address of a Dask distributed scheduler (``tcp://host:8786``); needs the optional
        extra ``mocaplib[dask]``. Overrides ``jobs``.
    cache_dir
        Folder of cached per-capture results (JSON); None disables the cache.
    progress
        Show a progress bar with ETA on stderr.
    process
        The per-capture function, :func:`process_capture` by default (any pure, picklable
        function of ``(path, settings)`` returning a :class:`CaptureResult`).

    Returns
    -------
    BuildResult
        Captures that failed are in it, not raised. A capture whose worker process dies is
        run once more in a new worker, then fails alone (stage ``worker``); no worker outlives
        the build (:mod:`mocaplib.workers`). At most :func:`mocaplib.workers.max_jobs` worker
        processes are started.
    """
    from tqdm import tqdm

    settings = settings or BuildSettings()
    process = process or process_capture
    if jobs < 1:
        raise MocapError(f"jobs must be >= 1, got {jobs}")
    started = time.perf_counter()
    paths = find_captures(inputs)
    if not paths:
        raise MocapError("no C3D captures found in the inputs",
                         hint="give .c3d files or folders that contain some")
    pool, planned = plan_captures(paths, settings)
    if settings.require_static and not any(p.statics for p in planned):
        raise MocapError("the build requires a static (require_static) but none is given or "
                         "found among the captures",
                         hint="give the statics with --static or a session.toml beside the "
                              "captures, or leave --require-static out")
    if pool.forward_reference is not None and pool.heading_offsets is None:
        offsets = pinned(forward_offsets, pool)
        planned = [replace(p, heading_offsets=offsets) if p is pool else p for p in planned]
        pool = replace(pool, heading_offsets=offsets)
    results: dict[int, CaptureResult] = {}
    keys: dict[int, str] = {}
    notes: list[str] = []
    cache = None if cache_dir is None else Path(cache_dir)
    for i, path in enumerate(paths):
        if cache is not None:
            try:
                keys[i] = cache_key(path, file_sha256(path), planned[i])
            except OSError:
                continue  # unreadable: its processing fails and says why
            cached, why = _read_cache(cache, keys[i])
            if cached is not None:
                cached.source = os.fspath(path)
                results[i] = cached
            elif why is not None:
                notes.append(f"{fs_text(path.name)}: its cached result was not used ({why}): "
                             "processed again")
    todo = [i for i in range(len(paths)) if i not in results]
    cache_failed = False
    with tqdm(total=len(paths), initial=len(results), desc="build", unit="capture",
              disable=not progress, file=sys.stderr, dynamic_ncols=True) as bar:
        for i, result in _run(process, [(i, paths[i], planned[i]) for i in todo], jobs,
                              scheduler):
            results[i] = result
            if i in keys and not _internal(result) and not cache_failed:
                try:
                    _write_cache(cache, keys[i], result)
                except MocapError as exc:  # the build goes on, uncached
                    notes.append(f"results not cached: {exc}")
                    cache_failed = True
            bar.update(1)
    captures = [results[i] for i in range(len(paths))]
    _unique_entry_ids(captures)
    library = assemble_library([e for c in captures for e in c.entries],
                               settings=pool.to_dict(), qc_thresholds=pool.qc_thresholds)
    return BuildResult(library, captures, pool, time.perf_counter() - started, notes)


def build_inputs(captures: Iterable[str | os.PathLike], settings: BuildSettings) -> list[Path]:
    """Every file a build of ``captures`` reads: the captures, their truth sidecars
    (``<stem>.truth.json``, which name the locomotion class) that exist, the statics and the
    forward references. An output must be none of them."""
    files = [Path(c) for c in captures]
    files += [t for c in files if (t := c.with_name(f"{c.stem}.truth.json")).is_file()]
    return files + [Path(f) for f in (*settings.statics, *settings.forward_references)]


def _internal(result: CaptureResult) -> bool:
    """An unexpected exception or a dead worker is not cached: it may be a fixed bug."""
    return result.stage == "worker" or "internal error" in (result.error or "")


#: ``format`` and ``version`` of a cache entry.
CACHE_FORMAT, CACHE_VERSION = "mocaplib-cache", 1
#: Largest cache entry read (bytes): a capture's result takes tens of kB.
MAX_CACHE_BYTES = 64 << 20
#: Types of the fields a cached :class:`CaptureResult` must have to be trusted.
_CACHED_TYPES = {"source": str, "sha256": str, "ok": bool, "entries": list, "diagnostics": dict,
                 "warnings": list, "stage_times": dict, "n_frames": int, "n_cycles": int}


def _write_cache(cache: Path, key: str, result: CaptureResult) -> None:
    """Store ``result`` under ``key`` (:func:`cache_key`: the hash of the capture's inputs
    and of the code), with the hash of its content (see :func:`_read_cache`)."""
    data = to_json_data(result.to_dict())
    atomic_write_text(cache / f"{key}.json", json_text({
        "format": CACHE_FORMAT, "version": CACHE_VERSION, "key": key,
        "content_sha256": canonical_sha256(data), "result": data}))


def _read_cache(cache: Path, key: str) -> tuple[CaptureResult | None, str | None]:
    """The cached result under ``key`` and None; ``(None, None)`` when there is none; and
    ``(None, why)`` when the entry does not verify: not a regular file (a pipe, device or
    link is refused before it is opened), too large, unreadable, not an entry as
    :func:`_write_cache` writes it, stored under another key, or with content that does not
    match its hash (a truncated or hand-edited file)."""
    path = cache / f"{key}.json"
    try:
        entry = parse_json(read_regular(path, limit=MAX_CACHE_BYTES, follow_links=False)
                           .decode("utf-8"))
    except FileNotFoundError:
        return None, None
    except OSError as exc:
        return None, f"{path.name}: {exc.strerror}"
    except ValueError:  # also UnicodeDecodeError
        return None, f"{path.name}: not JSON text"
    if not (isinstance(entry, dict) and entry.get("format") == CACHE_FORMAT
            and entry.get("version") == CACHE_VERSION):
        return None, f"{path.name}: not a mocaplib cache entry of version {CACHE_VERSION}"
    if entry.get("key") != key:
        return None, f"{path.name}: stored for other inputs or code"
    data = entry.get("result")
    if entry.get("content_sha256") != canonical_sha256(data):
        return None, f"{path.name}: its content does not match its hash (changed after it " \
                     "was written)"
    if not (isinstance(data, dict) and set(data) == {f.name for f in fields(CaptureResult)}
            and all(isinstance(data[name], kind) for name, kind in _CACHED_TYPES.items())
            and all(isinstance(e, dict) for e in data["entries"])):
        return None, f"{path.name}: not a capture's result"
    result = CaptureResult.from_dict(data)
    result.from_cache = True
    return result, None


def _run(process, work: list[tuple[int, Path, BuildSettings]], jobs: int,
         scheduler: str | None):
    """Yield ``(index, CaptureResult)`` as captures finish (in any order), each work item
    ``(index, path, its settings)`` run by :func:`mocaplib.workers.run_tasks` or on a Dask
    cluster."""
    if not work:
        return
    if scheduler is not None:
        yield from _run_dask(process, work, scheduler)
        return
    tasks = [(os.fspath(path), settings) for _, path, settings in work]
    for k, result, error in run_tasks(process, tasks, jobs=jobs):
        index, path, _ = work[k]
        yield index, result if error is None else _worker_failure(path, error)


def _run_dask(process, work, address: str):
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError as exc:
        raise MocapError("a Dask scheduler needs the optional dask extra",
                         hint="pip install 'mocaplib[dask]'") from exc
    try:
        client = Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address
        raise MocapError(f"cannot connect to the Dask scheduler at {address}: {exc}",
                         hint="start one with `dask scheduler` or check the address") from exc
    with client:
        futures = {client.submit(pinned, process, os.fspath(path), settings, pure=False):
                   (i, path) for i, path, settings in work}
        for future in dask_completed(futures):
            index, path = futures[future]
            try:
                result = future.result()
            except Exception as exc:  # the task raised, or its worker died (KilledWorker)
                result = _worker_failure(path, exc)
            yield index, result


def _worker_failure(path, error: BaseException) -> CaptureResult:
    """The result of a capture whose processing raised or whose worker died: it fails alone."""
    source = os.fspath(path)
    return CaptureResult(source=source, ok=False, stage="worker",
                         error=f"{source}: worker failed: {type(error).__name__}: {error}")


def _unique_entry_ids(captures: list[CaptureResult]) -> None:
    """Make entry ids unique when captures share a file name (append the SHA-256 prefix).

    A byte-identical copy of an earlier capture adds nothing: its entries are dropped with a
    warning.
    """
    first_with_content: dict[str, str] = {}
    names: dict[str, set[str]] = {}
    for c in captures:
        if c.entries and c.sha256 in first_with_content:
            c.warnings.append(f"same content as {first_with_content[c.sha256]}: "
                              "its cycles are not added twice")
            c.entries = []
            for cycle in c.diagnostics.get("cycles", []) + c.diagnostics.get("mirror_cycles", []):
                cycle["entry_id"] = None
        elif c.entries:
            first_with_content[c.sha256] = c.source
        for e in c.entries:
            names.setdefault(e["id"], set()).add(c.sha256)
    for c in captures:
        renamed = {e["id"]: f"{e['id']}@{c.sha256[:8]}" for e in c.entries
                   if len(names[e["id"]]) > 1}
        for e in c.entries:
            e["id"] = renamed.get(e["id"], e["id"])
            if "mirror_of" in e:
                e["mirror_of"] = renamed.get(e["mirror_of"], e["mirror_of"])
        for cycle in c.diagnostics.get("cycles", []) + c.diagnostics.get("mirror_cycles", []):
            cycle["entry_id"] = renamed.get(cycle.get("entry_id"), cycle.get("entry_id"))


def downsample(n_points: int, limit: int = MAX_SERIES_POINTS) -> slice:
    """A slice keeping at most about ``limit`` evenly spaced points of a series of ``n_points``."""
    return slice(None, None, max(1, -(-n_points // limit)))
