"""Small helpers shared by the sub-commands (output formatting, input expansion, --protocol)."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from ..errors import MocapError
from ..io import open_regular, printable
from ..io.jsonvalues import json_values


class UsageError(MocapError):
    """A mistake in the command line found after parsing: exits 2, as argparse's do."""


#: What ``-`` as a path is told: no command reads standard input or writes standard output.
DASH = ("'-' (standard input or output) is not supported here: give a file name (./- for a "
        "file named '-')")


def check_outputs(outputs: dict[str, str | os.PathLike | None],
                  inputs: list[str | os.PathLike], *, create_folders: bool = False,
                  force: bool = False) -> None:
    """Raise :class:`UsageError` before anything is written when an output file (``{option:
    path}``, None = not asked for) is ``-``, would overwrite an input or another output, lies
    in a system folder or is not a regular file (a device, a pipe, a folder, a link loop:
    :func:`mocaplib.io.atomic.destination`; a link is followed and its file checked), would
    overwrite a file mocaplib did not write (a C3D capture above all, :func:`foreign_file`)
    unless ``force``, or lies where nothing can be written: its folder does not exist (unless
    ``create_folders``: then its nearest existing folder), is a file, or refuses a new file
    (tried: a temporary file is created and removed, which also catches read-only and virtual
    file systems)."""
    from ..io.atomic import destination

    given = [(option, Path(path)) for option, path in outputs.items() if path is not None]
    existing = [Path(path) for path in inputs if Path(path).is_file()]
    for n, (option, path) in enumerate(given):
        if os.fspath(path) == "-":
            raise UsageError(f"{option}: {DASH}")
        try:
            target = destination(path)
        except MocapError as exc:
            raise UsageError(f"{option} {path}: {exc.message} ({exc.hint})") from None
        parent = target.absolute().parent
        folder = next(p for p in (parent, *parent.parents) if p.exists())
        if not folder.is_dir():
            raise UsageError(f"{option} {path}: cannot write into {folder}: it is a file, not "
                             "a folder (choose another output path)")
        if folder != parent and not create_folders:
            raise UsageError(f"{option} {path}: the folder {parent} does not exist (create it, "
                             "or choose a path in an existing folder)")
        _check_writable(option, path, folder)
        if target.exists() and any(os.path.samefile(target, source) for source in existing):
            raise UsageError(f"{option} {path} is an input of this command; writing it "
                             "would overwrite the input: give another file name")
        why = None if force else foreign_file(target)
        if why is not None:
            raise UsageError(f"{option} {path} exists and is {why}; mocaplib did not write "
                             "it: give another file name, or --force to overwrite it")
        for other, earlier in given[:n]:
            if os.path.abspath(path) == os.path.abspath(earlier):
                raise UsageError(f"{option} and {other} name the same file {path}")


#: The start of each kind of file mocaplib writes (bytes), other than the JSON it marks with
#: ``"format": "mocaplib-..."`` and glTF: angles CSV, BVH, OpenSim .osim, HTML report.
OWN_STARTS = (b"time_s,", b"HIERARCHY", b"<?xml", b"<OpenSimDocument", b"<!DOCTYPE html",
              b"<!doctype html")


def foreign_file(path: Path) -> str | None:
    """Why the existing file ``path`` must not be overwritten without ``--force``, or None
    (absent, empty, or of a kind mocaplib writes): "a C3D capture" (named ``*.c3d`` or holding
    a C3D header: its second byte is 0x50), or "not a file mocaplib writes" when it begins
    with none of :data:`OWN_STARTS` and is neither a JSON object naming a ``mocaplib-*``
    ``format`` (at most :data:`MAX_OWN_JSON_BYTES`) nor glTF (.mot files start with their
    own name and are recognised by their ``endheader`` line)."""
    from ..io import read_regular
    from ..io.jsonvalues import parse_json

    try:
        with open_regular(path) as handle:
            start = handle.read(4096)
    except FileNotFoundError:
        return None
    except OSError:
        return "not a file mocaplib can read"
    if path.suffix.lower() == ".c3d" or start[1:2] == b"\x50" and len(start) >= 512:
        return "a C3D capture"
    text = start.lstrip()
    if not text or text.startswith(OWN_STARTS) or b"\nendheader\n" in start:
        return None
    if text.startswith(b"glTF"):
        return None
    if text.startswith(b"{"):
        try:
            document = parse_json(read_regular(path, limit=MAX_OWN_JSON_BYTES).decode("utf-8"))
        except (OSError, ValueError):
            document = None
        if isinstance(document, dict) and (
                str(document.get("format", "")).startswith("mocaplib-") or "asset" in document):
            return None
    return "not a file mocaplib writes"


