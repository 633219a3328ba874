"""Capture sessions: which static calibrates which capture of a build, and which files are statics.

A build's inputs may mix subjects and sessions, some with a static trial and some without
(docs/guide/build.md, *Capture sessions*). :func:`plan_captures` gives each capture the
settings it is processed with:

1. **A ``session.toml`` beside captures** (:data:`SESSION_FILE`, :func:`load_session`) names
   their session's static(s), and optionally its static pose, the stretch of the static to
   use and the marker-set protocol. Those captures are calibrated with it. Its statics pass
   the check ``--static`` passes (:func:`check_session_static`).
2. **Other captures** are calibrated with the ``--static`` trials and the *standing* files
   found among the inputs (:func:`mocaplib.statics.check_standing` over the whole file):
   each with the one that shows its subject (:func:`mocaplib.model.calibration_checks.choose_static`).
3. **A capture no static shows** is calibrated from itself, with a warning, unless the build
   requires a static (``require_static``): then it fails, naming each static and why.

A file that is a static — named by ``--static`` or a ``session.toml``, or found standing — is
used as one and never counts as a failed capture: processed as a capture it gives its rest
entry when it spans the second a rest entry needs, otherwise no entry, and says why
(:func:`mocaplib.build.workflow.process_capture`).

The format of ``session.toml`` (every key optional)::

    static = "Static1.c3d"        # or a list, one per subject; paths relative to this file
    static_pose = "neutral"       # "free" or "neutral" (default: the build's --static-pose)
    static_window = [0.5, 2.0]    # seconds of the static to calibrate on (default: the
                                  # whole static when standing, else its quietest second)
    protocol = "padova30"         # a shipped protocol name or a TOML path (relative to this
                                  # file; default: the build's --protocol)
    keep_non_level = true         # keep cycles on stairs or slopes, flagged (default: the
                                  # build's --keep-non-level)

    [capture."Take03.c3d"]        # one capture beside this file (:data:`CAPTURE_KEYS`)
    trim = [[2.0, 9.5]]           # windows (s from its first frame) its cycles must lie in
    cycles = [3, 7]               # the cycles (indices, as entry ids _c<k>) to keep instead of
                                  # one per activity segment
    drop_cycles = [0]             # cycles never to keep
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import MocapError
from ..io.c3d import read_c3d
from ..io.tomlfile import read_toml
from ..statics import STATIC_POSES, check_standing, standing_part
from .settings import STATIC_SOURCES

#: The name of a session's description, beside its captures.
SESSION_FILE = "session.toml"
#: The keys a session file may hold.
SESSION_KEYS = ("static", "static_pose", "static_window", "protocol", "keep_non_level",
                "capture")
#: The keys of a session file's ``[capture."NAME.c3d"]`` table.
CAPTURE_KEYS = ("trim", "cycles", "drop_cycles")


@dataclass(frozen=True)
class CaptureChoice:
    """A session's choice for one capture: ``trim`` windows ((start, end) s), the ``cycles`` to
    keep (indices) and the ``drop_cycles`` never to keep
    (:func:`mocaplib.build.capture.cut_cycles`)."""

    trim: tuple[tuple[float, float], ...] | None = None
    cycles: tuple[int, ...] | None = None
    drop_cycles: tuple[int, ...] = ()


@dataclass(frozen=True)
class Session:
    """One folder's ``session.toml``: its statics (absolute paths), static pose, static window
    (start, end) s, protocol and ``keep_non_level``, None where the file leaves the build's
    setting; and its per-capture choices by capture path (absolute)."""

    source: Path
    statics: tuple[str, ...] = ()
    static_pose: str | None = None
    static_window: tuple[float, float] | None = None
    protocol: str | None = None
    keep_non_level: bool | None = None
    captures: tuple[tuple[str, CaptureChoice], ...] = ()

    def choice(self, capture, /) -> CaptureChoice:
        """The session's choice for ``capture`` (a path), the default when it names none."""
        return dict(self.captures).get(os.path.abspath(capture), CaptureChoice())


