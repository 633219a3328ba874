"""One capture through every stage: import, protocol, calibration, fit, events, cycles, pattern
and velocities, Fourier, library entries (:func:`process_capture`); the forward reference's
heading correction is :func:`mocaplib.build.forward.forward_offsets`.

:func:`process_capture` is a pure, picklable function of the file's content and the settings: it
never raises for a bad capture but returns a :class:`CaptureResult` carrying the error (file,
stage, reason).
"""


from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass, field, fields
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import C3DError, CalibrationError, MocapError, NoCycleError
from ..gait.activity import non_level, set_activities
from ..gait.cycles import motion_cycles
from ..gait.locomotion import locomotion_class
from ..gait.patterns import cycle_times
from ..gait.poulaine import cycle_poulaine
from ..gait.qc import cycle_qc, inside_cycle, named_failures, qc_failures, qc_series
from ..io import fs_text, open_regular
from ..io.c3d import read_c3d
from ..library.entry import EntryDrift, EntryFourier, EntryPattern, EntryPoulaine, LibraryEntry
from ..library.format import to_json_data
from ..library.mirror import (MIRROR_TAG, REFLECTION, SYMMETRIC_DISTANCE, image_distance,
                              mirror_events, mirror_motion)
from ..markersets.matching import match_trial
from ..model.calibration import calibrate
from ..model.filtering import resample
from ..model.fitting import StageClock
from ..skeleton import DOF_NAMES
from ..statics import static_names
from .capture import ProcessedCapture, cut_cycles, fit_events
from .settings import CAPTURE_CHOICE, BuildSettings

#: Long series in the diagnostics are downsampled to at most this many points.
MAX_SERIES_POINTS = 300


#: The chosen cycle's angles are downsampled to at most this many points per DOF.
MAX_CYCLE_POINTS = 100


#: The chosen cycle's measured ankle paths are downsampled to at most this many points.
MAX_POULAINE_POINTS = 60