#: The largest JSON output read to tell whether mocaplib wrote it (bytes).
MAX_OWN_JSON_BYTES = 512 << 20


def _check_writable(option: str, path: Path, folder: Path) -> None:
    """Create and remove a temporary file in ``folder``: permissions alone do not tell
    (root may write anywhere but a read-only or virtual file system such as /proc)."""
    import tempfile

    try:
        fd, probe = tempfile.mkstemp(prefix=".mocaplib-probe.", dir=folder)
    except OSError as exc:
        raise UsageError(f"{option} {path}: cannot write into {folder}: "
                         f"{exc.strerror or exc} (choose a folder you can write to)") from None
    os.close(fd)
    os.unlink(probe)


def add_force_option(parser) -> None:
    """``--force``: overwrite an existing output mocaplib did not write (:func:`foreign_file`)."""
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing output file that mocaplib did not write "
                             "(a C3D capture, another program's file); without it such a "
                             "file is refused before any work")


def check_output_folder(option: str, folder: str | os.PathLike, file_name: str,
                        inputs: list[str | os.PathLike]) -> None:
    """Raise :class:`UsageError` before any work when the folder ``option`` names cannot take
    the file ``file_name``: the folder is ``-`` or a file, lies under a file or where nothing
    can be written, or the file would overwrite an input or be a folder
    (:func:`check_outputs`; a missing folder is created when the file is written)."""
    if os.fspath(folder) == "-":
        raise UsageError(f"{option}: {DASH}")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{option} {folder} is a file; give a folder")
    check_outputs({option: folder / file_name}, inputs, create_folders=True)