def load_session(path: str | os.PathLike, /) -> Session:
    """Read and check a ``session.toml`` (module docstring); :class:`MocapError` naming the
    file and the key for a file that cannot be read or holds a wrong value."""

    path = Path(path)
    hint = f"see docs/guide/build.md (Capture sessions) for the keys of {SESSION_FILE}"
    data = read_toml(path, what="session file", hint=hint)
    unknown = sorted(set(data) - set(SESSION_KEYS))
    if unknown:
        raise MocapError(f"unknown key(s) {', '.join(unknown)}; known: {', '.join(SESSION_KEYS)}",
                         path=path, hint=hint)
    statics = data.get("static", [])
    statics = [statics] if isinstance(statics, str) else statics
    if not isinstance(statics, list) or not all(isinstance(s, str) and s for s in statics):
        raise MocapError("static must be a file name or a list of file names", path=path,
                         hint=hint)
    statics = tuple(os.fspath((path.parent / name).absolute()) for name in statics)
    for static in statics:
        if not Path(static).is_file():
            raise MocapError(f"its static {static} does not exist", path=path,
                             hint="name a C3D file beside the session file, or a path "
                                  "relative to it")
    pose = data.get("static_pose")
    if pose is not None and pose not in STATIC_POSES:
        raise MocapError(f"static_pose must be one of {', '.join(STATIC_POSES)}, got {pose!r}",
                         path=path, hint=hint)
    if pose == "neutral" and not statics:
        raise MocapError("static_pose 'neutral' describes a static: name it with static",
                         path=path, hint=hint)
    window = data.get("static_window")
    if window is not None:
        if not (isinstance(window, list) and len(window) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in window)
                and 0 <= window[0] <= window[1]):
            raise MocapError(f"static_window must be [start, end] seconds with 0 <= start <= "
                             f"end, got {window!r}", path=path, hint=hint)
        window = (float(window[0]), float(window[1]))
    for static in statics:
        check_session_static(path, static, window)
    protocol = data.get("protocol")
    if protocol is not None:
        if not isinstance(protocol, str) or not protocol:
            raise MocapError("protocol must be a protocol name or a TOML path", path=path,
                             hint=hint)
        relative = path.parent / protocol
        protocol = os.fspath(relative.absolute()) if relative.suffix == ".toml" else protocol
    keep = data.get("keep_non_level")
    if keep is not None and not isinstance(keep, bool):
        raise MocapError(f"keep_non_level must be true or false, got {keep!r}", path=path,
                         hint=hint)
    captures = data.get("capture", {})
    if not isinstance(captures, dict):
        raise MocapError('capture must be tables, one per capture: [capture."NAME.c3d"]',
                         path=path, hint=hint)
    choices = tuple((os.fspath((path.parent / name).absolute()),
                     _capture_choice(path, name, table, hint))
                    for name, table in captures.items())
    return Session(path, statics, pose, window, protocol, keep, choices)


def _capture_choice(path: Path, name: str, table, hint: str) -> CaptureChoice:
    """The ``[capture."NAME"]`` table of the session file ``path``, checked; MocapError naming
    the file, the capture and the key."""
    where = f'[capture."{name}"]'
    if not (path.parent / name).is_file():
        raise MocapError(f"{where}: no capture {name} beside the session file", path=path,
                         hint="name a C3D file in the session file's folder")
    if not isinstance(table, dict):
        raise MocapError(f"{where} must be a table of {', '.join(CAPTURE_KEYS)}", path=path,
                         hint=hint)
    unknown = sorted(set(table) - set(CAPTURE_KEYS))
    if unknown:
        raise MocapError(f"{where}: unknown key(s) {', '.join(unknown)}; known: "
                         f"{', '.join(CAPTURE_KEYS)}", path=path, hint=hint)
    trim = table.get("trim")
    if trim is not None:
        if not (isinstance(trim, list) and trim and all(
                isinstance(w, list) and len(w) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in w)
                and 0 <= w[0] < w[1] for w in trim)):
            raise MocapError(f"{where}: trim must be a list of [start, end] windows in seconds "
                             f"with 0 <= start < end, got {trim!r}", path=path, hint=hint)
        trim = tuple((float(a), float(b)) for a, b in trim)
    picked, dropped = (_indices(path, where, key, table.get(key), hint)
                       for key in ("cycles", "drop_cycles"))
    both = sorted(set(picked or ()) & set(dropped or ()))
    if both:
        raise MocapError(f"{where}: cycle(s) {', '.join(map(str, both))} both in cycles and "
                         "in drop_cycles", path=path, hint="name each cycle in one of them")
    return CaptureChoice(trim, picked, dropped or ())