#: Significant digits of the diagnostics' numbers (plots need no more).
DIAGNOSTICS_DIGITS = 6


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
    entries : list[LibraryEntry]
        Library entries (:class:`mocaplib.library.entry.LibraryEntry`).
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
    provenance : dict
        What the capture was calibrated from (``calibrated_from``: one of
        :data:`mocaplib.build.settings.STATIC_SOURCES` or "the capture itself"; ``static``: the
        static's file name or None; ``static_pose``, with a static) and its marker-set protocol
        (``protocol``: name, ``protocol_origin``:
        :attr:`mocaplib.markersets.protocols.Protocol.origin`), with its session's
        ``trim``, ``cycles`` and ``drop_cycles`` when set, and ``joint_centres`` ("the
        motion") when a cluster set's joints were assumed from its motion
        (:attr:`mocaplib.model.fitting.FittedCapture.joint_centres_from_motion`); empty when
        it failed before.
    no_entry : str or None
        Why a capture that did not fail gave no library entry (None when it gave some, or
        failed): no complete cycle, every cycle left out by QC or as not level, or by the
        session, or a static trial that cannot be a rest entry.
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
    provenance: dict = field(default_factory=dict)
    no_entry: str | None = None

    @property
    def file(self) -> str:
        """The capture's file name as text (:func:`mocaplib.io.fs_text`)."""
        return fs_text(Path(self.source).name)

    def to_dict(self) -> dict:
        """As JSON data (entries as the library stores them), 10 significant digits."""
        return to_json_data({f.name: getattr(self, f.name) for f in fields(self)}
                            | {"entries": [e.to_json() for e in self.entries]})

    @classmethod
    def from_dict(cls, data: dict) -> "CaptureResult":
        """The result :meth:`to_dict` gave; LibraryError for an entry that is not one."""
        values = {f.name: data[f.name] for f in fields(cls) if f.name in data}
        values["entries"] = [LibraryEntry.from_json(e) for e in values.get("entries", [])]
        return cls(**values)


# --------------------------------------------------------------------------- one capture
def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes; OSError for anything but a regular file (a pipe or
    device could block or never end: :func:`mocaplib.io.open_regular`)."""
    digest = hashlib.sha256()
    with open_regular(path) as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


#: The reason of a capture whose file changed while it was processed (never cached).
CHANGED_WHILE_READ = "the file changed while it was processed"


def _file_state(path) -> tuple[int, int, int] | None:
    """What tells that a file's content changed: its inode, size and modification time (ns);
    None when it cannot be seen."""
    try:
        found = os.stat(path)
    except (OSError, ValueError):
        return None
    return found.st_ino, found.st_size, found.st_mtime_ns


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
    clock = StageClock()
    is_static = os.path.realpath(path) in {os.path.realpath(s) for s in settings.statics}
    state = _file_state(path)
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
    if state is not None and _file_state(path) != state:
        result.no_entry = None
        _fail(result, "read", f"{path}: {CHANGED_WHILE_READ} (its result would mix two "
                              "contents): build again once the file is complete")
    if is_static and not result.ok:
        why = (result.error or "").removeprefix(f"{path}: ")
        result.ok, result.error, result.no_entry = True, None, \
            f"a static trial: used to calibrate, no entry of its own ({result.stage}: {why})"
        result.stage = None
    elif is_static and result.no_entry:
        result.no_entry = f"a static trial: used to calibrate, no entry of its own " \
                          f"({result.no_entry})"
    result.stage_times = clock.times
    return result


def _run_stages(path: Path, settings: BuildSettings, result: CaptureResult, clock: StageClock):
    """:func:`cut_capture`, then the entries (and with ``settings.mirror`` those of the mirror
    image, :func:`mirror_entries`); fills ``result`` (raises MocapError for a bad capture)."""
    processed = cut_capture(path, settings, result, clock)
    trial, motion, cycles, qcs = processed.trial, processed.motion, processed.cycles, processed.qc
    events, ground = processed.events, processed.ground
    with clock.stage("entries"):
        result.n_cycles = sum(not c.rest for c in cycles)
        kept = [c for c in cycles if c.left_out is None and (c.chosen or settings.all_cycles)]
        unknown = sorted(set(settings.cycles or ()) - {c.index for c in cycles})
        if unknown:
            result.warnings.append(f"the session names cycle(s) {', '.join(map(str, unknown))}"
                                   f": the capture has cycles 0-{len(cycles) - 1}")
        if not kept:
            raise NoCycleError("the session leaves every cycle out: " + "; ".join(
                f"cycle {c.index} ({c.start_s:.2f}-{c.end_s:.2f} s) "
                f"{c.left_out or 'not among its cycles'}" for c in cycles), path=path,
                hint="check the capture's trim, cycles and drop_cycles in its session.toml")
    with clock.stage("poulaines"):
        shapes = cycle_shapes(motion, kept)
    with clock.stage("entries"):
        result.entries = _entries(path, result, kept, qcs, settings, motion, trial.first_frame,
                                  shapes, events)
        if not result.entries:
            sloped = {c.index: non_level(c) for c in kept if not settings.keep_non_level}
            result.no_entry = ("every complete cycle was left out by QC"
                               + (" or as not level: " if any(sloped.values()) else ": ")
                               + "; ".join(
                f"cycle {c.index} ({c.start_s:.2f}-{c.end_s:.2f} s) "
                + (sloped.get(c.index) or ", ".join(named_failures(
                    c, motion, qcs[c.index], settings.qc_thresholds, facts=result.provenance)))
                for c in kept))
        result.diagnostics.update(_cycle_diagnostics(
            motion, cycles, {e.cycle_index: e.id for e in result.entries}, shapes))
    if settings.mirror and result.entries:
        with clock.stage("mirror"):
            images, entries = mirror_entries(path, result, cycles, motion, events, ground,
                                             settings, trial.first_frame)
            result.entries += entries
            ids = {e.cycle_index: e.id for e in entries}
            result.diagnostics["mirror_cycles"] = to_json_data(
                [{**c.to_dict(), "entry_id": ids.get(c.index)} for c in images],
                DIAGNOSTICS_DIGITS)


def cut_capture(path: Path, settings: BuildSettings, result: CaptureResult, clock: StageClock
                 ) -> ProcessedCapture:
    """:func:`mocaplib.build.capture.process` with the build's settings: import -> protocol ->
    calibrate -> fit -> events -> cycles (patterns, velocities, Fourier) -> QC and the chosen
    cycle; puts the warnings, the static used and the capture's diagnostic series in
    ``result`` (the series between :func:`~mocaplib.build.capture.fit_events` and
    :func:`~mocaplib.build.capture.cut_cycles`, so a capture without a cycle keeps them). The statics are read once per process and a static in the neutral pose
    calibrated once; a build falls back to calibrating from the capture when none of its
    statics shows the subject, unless ``settings.require_static``. Settings with a forward
    reference must carry its measured ``heading_offsets`` (:func:`~mocaplib.build.pipeline.build_library` measures them).
    """
    if settings.forward_reference is not None and settings.heading_offsets is None:
        raise MocapError("the forward reference's heading offsets are not measured: build with "
                         "build_library, or set heading_offsets=forward_offsets(settings)")
    with clock.stage("import"):
        trial = read_c3d(path)
        statics = [(static, static_sha256(static)) for static in settings.statics]
        static_trials = [_read_static(*key) for key in statics]
    result.n_frames = trial.n_frames
    result.warnings.extend(trial.warnings)
    if not statics and settings.require_static:
        raise CalibrationError("no static trial given, and the build requires one "
                               "(require_static)", path=trial.source,
                               hint="give the subject's static with --static or a "
                                    "session.toml, or leave --require-static out")

    with clock.stage("protocol"):
        match = match_trial(trial, settings.protocol)

    def neutral_model(i: int):
        return _neutral_model(*statics[i], match.protocol, settings.heading_offset(i),
                              tuple(sorted(settings.measurements.items())),
                              settings.static_window)

    processed = fit_events(trial, protocol=match, static=static_trials,
                           static_pose=settings.static_pose, cutoff=settings.cutoff,
                           measurements=settings.measurements,
                           static_window=settings.static_window, toe_off=settings.toe_off,
                           max_gap_s=settings.max_gap_s, fallback=not settings.require_static,
                           neutral_model=neutral_model, clock=clock)
    fitted = processed.fitted
    result.provenance = {"calibrated_from": "the capture itself", "static": None,
                         "protocol": match.protocol.name,
                         "protocol_origin": match.protocol.origin}
    result.provenance |= {key: getattr(settings, key) for key in CAPTURE_CHOICE
                          if getattr(settings, key) not in (None, ())}
    if fitted.joint_centres_from_motion:
        result.provenance["joint_centres"] = "the motion"
    if fitted.static is not None:
        result.static = static_names(settings.statics)[fitted.static]
        result.provenance.update(calibrated_from=settings.static_source(fitted.static),
                                 static=result.static, static_pose=settings.static_pose)
        result.diagnostics["static_window_s"] = list(fitted.model.static_window_s)
    result.warnings.extend(fitted.warnings)
    result.warnings.extend(e.warning for e in processed.events if e.warning)
    result.diagnostics.update(_series(trial, processed.motion, processed.shoulders,
                                      processed.events, fitted.cutoff))
    return cut_cycles(processed, max_gap_s=settings.max_gap_s,
                      qc_thresholds=settings.qc_thresholds, clock=clock, trim=settings.trim,
                      picked=settings.cycles, dropped=settings.drop_cycles)


def static_sha256(path: str) -> str:
    """SHA-256 of a static trial's file; one that cannot be read is named (C3DError)."""

    try:
        return file_sha256(path)
    except OSError as exc:
        raise C3DError(f"cannot read the static trial: {exc.strerror or exc}", path=path,
                       hint="check the --static path") from None


@lru_cache(maxsize=None)
def _read_static(path: str, sha256: str):
    """The static trial, read once per worker process for each content (``sha256``)."""
    return read_c3d(path)


@lru_cache(maxsize=None)
def _neutral_model(path: str, sha256: str, protocol, heading_offset: float,
                   measurements: tuple = (), window: tuple[float, float] | None = None):
    """The model calibrated on the neutral-pose static ``path`` with its heading turned by
    ``heading_offset`` (radians), once per worker process for each content, protocol and
    offset and measurements ((name, value) pairs) and static ``window``: it depends on nothing
    else, so each
    capture only checks that it shows the same subject
    (:func:`mocaplib.model.calibration_checks.check_static`)."""
    static = _read_static(path, sha256)
    return calibrate(static, protocol=protocol, static=static, static_pose="neutral",
                     heading_offset=heading_offset, measurements=dict(measurements),
                     static_window=window)


def _entries(path: Path, result: CaptureResult, cycles, qcs: dict[int, dict],
             settings: BuildSettings, motion, first_frame: int, shapes: dict, events, *,
             mirror_of: dict[int, str] | None = None):
    """Library entries of the kept cycles of the fitted ``motion``; cycles failing QC are
    dropped or waived. ``qcs``: QC metrics by cycle index (:func:`qc_and_choice`);
    ``first_frame``: the capture's first C3D frame number (``start_s`` counts from it);
    ``shapes``: :func:`cycle_shapes`; ``events``: the gait events the cycles were
    cut at (their order gives a cycle's gait, :func:`mocaplib.gait.locomotion.locomotion_class`);
    ``mirror_of``: for the cycles of a mirror
    image (``motion`` mirrored), the id of the entry each one mirrors, by cycle index."""

    entries = []
    for cycle in cycles:
        qc = qcs[cycle.index]
        failures = qc_failures(qc, settings.qc_thresholds)
        image_of = None if mirror_of is None else mirror_of[cycle.index]
        where = (f"{'mirror image ' if image_of else ''}cycle {cycle.index} "
                 f"({cycle.start_s:.2f}-{cycle.end_s:.2f} s, {cycle.activity})")
        sloped = non_level(cycle)
        if sloped and not settings.keep_non_level:
            result.warnings.append(f"{where} left out of the level-locomotion library: "
                                   f"{sloped}; --keep-non-level keeps it, flagged")
            continue
        if sloped:
            result.warnings.append(f"{where} kept, flagged {sloped}")
        waived = {}
        if failures and settings.qc_policy == "drop":
            result.warnings.append(f"{where} left out of the library: "
                                   + "; ".join(named_failures(cycle, motion, qc,
                                                              settings.qc_thresholds,
                                                              facts=result.provenance)))
            continue
        if failures:
            waived = {f.split()[0]: f"accepted by build setting qc_policy=waive ({f})"
                      for f in failures}
            result.warnings.append(f"{where} kept with QC waived: {'; '.join(failures)}")
        vel, enc = cycle.velocities, cycle.encoding
        entries.append(LibraryEntry(
            id=f"{fs_text(path.stem)}{MIRROR_TAG if image_of else ''}_c{cycle.index}",
            source_file=fs_text(path.name),
            source_sha256=result.sha256, cycle_index=cycle.index, chosen=cycle.chosen,
            start_s=cycle.start_s, end_s=cycle.end_s, T=cycle.period,
            pattern=EntryPattern(**vel.pattern.to_dict()), v=vel.v, omega=vel.omega,
            v_l=vel.v_l, v_f=vel.v_f, fourier=EntryFourier.of(enc.series.a, enc.series.b,
                                                                ramp=enc.ramp),
            root_drift=EntryDrift.moving(enc.drift.u_f, enc.drift.u_l, enc.drift.omega,
                                         cycle.period),
            qc=qc, qc_waived=waived, locomotion_class=locomotion_class(cycle, events),
            segment_lengths_m=motion.skeleton.lengths, rate_hz=motion.rate,
            first_frame=first_frame, joint_shifts_m=motion.skeleton.shifts,
            held_dofs=motion.unobservable,
            dofs_at_limit=motion.limit_shares(inside_cycle(cycle, motion)),
            right_toe_off_s=cycle.right_toe_off, left_toe_off_s=cycle.left_toe_off,
            cycle_start=None if cycle.left_toe_off is None else cycle.start_event,
            mirror_of=image_of, mirror_method=None if image_of is None else "capture",
            poulaine=None if cycle.rest else EntryPoulaine.of(shapes[cycle.index]["poulaine"])))
    return entries


def cycle_shapes(motion, cycles) -> dict[int, dict]:
    """Each of ``cycles``' samples, by cycle index: ``phase`` (n,) t/T in [0, 1), ``q`` its
    coordinates (n, D) in its path frame (root as the library stores it), and, unless it is
    rest, its ``poulaine`` (:class:`mocaplib.gait.poulaine.Poulaine`) and the ``measured``
    ankle centres (n, 2, 3) m it models (:func:`mocaplib.gait.poulaine.cycle_poulaine`). The
    motion's angles are unwrapped once for all the cycles (a long take's hundreds of cycles
    cost their own frames, not the take's each)."""

    unwrapped = np.unwrap(motion.q, axis=0)
    shapes = {}
    for cycle in cycles:
        times = cycle_times(cycle.start_s, cycle.end_s, motion.rate)[:-1]
        q = resample(unwrapped, motion.rate, times)
        shape = {"phase": (times - cycle.start_s) / cycle.period,
                 "q": cycle.encoding.drift.remove(q, times - cycle.start_s)}
        if not cycle.rest:
            shape["poulaine"], shape["measured"] = cycle_poulaine(
                motion.skeleton, shape["q"], shape["phase"], cycle.encoding.drift)
        shapes[cycle.index] = shape
    return shapes


def mirror_entries(path: Path, result: CaptureResult, cycles, motion, events, ground,
                   settings: BuildSettings, first_frame: int) -> tuple[list, list[LibraryEntry]]:
    """The capture's mirror image, cut and measured as a capture: its cycles (all of them,
    :class:`~mocaplib.gait.cycles.Cycle`) and the entries they give.

    The fitted ``motion`` is reflected (world y -> -y, :func:`mocaplib.library.mirror.mirror_motion`)
    and its gait events exchange sides, so its cycles run between the capture's *right*
    toe-offs; patterns, velocities, Fourier series and QC are measured on them as on any
    capture (:func:`mocaplib.gait.cycles.motion_cycles`, :func:`cycle_qc`). Each names in
    ``mirror_of`` the capture's entry (in ``result.entries``) whose cycle overlaps it most in
    time (the nearest when none overlaps). Which become entries: the image of the capture's
    chosen cycle, the one overlapping it most (chosen when its source is in the library), or
    with ``settings.all_cycles`` every image. QC failures are dropped or waived as for the
    capture's own cycles; an image within :data:`mocaplib.library.mirror.SYMMETRIC_DISTANCE` of its
    source in the control space is left out (the cycle is its own mirror image: straight
    walks, runs, rest). What is left out is said in ``result.warnings``.
    """

    mirrored = mirror_motion(motion)
    image_events = mirror_events(events)
    try:
        images = motion_cycles(image_events, mirrored,
                               ground=None if ground is None else REFLECTION @ ground,
                               max_gap_s=settings.max_gap_s, source=path)
    except MocapError as exc:  # fewer than two right toe-offs: the capture's own entries stay
        result.warnings.append(f"no mirror image: {exc.message}")
        return [], []
    set_activities(images, image_events)
    sources = {e.cycle_index: e for e in result.entries}
    chosen = next(c for c in cycles if c.chosen)
    partner = _nearest(chosen, images)
    for image in images:
        image.chosen = image is partner and chosen.index in sources
    kept = images if settings.all_cycles else [partner]
    own = [c for c in cycles if c.index in sources]
    mirror_of = {image.index: sources[_nearest(image, own).index].id for image in kept}
    series = qc_series(mirrored, None if ground is None else REFLECTION @ ground)
    qcs = {image.index: cycle_qc(image, mirrored, series) for image in kept}
    shapes = cycle_shapes(mirrored, kept)
    entries = []
    for entry in _entries(path, result, kept, qcs, settings, mirrored, first_frame, shapes,
                          image_events, mirror_of=mirror_of):
        source = next(e for e in result.entries if e.id == entry.mirror_of)
        distance = image_distance(source.velocity, entry.velocity)
        if distance < SYMMETRIC_DISTANCE:
            result.warnings.append(f"mirror image cycle {entry.cycle_index} left out: it "
                                   f"lies {distance:.3f} (normalised) from {source.id} in "
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
    measured ankle paths (``shapes``: :func:`cycle_shapes`)."""
    chosen = next(c for c in cycles if c.index in shapes and (c.chosen or not any(
        k.chosen for k in cycles if k.index in shapes)))
    shape = shapes[chosen.index]
    pick = downsample(len(shape["phase"]), MAX_CYCLE_POINTS)
    angles = {"time_s": shape["phase"][pick] * chosen.period}
    angles.update({name: shape["q"][pick, d] for d, name in enumerate(DOF_NAMES)})
    poulaine = None
    if "measured" in shape:
        pick = downsample(len(shape["phase"]), MAX_POULAINE_POINTS)
        poulaine = {"phase": shape["phase"][pick], "left_m": shape["measured"][pick, 0],
                    "right_m": shape["measured"][pick, 1]}
    return to_json_data({
        "cycles": [{**c.to_dict(), "entry_id": entry_ids.get(c.index)} for c in cycles],
        "angles": angles, "poulaine": poulaine,
    }, DIAGNOSTICS_DIGITS)


def _fail(result: CaptureResult, stage: str | None, reason: str) -> None:
    result.ok, result.stage, result.error = False, stage, reason
    result.entries = []


def downsample(n_points: int, limit: int = MAX_SERIES_POINTS) -> slice:
    """A slice keeping at most about ``limit`` evenly spaced points of a series of ``n_points``."""
    return slice(None, None, max(1, -(-n_points // limit)))