def print_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NaN written as null)."""
    print(json.dumps(json_values(obj), indent=2, ensure_ascii=False))


def warn(message: str) -> None:
    """Print ``message`` as one warning line (control characters, line feeds included,
    escaped: :func:`mocaplib.io.printable`)."""
    print(f"warning: {printable(message, keep='')}", file=sys.stderr)


def add_protocol_option(parser, *, default: str = "the best shipped protocol") -> None:
    """``--protocol NAME|PATH|auto`` and ``--protocols DIR`` (repeatable): users' protocol
    folders added to the shipped one. Both are checked by :func:`apply_protocol_options` once
    the whole line is parsed (a name may come from a folder given after it): an unknown or
    malformed protocol, or a missing folder, is a usage error (exit 2)."""
    parser.add_argument("--protocol", default="auto", metavar="NAME|PATH|auto",
                        help="marker-set protocol: a name (shipped, or in a --protocols "
                             f"folder), a .toml file, or 'auto' (default: {default})")
    add_protocol_folders_option(parser)


def add_protocol_folders_option(parser) -> None:
    """``--protocols DIR`` (repeatable): users' protocol folders added to the shipped one
    (checked by :func:`apply_protocol_options`)."""
    parser.add_argument("--protocols", action="append", default=[], metavar="DIR",
                        help="a folder of your own protocols (*.toml) and landmarks "
                             "(landmarks.toml), added to the shipped ones; a name defined "
                             "there wins (repeatable; also $MOCAPLIB_PROTOCOLS)")


def apply_protocol_options(args) -> None:
    """Add ``args.protocols`` folders (:func:`mocaplib.markersets.protocols.use_protocol_folders`) and
    check ``args.protocol`` loads; :class:`UsageError` (exit 2) otherwise. Commands without
    the options pass through."""
    from ..markersets.protocols import load_protocol, use_protocol_folders

    option = "--protocols"
    try:
        if getattr(args, "protocols", None):
            use_protocol_folders(args.protocols)
        option = "--protocol"
        if getattr(args, "protocol", "auto") != "auto":
            load_protocol(args.protocol)
    except MocapError as exc:
        raise UsageError(f"{option}: {exc}") from None


#: ``--toe-off`` choices: :data:`mocaplib.gait.events.TOE_OFF_DEFINITIONS`, not imported here so that
#: the command line parses without loading scipy (~0.8 s); a test keeps the two equal.
TOE_OFF_CHOICES = ("foot_velocity", "lift")


def add_toe_off_option(parser) -> None:
    """``--toe-off``: which toe-off definition cuts the cycles (:mod:`mocaplib.gait.events`)."""
    parser.add_argument("--toe-off", choices=TOE_OFF_CHOICES, default="foot_velocity",
                        help="toe-off definition: 'foot_velocity' (the foot's upward-velocity "
                             "peak and the end of its roll, close to a force plate's Foot Off; "
                             "default) or 'lift' (a "
                             "rigid foot's lift-off: where the toe's upward velocity rises "
                             "fastest, ~18 ms before Foot Off on real feet)")


#: ``--max-gap`` default: :data:`mocaplib.gait.cycles.MAX_GAP_S` (a test keeps the two equal).
MAX_GAP_DEFAULT = 0.25
#: Largest ``--max-gap`` (s): :data:`mocaplib.build.settings.MAX_GAP_LIMIT_S` (a test keeps
#: the two equal).
MAX_GAP_LIMIT = 3600.0


def add_gap_option(parser) -> None:
    """``--max-gap``: the longest gap filled by interpolation (:mod:`mocaplib.gait.cycles`)."""
    parser.add_argument("--max-gap", type=positive(float, unit=" s", most=MAX_GAP_LIMIT),
                        default=MAX_GAP_DEFAULT,
                        metavar="S", dest="max_gap_s",
                        help="longest gap (s) filled by interpolation: in the foot markers the "
                             "gait events read, and in the frames the fit could not solve "
                             "inside a cycle; a cycle spanning a longer one is not cut "
                             f"(default {MAX_GAP_DEFAULT:g})")


def positive(kind: type, *, unit: str = "", most: float = math.inf):
    """argparse ``type=`` accepting finite numbers of ``kind`` (int or float) in (0, most];
    else exit 2."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            what = "a whole number" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (math.isfinite(value) and 0 < value <= most):
            limit = "" if math.isinf(most) else f" and <= {most:g}{unit}"
            raise argparse.ArgumentTypeError(f"must be > 0{unit}{limit}, got {text}")
        return value
    return parse


def jobs_count(text: str) -> int:
    """argparse ``type=`` of ``--jobs``: a whole number from 1 to
    :func:`mocaplib.build.workers.max_jobs` (more processes than processors only compete for
    them, each holding its own memory); else exit 2."""
    from ..build.workers import max_jobs

    jobs, limit = positive(int)(text), max_jobs()
    if jobs > limit:
        raise argparse.ArgumentTypeError(f"at most {limit}, the processors mocaplib may use "
                                          f"here; got {text}")
    return jobs