def _indices(path: Path, where: str, key: str, value, hint: str) -> tuple[int, ...] | None:
    if value is None:
        return None
    if not (isinstance(value, list) and all(isinstance(i, int) and not isinstance(i, bool)
                                            and i >= 0 for i in value)):
        raise MocapError(f"{where}: {key} must be a list of cycle indices (0, 1, ...: the "
                         f"_c<k> of the entry ids), got {value!r}", path=path, hint=hint)
    return tuple(value)


def check_session_static(session: Path, static: str, window: tuple[float, float] | None,
                         /) -> None:
    """Raise :class:`MocapError` naming the session file ``session`` and its ``static`` when
    the static cannot be read or does not stand still in ``window`` (start, end) s or its
    quietest second: the check ``--static`` passes (:func:`mocaplib.statics.standing_part`)."""
    try:
        standing_part(read_c3d(static), window=window)
    except MocapError as exc:
        raise MocapError(f"its static {static}: {exc.message}", path=session,
                         hint="name the static calibration trial (the subject standing still) "
                              "with static, or the stretch where the subject stands with "
                              "static_window = [start, end]") from None


def sessions_of(captures: list[Path], /) -> dict[Path, Session]:
    """The :class:`Session` of each folder holding captures and a :data:`SESSION_FILE`, by
    folder (absolute)."""
    folders = {Path(os.path.abspath(c)).parent for c in captures}
    return {folder: load_session(folder / SESSION_FILE) for folder in sorted(folders)
            if (folder / SESSION_FILE).is_file()}


def standing_files(captures: list[Path], /, *, exclude: set[str] = frozenset()) -> list[str]:
    """The captures (paths as given) whose markers stand still over the whole file
    (:func:`mocaplib.statics.check_standing`), except those whose real path is in
    ``exclude``; a file that cannot be read (whatever the exception) or holds no markers is
    not one (its processing fails alone and says why)."""
    found = []
    for capture in captures:
        if os.path.realpath(capture) in exclude:
            continue
        try:
            trial = read_c3d(capture)
            if trial.n_frames and trial.n_markers:   # no markers: nothing stands
                check_standing(trial)
                found.append(os.fspath(capture))
        except Exception:  # noqa: BLE001 - its own processing names the failure and stage
            continue
    return found


def plan_captures(captures: list[Path], settings, /) -> tuple:
    """The settings (:class:`mocaplib.build.settings.BuildSettings`) of the captures that no
    ``session.toml`` describes — ``settings`` with the standing files among the captures added
    to its statics (their heading offsets 0 when ``settings`` has measured ones) — and those
    each capture is processed with, in order (module docstring): that pool, or for the
    captures beside a ``session.toml`` its statics, pose, window and protocol (without forward
    references). Raises :class:`MocapError` naming a session file that cannot be used."""
    sessions = sessions_of(captures)
    named = {os.path.realpath(s) for s in settings.statics}
    named |= {os.path.realpath(s) for session in sessions.values() for s in session.statics}
    found = tuple(standing_files(captures, exclude=named))
    given = settings.static_sources or tuple(STATIC_SOURCES[0] for _ in settings.statics)
    pool = replace(settings, static_sources=given or None)
    if found:
        offsets = settings.heading_offsets
        pool = replace(settings, static=(*settings.statics, *found),
                       static_sources=(*given, *(STATIC_SOURCES[2] for _ in found)),
                       heading_offsets=None if offsets is None else (*offsets,
                                                                     *(0.0 for _ in found)))
    planned = []
    for capture in captures:
        session = sessions.get(Path(os.path.abspath(capture)).parent)
        if session is None:
            planned.append(pool)
            continue
        statics = session.statics or pool.statics
        choice = session.choice(capture)
        planned.append(replace(
            settings, static=statics or None,
            static_sources=(tuple(STATIC_SOURCES[1] for _ in session.statics)
                            or pool.static_sources),
            static_pose=session.static_pose or (settings.static_pose if statics else "free"),
            static_window=session.static_window or settings.static_window,
            protocol=session.protocol or settings.protocol, forward_reference=None,
            heading_offsets=None, trim=choice.trim, cycles=choice.cycles,
            drop_cycles=choice.drop_cycles,
            keep_non_level=(settings.keep_non_level if session.keep_non_level is None
                            else session.keep_non_level)))
    return pool, planned