def bounded(limit: float):
    """argparse ``type=`` accepting numbers with ``|value| <= limit`` (NaN and inf refused);
    else exit 2."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not abs(value) <= limit:
            raise argparse.ArgumentTypeError(f"must be a number within ±{limit:g}, got {text}")
        return value
    return parse


def cutoff_type(text: str) -> float | str | None:
    """``--cutoff`` value: a frequency in Hz (> 0), ``auto`` or ``none`` (None)."""
    if text.lower() in ("auto", "none"):
        return None if text.lower() == "none" else "auto"
    return positive(float, unit=" Hz")(text)


def add_static_options(parser) -> None:
    """``--static FILE`` (repeatable: one static per subject or session), ``--static-pose``
    and ``--forward-reference FILE`` (repeatable), shared by ``fit``, ``cycles`` and
    ``build``."""
    parser.add_argument("--static", metavar="FILE", action="append",
                        help="static calibration C3D of the subject (default: calibrate from "
                             "each capture); repeat it for several subjects or sessions: each "
                             "capture is calibrated with the static showing its subject, and "
                             "one that none shows is an error")
    parser.add_argument("--static-window", type=time_window, metavar="START:END",
                        help="seconds of the static to calibrate on (default: the whole static "
                             "when the subject stands still in it, else its quietest second, "
                             "e.g. after a step in)")
    parser.add_argument("--static-pose", choices=("free", "neutral"), default="free",
                        help="'neutral': the static subject stands in the anatomical neutral "
                             "pose (every joint angle 0) and each marker's offset is measured "
                             "on it, placement error included; 'free' (default): the static "
                             "pose is fitted, then refined on the motion")
    parser.add_argument("--subject", metavar="NAME=VALUE", action="append", type=measurement,
                        default=[],
                        help="a subject measurement, metres or kilograms, that overrides the "
                             "one the calibration file stores (Plug-in Gait's PROCESSING "
                             "group): knee_width, ankle_width, elbow_width, shoulder_offset "
                             "(both sides, or with _l/_r), marker_diameter, leg_length (Davis "
                             "hip centres), "
                             "inter_asis_distance, body_mass, height; repeatable")
    parser.add_argument("--forward-reference", metavar="FILE", action="append",
                        help="a capture in which the subject walks forwards (straight or "
                             "curving, not side-stepping): the neutral static's heading is "
                             "turned so that the subject faces where they walk in it, which "
                             "removes the heading error of marker placement from v_l; repeat "
                             "it for several subjects or sessions (needs --static-pose neutral)")


def time_window(text: str) -> tuple[float, float]:
    """One ``START:END`` (seconds, 0 <= START <= END)."""
    start, colon, end = text.partition(":")
    try:
        window = (float(start), float(end))
    except ValueError:
        window = None
    if not colon or window is None or not (0 <= window[0] <= window[1] < math.inf):
        raise argparse.ArgumentTypeError(f"expected START:END in seconds with 0 <= START <= "
                                         f"END, got {text!r}")
    return window


def measurement(text: str) -> tuple[str, float]:
    """One ``--subject NAME=VALUE``: a known measurement name (sided names without ``_l`` or
    ``_r`` mean both sides) and a number > 0, SI units."""
    from ..model.anatomy import MEASUREMENT_LIMITS, MEASUREMENTS

    name, _, value = text.partition("=")
    name = name.strip()
    known = set(MEASUREMENTS) | {m[:-2] for m in MEASUREMENTS if m.endswith(("_l", "_r"))}
    if name not in known:
        raise argparse.ArgumentTypeError(f"unknown measurement {name!r}; known: "
                                         f"{', '.join(sorted(known))}")
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: {value!r} is not a number") from None
    most = MEASUREMENT_LIMITS[name.removesuffix("_l").removesuffix("_r")]
    if not 0 < number <= most:
        raise argparse.ArgumentTypeError(f"{name}: {value} must be > 0 and <= {most:g} "
                                         f"({'kg' if name == 'body_mass' else 'metres'})")
    return name, number


def measurements(args) -> dict[str, float]:
    """The ``--subject`` values as :attr:`mocaplib.trial.Trial.measurements` keys (a sided
    name given bare sets both sides)."""
    from ..model.anatomy import MEASUREMENTS

    out: dict[str, float] = {}
    for name, value in args.subject:
        for key in ([name] if name in MEASUREMENTS else [f"{name}_l", f"{name}_r"]):
            out[key] = value
    return out


def add_cutoff_option(parser) -> None:
    parser.add_argument("--cutoff", type=cutoff_type, default="auto", metavar="HZ|auto|none",
                        help="low-pass the markers before calibrating and fitting: zero-lag "
                             "Butterworth at HZ (-3 dB), 'auto' (default: Winter's residual "
                             "analysis per capture) or 'none'")


#: What to do about a library path that does not exist.
LIBRARY_HINT = "check the path; `mocaplib build` writes a library"


def check_inputs(inputs: list[str], statics: list[str] | None = None, *,
                 static_pose: str = "free", references: list[str] | None = None,
                 static_window: tuple[float, float] | None = None,
                 hint: str = "check the path") -> list:
    """Raise :class:`UsageError` before any work when a path given on the command line does
    not exist (the message ends with ``hint``), a ``--static`` cannot be read or does not
    stand still in ``static_window`` or its quietest second
    (:func:`mocaplib.statics.standing_part`), a ``--forward-reference``
    cannot be read, or ``--static-pose neutral`` comes without a static or
    ``--forward-reference`` without a neutral static; a static or reference must be one C3D
    file. Returns the static trials, each file read once (the same file given twice counts
    once: :func:`mocaplib.io.unique_paths`)."""
    if static_pose == "neutral" and not statics:
        raise UsageError("--static-pose neutral describes the static trial: give it with "
                         "--static FILE, or leave --static-pose out")
    if references and static_pose != "neutral":
        raise UsageError("--forward-reference turns the heading of a static in the neutral "
                         "pose: give --static FILE --static-pose neutral, or leave "
                         "--forward-reference out")
    from ..io import unique_paths
    from ..io.c3d import read_c3d
    from ..trial import require_markers

    calibration = [("--static", path) for path in statics or ()] + [
        ("--forward-reference", path) for path in references or ()]
    for option, path in calibration:
        if not path:
            raise UsageError(f"{option}: an empty path: give a C3D file")
    for option, path in [*(("", path) for path in inputs),
                         *((f"{option}: ", path) for option, path in calibration)]:
        if os.fspath(path) == "-":
            raise UsageError(f"{option}{DASH}")
        if not Path(path).exists():
            raise UsageError(f"{option}{path}: no such file or folder ({hint})")
    for option, path in calibration:
        if Path(path).is_dir():
            raise UsageError(f"{option}: {path}: is a folder: give one C3D file")
    trials = []
    for path in unique_paths(statics or ()):
        from ..statics import standing_part

        try:
            trials.append(read_c3d(path))
            require_markers(trials[-1])
            standing_part(trials[-1], window=static_window)
        except Exception as exc:
            raise UsageError(f"--static: {unreadable(path, exc)}") from None
    for path in unique_paths(references or ()):
        try:
            require_markers(read_c3d(path))
        except Exception as exc:
            raise UsageError(f"--forward-reference: {unreadable(path, exc)}") from None
    return trials


def unreadable(path: str | os.PathLike, error: Exception) -> str:
    """Why the file ``path`` could not be used, as one line: a :class:`MocapError`'s own text,
    any other exception as an internal error naming the file."""
    if isinstance(error, MocapError):
        return str(error)
    return (f"{os.fspath(path)}: internal error: {type(error).__name__}: {error} (a bug in "
            "mocaplib: please report it with this file)")


def heading_offsets(args) -> tuple[float, ...] | None:
    """Per ``--static``, the heading correction (radians) its ``--forward-reference`` captures
    measure, through the stages ``mocaplib build`` runs with these options
    (:func:`mocaplib.build.forward.forward_offsets`); None without a reference."""
    if not args.forward_reference:
        return None
    from ..build.forward import forward_offsets
    from ..build.settings import BuildSettings

    return forward_offsets(BuildSettings(
        protocol=args.protocol, static=args.static, static_pose=args.static_pose,
        static_window=args.static_window,
        forward_reference=args.forward_reference, cutoff=args.cutoff,
        measurements=measurements(args),
        toe_off=getattr(args, "toe_off", "foot_velocity")))
